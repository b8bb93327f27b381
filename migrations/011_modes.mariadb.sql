-- 011 modes (MariaDB): mirrors 011_modes.sqlite.sql; see there for the why. MODIFY changes a
-- CHECK in place; every statement runs again harmlessly. MariaDB has no partial index: "one
-- open call per table and kind" is a UNIQUE index on a generated column that holds the pair
-- only while the call is open (NULLs never collide), as task_active_robot does in 001.

ALTER TABLE waypoints
    MODIFY COLUMN kind VARCHAR(16) NOT NULL DEFAULT 'other'
        CHECK (kind IN ('table', 'home', 'pass', 'other', 'dish_return', 'dock'));

ALTER TABLE robot_info
    MODIFY COLUMN status VARCHAR(16) NOT NULL DEFAULT 'Offline' CHECK (status IN (
        'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered', 'Stopped',
        'Transit', 'Manual', 'Error', 'Charging')),
    MODIFY COLUMN resume VARCHAR(16) NULL CHECK (resume IS NULL OR resume IN (
        'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered', 'Stopped',
        'Transit', 'Manual', 'Error', 'Charging')),
    ADD COLUMN IF NOT EXISTS dock VARCHAR(255) NULL;

ALTER TABLE task
    ADD COLUMN IF NOT EXISTS kind VARCHAR(16) NOT NULL DEFAULT 'delivery'
        CHECK (kind IN ('delivery', 'bussing', 'cruise'));
ALTER TABLE task_stop
    ADD COLUMN IF NOT EXISTS purpose VARCHAR(16) NOT NULL DEFAULT 'deliver'
        CHECK (purpose IN ('deliver', 'collect', 'unload', 'visit'));
ALTER TABLE orders
    ADD COLUMN IF NOT EXISTS special VARCHAR(120) NULL,
    ADD COLUMN IF NOT EXISTS tray INT NULL CHECK (tray IS NULL OR (tray >= 1 AND tray <= 12));

CREATE TABLE IF NOT EXISTS `call` (
    id           BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    table_name   VARCHAR(255) NOT NULL,
    kind         VARCHAR(16) NOT NULL CHECK (kind IN ('plates', 'waiter', 'bill')),
    source       VARCHAR(255) NOT NULL CHECK (char_length(source) > 0),
    opened_at    DOUBLE NOT NULL,
    presses      INT NOT NULL DEFAULT 1 CHECK (presses >= 1),
    escalated_at DOUBLE NULL,
    answered_at  DOUBLE NULL,
    answered_by  VARCHAR(255) NULL,
    cancelled_at DOUBLE NULL,
    cancelled_by VARCHAR(255) NULL,
    task_id      BIGINT NULL,
    open_key     VARCHAR(300) AS (CASE WHEN answered_at IS NULL AND cancelled_at IS NULL
                                       THEN concat(kind, '/', table_name) END) PERSISTENT,
    CHECK (answered_at IS NULL OR cancelled_at IS NULL),
    UNIQUE KEY call_open (open_key),
    KEY call_opened (opened_at),
    CONSTRAINT call_table FOREIGN KEY (table_name) REFERENCES waypoints (name),
    CONSTRAINT call_task FOREIGN KEY (task_id) REFERENCES task (id)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS call_button (
    name        VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    table_name  VARCHAR(255) NOT NULL,
    kind        VARCHAR(16) NOT NULL CHECK (kind IN ('plates', 'waiter', 'bill')),
    digest      VARCHAR(64) NOT NULL,
    created_at  DOUBLE NOT NULL,
    revoked_at  DOUBLE NULL,
    last_press  DOUBLE NULL,
    UNIQUE KEY call_button_digest (digest),
    CONSTRAINT call_button_table FOREIGN KEY (table_name) REFERENCES waypoints (name)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

ALTER TABLE robot_info
    ADD CONSTRAINT robot_info_dock FOREIGN KEY IF NOT EXISTS (dock) REFERENCES waypoints (name);
