-- 010 site backdrop (SQLite): the floor plan drawn under the robot's map (issue 29).
--
-- One row at most: the floor-plan image as the owner gave it (PNG or JPEG, never decoded by the
-- server: the browsers draw it) and the similarity that carries its pixels onto the map
-- (metres = scale * R(rotation) * (column, -row) + (tx, ty)), fitted from matched points
-- (serveur.maps.align). `digest` names the image in its address (/site/backdrop/<digest>):
-- a new plan is a new address, so browsers cache each forever. A new map of the room clears
-- it (its frame is another).

CREATE TABLE site_backdrop (
    id          INTEGER PRIMARY KEY NOT NULL CHECK (id = 1),
    image       BLOB NOT NULL CHECK (length(image) > 0),
    mime        TEXT NOT NULL CHECK (mime IN ('image/png', 'image/jpeg')),
    digest      TEXT NOT NULL,
    scale       REAL NOT NULL CHECK (scale > 0),
    rotation    REAL NOT NULL,
    tx          REAL NOT NULL,
    ty          REAL NOT NULL,
    rms         REAL NOT NULL CHECK (rms >= 0),
    points      INTEGER NOT NULL CHECK (points >= 2),
    updated_at  REAL NOT NULL,
    updated_by  TEXT
) STRICT;
