"""A fast model of a replayed service, for tuning the staff strategy before the real replay.

``serveur replay`` runs the real server and simulated robots; a 4-hour service takes minutes
and is slightly noisy. Tuning ``suggest_carts`` (hold time, spreading) needs hundreds of
services, so this script replays a log as a discrete-event model in milliseconds: the same
staff functions (:func:`~serveur.scheduler.fifo_cart`, :func:`~serveur.scheduler.suggest_carts`),
the same stop ordering as the server (cart order for baseline, ``order_stops`` otherwise), the
same guests (:func:`~serveur.replay.model.stop_dwell`) and path distances on the demo map; robots
move at an effective speed with a fixed cost per leg, calibrated against real replays
(docs/performance.md). Its figures are estimates; the real replay has the last word.

Run: ``python bench/policy_model.py LOG.csv [--robots 3] [--hold 0 10 25] [--hold-max 60]
[--rank fifo wspt best]``.
"""

from __future__ import annotations

import argparse
import heapq
import itertools
from collections.abc import Callable, Sequence

from serveur.maps.navigation import DistanceTable, Planner, load_demo
from serveur.replay.model import stop_dwell
from serveur.replay.orders import LogOrder, demo_tables, read_orders
from serveur.scheduler import RANKS, Dish, TripEstimate, fifo_cart, order_stops, suggest_carts

SPEED = 0.6  # m/s effective (0.7 m/s top speed, acceleration, corners)
LEG = 2.5  # s per leg: planning, turning on the spot, settling at the goal


def model(
    log: Sequence[LogOrder],
    policy: str,
    robots: int,
    distance: Callable[[str, str], float],
    *,
    hold: float = 10.0,
    hold_max: float = 60.0,
    rank: str = "best",
    lookahead: float = 60.0,
    seed: int = 0,
    capacity: int = 4,
) -> list[float]:
    """Waits (ready -> collected) of every dish of ``log`` under ``policy``."""
    homes = [f"home{i + 1}" for i in range(robots)]
    free_at = dict.fromkeys(homes, 0.0)  # robot (by home) -> when it is home again
    eta = dict.fromkeys(homes, 0.0)  # ... and when the staff expect it (TripEstimate)
    idle_since = dict.fromkeys(homes, 0.0)
    pending: dict[int, Dish] = {}
    waits: list[float] = []
    created = 0
    t = 0.0
    events: list[float] = [o.ready_at for o in log]
    heapq.heapify(events)

    def leg(a: str, b: str) -> float:
        return distance(a, b) / SPEED + LEG

    while created < len(log) or pending:
        t = heapq.heappop(events) if events else t + 1.0
        while created < len(log) and log[created].ready_at <= t:
            o = log[created]
            pending[created] = Dish(created, o.table, o.ready_at)
            created += 1
        free = sorted((h for h in homes if free_at[h] <= t), key=lambda h: idle_since[h])
        if not free or not pending:
            continue
        dishes = list(pending.values())
        if policy == "baseline":
            carts = []
            for _ in free:
                cart = fifo_cart(dishes, capacity)
                if not cart:
                    break
                carts.append(cart)
                dishes = [d for d in dishes if d.id not in set(cart)]
        else:
            coming = [
                Dish(-1 - i, o.table, o.ready_at)
                for i, o in enumerate(log[created:])
                if o.ready_at <= t + lookahead
            ]
            busy = [max(1.0, eta[h] - t) for h in homes if free_at[h] > t]
            carts = suggest_carts(
                dishes,
                len(free),
                distance,
                now=t,
                origin=free[0],
                capacity=capacity,
                coming=coming,
                hold=hold,
                hold_max=hold_max,
                busy=busy,
                rank=rank,
            )
            if not carts:
                heapq.heappush(events, t + 1.0)  # a hold runs out: look again
        for cart, home in zip(carts, free, strict=False):
            tables = list(dict.fromkeys(pending[i].table for i in cart))
            if policy != "baseline":
                tables = order_stops(home, tables, distance, end=home)
            here, clock = home, t
            plates = [(tb, sum(1 for i in cart if pending[i].table == tb)) for tb in tables]
            eta[home] = t + TripEstimate().trip(home, plates, distance)
            for table in tables:
                clock += leg(here, table)
                ids = [i for i in cart if pending[i].table == table]
                clock += stop_dwell(seed, [log[i].line or i for i in ids])
                waits.extend(clock - pending[i].ready_at for i in ids)
                here = table
            clock += leg(here, home)
            for i in cart:
                del pending[i]
            free_at[home] = idle_since[home] = clock
            heapq.heappush(events, clock)
    return waits


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("logs", nargs="+")
    ap.add_argument("--robots", type=int, default=3)
    ap.add_argument("--hold", type=float, nargs="+", default=[10.0])
    ap.add_argument("--hold-max", type=float, nargs="+", default=[60.0])
    ap.add_argument("--rank", nargs="+", default=["best"], choices=RANKS)
    ns = ap.parse_args()
    grid, wps = load_demo()
    table = DistanceTable(Planner(grid, robot_radius=0.2), wps)
    table.matrix(sorted(wps))
    tables = set(demo_tables())
    for path in ns.logs:
        log = read_orders(path, tables=tables)
        base = model(log, "baseline", ns.robots, table.distance)
        b = sum(base) / len(base)
        print(f"{path}: {len(log)} dishes, baseline mean {b:.1f} s")
        for hold, hold_max, rank in itertools.product(ns.hold, ns.hold_max, ns.rank):
            w = model(
                log, "serveur", ns.robots, table.distance, hold=hold, hold_max=hold_max, rank=rank
            )
            m = sum(w) / len(w)
            print(
                f"  serveur {rank:>4} hold {hold:>3.0f}-{max(hold, hold_max):.0f} s: "
                f"mean {m:.1f} s ({100 * (m - b) / b:+.0f} %)"
            )


if __name__ == "__main__":
    main()
