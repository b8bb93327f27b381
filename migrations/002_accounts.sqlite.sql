-- 002 accounts (SQLite): people, access tokens and the audit trail (security issue).
--
--  * users are people who log in with a password (owner, staff); ``pw_hash`` is scrypt with
--    its parameters inside (serveur.auth.hash_password), never the password;
--  * tokens are what a connection presents: a person's session (kind 'session', made by a
--    password login, expiring) or a device/script token (kind 'device': robot and table
--    screens, integrations, staff kiosks). Only SHA-256 of the token is stored (``digest``),
--    so a copy of this file does not hand out working sessions. Revoked and expired tokens
--    stay as history until removed; a user's removal deletes their sessions with them;
--  * audit has one row per instruction given (accepted or refused): who, from where, what,
--    and the outcome. Separate from ``events``: events say what changed, audit says who
--    asked, including requests that changed nothing because they were refused.

CREATE TABLE users (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    role        TEXT NOT NULL CHECK (role IN ('owner', 'staff')),
    pw_hash     TEXT NOT NULL,
    created_at  REAL NOT NULL,
    changed_at  REAL NOT NULL
) STRICT;

CREATE TABLE tokens (
    id          INTEGER PRIMARY KEY,
    digest      TEXT NOT NULL UNIQUE CHECK (length(digest) = 64),
    kind        TEXT NOT NULL CHECK (kind IN ('session', 'device')),
    user_name   TEXT REFERENCES users (name) ON DELETE CASCADE,
    role        TEXT NOT NULL CHECK (role IN (
                    'owner', 'staff', 'robot-screen', 'table-screen', 'integration')),
    robot       TEXT,
    tbl         TEXT,
    scopes      TEXT NOT NULL DEFAULT '',
    label       TEXT NOT NULL DEFAULT '',
    created_at  REAL NOT NULL,
    expires_at  REAL,
    revoked_at  REAL,
    last_used_at REAL,
    CHECK (kind = 'device' OR user_name IS NOT NULL),
    CHECK (role <> 'robot-screen' OR robot IS NOT NULL),
    CHECK (role <> 'table-screen' OR tbl IS NOT NULL)
) STRICT;
CREATE INDEX tokens_user ON tokens (user_name);

CREATE TABLE audit (
    id          INTEGER PRIMARY KEY,
    ts          REAL NOT NULL,
    actor       TEXT NOT NULL,
    role        TEXT NOT NULL,
    peer        TEXT NOT NULL,
    verb        TEXT NOT NULL,
    target      TEXT,
    outcome     TEXT NOT NULL,
    data        TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(data))
) STRICT;
CREATE INDEX audit_ts ON audit (ts);
