"""Replay speed: a 4-hour service of 1,000 dishes on 30 tables with 5 robots, wall time.

The demo restaurant has 16 tables, so this script first draws a larger dining room with 30
(6 columns x 5 rows, 22 m x 14.5 m, counter and six home spots along the north wall), in the
style of ``bench/make_demo_map.py``, into a temporary directory; then generates the log
(``serveur.replay.orders.generate_orders``, the first 1,000 dishes of the first seed giving at least
that many) and runs ``serveur replay`` in-process with the serveur policy.

Run: ``python bench/bench_replay.py [--time-scale 300] [--profile]``. ``--profile`` writes a
pyinstrument profile to ``bench-replay-profile.txt`` (``pip install pyinstrument``).
It prints the wall time, the simulated time and the summary; it stops by itself (the replay
gives up one hour of simulated time after the last dish).
"""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from pathlib import Path

import numpy as np

from serveur.maps.mapio import OccupancyMap, Waypoint, save_map, save_waypoints
from serveur.replay.orders import format_orders, generate_orders
from serveur.replay.report import summary_text
from serveur.replay.service import ReplayOptions, run_replay

RES = 0.05
ROOM_W, ROOM_H = 22.0, 14.5
WALL, MARGIN = 0.15, 0.5
COLS = [2.4 + 3.5 * k for k in range(6)]
ROWS = [1.6, 4.0, 6.4, 8.8, 11.0]
COUNTER = (3.0, 13.9, 19.0, 14.5)
HOME_Y = 13.3


def build_room() -> tuple[OccupancyMap, dict[str, Waypoint]]:
    """30 rectangular tables (1.0 x 0.8 m), served from the north side, facing south."""
    pad = WALL + MARGIN
    width, height = round((ROOM_W + 2 * pad) / RES), round((ROOM_H + 2 * pad) / RES)
    xs = -pad + (np.arange(width) + 0.5) * RES
    ys = -pad + (np.arange(height) + 0.5) * RES
    x, y = np.meshgrid(xs, ys)

    def box(x0: float, y0: float, x1: float, y1: float) -> np.ndarray:
        return (x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)

    grid = np.full((height, width), -1, dtype=np.int8)
    grid[box(-WALL, -WALL, ROOM_W + WALL, ROOM_H + WALL)] = 100
    grid[box(0.0, 0.0, ROOM_W, ROOM_H)] = 0
    grid[box(*COUNTER)] = 100
    wps: list[Waypoint] = [
        Waypoint(f"home{i + 1}", 5.0 + 2.0 * i, HOME_Y, math.pi / 2, "home") for i in range(6)
    ]
    wps.append(Waypoint("pass", 11.0 + 1.0, HOME_Y, math.pi / 2, "pass"))
    n = 0
    for cy in reversed(ROWS):
        for cx in COLS:
            n += 1
            grid[box(cx - 0.5, cy - 0.4, cx + 0.5, cy + 0.4)] = 100
            wps.append(Waypoint(f"T{n}", cx, cy + 0.4 + 0.5, -math.pi / 2, "table"))
    return OccupancyMap(grid, RES, (-pad, -pad, 0.0)), {w.name: w for w in wps}


def write_room(out: Path) -> Path:
    grid, wps = build_room()
    save_map(grid, out / "room30.yaml", "pgm")
    save_waypoints(wps, out / "room30_waypoints.json")
    return out / "room30.yaml"


def run(ns: argparse.Namespace) -> None:
    with tempfile.TemporaryDirectory(prefix="serveur-bench-replay-") as tmp:
        yaml = write_room(Path(tmp))
        tables = [f"T{i}" for i in range(1, 31)]
        seed = 0
        while len(orders := generate_orders(tables, 4.0, ns.rate, seed)) < ns.orders:
            seed += 1
        orders = orders[: ns.orders]
        (Path(tmp) / "orders.csv").write_text(format_orders(orders))
        opts = ReplayOptions(
            robots=ns.robots, time_scale=ns.time_scale, map_path=str(yaml), progress=True
        )
        t0 = time.perf_counter()
        res = run_replay(orders, opts, [ns.policy])
        wall = time.perf_counter() - t0
        r = res[ns.policy]
        print(summary_text(res, f"{len(orders)} dishes (log seed {seed})", opts))
        print(
            f"wall {wall:.1f} s for {r.sim_seconds / 3600:.2f} h simulated "
            f"({r.sim_seconds / wall:.0f}x), last dish at {orders[-1].ready_at / 3600:.2f} h"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description="replay speed benchmark")
    ap.add_argument(
        "--time-scale", type=float, default=None, help="wall-clock mode (default: virtual time)"
    )
    ap.add_argument("--robots", type=int, default=5)
    ap.add_argument("--orders", type=int, default=1000)
    ap.add_argument("--rate", type=float, default=260.0, help="dishes an hour for the generator")
    ap.add_argument("--policy", default="serveur")
    ap.add_argument("--profile", action="store_true")
    ns = ap.parse_args()
    if ns.profile:
        from pyinstrument import Profiler

        with Profiler(async_mode="disabled", interval=0.002) as prof:
            run(ns)
        Path("bench-replay-profile.txt").write_text(prof.output_text(show_all=False))
    else:
        run(ns)


if __name__ == "__main__":
    main()
