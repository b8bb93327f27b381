"""Navigation timings on the demo restaurant: what the scheduler and simulator pay.

Run: ``python bench/bench_navigation.py`` (prints median wall times; numbers go into the
"## Navigation" section of docs/performance.md).

- DistanceTable, full matrix of all demo waypoints, from a cold Planner: the server's start-up
  cost (one distance field per waypoint plus a smoothed path per pair).
- One plan across the room (home1 -> T16): cold (its goal's distance field not cached yet)
  and warm (cached, the common case: robots keep going to the same tables).
- One 360-ray raycast with a 10 m range: the simulator casts one per robot at 5 Hz.
"""

from __future__ import annotations

import argparse
import math
import platform
import statistics
import time
from collections.abc import Callable

import numpy as np

from serveur.maps.navigation import DistanceTable, Planner, inflate, load_demo, raycast


def median_ms(fn: Callable[[], object], repeat: int) -> tuple[float, float]:
    """Median and minimum wall time of ``fn`` in milliseconds."""
    times = []
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        times.append((time.perf_counter() - t0) * 1000.0)
    return statistics.median(times), min(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=7, help="runs of each slow case")
    args = parser.parse_args()
    m, wps = load_demo()
    names = list(wps)
    home, far = wps["home1"], wps["T16"]
    start, goal = (home.x, home.y), (far.x, far.y)
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    warm = Planner(m, robot_radius=0.2)
    warm.plan(start, goal)
    path = warm.plan(start, goal)

    def matrix() -> None:
        DistanceTable(Planner(m, robot_radius=0.2), wps).matrix(names)

    def cold_plan() -> None:
        Planner(m, robot_radius=0.2).plan(start, goal)

    rows = [
        (f"DistanceTable.matrix, {len(names)} waypoints, cold", median_ms(matrix, args.repeat)),
        ("Planner() construction (inflation + clearance bands)", median_ms(lambda: Planner(m), 21)),
        ("plan home1 -> T16, cold (incl. Planner())", median_ms(cold_plan, 3 * args.repeat)),
        ("plan home1 -> T16, warm", median_ms(lambda: warm.plan(start, goal), 101)),
        (
            "raycast 360 rays, 10 m, room centre",
            median_ms(lambda: raycast(m, 8.0, 6.0, angles, 10.0), 501),
        ),
        (
            "raycast 360 rays, 10 m, at home1",
            median_ms(lambda: raycast(m, home.x, home.y, angles, 10.0), 501),
        ),
        ("inflate r=0.2 m", median_ms(lambda: inflate(m, 0.2), 51)),
    ]
    print(
        f"# {time.strftime('%Y-%m-%d')} {platform.python_implementation()} "
        f"{platform.python_version()} numpy {np.__version__} on {platform.machine()}"
    )
    print(
        f"# demo map {m.width}x{m.height} cells at {m.resolution} m; path home1 -> T16 has "
        f"{len(path)} points, {warm.path_length(start, goal):.2f} m"
    )
    print(f"{'case':<54} {'median ms':>10} {'min ms':>8}")
    for name, (med, best) in rows:
        print(f"{name:<54} {med:>10.2f} {best:>8.2f}")


if __name__ == "__main__":
    main()
