-- 009 site map (SQLite): the restaurant's map as the owner set it in the console (issue 29).
--
-- One row at most: the occupancy grid serveur plans on and screens draw, int8 cells row-major
-- with row 0 at the lowest y (nav_msgs/OccupancyGrid's data), with its resolution and origin.
-- In the database, not a file beside it: a backup holds it and a restore brings it back, and
-- it wins over `serveur run --map` (the console is where the owner changes it). `source` says
-- where it came from ("robot files room.yaml", "floor plan").

CREATE TABLE site_map (
    id          INTEGER PRIMARY KEY NOT NULL CHECK (id = 1),
    resolution  REAL NOT NULL CHECK (resolution > 0),
    origin_x    REAL NOT NULL,
    origin_y    REAL NOT NULL,
    width       INTEGER NOT NULL CHECK (width > 0),
    height      INTEGER NOT NULL CHECK (height > 0),
    cells       BLOB NOT NULL CHECK (length(cells) = width * height),
    source      TEXT NOT NULL,
    updated_at  REAL NOT NULL,
    updated_by  TEXT
) STRICT;
