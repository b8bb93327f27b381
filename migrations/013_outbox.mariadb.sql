-- 013 outbox (MariaDB): mirrors 013_outbox.sqlite.sql (issue 34), which says why.
-- ``outbox_state``'s one row is updated by every event's transaction: InnoDB's row lock makes
-- the numbers follow commit order (a second writer waits for the first to commit).

CREATE TABLE IF NOT EXISTS outbox (
    seq       BIGINT NOT NULL PRIMARY KEY CHECK (seq > 0),
    event_id  BIGINT NOT NULL,
    at        DOUBLE NOT NULL,
    UNIQUE KEY outbox_event (event_id)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS outbox_state (
    id         INT NOT NULL PRIMARY KEY CHECK (id = 1),
    head       BIGINT NOT NULL CHECK (head >= 0),
    sent       BIGINT NOT NULL DEFAULT 0 CHECK (sent >= 0),
    sent_at    DOUBLE NULL,
    confirmed  BIGINT NOT NULL DEFAULT 0 CHECK (confirmed >= 0)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

INSERT INTO outbox (seq, event_id, at)
    SELECT ROW_NUMBER() OVER (ORDER BY id), id, ts FROM events;

INSERT INTO outbox_state (id, head) SELECT 1, COUNT(*) FROM events;
