"""Generate the narrow-aisle demo room: ``serveur/data/narrow_restaurant.{yaml,png}``,
``narrow_restaurant_waypoints.json`` and ``narrow_restaurant_zones.json`` (issue 21).

A restaurant cut in two by a thick wall (a service corridor, a bar, a row of pillars with
planters between them) with ONE opening one robot wide: the kitchen pass and the robots' homes
on the west side, five tables on the east side. Every trip drives the aisle out and back, so
two robots meeting in it head-on block each other unless the server leases the aisle (a zone of
capacity 1 in ``_zones.json``).

Layout (metres, x to the east, y to the north, room interior [0, 13] x [0, 7]):

* the pass counter along the west wall, six homes 1 m apart in a column 0.7 m in front of it,
  facing it (robots load at home, as in the demo room), the pass spot beside them;
* the dividing wall x 5..7, with the aisle at y 3.175..3.825 (0.65 m: a 0.4 m robot, never two
  side by side; at 0.55-0.6 m the simulator's path follower, cutting the corner into the aisle
  by a few centimetres, got stuck against the wall), its mouths chamfered 0.6 m;
* east of the wall, five tables around a hall 2.5 m wide, their serving spots on the hall's
  edges (a robot serving a table is not in the way of robots going to the others);
* the zone ``aisle`` (capacity 1): the aisle, the whole floor between the front of the homes
  (0.45 m from each home) and its west mouth, and the middle of the hall beyond its east mouth
  (x 7.4..10.4, y 2.65..4.35, clear of the table spots). Drawn as the aisle alone (x 4.4..7.6),
  robots still met on the floors at either end: a robot coming home and the next one leaving
  for the aisle (the lease passes when the first robot leaves the zone), and robots crossing the
  hall between tables (the simulator's local planner stops short of a robot in its way and
  plans around it only once it stands still, as move_base does, so robots crossing in the open
  come within 5 cm of each other: a conflict by the replay's measure). Homes, the pass and
  every table spot are outside it, even widened by a robot's radius.

The geometry below is the single source of truth; re-running the script reproduces the
committed files byte for byte. Run: ``python tools/make_narrow_map.py``.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from serveur.maps.mapio import OccupancyMap, Waypoint, save_map, save_waypoints

RES = 0.05
ROOM_W, ROOM_H = 13.0, 7.0
WALL = 0.15
MARGIN = 0.25  # unknown band outside the walls
PAD = WALL + MARGIN

FACE_WEST, FACE_EAST, FACE_NORTH, FACE_SOUTH = math.pi, 0.0, math.pi / 2, -math.pi / 2

PASS_COUNTER = (0.0, 0.5, 0.5, 6.5)  # against the west wall
HOME_X = 1.2
HOMES_Y = (1.0, 2.0, 3.0, 4.0, 5.0, 6.0)  # 1 m apart: a robot drives past a parked one
PASS_SPOT = (2.2, 6.3)
DIVIDER = (5.0, 7.0)  # x extent of the dividing wall
AISLE = (3.175, 3.825)  # y extent of the opening: 0.65 m
CHAMFER = 0.6
#: The floor between the homes and the aisle's west mouth, the aisle, and the middle of the hall
#: beyond it (clear of the table spots).
ZONE = [
    [1.65, 0.55], [4.4, 2.9], [7.0, 2.9], [7.4, 2.65], [10.4, 2.65],
    [10.4, 4.35], [7.4, 4.35], [7.0, 4.1], [4.4, 4.1], [1.65, 6.45],
]  # fmt: skip
SPOT_GAP = 0.5  # serving spot distance from the table edge

# name: (cx, cy, size, serving side); square tables.
TABLES: dict[str, tuple[float, float, float, str]] = {
    "T1": (9.0, 1.3, 0.9, "north"),  # east side: spots on the hall in the middle
    "T2": (9.0, 5.7, 0.9, "south"),
    "T3": (11.8, 1.3, 0.9, "north"),
    "T4": (11.8, 3.5, 0.9, "west"),
    "T5": (11.8, 5.7, 0.9, "south"),
}

OUT = Path(__file__).resolve().parent.parent / "serveur" / "data"
STEM = "narrow_restaurant"


def build_grid() -> np.ndarray:
    """Rasterise the layout: a cell takes the value of whatever covers its centre."""
    width = round((ROOM_W + 2 * PAD) / RES)
    height = round((ROOM_H + 2 * PAD) / RES)
    xs = -PAD + (np.arange(width) + 0.5) * RES
    ys = -PAD + (np.arange(height) + 0.5) * RES
    x, y = np.meshgrid(xs, ys)  # row 0 = lowest y, like the grid

    def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    grid = np.full((height, width), -1, dtype=np.int8)
    grid[box(-WALL, -WALL, ROOM_W + WALL, ROOM_H + WALL)] = 100
    grid[box(0.0, 0.0, ROOM_W, ROOM_H)] = 0
    x0, x1 = DIVIDER
    a0, a1 = AISLE
    wall = box(x0, 0.0, x1, ROOM_H) & ~box(x0, a0, x1, a1)
    # Chamfered mouths: the wall's four corners at the opening cut at 45 degrees.
    for cx, sx in ((x0, 1.0), (x1, -1.0)):
        for cy, sy in ((a0, -1.0), (a1, 1.0)):
            dx, dy = (x - cx) * sx, (y - cy) * sy  # >= 0 inside the wall's corner
            wall &= ~((dx >= 0) & (dy >= 0) & (dx + dy < CHAMFER))
    obstacles = [box(*PASS_COUNTER), wall]
    for cx, cy, size, _ in TABLES.values():
        h = size / 2
        obstacles.append(box(cx - h, cy - h, cx + h, cy + h))
    for mask in obstacles:
        grid[mask] = 100
    return grid


def build_waypoints() -> dict[str, Waypoint]:
    """Homes and the pass face the counter (west); table spots face their table."""
    wps = [Waypoint(f"home{i + 1}", HOME_X, hy, FACE_WEST, "home") for i, hy in enumerate(HOMES_Y)]
    wps.append(Waypoint("pass", PASS_SPOT[0], PASS_SPOT[1], FACE_WEST, "pass"))
    for name, (cx, cy, size, side) in TABLES.items():
        d = size / 2 + SPOT_GAP
        if side == "west":
            wps.append(Waypoint(name, cx - d, cy, FACE_EAST, "table"))
        elif side == "north":  # the spot north of the table, facing south
            wps.append(Waypoint(name, cx, cy + d, FACE_SOUTH, "table"))
        else:
            wps.append(Waypoint(name, cx, cy - d, FACE_NORTH, "table"))
    return {w.name: w for w in wps}


def zones_text() -> str:
    zone = {"name": "aisle", "points": ZONE, "capacity": 1}
    return '{"zones": [\n  ' + json.dumps(zone) + "\n]}\n"


def main() -> None:
    OUT.mkdir(parents=True, exist_ok=True)
    m = OccupancyMap(build_grid(), RES, (-PAD, -PAD, 0.0))
    save_map(m, OUT / f"{STEM}.yaml", "png")
    save_waypoints(build_waypoints(), OUT / f"{STEM}_waypoints.json")
    (OUT / f"{STEM}_zones.json").write_text(zones_text(), encoding="utf-8")
    print(f"wrote {OUT}/{STEM}.yaml + .png ({m.width}x{m.height} cells), waypoints and zones")


if __name__ == "__main__":
    main()
