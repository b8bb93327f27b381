-- 012 till (MariaDB): orders from the restaurant's till (issue 33); 012_till.sqlite.sql says
-- what each table holds.

CREATE TABLE IF NOT EXISTS till_job (
    id           BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    received_at  DOUBLE NOT NULL,
    source       VARCHAR(255) NOT NULL,
    raw          LONGBLOB NOT NULL,
    forwarded    TINYINT NULL CHECK (forwarded IS NULL OR forwarded IN (0, 1))
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS till_ticket (
    id           BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    job_id       BIGINT NOT NULL,
    part         INT NOT NULL DEFAULT 0,
    received_at  DOUBLE NOT NULL,
    text         LONGTEXT NOT NULL,
    status       VARCHAR(16) NOT NULL DEFAULT 'unread'
                     CHECK (status IN ('unread', 'ordered', 'reprint', 'void', 'by_hand')),
    `key`        VARCHAR(64) NULL,
    first_key    VARCHAR(64) NULL,
    table_name   VARCHAR(255) NULL,
    reading      LONGTEXT NULL CHECK (reading IS NULL OR json_valid(reading)),
    problem      TEXT NULL,
    of_ticket    BIGINT NULL,
    read_at      DOUBLE NULL,
    handled_by   VARCHAR(255) NULL,
    KEY till_ticket_key (`key`),
    UNIQUE KEY till_ticket_first_key (first_key),
    KEY till_ticket_status (status, id),
    CONSTRAINT till_ticket_job FOREIGN KEY (job_id) REFERENCES till_job (id),
    CONSTRAINT till_ticket_of FOREIGN KEY (of_ticket) REFERENCES till_ticket (id)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS till_name (
    pos_name     VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(pos_name) > 0),
    dish         VARCHAR(255) NOT NULL CHECK (char_length(dish) > 0),
    updated_at   DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS till_setting (
    name         VARCHAR(64) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    value        LONGTEXT NOT NULL CHECK (json_valid(value)),
    updated_at   DOUBLE NOT NULL,
    updated_by   VARCHAR(255) NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

ALTER TABLE orders ADD COLUMN IF NOT EXISTS ticket_id BIGINT NULL;
ALTER TABLE orders
    ADD CONSTRAINT orders_ticket FOREIGN KEY IF NOT EXISTS (ticket_id) REFERENCES till_ticket (id);
