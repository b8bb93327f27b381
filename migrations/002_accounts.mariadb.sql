-- 002 accounts (MariaDB): mirrors 002_accounts.sqlite.sql; see there for the why.

CREATE TABLE users (
    name        VARCHAR(64) NOT NULL PRIMARY KEY CHECK (CHAR_LENGTH(name) > 0),
    role        VARCHAR(16) NOT NULL CHECK (role IN ('owner', 'staff')),
    pw_hash     VARCHAR(255) NOT NULL,
    created_at  DOUBLE NOT NULL,
    changed_at  DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE tokens (
    id          BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    digest      CHAR(64) NOT NULL UNIQUE,
    kind        VARCHAR(16) NOT NULL CHECK (kind IN ('session', 'device')),
    user_name   VARCHAR(64),
    role        VARCHAR(16) NOT NULL CHECK (role IN (
                    'owner', 'staff', 'robot-screen', 'table-screen', 'integration')),
    robot       VARCHAR(64),
    tbl         VARCHAR(64),
    scopes      VARCHAR(255) NOT NULL DEFAULT '',
    label       VARCHAR(255) NOT NULL DEFAULT '',
    created_at  DOUBLE NOT NULL,
    expires_at  DOUBLE,
    revoked_at  DOUBLE,
    last_used_at DOUBLE,
    CONSTRAINT tokens_session_user CHECK (kind = 'device' OR user_name IS NOT NULL),
    CONSTRAINT tokens_robot_screen CHECK (role <> 'robot-screen' OR robot IS NOT NULL),
    CONSTRAINT tokens_table_screen CHECK (role <> 'table-screen' OR tbl IS NOT NULL),
    CONSTRAINT tokens_user FOREIGN KEY (user_name) REFERENCES users (name) ON DELETE CASCADE
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE audit (
    id          BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    ts          DOUBLE NOT NULL,
    actor       VARCHAR(255) NOT NULL,
    role        VARCHAR(16) NOT NULL,
    peer        VARCHAR(255) NOT NULL,
    verb        VARCHAR(32) NOT NULL,
    target      VARCHAR(255),
    outcome     VARCHAR(32) NOT NULL,
    data        LONGTEXT NOT NULL DEFAULT '{}' CHECK (json_valid(data)),
    INDEX audit_ts (ts)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
