"""The replay's pure parts: its options, the guests' and the pass's models, what a replay measured.

Split from :mod:`serveur.replay.service` because none of it needs a server, an event loop or
a socket: the benchmark's analytic model (``bench/policy_model.py``) prices trips with the very same
guests (:func:`stop_dwell`), the tests check the statistics on hand-made numbers, and
:mod:`serveur.replay.report` reads :class:`PolicyResult` — all without importing the server.
Everything here is also importable from :mod:`serveur.replay.service`.

The models and where their numbers come from (none is a measurement of a real restaurant: each
is an assumption, stated here; loading and absences have options for a site's own figures):

* **dwell** (:func:`dish_dwell`, :func:`stop_dwell`): guests take 6-20 s to notice the robot
  and lift a dish, a long tail to 40 s, 2 s more per extra plate;
* **loading at the pass** (:func:`loading_time`): since the dinner service, a trip waits at
  the pass (status ``Loading``) until staff have put its plates on the trays and pressed Go.
  Staff take a fixed part (walk to the robot, read the trip's trays on its screen, press Go:
  ``load_fixed``, 10 s) plus a part per plate (lift it off the pass onto its tray:
  ``load_per_dish``, 4 s), times a seeded spread (log-normal, ``load_spread`` 0.3: half the
  trips within -18 %/+22 % of that, one in a hundred twice as long: a crowded pass). Not
  measured and no source: an assumption sized on carrying plates by hand (a plate every few
  seconds);
* **guests away** (:func:`absences`): with probability ``away`` (3 %) a party is away from its
  table (a smoke, a phone call, the washroom) from the moment its first dish is ready, for
  3-12 minutes (uniform). A robot that arrives meanwhile waits; if they are not back within
  the server's ``table_timeout`` (180 s, the server's default) it skips the table and the
  dishes go back to the pass, for staff to send again. Also an assumption: no source.

With ``calls`` on (``serveur replay``'s default, ``--no-calls`` off), guests also call, and a
robot clears the plates (issue 32). Each party's calls and their times come from
:func:`serveur.replay.orders.guest_calls` (the meal 12-30 min from the last dish collected,
then the plates call for 80 % of parties, a waiter once during the meal for 30 %, the bill
3-12 min after the meal for 50 %); the rest is here. ``../shared/notes/field.md`` says what
call systems do (a button bound to a table, call -> answer timed, unanswered calls escalated)
and that restaurant robots bus dishes to a dish return, but gives no figure for any of it:
every number below is an assumption, sized by what the step involves.

* **staff answering a waiter or bill call** (:func:`answer_delay`): 15 s to see it and finish
  the plate in hand, plus a walk and a wait for a free moment, log-normal with a median of
  40 s (half of the calls answered within 55 s, one in ten after about 1 min 45 s: beyond
  the server's ``call_escalate`` of 120 s a few times an evening), 10 min at most;
* **guests putting their plates on a bussing robot** (:func:`plates_dwell`): 8 s to notice
  it, 3 s a plate, a tail to a minute (mean 8 s more); 15 % of parties (``forget_done``)
  stack their plates and turn back to the table without pressing Done: the robot goes on
  after the server's ``bussing_wait`` (120 s);
* **emptying a bussing robot at the dish return** (:func:`unload_time`): staff by the
  dishwasher take ``unload_fixed`` (20 s: see it, walk over) plus ``unload_per_table``
  (10 s: a table's plates off a tray), times the loading's seeded spread, then press Done.
"""

from __future__ import annotations

import math
import random
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from serveur.replay.orders import EAT, PAY, LogOrder, parties

__all__ = [
    "CALL_KINDS",
    "POLICIES",
    "Absence",
    "PolicyResult",
    "ReplayOptions",
    "absences",
    "answer_delay",
    "dish_dwell",
    "forgets_done",
    "loading_time",
    "peak_utilisation",
    "percentile",
    "plates_dwell",
    "service_events",
    "stop_dwell",
    "unload_time",
]

POLICIES = ("baseline", "serveur")
#: What guests call for (serveur.domain.CallKind's values).
CALL_KINDS = ("plates", "waiter", "bill")


@dataclass(frozen=True)
class ReplayOptions:
    """How to replay. Times are simulated seconds unless said otherwise."""

    robots: int = 3
    time_scale: float | None = None  # None: virtual time (deterministic, as fast as the CPU)
    map_path: str | None = None  # ROS map YAML; waypoints from <stem>_waypoints.json beside it
    seed: int = 0
    capacity: int = 4
    kinematics: str = "omni"
    #: Which ROS each robot runs, cycled over the robots: (1,), (2,) or a mixed fleet (1, 2).
    ros: tuple[int, ...] = (1,)
    hold: float = 10.0  # serveur staff: wait this long at most for a table's next dish ...
    hold_max: float = 60.0  # ... growing to this as tables queue (scheduler.adaptive_hold)
    rank: str = "best"  # serveur staff: how tables are ranked (scheduler.RANKS)
    join: bool = True  # serveur staff: a dish goes on its table's trip still at the pass
    lookahead: float = 60.0  # the kitchen display shows dishes this far ahead of ready
    #: Seconds before a dish is ready that the kitchen enters it in the server (``ordered``,
    #: then ``ready`` at its time), so the server knows food is coming (a bussing trip waits
    #: for it: serveur.scheduler.may_bus). 0: a dish appears when ready, the log's one time
    #: (``serveur replay``'s default is ``lookahead``: the server knows what the kitchen
    #: display shows; deliveries alone wait the same either way).
    kitchen_ahead: float = 0.0
    # Loading at the pass (loading_time): fixed s a trip + s a plate, times a seeded spread.
    load_fixed: float = 10.0
    load_per_dish: float = 4.0
    load_spread: float = 0.3  # sigma of the log-normal factor (0: always the mean)
    away: float = 0.03  # probability a party is away when its food comes (absences)
    table_timeout: float | None = 180.0  # the server's: a robot waits this long at a table
    overtime: float = 3600.0  # give up this long after the last dish was ready
    progress: bool = True
    # Traffic (issue 21, serveur.replay.traffic). Robots' footprints are obstacles to each
    # other in the simulator (off: robots drive through each other, as before).
    robots_see_each_other: bool = True
    #: Zones file the replay creates before the service opens; None: ``<map stem>_zones.json``
    #: beside the map if there is one; "": no zones.
    zones: str | None = None
    leases: bool = True  # CoreConfig.leases: False ignores the zones
    conflict_distance: float = 0.45  # m between centres: 2 x robot radius + 5 cm
    deadlock_after: float = 20.0  # s of sim time without progress, robots near each other
    # Guests' calls and bussing (issue 32; the module's docstring). Off here, so that a
    # forecast or a test replays deliveries alone unless it asks; ``serveur replay`` turns
    # them on (``--no-calls``: off) and replays the same service without them beside it.
    calls: bool = False
    call_plates: float = 0.8  # share of parties that call for their plates to be cleared
    call_waiter: float = 0.3  # ... that call a waiter once during the meal
    call_bill: float = 0.5  # ... that call for the bill
    eat: tuple[float, float] = EAT  # s from a party's last dish collected to its plates call
    pay: tuple[float, float] = PAY  # s from the end of the meal to the bill call
    forget_done: float = 0.15  # share of parties that never press Done on a bussing robot
    unload_fixed: float = 20.0  # staff at the dish return: s to empty a bussing robot ...
    unload_per_table: float = 10.0  # ... plus this per table it collected at
    #: Where the replay adds a dish return (x, y) when the map has none; None: beside the
    #: demo room's pass (9.0, 10.8), and a map of one's own must have one or say where.
    dish_return: tuple[float, float] | None = None


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


def loading_time(opts: ReplayOptions, key: int, dishes: int) -> float:
    """Seconds staff take to load a trip of ``dishes`` plates and press Go (seeded by ``key``,
    the trip's first log line, so the same cart loads as fast under either policy)."""
    base = opts.load_fixed + opts.load_per_dish * dishes
    if base <= 0.0:
        return 0.0
    factor = 1.0
    if opts.load_spread > 0.0:
        rng = random.Random(f"load:{opts.seed}:{key}")
        factor = min(3.0, max(0.5, rng.lognormvariate(0.0, opts.load_spread)))
    return round(base * factor, 1)


def _spread(opts: ReplayOptions, key: str) -> float:
    """The loading's seeded log-normal factor (``load_spread``), between 0.5 and 3."""
    if opts.load_spread <= 0.0:
        return 1.0
    rng = random.Random(f"{key}:{opts.seed}")
    return min(3.0, max(0.5, rng.lognormvariate(0.0, opts.load_spread)))


def answer_delay(seed: int, key: str) -> float:
    """Seconds staff take to answer a waiter or bill call (seeded by ``key``: the party's
    first line and the call's kind, so the same call is answered as fast under either
    policy). 15 s plus a log-normal of median 40 s (sigma 0.6), 600 s at most."""
    rng = random.Random(f"answer:{seed}:{key}")
    return round(min(600.0, 15.0 + 40.0 * rng.lognormvariate(0.0, 0.6)), 1)


def plates_dwell(seed: int, line: int, plates: int) -> float:
    """Seconds a party (keyed by its first line) takes to put ``plates`` used plates on a
    bussing robot before pressing Done: 8 s, 3 s a plate, an exponential tail (mean 8 s),
    90 s at most."""
    rng = random.Random(f"plates:{seed}:{line}")
    return round(min(90.0, 8.0 + 3.0 * plates + rng.expovariate(1 / 8.0)), 1)


def forgets_done(seed: int, line: int, share: float) -> bool:
    """Does this party (keyed by its first line) leave its plates on the robot without
    pressing Done (the robot then goes on after the server's ``bussing_wait``)?"""
    return random.Random(f"forget:{seed}:{line}").random() < share


def unload_time(opts: ReplayOptions, key: int, tables: int) -> float:
    """Seconds staff take to empty a bussing robot that collected at ``tables`` tables and
    press Done at the dish return (seeded by ``key``, the trip's id)."""
    base = opts.unload_fixed + opts.unload_per_table * tables
    return round(max(0.0, base) * _spread(opts, f"unload:{key}"), 1)


#: How long a party is away when it is (seconds, uniform): see the module's docstring.
AWAY_FOR = (180.0, 720.0)


@dataclass(frozen=True, slots=True)
class Absence:
    """A party away from ``table`` from ``start`` to ``end`` (seconds of service); ``line``:
    its first dish's log line."""

    table: str
    start: float
    end: float
    line: int


def absences(orders: Sequence[LogOrder], seed: int, away: float) -> list[Absence]:
    """The parties of a log (:func:`serveur.replay.orders.parties`) that are away when their
    food comes: each with probability ``away``, seeded per party by its first dish's line,
    from its first dish's ready time for :data:`AWAY_FOR` seconds."""
    out = []
    for party in parties(orders):
        first = party[0]
        rng = random.Random(f"away:{seed}:{first.line}")
        if rng.random() < away:
            end = first.ready_at + rng.uniform(*AWAY_FOR)
            out.append(Absence(first.table, first.ready_at, end, first.line))
    return out


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
class ServiceEvents:
    """The dinner service's steps as the server's event log recorded them.

    ``loading``: robot -> seconds it spent ``Loading`` at the pass; ``timeouts``: stops the
    server skipped because nobody collected (``stop.skipped`` with no person behind it);
    ``skips``: stops staff skipped; ``returned`` / ``resent``: order id -> how many times the
    dish came back to the pass / was sent again (``order.ready`` from ``returned``);
    ``joined``: dishes put on a trip still at the pass (``task.dishes_added``).
    """

    loading: dict[str, float] = field(default_factory=dict)
    joined: int = 0
    timeouts: int = 0
    skips: int = 0
    returned: dict[int, int] = field(default_factory=dict)
    resent: dict[int, int] = field(default_factory=dict)


def service_events(events: Sequence[dict[str, Any]], end: float) -> ServiceEvents:
    """Read :class:`ServiceEvents` off event records (``ts``, ``kind``, ``robot``,
    ``order_id``, ``data``; oldest first), a robot still Loading at ``end`` counted to it."""
    out = ServiceEvents()
    since: dict[str, float] = {}  # robot -> when it entered Loading
    for e in events:
        kind, data, robot = e["kind"], e.get("data") or {}, e.get("robot")
        if kind.startswith("robot.") and robot is not None and "status" in data:
            if robot in since and data["status"] != "Loading":
                out.loading[robot] = out.loading.get(robot, 0.0) + e["ts"] - since.pop(robot)
            if data["status"] == "Loading" and robot not in since:
                since[robot] = e["ts"]
        elif kind == "stop.skipped":
            if data.get("by") is None:
                out.timeouts += 1
            else:
                out.skips += 1
            for oid in data.get("orders", []):
                out.returned[oid] = out.returned.get(oid, 0) + 1
        elif kind == "task.dishes_added":
            out.joined += len(data.get("orders", []))
        elif kind == "order.ready" and data.get("from") == "returned":
            oid = e["order_id"]
            out.resent[oid] = out.resent.get(oid, 0) + 1
    for robot, t in since.items():
        out.loading[robot] = out.loading.get(robot, 0.0) + max(0.0, end - t)
    return out


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
    #: The dinner service, from the server's event log (:func:`service_events`): seconds
    #: robots spent Loading, tables timed out, dishes returned and sent again.
    loading: float = 0.0
    table_timeouts: int = 0
    staff_skips: int = 0
    returned: int = 0
    resent: int = 0
    joined: int = 0
    #: What the replay's players did, to check the event log against: Go pressed, loading
    #: seconds staff took, dishes sent again, stops the guests were back too late for.
    players: dict[str, Any] = field(default_factory=dict)
    #: Robots and each other (serveur.replay.traffic.TrafficWatch.result): conflicts,
    #: deadlocks, aborted goals; ``zone_waits``: the server's lease.waited events summed
    #: (serveur.replay.traffic.zone_waits); ``wait_places``: each wait for a zone seen on the
    #: robots' records (robot, t, s, zones, x, y); ``zones``: the zones created.
    traffic: dict[str, Any] = field(default_factory=dict)
    zone_waits: dict[str, Any] = field(default_factory=dict)
    wait_places: list[dict[str, Any]] = field(default_factory=list)
    zones: list[dict[str, Any]] = field(default_factory=list)
    #: Guests' calls and bussing (``ReplayOptions.calls``), read back from the server's
    #: records (service seconds): ``calls``, each call (id, table, kind, source, opened,
    #: answered, by, after, escalated, cancelled, task); ``bussing``, each bussing trip (id,
    #: robot, status, created, started, finished, unloaded, and its ``stops``: table, arrived,
    #: done, the call it answered and ``call_to_robot``, s from that call to the robot there);
    #: ``dish_return``, the place they unloaded at; ``callers``, what the players did.
    calls: list[dict[str, Any]] = field(default_factory=list)
    bussing: list[dict[str, Any]] = field(default_factory=list)
    dish_return: str | None = None
    callers: dict[str, Any] = field(default_factory=dict)
    #: The same service replayed without calls and bussing (``serveur replay`` with calls
    #: on), for the dish waits side by side (:meth:`modes`).
    alone: PolicyResult | None = None

    def waits(self) -> list[float]:
        return [o["wait"] for o in self.orders if o["wait"] is not None]

    def deliveries(self) -> list[dict[str, Any]]:
        """The delivery trips finished (bussing trips are :attr:`bussing`'s)."""
        return [
            t
            for t in self.trips
            if t["status"] == "done" and t.get("kind", "delivery") == "delivery"
        ]

    def dish_waits(self) -> dict[str, Any]:
        """The dishes' waits (ready -> collected): count, mean, p50, p95, max."""
        waits = self.waits()
        return {
            "delivered": len(waits),
            "undelivered": self.undelivered,
            "mean": sum(waits) / len(waits) if waits else math.nan,
            "p50": percentile(waits, 50),
            "p95": percentile(waits, 95),
            "max": max(waits) if waits else math.nan,
        }

    def modes(self) -> dict[str, Any]:
        """Waits per mode: the dish waits of this service beside those of the same service
        with deliveries alone (:attr:`alone`, None if it was not run), each kind of call
        (how many, who answered, seconds to answer: mean, p50, p90, max) and the bussing
        trips (how many, and seconds from a plates call to the robot at the table)."""
        kinds: dict[str, Any] = {}
        for kind in CALL_KINDS:
            mine = [c for c in self.calls if c["kind"] == kind]
            after = [c["after"] for c in mine if c["answered"] is not None]
            robot = sum(1 for c in mine if str(c.get("by") or "").startswith("robot:"))
            kinds[kind] = {
                "calls": len(mine),
                "answered": len(after),
                "by_robot": robot,
                "by_staff": len(after) - robot,
                "cancelled": sum(1 for c in mine if c["cancelled"] is not None),
                "open": sum(1 for c in mine if c["answered"] is None and c["cancelled"] is None),
                "escalated": sum(1 for c in mine if c["escalated"] is not None),
                "presses": sum(c.get("presses", 1) for c in mine),
                "answer_mean": sum(after) / len(after) if after else math.nan,
                "answer_p50": percentile(after, 50),
                "answer_p90": percentile(after, 90),
                "answer_max": max(after) if after else math.nan,
            }
        reach = [
            s["call_to_robot"]
            for b in self.bussing
            for s in b["stops"]
            if s.get("call_to_robot") is not None
        ]
        done = [b for b in self.bussing if b["status"] == "done"]
        return {
            "dish_waits": {
                "calls_and_bussing": self.dish_waits(),
                "deliveries_alone": None if self.alone is None else self.alone.dish_waits(),
            },
            "calls": kinds,
            "escalated": sum(1 for c in self.calls if c["escalated"] is not None),
            "bussing": {
                "trips": len(self.bussing),
                "done": len(done),
                "tables": sum(len(b["stops"]) for b in self.bussing),
                "robot_s": sum(
                    b["finished"] - b["started"]
                    for b in done
                    if b["finished"] is not None and b["started"] is not None
                ),
                "call_to_robot_mean": sum(reach) / len(reach) if reach else math.nan,
                "call_to_robot_p50": percentile(reach, 50),
                "call_to_robot_p90": percentile(reach, 90),
                "call_to_robot_max": max(reach) if reach else math.nan,
            },
            "dish_return": self.dish_return,
        }

    def stats(self) -> dict[str, Any]:
        """The figures the summary prints (raw floats; the text rounds them)."""
        waits = self.waits()
        bounds = [o["lower_bound"] for o in self.orders]
        trips = self.deliveries()
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
            "loading_s": self.loading,
            "loading_per_trip": self.loading / len(trips) if trips else 0.0,
            "table_timeouts": self.table_timeouts,
            "staff_skips": self.staff_skips,
            "returned": self.returned,
            "resent": self.resent,
            "joined": self.joined,
            "resent_delivered": sum(
                1 for o in self.orders if o.get("resent") and o["wait"] is not None
            ),
            "conflicts": len(self.traffic.get("conflicts", [])),
            "deadlocks": len(self.traffic.get("deadlocks", [])),
            "aborted_by_robot": self.traffic.get("aborted_by_robot", 0),
            "aborted_other": self.traffic.get("aborted_other", 0),
            "closest_m": self.traffic.get("closest"),
            "zone_waits": self.zone_waits.get("waits", 0),
            "zone_wait_s": self.zone_waits.get("seconds", 0.0),
            "zone_wait_per_robot": {
                k: v["seconds"] for k, v in self.zone_waits.get("per_robot", {}).items()
            },
        }
