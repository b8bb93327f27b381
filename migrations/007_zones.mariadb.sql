-- 007 zones (MariaDB): mirrors 007_zones.sqlite.sql; see there for the why.

CREATE TABLE IF NOT EXISTS zones (
    name        VARCHAR(64) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    points      LONGTEXT NOT NULL CHECK (json_valid(points) AND json_length(points) >= 3),
    wait_at     VARCHAR(255) NULL,
    capacity    INT NOT NULL DEFAULT 1 CHECK (capacity >= 1 AND capacity <= 8),
    updated_at  DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
