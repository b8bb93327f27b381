-- 001 hq (MariaDB): the chain's centre (serveur hq, issue 34); 001_hq.sqlite.sql says what
-- each table is for.

CREATE TABLE IF NOT EXISTS hq_site (
    site        VARCHAR(32) NOT NULL PRIMARY KEY,
    stored      BIGINT NOT NULL DEFAULT 0 CHECK (stored >= 0),
    head        BIGINT NOT NULL DEFAULT 0 CHECK (head >= 0),
    heard_at    DOUBLE NULL,
    site_time   DOUBLE NULL,
    state       VARCHAR(8) NULL CHECK (state IS NULL OR state IN ('up', 'down')),
    state_at    DOUBLE NULL,
    first_at    DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS hq_event (
    site      VARCHAR(32) NOT NULL,
    seq       BIGINT NOT NULL CHECK (seq > 0),
    id        BIGINT NOT NULL,
    ts        DOUBLE NOT NULL,
    kind      VARCHAR(255) NOT NULL,
    robot     VARCHAR(255) NULL,
    task_id   BIGINT NULL,
    order_id  BIGINT NULL,
    data      LONGTEXT NOT NULL CHECK (json_valid(data)),
    PRIMARY KEY (site, seq),
    CONSTRAINT hq_event_site FOREIGN KEY (site) REFERENCES hq_site (site)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS hq_liveness (
    id     BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    site   VARCHAR(32) NOT NULL,
    at     DOUBLE NOT NULL,
    state  VARCHAR(8) NOT NULL CHECK (state IN ('up', 'down')),
    CONSTRAINT hq_liveness_site FOREIGN KEY (site) REFERENCES hq_site (site)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS hq_user (
    name           VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    password_hash  VARCHAR(255) NOT NULL,
    created_at     DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
