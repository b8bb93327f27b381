-- 007 zones (SQLite): the parts of the room robots take turns through (issue 21).
--
-- A zone is a polygon of map points (JSON [[x, y], ...], metres) leased to at most capacity
-- robots at a time (serveur.core.leases); wait_at names the waypoint, outside it, where a robot
-- standing in the zone goes to wait when it cannot get the other zones of its next leg. Leases themselves are not stored: they describe
-- where robots are now and end when the server stops (robots are stopped with it); a restarted
-- server grants them again before the next leg.

CREATE TABLE zones (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    points      TEXT NOT NULL CHECK (json_valid(points) AND json_array_length(points) >= 3),
    wait_at     TEXT,
    capacity    INTEGER NOT NULL DEFAULT 1 CHECK (capacity >= 1 AND capacity <= 8),
    updated_at  REAL NOT NULL
) STRICT;
