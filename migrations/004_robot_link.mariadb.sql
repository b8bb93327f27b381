-- 004 robot_link (MariaDB): mirrors 004_robot_link.sqlite.sql; see there for the why.

ALTER TABLE robot_info ADD COLUMN link VARCHAR(2000) NOT NULL DEFAULT '{}';
