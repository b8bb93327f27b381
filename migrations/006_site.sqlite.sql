-- 006 site (SQLite): what the owner changes from the console (issue 20).
--
-- A robot or a waypoint the owner removes keeps its row, marked with removed_at: trips, stops
-- and orders of past services refer to it by name (foreign keys), and their history must stay
-- readable. The live lists skip removed rows; registering the name again brings the row back
-- with the new fields. Renaming a waypoint is a new waypoint plus the old one removed, so past
-- orders keep the name they were served under.
--
-- settings: the site's settings the owner edits in the console (table timeout, trays, the
-- languages offered); one row each, its value as JSON. A setting without a row keeps the
-- server's command-line value.

ALTER TABLE robot_info ADD COLUMN removed_at REAL;
ALTER TABLE waypoints ADD COLUMN removed_at REAL;

CREATE TABLE settings (
    name        TEXT PRIMARY KEY NOT NULL CHECK (length(name) > 0),
    value       TEXT NOT NULL CHECK (json_valid(value)),
    updated_at  REAL NOT NULL,
    updated_by  TEXT
) STRICT;

CREATE INDEX audit_actor ON audit (actor, id);
CREATE INDEX audit_verb ON audit (verb, id);
