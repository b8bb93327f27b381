-- 005 service (MariaDB): the same changes as 005_service.sqlite.sql (read it for the why).
--
-- MariaDB changes a column's CHECK with MODIFY COLUMN, in place; no rebuild by hand. Every
-- statement is written to run again harmlessly (see 001): MODIFY is idempotent, ADD COLUMN
-- and CREATE TABLE say IF NOT EXISTS, the data update and the seed only touch what is missing.

ALTER TABLE robot_info
    MODIFY COLUMN status VARCHAR(16) NOT NULL DEFAULT 'Offline' CHECK (status IN (
        'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered', 'Stopped',
        'Transit', 'Manual', 'Error')),
    MODIFY COLUMN resume VARCHAR(16) NULL CHECK (resume IS NULL OR resume IN (
        'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered', 'Stopped',
        'Transit', 'Manual', 'Error')),
    ADD COLUMN IF NOT EXISTS trays INT NULL CHECK (trays IS NULL OR (trays >= 1 AND trays <= 12));

ALTER TABLE orders
    MODIFY COLUMN status VARCHAR(16) NOT NULL DEFAULT 'pending'
        CHECK (status IN ('ordered', 'cooking', 'pending', 'assigned', 'delivered', 'returned',
                          'voided', 'cancelled')),
    MODIFY COLUMN ready_at DOUBLE NULL,
    ADD COLUMN IF NOT EXISTS quantity INT NOT NULL DEFAULT 1 CHECK (quantity >= 1 AND quantity <= 99),
    ADD COLUMN IF NOT EXISTS note VARCHAR(200) NULL,
    ADD COLUMN IF NOT EXISTS ordered_at DOUBLE NULL,
    ADD COLUMN IF NOT EXISTS returned_at DOUBLE NULL,
    ADD COLUMN IF NOT EXISTS voided_at DOUBLE NULL;

UPDATE orders SET status = 'voided' WHERE status = 'cancelled';
UPDATE orders SET ordered_at = ready_at WHERE ordered_at IS NULL;

ALTER TABLE orders
    MODIFY COLUMN status VARCHAR(16) NOT NULL DEFAULT 'pending'
        CHECK (status IN ('ordered', 'cooking', 'pending', 'assigned', 'delivered', 'returned',
                          'voided'));

CREATE TABLE IF NOT EXISTS menu (
    dish        VARCHAR(64) NOT NULL PRIMARY KEY CHECK (char_length(dish) > 0),
    category    VARCHAR(64) NOT NULL DEFAULT '',
    price_cents BIGINT NULL CHECK (price_cents IS NULL OR price_cents >= 0),
    available   TINYINT NOT NULL DEFAULT 1 CHECK (available IN (0, 1)),
    position    INT NOT NULL DEFAULT 0,
    updated_at  DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

INSERT IGNORE INTO menu (dish, category, position, updated_at) VALUES
    ('Laksa', 'Mains', 1, 0), ('Satay', 'Mains', 2, 0), ('Nasi lemak', 'Mains', 3, 0),
    ('Rendang', 'Mains', 4, 0), ('Roti canai', 'Mains', 5, 0), ('Char kway teow', 'Mains', 6, 0),
    ('Teh tarik', 'Drinks', 7, 0), ('Cendol', 'Desserts', 8, 0);

CREATE TABLE IF NOT EXISTS table_block (
    waypoint    VARCHAR(255) NOT NULL PRIMARY KEY,
    reason      TEXT NOT NULL,
    robot       VARCHAR(255) NULL,
    since       DOUBLE NOT NULL,
    CONSTRAINT table_block_waypoint FOREIGN KEY (waypoint) REFERENCES waypoints (name)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
