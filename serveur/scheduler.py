"""Trips: batching dishes into trips, ordering stops, choosing robots (pure) + the dispatch loop.

Staff pick *dishes*, never tables; the server knows each dish's table. A confirmed cart becomes
one or more trips of at most ``capacity`` tables (a tray holds about four tables' dishes, as on
commercial waiter robots). Which tables share a trip and in which order the robot visits them
is decided by path distance on the map, not by the order staff tapped them in:

* :func:`group_by_table` — the cart's dishes per table, tables in first-ready order;
* :func:`split_trips` — tables into trips: seed each trip with the table farthest from the pass
  still unserved, then add its nearest unserved neighbours (so one trip serves one area);
* :func:`order_stops` — the shortest open route from the start through every stop (exact for
  up to 7 stops by permutation, else nearest neighbour + 2-opt);
* :func:`choose_robot` — the free robot that has waited longest (ties: most battery), so work
  spreads over the fleet instead of one robot doing everything while others idle.

Staff choose which dishes go on a cart; :func:`suggest_carts` is the advice they (and the
replay's staff) follow: each waiting table on the trip that collects it soonest, counting
robots due back (:class:`TripEstimate`), tables handed their slots most plates per robot-second
first (:func:`rank_tables`), a hold for a party's next dish that grows as tables queue
(:func:`adaptive_hold`); :func:`fifo_cart` is the design report's staff.

:class:`Dispatcher` is the loop (the design report's flowchart): whenever something changes it
gives each queued trip, oldest first, to the best free robot. The I/O it needs is behind the
small :class:`Fleet` protocol that the server core implements.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol

from serveur.domain import Order

__all__ = [
    "DEFAULT_CAPACITY",
    "MIN_BATTERY",
    "RANKS",
    "UNLOAD_SECONDS",
    "Candidate",
    "Dish",
    "Dispatcher",
    "Distance",
    "Fleet",
    "QueuedTrip",
    "TripEstimate",
    "adaptive_hold",
    "bussing_seconds",
    "can_carry",
    "cart_order_trips",
    "choose_robot",
    "fifo_cart",
    "group_by_table",
    "may_bus",
    "order_stops",
    "plan_trips",
    "rank_tables",
    "route_length",
    "split_trips",
    "suggest_carts",
    "usable",
]

log = logging.getLogger(__name__)

DEFAULT_CAPACITY = 4
#: ``distance(a, b)`` in metres between two named places (waypoints).
Distance = Callable[[str, str], float]

_EXACT_LIMIT = 7


def group_by_table(orders: Iterable[Order]) -> list[tuple[str, list[int]]]:
    """Dishes per table; tables in the order their first dish became ready."""
    groups: dict[str, list[int]] = {}
    first: dict[str, tuple[float, int]] = {}
    for o in sorted(orders, key=lambda o: (o.ready_at or 0.0, o.id)):
        groups.setdefault(o.table, []).append(o.id)
        first.setdefault(o.table, (o.ready_at or 0.0, o.id))
    return [(t, groups[t]) for t in sorted(groups, key=lambda t: first[t])]


def route_length(start: str, stops: Sequence[str], distance: Distance, end: str | None) -> float:
    """Length of start -> stops... (-> end, if given)."""
    total = 0.0
    here = start
    for s in stops:
        total += distance(here, s)
        here = s
    if end is not None and stops:
        total += distance(here, end)
    return total


def _cumulative(start: str, stops: Sequence[str], distance: Distance) -> float:
    """Sum of the distances travelled before each stop: lower means dishes arrive sooner."""
    total = here_total = 0.0
    here = start
    for s in stops:
        here_total += distance(here, s)
        total += here_total
        here = s
    return total


def order_stops(
    start: str, stops: Sequence[str], distance: Distance, *, end: str | None = None
) -> list[str]:
    """The visiting order of ``stops`` minimising the route from ``start`` (and back to ``end``).

    Exact below :data:`_EXACT_LIMIT` stops (7! = 5040 routes is still fast); above it, nearest
    neighbour improved by 2-opt, which is within a few percent on restaurant-sized problems.
    A round trip and its reverse are equally long; between equal routes the one that reaches
    its tables sooner wins (guests wait less), then the given order, so the result is
    deterministic.
    """
    stops = list(dict.fromkeys(stops))
    if len(stops) <= 1:
        return stops
    if len(stops) <= _EXACT_LIMIT:
        best = min(
            itertools.permutations(stops),
            key=lambda p: (
                round(route_length(start, p, distance, end), 6),
                _cumulative(start, p, distance),
            ),
        )
        return list(best)
    route: list[str] = []
    left = list(stops)
    here = start
    while left:
        nxt = min(left, key=lambda s: distance(here, s))
        route.append(nxt)
        left.remove(nxt)
        here = nxt
    improved = True
    while improved:
        improved = False
        for i in range(len(route) - 1):
            for j in range(i + 1, len(route)):
                cand = route[:i] + route[i : j + 1][::-1] + route[j + 1 :]
                if route_length(start, cand, distance, end) + 1e-9 < route_length(
                    start, route, distance, end
                ):
                    route = cand
                    improved = True
    return route


def split_trips(
    tables: Sequence[str], origin: str, distance: Distance, capacity: int = DEFAULT_CAPACITY
) -> list[list[str]]:
    """Tables into trips of at most ``capacity`` tables, each trip one area of the room.

    Seeding with the farthest table keeps the far corners from being left for a last, long,
    nearly empty trip; growing by nearest neighbour keeps each trip's tables close together.
    """
    if capacity < 1:
        raise ValueError("capacity must be >= 1")
    left = list(dict.fromkeys(tables))
    trips: list[list[str]] = []
    while left:
        seed = max(left, key=lambda t: distance(origin, t))
        trip = [seed]
        left.remove(seed)
        while left and len(trip) < capacity:
            nxt = min(left, key=lambda t: min(distance(s, t) for s in trip))
            trip.append(nxt)
            left.remove(nxt)
        trips.append(trip)
    return trips


def plan_trips(
    orders: Iterable[Order],
    origin: str,
    distance: Distance,
    capacity: int = DEFAULT_CAPACITY,
) -> list[list[tuple[str, list[int]]]]:
    """A cart of dishes as trips: each trip's stops in visiting order with their dish ids."""
    groups = dict(group_by_table(orders))
    trips = split_trips(list(groups), origin, distance, capacity)
    return [
        [(t, groups[t]) for t in order_stops(origin, trip, distance, end=origin)] for trip in trips
    ]


def cart_order_trips(
    orders: Sequence[Order], capacity: int = DEFAULT_CAPACITY
) -> list[list[tuple[str, list[int]]]]:
    """The design report's behaviour: tables in the order staff put their dishes in the cart.

    No reordering and no grouping by area: the first ``capacity`` tables of the cart are the
    first trip, and so on. Kept for ``CoreConfig(policy="baseline")`` so the improvement of
    :func:`plan_trips` can be measured against the behaviour it replaces.
    """
    if capacity < 1:
        raise ValueError("capacity must be >= 1")
    groups: dict[str, list[int]] = {}
    for o in orders:
        groups.setdefault(o.table, []).append(o.id)
    tables = list(groups)
    return [
        [(t, groups[t]) for t in tables[i : i + capacity]] for i in range(0, len(tables), capacity)
    ]


# -- the staff's side: which dishes go on the next cart ---------------------------------------


@dataclass(frozen=True, slots=True)
class Dish:
    """A dish as staff see it at the pass (``ready_at`` in any consistent time base)."""

    id: int
    table: str
    ready_at: float


def fifo_cart(dishes: Iterable[Dish], capacity: int = DEFAULT_CAPACITY) -> list[int]:
    """The baseline staff: dishes first ready first, until the tray holds ``capacity`` tables.

    Strict first-in first-out: filling stops at the first dish whose table would not fit,
    even if a later dish is for a table already on the tray (staff work down the ticket rail).
    """
    cart: list[int] = []
    tables: set[str] = set()
    for d in sorted(dishes, key=lambda d: (d.ready_at, d.id)):
        if d.table not in tables:
            if len(tables) >= capacity:
                break
            tables.add(d.table)
        cart.append(d.id)
    return cart


@dataclass(frozen=True, slots=True)
class TripEstimate:
    """How long trips take, as staff (and :func:`suggest_carts`) reckon it.

    Fitted to replays on the demo room (docs/performance.md): robots average ``speed`` over a
    leg once acceleration and corners count, plus ``per_leg`` for planning, turning on the
    spot and settling at the goal; guests at a stop take ``stop`` seconds plus ``per_plate``
    for each plate (the slowest of several guests sets the pace, so more plates, longer).
    Only relative values matter to the planner: they decide whether a table is collected
    sooner as one more stop of a trip leaving now or on a robot coming back later.
    """

    speed: float = 0.6
    per_leg: float = 2.5
    stop: float = 12.0
    per_plate: float = 5.0

    def leg(self, distance: Distance, a: str, b: str) -> float:
        """Seconds to drive from ``a`` to ``b`` (0 when already there)."""
        return 0.0 if a == b else distance(a, b) / self.speed + self.per_leg

    def dwell(self, plates: int) -> float:
        """Seconds a robot stands at a table where ``plates`` dishes are collected."""
        return self.stop + self.per_plate * plates

    def trip(self, origin: str, stops: Sequence[tuple[str, int]], distance: Distance) -> float:
        """Seconds from leaving ``origin`` through ``(table, plates)`` stops and back."""
        total, here = 0.0, origin
        for table, plates in stops:
            total += self.leg(distance, here, table) + self.dwell(plates)
            here = table
        return total + self.leg(distance, here, origin)


#: How :func:`suggest_carts` may rank the waiting tables before giving each its trip.
RANKS = ("fifo", "wspt", "best")


def suggest_carts(
    dishes: Sequence[Dish],
    free_robots: int,
    distance: Distance,
    *,
    now: float,
    origin: str,
    capacity: int = DEFAULT_CAPACITY,
    coming: Sequence[Dish] = (),
    hold: float = 10.0,
    hold_max: float = 60.0,
    busy: Sequence[float] = (),
    estimate: TripEstimate = TripEstimate(),
    return_weight: float = 1.0,
    starve: float = 120.0,
    rank: str = "best",
) -> list[list[int]]:
    """Carts for the robots free now, chosen so that dishes are collected soonest.

    A guest's wait (ready at the pass -> collected) is time on the pass, plus the ride
    (including earlier stops' guests), plus the stop's own dwell. What really moves the
    mean in a busy service is the first term: queueing for a robot in the rushes. So:

    * **Each waiting table goes where it is collected soonest.** The options are one more
      stop on a cart being filled for a robot free now, or a first stop for a robot that is
      free now or due back (``busy``: seconds until each busy robot is back at the pass,
      estimated by staff from its trip). A table is *left on the pass* for a robot coming
      back when that robot would still collect it sooner than riding behind another table's
      dwell; a free robot then leaves with a short trip (or none) instead of a full tray.
      Batching thus happens only when it helps: in a rush, when the next robot is far off,
      neighbouring tables share a trip; when robots are about, each table gets its own.
    * **Tables choose in the order that serves the most plates soonest.** Tables choose
      their slot one after the other, so the first ones get the soonest robots. Besides
      first-ready order, the tables are ranked by plates per second of robot time
      (:func:`rank_tables`: Smith's rule, which minimises the plate-weighted completion
      time on one machine), tables that waited ``starve`` seconds first so that a one-plate
      table at the far end is not passed over for ever. Of the two assignments the one with
      the lower estimated plate-weighted collection time wins (``rank="best"``; ``"fifo"``
      or ``"wspt"`` force one).
    * **The cost of a longer trip counts too.** Each option costs the table's plates times
      its estimated collection time; adding a stop to a trip also costs ``return_weight``
      times how much later that robot gets back (seconds that dishes still to come would
      wait for it). Opening a trip on an idle robot is not charged: a robot left at the pass
      serves nobody.
    * **Hold for a table's next dish when robots are short, longer the shorter they are.**
      A table whose next dish (``coming``: the kitchen's tickets being plated) is ready
      within the hold is left for that dish, unless one of its dishes already waited that
      long: half a party's food now means a second trip for the rest, a whole round trip
      of a robot that other tables need. The hold grows from ``hold`` to ``hold_max`` as
      tables queue beyond the robots (:func:`adaptive_hold`): in a rush a robot's round trip
      is worth more than a few seconds on the pass. When more robots are free than tables
      are waiting or about to, nothing is held.

    Estimates use ``estimate`` (speed, leg overhead, dwell per stop and plate); they are
    guesses of the future and only need to rank the options. Returns the carts (dish ids,
    stops in choosing order; the server re-orders stops by route); ``[]`` means wait.
    """
    if free_robots < 1 or not dishes:
        return []
    if capacity < 1:
        raise ValueError("capacity must be >= 1")
    if rank not in RANKS:
        raise ValueError(f"rank must be one of {RANKS}")
    groups: dict[str, list[Dish]] = {}
    for d in sorted(dishes, key=lambda d: (d.ready_at, d.id)):
        groups.setdefault(d.table, []).append(d)
    wait = adaptive_hold(hold, hold_max, len(groups), free_robots + len(busy), capacity)
    soon: dict[str, float] = {}
    for d in coming:
        if d.ready_at - now <= wait:
            soon[d.table] = min(soon.get(d.table, math.inf), d.ready_at)
    if free_robots > len(groups.keys() | soon.keys()):
        soon.clear()  # robots to spare: holding a table would only make it wait
    tables = [
        t
        for t in sorted(groups, key=lambda t: (groups[t][0].ready_at, groups[t][0].id))
        if t not in soon or now - groups[t][0].ready_at >= wait
    ]
    plates = {t: len(groups[t]) for t in tables}
    rankings: list[list[str]] = []
    if rank in ("fifo", "best"):
        rankings.append(tables)
    if rank in ("wspt", "best"):
        oldest = {t: groups[t][0].ready_at for t in tables}
        ranked = rank_tables(
            plates,
            oldest,
            now=now,
            origin=origin,
            distance=distance,
            estimate=estimate,
            starve=starve,
        )
        if ranked not in rankings:
            rankings.append(ranked)
    chosen: list[_Plan] = []
    lowest = math.inf
    for ranking in rankings:
        plans = [_Plan(0.0, origin, True) for _ in range(free_robots)]
        plans += [_Plan(max(0.0, b), origin, False) for b in sorted(busy)]
        cost = _assign(ranking, plates, plans, distance, origin, capacity, estimate, return_weight)
        if cost < lowest - 1e-9:  # ties: the first ranking (first-ready) stays
            chosen, lowest = plans, cost
    return [[d.id for t in p.stops for d in groups[t]] for p in chosen if p.free and p.stops]


def adaptive_hold(hold: float, hold_max: float, waiting: int, robots: int, capacity: int) -> float:
    """How long a table may wait for its next dish, from ``hold`` up to ``hold_max``.

    ``waiting`` tables on the pass, ``robots`` free or due back: while every table can have
    a robot of its own, ``hold`` (a party's dishes come out a few seconds apart). Beyond
    that, the hold grows linearly with the tables queued per robot and reaches ``hold_max``
    when every robot's tray would be full: a trip saved then is a whole round trip (about a
    minute) that the queued tables get back, worth far more than the held dish's seconds.
    """
    if hold_max <= hold or robots < 1:
        return hold
    queued = max(0, waiting - robots)
    full = max(1, robots * (capacity - 1))
    return hold + (hold_max - hold) * min(1.0, queued / full)


def rank_tables(
    plates: dict[str, int],
    oldest: dict[str, float],
    *,
    now: float,
    origin: str,
    distance: Distance,
    estimate: TripEstimate = TripEstimate(),
    starve: float = 120.0,
) -> list[str]:
    """Tables by plates per second of robot time (Smith's rule), the long-waiting first.

    A table's robot time is a trip of its own (``estimate``: out, its dwell, back). Serving
    first the tables with the most plates per second of robot time minimises the sum of the
    plates' collection times on one robot (weighted shortest processing time); with a
    few robots it is a good order to hand out the soonest slots in. Tables whose oldest
    dish (``oldest``) has waited ``starve`` seconds come first, oldest first, else a far,
    one-plate table could wait as long as the rush lasts. Ties: older first, then name.
    """

    def key(t: str) -> tuple[int, float, float, str]:
        if now - oldest[t] >= starve:
            return (0, oldest[t], 0.0, t)
        work = estimate.trip(origin, [(t, plates[t])], distance)
        return (1, -plates[t] / work, oldest[t], t)

    return sorted(plates, key=key)


def _assign(
    ranking: Sequence[str],
    plates: dict[str, int],
    plans: list[_Plan],
    distance: Distance,
    origin: str,
    capacity: int,
    estimate: TripEstimate,
    return_weight: float,
) -> float:
    """Give each table of ``ranking``, in turn, its cheapest slot; the total cost (estimated).

    The cost is the one the slots are compared by (plates x collection time, plus the
    return delay of a longer trip). A table that finds every tray full is charged a trip of
    its own after the last robot is back, so that rankings leaving tables over compare
    fairly with those that do not.
    """
    total = 0.0
    for t in ranking:
        n = plates[t]
        best: tuple[float, int] | None = None
        for i, p in enumerate(plans):
            if len(p.stops) >= capacity:
                continue
            done = p.clock + estimate.leg(distance, p.here, t) + estimate.dwell(n)
            cost = n * done
            if p.stops:  # a longer trip: the robot is back later for everyone else
                back_before = p.clock + estimate.leg(distance, p.here, origin)
                back_after = done + estimate.leg(distance, t, origin)
                cost += return_weight * (back_after - back_before)
            if best is None or cost < best[0] - 1e-9:
                best = (cost, i)
        if best is None:  # every tray is full: the table waits for the next round
            late = max(p.clock + estimate.leg(distance, p.here, origin) for p in plans)
            total += n * (late + estimate.trip(origin, [(t, n)], distance))
            continue
        p = plans[best[1]]
        p.clock += estimate.leg(distance, p.here, t) + estimate.dwell(n)
        p.here = t
        p.stops.append(t)
        total += best[0]
    return total


@dataclass(slots=True)
class _Plan:
    """A robot's trip being filled by :func:`suggest_carts` (clock: seconds from now)."""

    clock: float
    here: str
    free: bool
    stops: list[str] = field(default_factory=list)


@dataclass(frozen=True, slots=True)
class Candidate:
    """A robot that could take a trip now."""

    name: str
    idle_since: float
    battery: float | None = None
    trays: int | None = None  # tables one trip of it may serve; None: any trip
    lost: bool = False  # not sure where it is: it would serve the wrong table


def can_carry(c: Candidate, stops: int) -> bool:
    """Has the robot a tray for each table of a trip of ``stops`` tables?"""
    return c.trays is None or c.trays >= stops


#: Below this charge a robot gets no new trip (it charges at home; staff can still drive it).
MIN_BATTERY = 0.15


def usable(c: Candidate, min_battery: float = MIN_BATTERY) -> bool:
    """Could the robot take a trip: charged enough and sure where it is?"""
    return (c.battery is None or c.battery >= min_battery) and not c.lost


def choose_robot(
    candidates: Sequence[Candidate], *, min_battery: float = MIN_BATTERY
) -> str | None:
    """The free robot that has waited longest; robots below ``min_battery``, and robots not
    sure where they are, are skipped."""
    found = [c for c in candidates if usable(c, min_battery)]
    if not found:
        return None
    best = min(found, key=lambda c: (c.idle_since, -(c.battery or 0.0), c.name))
    return best.name


class QueuedTrip(NamedTuple):
    """A trip waiting for a robot: its tables, and for a bussing trip how long it would keep
    its robot (seconds, :func:`bussing_seconds`)."""

    task_id: int
    stops: int
    bussing: bool = False
    seconds: float = 0.0


#: Seconds staff take to empty a bussing robot at the dish return (for :func:`may_bus`).
UNLOAD_SECONDS = 60.0


def bussing_seconds(
    origin: str,
    tables: Sequence[str],
    dish_return: str,
    distance: Distance,
    *,
    wait: float,
    estimate: TripEstimate = TripEstimate(),
) -> float:
    """How long a bussing trip keeps its robot, at worst: the drive from ``origin`` round the
    tables (each its full ``wait``), to the dish return (emptied in :data:`UNLOAD_SECONDS`),
    and back."""
    total, here = 0.0, origin
    for t in tables:
        total += estimate.leg(distance, here, t) + wait
        here = t
    total += estimate.leg(distance, here, dish_return) + UNLOAD_SECONDS
    return total + estimate.leg(distance, dish_return, origin)


def may_bus(free: int, seconds: float, *, tables_waiting: int, max_delay: float) -> bool:
    """May one of ``free`` robots leave on a bussing trip of ``seconds`` now?

    Hot food first: a bussing trip never holds back a dish beyond ``max_delay``. It may go if
    no dish is waiting at the pass or being cooked (``tables_waiting``: the tables they are
    for), or the trip is back within ``max_delay`` (a dish ready the moment it leaves waits
    that long at most), or a robot stays free for each waiting table. Not one per
    ``capacity`` tables: tables' dishes come out at different times and each leaves as soon
    as it is ready (a replayed dinner: two tables due within a minute, one robot left for
    both, the second table's nine dishes waited for a bussing robot to come back). Queued
    deliveries are served before any bussing trip (:class:`Dispatcher`).
    """
    if tables_waiting <= 0 or seconds <= max_delay:
        return True
    return free - 1 >= tables_waiting


class Fleet(Protocol):
    """What the dispatcher needs from the server core."""

    async def queued_tasks(self) -> list[QueuedTrip]:
        """The queued trips, oldest first."""
        ...

    def free_robots(self) -> list[Candidate]: ...

    async def start_trip(self, task_id: int, robot: str) -> bool:
        """Give the trip to the robot; False if either was taken meanwhile."""
        ...

    async def tables_waiting(self) -> int:
        """How many tables have a dish ordered, cooking or ready and not yet on a trip?"""
        ...

    def bussing_max_delay(self) -> float:
        """The site's ``bussing_max_delay`` (s)."""
        ...

    def cruising(self) -> list[str]:
        """The robots on a cruise (they come back when deliveries need them)."""
        ...

    async def recall(self, robot: str) -> bool:
        """End the robot's cruise: it goes home into service; False if it moved on."""
        ...


class Dispatcher:
    """Gives queued trips to free robots whenever :meth:`kick` says something changed."""

    def __init__(self, fleet: Fleet) -> None:
        self._fleet = fleet
        self._wake = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self.rounds = 0

    def kick(self) -> None:
        """Something changed (a trip queued, a robot freed): dispatch soon."""
        self._wake.set()

    async def dispatch_once(self) -> int:
        """One round: assign as many queued trips as there are free robots, deliveries first,
        then bussing trips that hold no dish back (:func:`may_bus`); a delivery left without a
        robot calls a cruising robot back. Returns the count."""
        self.rounds += 1
        fleet = self._fleet
        assigned = 0
        cruising = fleet.cruising()
        if not fleet.free_robots() and not cruising:
            # Every robot busy: most rounds in a rush (each new trip kicks one). Reading the
            # whole queue for nothing made each of them cost more as the backlog grew.
            return 0
        queued = await fleet.queued_tasks()
        unserved = 0
        for q in (q for q in queued if not q.bussing):
            free = fleet.free_robots()
            # A trip waits for a robot with a tray per table; smaller trips behind it go on.
            robot = choose_robot([c for c in free if can_carry(c, q.stops)])
            if robot is not None and await fleet.start_trip(q.task_id, robot):
                assigned += 1
            else:
                unserved += 1
        for robot_name in cruising[:unserved]:
            await fleet.recall(robot_name)  # home, then the trip waiting for it
        if unserved:
            return assigned
        waiting: int | None = None
        for q in (q for q in queued if q.bussing):
            # Only robots that could take a trip count: a lost or flat one serves no dish.
            free = [c for c in fleet.free_robots() if usable(c)]
            if not free:
                break
            if waiting is None:
                waiting = await fleet.tables_waiting()
            max_delay = fleet.bussing_max_delay()
            if not may_bus(len(free), q.seconds, tables_waiting=waiting, max_delay=max_delay):
                break  # oldest first: a later bussing trip does not jump the queue
            robot = choose_robot([c for c in free if can_carry(c, q.stops - 1)])
            if robot is not None and await fleet.start_trip(q.task_id, robot):
                assigned += 1
        return assigned

    async def run(self) -> None:
        while True:
            await self._wake.wait()
            self._wake.clear()
            try:
                await self.dispatch_once()
            except Exception:  # the loop must outlive any one failed round
                log.exception("dispatch round failed")

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self.run(), name="dispatcher")
            self.kick()

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None
