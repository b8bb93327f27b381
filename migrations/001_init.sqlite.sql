-- 001 init (SQLite): the restaurant's tables, after the design report's Appendix C, improved.
--
-- What changed from the report and why:
--  * every status column has a CHECK with the values of the Python enums, so a typo or a bug
--    fails loudly at the write instead of leaving a row no screen can show,
--  * cross-column CHECKs state the lifecycle invariants (an assigned order has a task, a
--    queued task has no robot, an active one has one),
--  * partial UNIQUE indexes make "one robot, one active trip" a database fact: even a buggy
--    caller or a second server process cannot give a robot two trips or a trip two robots,
--  * STRICT tables (SQLite >= 3.37) refuse a text in a REAL column instead of storing it,
--  * ``idempotency`` remembers client-chosen keys so that a resent "create" returns the first
--    result instead of creating twice (waiter tablets resend on a flaky Wi-Fi).
-- The MariaDB history (001_init.mariadb.sql) mirrors this file with its own syntax.

CREATE TABLE waypoints (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    x           REAL NOT NULL,
    y           REAL NOT NULL,
    yaw         REAL NOT NULL DEFAULT 0,
    kind        TEXT NOT NULL DEFAULT 'other' CHECK (kind IN ('table', 'home', 'pass', 'other')),
    created_at  REAL NOT NULL
) STRICT;

CREATE TABLE robot_info (
    name         TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    url          TEXT NOT NULL,
    home         TEXT REFERENCES waypoints (name),
    kinematics   TEXT NOT NULL DEFAULT 'omni' CHECK (length(kinematics) > 0),
    mode         TEXT NOT NULL DEFAULT 'off' CHECK (mode IN ('off', 'auto', 'manual')),
    status       TEXT NOT NULL DEFAULT 'Offline' CHECK (status IN (
                     'Offline', 'Ready', 'Awaiting', 'Delivering', 'Delivered', 'Stopped',
                     'Transit', 'Manual', 'Error')),
    resume       TEXT CHECK (resume IS NULL OR resume IN (
                     'Offline', 'Ready', 'Awaiting', 'Delivering', 'Delivered', 'Stopped',
                     'Transit', 'Manual', 'Error')),
    current_task INTEGER REFERENCES task (id),
    battery      REAL CHECK (battery IS NULL OR (battery >= 0 AND battery <= 1)),
    x            REAL,
    y            REAL,
    yaw          REAL,
    last_error   TEXT,
    updated_at   REAL NOT NULL
) STRICT;

-- One trip per robot at a time, and a trip on one robot at a time.
CREATE UNIQUE INDEX robot_info_current_task ON robot_info (current_task)
    WHERE current_task IS NOT NULL;

CREATE TABLE task (
    id           INTEGER PRIMARY KEY AUTOINCREMENT,
    robot_name   TEXT REFERENCES robot_info (name),
    status       TEXT NOT NULL DEFAULT 'queued'
                     CHECK (status IN ('queued', 'active', 'done', 'cancelled')),
    current_stop INTEGER NOT NULL DEFAULT 0 CHECK (current_stop >= 0),
    created_at   REAL NOT NULL,
    started_at   REAL,
    finished_at  REAL,
    CHECK (status <> 'queued' OR robot_name IS NULL),
    CHECK (status <> 'active' OR (robot_name IS NOT NULL AND started_at IS NOT NULL)),
    CHECK (status NOT IN ('done', 'cancelled') OR finished_at IS NOT NULL)
) STRICT;

CREATE INDEX task_status ON task (status);
CREATE UNIQUE INDEX task_active_robot ON task (robot_name) WHERE status = 'active';

-- Stops are numbered 0..n-1 in visiting order (``task.current_stop`` indexes them), one per
-- table and trip. A stop's dishes are the trip's orders for that table: no link table needed.
CREATE TABLE task_stop (
    task_id     INTEGER NOT NULL REFERENCES task (id) ON DELETE CASCADE,
    seq         INTEGER NOT NULL CHECK (seq >= 0),
    waypoint    TEXT NOT NULL REFERENCES waypoints (name),
    status      TEXT NOT NULL DEFAULT 'pending'
                    CHECK (status IN ('pending', 'arrived', 'done', 'skipped')),
    arrived_at  REAL,
    done_at     REAL,
    PRIMARY KEY (task_id, seq),
    UNIQUE (task_id, waypoint),
    CHECK (status <> 'done' OR done_at IS NOT NULL)
) STRICT;

CREATE TABLE idempotency (
    key          TEXT PRIMARY KEY NOT NULL CHECK (length(key) > 0),
    kind         TEXT NOT NULL CHECK (kind IN ('order', 'tasks')),
    fingerprint  TEXT NOT NULL,
    result       TEXT NOT NULL CHECK (json_valid(result)),
    created_at   REAL NOT NULL
) STRICT;

CREATE TABLE orders (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    dish          TEXT NOT NULL CHECK (length(dish) > 0),
    res_table     TEXT NOT NULL REFERENCES waypoints (name),
    status        TEXT NOT NULL DEFAULT 'pending'
                      CHECK (status IN ('pending', 'assigned', 'delivered', 'cancelled')),
    task_num      INTEGER REFERENCES task (id),
    key           TEXT UNIQUE,  -- the client's idempotency key, also in ``idempotency``
    ready_at      REAL NOT NULL,
    dispatched_at REAL,
    delivered_at  REAL,
    -- On a trip exactly while assigned or delivered: pending and cancelled dishes are free.
    CHECK ((task_num IS NOT NULL) = (status IN ('assigned', 'delivered'))),
    CHECK (status <> 'delivered' OR delivered_at IS NOT NULL)
) STRICT;

CREATE INDEX orders_status ON orders (status);
CREATE INDEX orders_table ON orders (res_table, status);
CREATE INDEX orders_task ON orders (task_num, res_table);

-- The audit trail. No foreign keys on purpose: it records history, it must never block (or
-- be cascaded by) a change to the rows it mentions.
CREATE TABLE events (
    id        INTEGER PRIMARY KEY AUTOINCREMENT,
    ts        REAL NOT NULL,
    kind      TEXT NOT NULL CHECK (length(kind) > 0),
    robot     TEXT,
    task_id   INTEGER,
    order_id  INTEGER,
    data      TEXT NOT NULL DEFAULT '{}' CHECK (json_valid(data))
) STRICT;

CREATE INDEX events_task ON events (task_id) WHERE task_id IS NOT NULL;
CREATE INDEX events_order ON events (order_id) WHERE order_id IS NOT NULL;

-- Every dish with the trip carrying it (the report's ``orders_view``). ``order_status`` and
-- ``task_status`` are both given: the report showed only the task's, which hid delivered
-- dishes of a trip still under way.
CREATE VIEW orders_view AS
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
CREATE VIEW robot_info_view AS
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
