-- 003 status_since (MariaDB): mirrors 003_status_since.sqlite.sql; see there for the why.

ALTER TABLE robot_info ADD COLUMN status_since DOUBLE NOT NULL DEFAULT 0;
UPDATE robot_info SET status_since = updated_at;
