-- 008 stop returned (MariaDB): mirrors 008_stop_returned.sqlite.sql; see there for the why.
-- Written to run again harmlessly (IF NOT EXISTS), like 005.

ALTER TABLE task_stop ADD COLUMN IF NOT EXISTS returned LONGTEXT NOT NULL DEFAULT '[]'
    CHECK (json_valid(returned));
