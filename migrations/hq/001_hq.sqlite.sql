-- 001 hq (SQLite): the chain's centre (serveur hq, issue 34). MariaDB is the centre's database
-- (001_hq.mariadb.sql); this file lets a small chain or a test run it on one file.
--
--  * hq_site: one row per site heard of: ``stored``, the last number of its events stored here
--    (every one up to it is, none after it: serveur.chain.ledger), ``head`` the last it said
--    it gave, when it was last heard and whether it is shown up or down;
--  * hq_event: every site's events, exactly once: the primary key (site, seq) is the
--    idempotency key (a duplicate changes nothing);
--  * hq_liveness: each time a site went down or came back up (once each);
--  * hq_user: the centre's own accounts (not the sites'): read-only dashboard logins.

CREATE TABLE hq_site (
    site        TEXT PRIMARY KEY NOT NULL,
    stored      INTEGER NOT NULL DEFAULT 0 CHECK (stored >= 0),
    head        INTEGER NOT NULL DEFAULT 0 CHECK (head >= 0),
    heard_at    REAL,
    site_time   REAL,
    state       TEXT CHECK (state IS NULL OR state IN ('up', 'down')),
    state_at    REAL,
    first_at    REAL NOT NULL
) STRICT;

CREATE TABLE hq_event (
    site      TEXT NOT NULL REFERENCES hq_site (site),
    seq       INTEGER NOT NULL CHECK (seq > 0),
    id        INTEGER NOT NULL,
    ts        REAL NOT NULL,
    kind      TEXT NOT NULL,
    robot     TEXT,
    task_id   INTEGER,
    order_id  INTEGER,
    data      TEXT NOT NULL CHECK (json_valid(data)),
    PRIMARY KEY (site, seq)
) STRICT;

CREATE TABLE hq_liveness (
    id     INTEGER PRIMARY KEY,
    site   TEXT NOT NULL REFERENCES hq_site (site),
    at     REAL NOT NULL,
    state  TEXT NOT NULL CHECK (state IN ('up', 'down'))
) STRICT;

CREATE TABLE hq_user (
    name           TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    password_hash  TEXT NOT NULL,
    created_at     REAL NOT NULL
) STRICT;
