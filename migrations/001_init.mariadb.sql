-- 001 init (MariaDB >= 10.5): the same tables, constraints and views as 001_init.sqlite.sql.
--
-- Same columns, names and rules as the SQLite file; only the dialect differs:
--  * text keys are VARCHAR(255) (an index needs a length) in utf8mb4_nopad_bin, so that names
--    compare like SQLite's TEXT: case-sensitive, and "T1 " is not "T1" (the PAD SPACE
--    collations, utf8mb4_bin included, would ignore trailing spaces),
--  * REAL is DOUBLE (both are IEEE binary64), AUTOINCREMENT is AUTO_INCREMENT (InnoDB keeps the
--    counter across restarts since 10.2.4, so ids are never reused; unlike SQLite a rolled-back
--    insert leaves a gap),
--  * ``key`` is a reserved word, quoted with backticks,
--  * MariaDB has no partial indexes. "one active task per robot" is a UNIQUE index on a
--    generated column that holds the robot's name only while the task is active (NULLs never
--    collide in a UNIQUE index); the other partial indexes are plain indexes (a UNIQUE index
--    ignores NULLs anyway, and NULL entries only cost a little space),
--  * robot_info <-> task refer to each other: robot_info is created without its foreign key to
--    task, which ALTER TABLE adds once task exists,
--  * JSON columns are LONGTEXT with CHECK (json_valid(...)), as in SQLite,
--  * the views are SQL SECURITY INVOKER: the reader's own SELECT rights apply, and they keep
--    working when the account that ran the migration is dropped (a DEFINER view would not).
-- Every statement is DDL, which MariaDB commits at once: a migration cannot be one transaction
-- here. So the store serialises migrations with GET_LOCK (two servers starting together), and
-- every statement is written to be run again harmlessly (IF NOT EXISTS): a server
-- that died half-way through leaves a version unrecorded, and the next start simply re-runs it.
-- Later MariaDB migrations must keep to that rule.

CREATE TABLE IF NOT EXISTS waypoints (
    name        VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    x           DOUBLE NOT NULL,
    y           DOUBLE NOT NULL,
    yaw         DOUBLE NOT NULL DEFAULT 0,
    kind        VARCHAR(16) NOT NULL DEFAULT 'other'
                    CHECK (kind IN ('table', 'home', 'pass', 'other')),
    created_at  DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS robot_info (
    name         VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(name) > 0),
    url          TEXT NOT NULL,
    home         VARCHAR(255) NULL,
    kinematics   VARCHAR(255) NOT NULL DEFAULT 'omni' CHECK (char_length(kinematics) > 0),
    mode         VARCHAR(16) NOT NULL DEFAULT 'off' CHECK (mode IN ('off', 'auto', 'manual')),
    status       VARCHAR(16) NOT NULL DEFAULT 'Offline' CHECK (status IN (
                     'Offline', 'Ready', 'Awaiting', 'Delivering', 'Delivered', 'Stopped',
                     'Transit', 'Manual', 'Error')),
    resume       VARCHAR(16) NULL CHECK (resume IS NULL OR resume IN (
                     'Offline', 'Ready', 'Awaiting', 'Delivering', 'Delivered', 'Stopped',
                     'Transit', 'Manual', 'Error')),
    current_task BIGINT NULL,
    battery      DOUBLE NULL CHECK (battery IS NULL OR (battery >= 0 AND battery <= 1)),
    x            DOUBLE NULL,
    y            DOUBLE NULL,
    yaw          DOUBLE NULL,
    last_error   TEXT NULL,
    updated_at   DOUBLE NOT NULL,
    -- One trip per robot at a time, and a trip on one robot at a time.
    UNIQUE KEY robot_info_current_task (current_task),
    CONSTRAINT robot_info_home FOREIGN KEY (home) REFERENCES waypoints (name)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS task (
    id           BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    robot_name   VARCHAR(255) NULL,
    status       VARCHAR(16) NOT NULL DEFAULT 'queued'
                     CHECK (status IN ('queued', 'active', 'done', 'cancelled')),
    current_stop INT NOT NULL DEFAULT 0 CHECK (current_stop >= 0),
    created_at   DOUBLE NOT NULL,
    started_at   DOUBLE NULL,
    finished_at  DOUBLE NULL,
    -- The robot while the task is active, else NULL: the partial index of the SQLite schema.
    active_robot VARCHAR(255) AS (CASE WHEN status = 'active' THEN robot_name END) PERSISTENT,
    CHECK (status <> 'queued' OR robot_name IS NULL),
    CHECK (status <> 'active' OR (robot_name IS NOT NULL AND started_at IS NOT NULL)),
    CHECK (status NOT IN ('done', 'cancelled') OR finished_at IS NOT NULL),
    KEY task_status (status),
    UNIQUE KEY task_active_robot (active_robot),
    CONSTRAINT task_robot FOREIGN KEY (robot_name) REFERENCES robot_info (name)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

ALTER TABLE robot_info
    ADD CONSTRAINT robot_info_task FOREIGN KEY IF NOT EXISTS (current_task) REFERENCES task (id);

-- Stops are numbered 0..n-1 in visiting order (``task.current_stop`` indexes them), one per
-- table and trip. A stop's dishes are the trip's orders for that table: no link table needed.
CREATE TABLE IF NOT EXISTS task_stop (
    task_id     BIGINT NOT NULL,
    seq         INT NOT NULL CHECK (seq >= 0),
    waypoint    VARCHAR(255) NOT NULL,
    status      VARCHAR(16) NOT NULL DEFAULT 'pending'
                    CHECK (status IN ('pending', 'arrived', 'done', 'skipped')),
    arrived_at  DOUBLE NULL,
    done_at     DOUBLE NULL,
    PRIMARY KEY (task_id, seq),
    UNIQUE KEY task_stop_table (task_id, waypoint),
    CHECK (status <> 'done' OR done_at IS NOT NULL),
    CONSTRAINT task_stop_task FOREIGN KEY (task_id) REFERENCES task (id) ON DELETE CASCADE,
    CONSTRAINT task_stop_waypoint FOREIGN KEY (waypoint) REFERENCES waypoints (name)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS idempotency (
    `key`        VARCHAR(255) NOT NULL PRIMARY KEY CHECK (char_length(`key`) > 0),
    kind         VARCHAR(16) NOT NULL CHECK (kind IN ('order', 'tasks')),
    fingerprint  VARCHAR(255) NOT NULL,
    result       LONGTEXT NOT NULL CHECK (json_valid(result)),
    created_at   DOUBLE NOT NULL
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

CREATE TABLE IF NOT EXISTS orders (
    id            BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    dish          TEXT NOT NULL CHECK (char_length(dish) > 0),
    res_table     VARCHAR(255) NOT NULL,
    status        VARCHAR(16) NOT NULL DEFAULT 'pending'
                      CHECK (status IN ('pending', 'assigned', 'delivered', 'cancelled')),
    task_num      BIGINT NULL,
    `key`         VARCHAR(255) NULL,  -- the client's idempotency key, also in ``idempotency``
    ready_at      DOUBLE NOT NULL,
    dispatched_at DOUBLE NULL,
    delivered_at  DOUBLE NULL,
    -- On a trip exactly while assigned or delivered: pending and cancelled dishes are free.
    CHECK ((task_num IS NOT NULL) = (status IN ('assigned', 'delivered'))),
    CHECK (status <> 'delivered' OR delivered_at IS NOT NULL),
    UNIQUE KEY orders_key (`key`),
    KEY orders_status (status),
    KEY orders_table (res_table, status),
    KEY orders_task (task_num, res_table),
    CONSTRAINT orders_table_wp FOREIGN KEY (res_table) REFERENCES waypoints (name),
    CONSTRAINT orders_task_fk FOREIGN KEY (task_num) REFERENCES task (id)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

-- The audit trail. No foreign keys on purpose: it records history, it must never block (or
-- be cascaded by) a change to the rows it mentions.
CREATE TABLE IF NOT EXISTS events (
    id        BIGINT NOT NULL AUTO_INCREMENT PRIMARY KEY,
    ts        DOUBLE NOT NULL,
    kind      VARCHAR(255) NOT NULL CHECK (char_length(kind) > 0),
    robot     VARCHAR(255) NULL,
    task_id   BIGINT NULL,
    order_id  BIGINT NULL,
    data      LONGTEXT NOT NULL DEFAULT '{}' CHECK (json_valid(data)),
    KEY events_task (task_id),
    KEY events_order (order_id)
) ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin;

-- Every dish with the trip carrying it (the report's ``orders_view``). ``order_status`` and
-- ``task_status`` are both given: the report showed only the task's, which hid delivered
-- dishes of a trip still under way.
CREATE SQL SECURITY INVOKER VIEW IF NOT EXISTS orders_view AS
SELECT
    o.id          AS id,
    o.dish        AS ordername,
    t.robot_name  AS robot_name,
    o.res_table   AS res_table,
    o.status      AS order_status,
    t.status      AS task_status,
    t.id          AS task_id
FROM orders AS o
LEFT JOIN task AS t ON t.id = o.task_num;

-- One row per robot (the report's ``robot_info_view``): where it is heading with food and how
-- many dishes its current trip carries. ``destination`` is NULL without a trip and once every
-- stop is done (the robot is on its way home).
CREATE SQL SECURITY INVOKER VIEW IF NOT EXISTS robot_info_view AS
SELECT
    r.name    AS robot_name,
    r.url     AS url,
    r.status  AS status,
    r.mode    AS mode,
    r.home    AS home,
    (SELECT s.waypoint
       FROM task AS t
       JOIN task_stop AS s ON s.task_id = t.id AND s.seq = t.current_stop
      WHERE t.id = r.current_task) AS destination,
    (SELECT count(*) FROM orders AS o WHERE o.task_num = r.current_task) AS number_of_orders
FROM robot_info AS r;
