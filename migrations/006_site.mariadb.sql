-- 006 site (MariaDB): mirrors 006_site.sqlite.sql; see there for the why. Written to run again
-- harmlessly (IF NOT EXISTS), like 005.

ALTER TABLE robot_info ADD COLUMN IF NOT EXISTS removed_at DOUBLE NULL;
ALTER TABLE waypoints ADD COLUMN IF NOT EXISTS removed_at DOUBLE NULL;

CREATE TABLE IF NOT EXISTS settings (
    name        VARCHAR(64) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    value       LONGTEXT NOT NULL CHECK (json_valid(value)),
    updated_at  DOUBLE NOT NULL,
    updated_by  VARCHAR(255) NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE INDEX IF NOT EXISTS audit_actor ON audit (actor, id);
CREATE INDEX IF NOT EXISTS audit_verb ON audit (verb, id);
