-- 011 modes (SQLite): what restaurant robots do besides delivering (issue 32).
--
--  * waypoints.kind: 'dish_return' (where a bussing robot is emptied) and 'dock' (a robot's
--    charger);
--  * robot_info: the status 'Charging' (on its dock) and ``dock``, the robot's charger;
--  * task.kind: 'delivery' (dishes from the pass), 'bussing' (used dishes from tables to the
--    dish return) or 'cruise' (a round of places); task_stop.purpose says what the robot does
--    at each stop: 'deliver', 'collect' (used dishes), 'unload' (at the dish return) or
--    'visit' (a cruise's place);
--  * orders: ``special`` (a birthday's message: the robot sings and shows it at the table,
--    and waits for Done) and ``tray`` (the tray staff chose for the dish; NULL: the plan's);
--  * call: a guest's call from a table (its screen or a Wi-Fi button), at most one open per
--    table and kind (a partial UNIQUE index: fifty presses merge into one);
--  * call_button: a Wi-Fi button's name, table, kind and token (kept as a SHA-256 digest,
--    like the API tokens: the database never holds a usable token).
--
-- SQLite cannot change a CHECK constraint in place: waypoints and robot_info are rebuilt, as
-- in 005, with foreign keys off around the migration.
-- serveur: foreign_keys off

DROP VIEW IF EXISTS robot_info_view;
DROP VIEW IF EXISTS orders_view;

CREATE TABLE waypoints_new (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    x           REAL NOT NULL,
    y           REAL NOT NULL,
    yaw         REAL NOT NULL DEFAULT 0,
    kind        TEXT NOT NULL DEFAULT 'other'
                    CHECK (kind IN ('table', 'home', 'pass', 'other', 'dish_return', 'dock')),
    created_at  REAL NOT NULL,
    removed_at  REAL
) STRICT;

INSERT INTO waypoints_new (name, x, y, yaw, kind, created_at, removed_at)
SELECT name, x, y, yaw, kind, created_at, removed_at FROM waypoints;

DROP TABLE waypoints;
ALTER TABLE waypoints_new RENAME TO waypoints;

CREATE TABLE robot_info_new (
    name         TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    url          TEXT NOT NULL,
    home         TEXT REFERENCES waypoints (name),
    kinematics   TEXT NOT NULL DEFAULT 'omni' CHECK (length(kinematics) > 0),
    mode         TEXT NOT NULL DEFAULT 'off' CHECK (mode IN ('off', 'auto', 'manual')),
    status       TEXT NOT NULL DEFAULT 'Offline' CHECK (status IN (
                     'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered',
                     'Stopped', 'Transit', 'Manual', 'Error', 'Charging')),
    resume       TEXT CHECK (resume IS NULL OR resume IN (
                     'Offline', 'Ready', 'Awaiting', 'Loading', 'Delivering', 'Delivered',
                     'Stopped', 'Transit', 'Manual', 'Error', 'Charging')),
    current_task INTEGER REFERENCES task (id),
    battery      REAL CHECK (battery IS NULL OR (battery >= 0 AND battery <= 1)),
    x            REAL,
    y            REAL,
    yaw          REAL,
    last_error   TEXT,
    updated_at   REAL NOT NULL,
    status_since REAL NOT NULL DEFAULT 0,
    link         TEXT NOT NULL DEFAULT '{}',
    trays        INTEGER CHECK (trays IS NULL OR (trays >= 1 AND trays <= 12)),
    removed_at   REAL,
    dock         TEXT REFERENCES waypoints (name)
) STRICT;

INSERT INTO robot_info_new (name, url, home, kinematics, mode, status, resume, current_task,
                            battery, x, y, yaw, last_error, updated_at, status_since, link,
                            trays, removed_at)
SELECT name, url, home, kinematics, mode, status, resume, current_task,
       battery, x, y, yaw, last_error, updated_at, status_since, link, trays, removed_at
FROM robot_info;

DROP TABLE robot_info;
ALTER TABLE robot_info_new RENAME TO robot_info;
CREATE UNIQUE INDEX robot_info_current_task ON robot_info (current_task)
    WHERE current_task IS NOT NULL;

ALTER TABLE task ADD COLUMN kind TEXT NOT NULL DEFAULT 'delivery'
    CHECK (kind IN ('delivery', 'bussing', 'cruise'));
ALTER TABLE task_stop ADD COLUMN purpose TEXT NOT NULL DEFAULT 'deliver'
    CHECK (purpose IN ('deliver', 'collect', 'unload', 'visit'));
ALTER TABLE orders ADD COLUMN special TEXT CHECK (special IS NULL OR length(special) <= 120);
ALTER TABLE orders ADD COLUMN tray INTEGER CHECK (tray IS NULL OR (tray >= 1 AND tray <= 12));

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

CREATE TABLE call (
    id           INTEGER PRIMARY KEY AUTOINCREMENT,
    table_name   TEXT NOT NULL REFERENCES waypoints (name),
    kind         TEXT NOT NULL CHECK (kind IN ('plates', 'waiter', 'bill')),
    source       TEXT NOT NULL CHECK (length(source) > 0),
    opened_at    REAL NOT NULL,
    presses      INTEGER NOT NULL DEFAULT 1 CHECK (presses >= 1),
    escalated_at REAL,
    answered_at  REAL,
    answered_by  TEXT,
    cancelled_at REAL,
    cancelled_by TEXT,
    task_id      INTEGER REFERENCES task (id),
    CHECK (answered_at IS NULL OR cancelled_at IS NULL)
) STRICT;

CREATE UNIQUE INDEX call_open ON call (table_name, kind)
    WHERE answered_at IS NULL AND cancelled_at IS NULL;
CREATE INDEX call_opened ON call (opened_at);

CREATE TABLE call_button (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    table_name  TEXT NOT NULL REFERENCES waypoints (name),
    kind        TEXT NOT NULL CHECK (kind IN ('plates', 'waiter', 'bill')),
    digest      TEXT NOT NULL UNIQUE,
    created_at  REAL NOT NULL,
    revoked_at  REAL,
    last_press  REAL
) STRICT;
