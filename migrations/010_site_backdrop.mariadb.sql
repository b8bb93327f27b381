-- 010 site backdrop (MariaDB): mirrors 010_site_backdrop.sqlite.sql; see there for the why.

CREATE TABLE IF NOT EXISTS site_backdrop (
    id          INT NOT NULL PRIMARY KEY CHECK (id = 1),
    image       LONGBLOB NOT NULL CHECK (length(image) > 0),
    mime        VARCHAR(16) NOT NULL CHECK (mime IN ('image/png', 'image/jpeg')),
    digest      VARCHAR(64) NOT NULL,
    scale       DOUBLE NOT NULL CHECK (scale > 0),
    rotation    DOUBLE NOT NULL,
    tx          DOUBLE NOT NULL,
    ty          DOUBLE NOT NULL,
    rms         DOUBLE NOT NULL CHECK (rms >= 0),
    points      INT NOT NULL CHECK (points >= 2),
    updated_at  DOUBLE NOT NULL,
    updated_by  VARCHAR(255) NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;
