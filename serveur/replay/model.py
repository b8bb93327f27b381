"""The replay's pure parts: its options, the guests' dwell model and what a replay measured.

Split from :mod:`serveur.replay.service` because none of it needs a server, an event loop or
a socket: the benchmark's analytic model (``bench/policy_model.py``) prices trips with the very same
guests (:func:`stop_dwell`), the tests check the statistics on hand-made numbers, and
:mod:`serveur.replay.report` reads :class:`PolicyResult` — all without importing the server.
Everything here is also importable from :mod:`serveur.replay.service`.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = [
    "POLICIES",
    "PolicyResult",
    "ReplayOptions",
    "dish_dwell",
    "peak_utilisation",
    "percentile",
    "stop_dwell",
]

POLICIES = ("baseline", "serveur")


@dataclass(frozen=True)
class ReplayOptions:
    """How to replay. Times are simulated seconds unless said otherwise."""

    robots: int = 3
    time_scale: float | None = None  # None: virtual time (deterministic, as fast as the CPU)
    map_path: str | None = None  # ROS map YAML; waypoints from <stem>_waypoints.json beside it
    seed: int = 0
    capacity: int = 4
    kinematics: str = "omni"
    hold: float = 10.0  # serveur staff: wait this long at most for a table's next dish ...
    hold_max: float = 60.0  # ... growing to this as tables queue (scheduler.adaptive_hold)
    rank: str = "best"  # serveur staff: how tables are ranked (scheduler.RANKS)
    lookahead: float = 60.0  # the kitchen display shows dishes this far ahead of ready
    overtime: float = 3600.0  # give up this long after the last dish was ready
    progress: bool = True


def dish_dwell(seed: int, line: int) -> float:
    """Seconds a guest takes to notice the robot and lift this dish (seeded per log line).

    Keyed by the dish, not by the trip, so both policies face the same guests.
    Mostly 6-20 s, a long tail to ~40 s (a guest on the phone).
    """
    rng = random.Random(seed * 1_000_003 + line)
    return round(min(40.0, 6.0 + rng.expovariate(1 / 8.0)), 1)


def stop_dwell(seed: int, lines: Sequence[int]) -> float:
    """A stop's dwell: the slowest guest at the table, plus 2 s per extra plate to lift."""
    if not lines:
        return 0.0
    return max(dish_dwell(seed, n) for n in lines) + 2.0 * (len(lines) - 1)


def peak_utilisation(
    spans: Sequence[Sequence[tuple[float, float]]], window: float = 3600.0, step: float = 60.0
) -> float:
    """The fleet's busiest ``window``: the largest fraction of robot-time spent away on trips.

    ``spans`` holds each robot's (left the pass, back and Awaiting) intervals. Windows start
    every ``step`` seconds; a service shorter than ``window`` is one window over all of it.
    It is how "busy" is measured for the baseline-vs-serveur comparison: near 1.0 the fleet
    is out the whole peak hour and dishes queue on the pass.
    """
    if not spans or not any(spans):
        return 0.0
    end = max(b for robot in spans for _, b in robot)
    window = min(window, end) or 1.0
    best = 0.0
    start = 0.0
    while True:
        lo, hi = start, start + window
        used = sum(max(0.0, min(b, hi) - max(a, lo)) for robot in spans for a, b in robot)
        best = max(best, used / (window * len(spans)))
        if hi >= end:
            return best
        start += step


def percentile(values: Sequence[float], q: float) -> float:
    """Nearest-rank percentile (no interpolation: the value one order actually had)."""
    if not values:
        return math.nan
    s = sorted(values)
    return s[max(0, math.ceil(q / 100.0 * len(s)) - 1)]


@dataclass
class PolicyResult:
    """Everything one replay measured (service times in seconds from opening)."""

    policy: str
    orders: list[dict[str, Any]] = field(default_factory=list)
    trips: list[dict[str, Any]] = field(default_factory=list)
    robots: list[dict[str, Any]] = field(default_factory=list)
    paths: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    undelivered: int = 0
    nav_errors: int = 0
    recoveries: int = 0
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0

    def waits(self) -> list[float]:
        return [o["wait"] for o in self.orders if o["wait"] is not None]

    def stats(self) -> dict[str, Any]:
        """The figures the summary prints (raw floats; the text rounds them)."""
        waits = self.waits()
        bounds = [o["lower_bound"] for o in self.orders]
        trips = [t for t in self.trips if t["status"] == "done"]
        mean_wait = sum(waits) / len(waits) if waits else math.nan
        mean_lb = sum(bounds) / len(bounds) if bounds else math.nan
        return {
            "orders": len(self.orders),
            "delivered": len(waits),
            "undelivered": self.undelivered,
            "wait_mean": mean_wait,
            "wait_p50": percentile(waits, 50),
            "wait_p95": percentile(waits, 95),
            "wait_max": max(waits) if waits else math.nan,
            "lower_bound_mean": mean_lb,
            "gap_to_lower_bound": mean_wait / mean_lb if mean_lb else math.nan,
            "trips": len(trips),
            "dishes_per_trip": sum(t["dishes"] for t in trips) / len(trips) if trips else 0.0,
            "tables_per_trip": sum(t["tables"] for t in trips) / len(trips) if trips else 0.0,
            "nav_errors": self.nav_errors,
            "recoveries": self.recoveries,
            "peak_utilisation": peak_utilisation(
                [[(a, b) for a, b in r.get("busy_spans", [])] for r in self.robots]
            ),
        }
