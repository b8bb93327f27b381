-- 009 site map (MariaDB): mirrors 009_site_map.sqlite.sql; see there for the why.

CREATE TABLE IF NOT EXISTS site_map (
    id          INT NOT NULL PRIMARY KEY CHECK (id = 1),
    resolution  DOUBLE NOT NULL CHECK (resolution > 0),
    origin_x    DOUBLE NOT NULL,
    origin_y    DOUBLE NOT NULL,
    width       INT NOT NULL CHECK (width > 0),
    height      INT NOT NULL CHECK (height > 0),
    cells       LONGBLOB NOT NULL CHECK (length(cells) = width * height),
    source      VARCHAR(255) NOT NULL,
    updated_at  DOUBLE NOT NULL,
    updated_by  VARCHAR(255) NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
