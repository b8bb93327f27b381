-- 005 service (SQLite): what a real dinner service needs beyond "ready at the pass -> delivered".
--
--  * robot_info: the status 'Loading' (a trip given to the robot at the pass, waiting for staff
--    to load the trays and press Go), and ``trays``: how many tables one trip may serve (NULL:
--    the site's default);
--  * orders: the whole life of a dish. 'ordered' and 'cooking' come before 'pending' (ready at
--    the pass), 'returned' (a skipped or timed-out table: the dish came back, never delivered)
--    and 'voided' (withdrawn; was 'cancelled') after it. ``ready_at`` is NULL until the kitchen
--    marks it ready. Quantity and a note ("no chilli") travel with the dish;
--  * menu: the dishes the console offers, edited by the owner;
--  * table_block: tables a robot could not reach, kept out of every trip until staff clear
--    them (a second robot sent there got stuck as well).
--
-- SQLite cannot change a CHECK constraint in place: robot_info and orders are rebuilt. That
-- needs foreign keys off (task <-> robot_info refer to each other), which SQLite ignores inside
-- a transaction; the line below asks the runner to switch them off around this migration and
-- to run PRAGMA foreign_key_check before it commits.
-- serveur: foreign_keys off

DROP VIEW IF EXISTS robot_info_view;
DROP VIEW IF EXISTS orders_view;

CREATE TABLE robot_info_new (
    name         TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    url          TEXT NOT NULL,
    home         TEXT REFERENCES waypoints (name),
    kinematics   TEXT NOT NULL DEFAULT 'omni' CHECK (length(kinematics) > 0),
    mode         TEXT NOT NULL DEFAULT 'off' CHECK (mode IN ('off', 'auto', 'manual')),
    status       TEXT NOT NULL DEFAULT 'Offline' CHECK (status IN (
                     'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered',
                     'Stopped', 'Transit', 'Manual', 'Error')),
    resume       TEXT CHECK (resume IS NULL OR resume IN (
                     'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered',
                     'Stopped', 'Transit', 'Manual', 'Error')),
    current_task INTEGER REFERENCES task (id),
    battery      REAL CHECK (battery IS NULL OR (battery >= 0 AND battery <= 1)),
    x            REAL,
    y            REAL,
    yaw          REAL,
    last_error   TEXT,
    updated_at   REAL NOT NULL,
    status_since REAL NOT NULL DEFAULT 0,
    link         TEXT NOT NULL DEFAULT '{}',
    trays        INTEGER CHECK (trays IS NULL OR (trays >= 1 AND trays <= 12))
) STRICT;

INSERT INTO robot_info_new (name, url, home, kinematics, mode, status, resume, current_task,
                            battery, x, y, yaw, last_error, updated_at, status_since, link)
SELECT name, url, home, kinematics, mode, status, resume, current_task,
       battery, x, y, yaw, last_error, updated_at, status_since, link
FROM robot_info;

DROP TABLE robot_info;
ALTER TABLE robot_info_new RENAME TO robot_info;
CREATE UNIQUE INDEX robot_info_current_task ON robot_info (current_task)
    WHERE current_task IS NOT NULL;

CREATE TABLE orders_new (
    id            INTEGER PRIMARY KEY AUTOINCREMENT,
    dish          TEXT NOT NULL CHECK (length(dish) > 0),
    res_table     TEXT NOT NULL REFERENCES waypoints (name),
    status        TEXT NOT NULL DEFAULT 'pending'
                      CHECK (status IN ('ordered', 'cooking', 'pending', 'assigned',
                                        'delivered', 'returned', 'voided')),
    task_num      INTEGER REFERENCES task (id),
    key           TEXT UNIQUE,
    ready_at      REAL,
    dispatched_at REAL,
    delivered_at  REAL,
    quantity      INTEGER NOT NULL DEFAULT 1 CHECK (quantity >= 1 AND quantity <= 99),
    note          TEXT CHECK (note IS NULL OR length(note) <= 200),
    ordered_at    REAL,
    returned_at   REAL,
    voided_at     REAL,
    -- On a trip exactly while assigned or delivered: the other dishes are on no trip.
    CHECK ((task_num IS NOT NULL) = (status IN ('assigned', 'delivered'))),
    CHECK (status <> 'delivered' OR delivered_at IS NOT NULL),
    -- From the pass on, a dish has been ready.
    CHECK (status IN ('ordered', 'cooking', 'voided') OR ready_at IS NOT NULL)
) STRICT;

INSERT INTO orders_new (id, dish, res_table, status, task_num, key, ready_at, dispatched_at,
                        delivered_at, ordered_at)
SELECT id, dish, res_table, CASE status WHEN 'cancelled' THEN 'voided' ELSE status END,
       task_num, key, ready_at, dispatched_at, delivered_at, ready_at
FROM orders;

DROP TABLE orders;
ALTER TABLE orders_new RENAME TO orders;
CREATE INDEX orders_status ON orders (status);
CREATE INDEX orders_table ON orders (res_table, status);
CREATE INDEX orders_task ON orders (task_num, res_table);

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

CREATE TABLE menu (
    dish        TEXT PRIMARY KEY NOT NULL CHECK (length(dish) > 0 AND length(dish) <= 64),
    category    TEXT NOT NULL DEFAULT '' CHECK (length(category) <= 64),
    price_cents INTEGER CHECK (price_cents IS NULL OR price_cents >= 0),
    available   INTEGER NOT NULL DEFAULT 1 CHECK (available IN (0, 1)),
    position    INTEGER NOT NULL DEFAULT 0,
    updated_at  REAL NOT NULL
) STRICT;

INSERT INTO menu (dish, category, position, updated_at) VALUES
    ('Laksa', 'Mains', 1, 0), ('Satay', 'Mains', 2, 0), ('Nasi lemak', 'Mains', 3, 0),
    ('Rendang', 'Mains', 4, 0), ('Roti canai', 'Mains', 5, 0), ('Char kway teow', 'Mains', 6, 0),
    ('Teh tarik', 'Drinks', 7, 0), ('Cendol', 'Desserts', 8, 0);

CREATE TABLE table_block (
    waypoint    TEXT PRIMARY KEY NOT NULL REFERENCES waypoints (name),
    reason      TEXT NOT NULL,
    robot       TEXT,
    since       REAL NOT NULL
) STRICT;
