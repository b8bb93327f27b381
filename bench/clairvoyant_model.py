"""The clairvoyant problem of issue 31: an order log served by robots that know the future.

:mod:`bench.clairvoyant` (the command) reports against it; this module holds the problem, the
rules a plan is judged by, the OR-Tools model that searches for a plan, and the true lower
bound. Nothing here imports the server's process: it is a benchmark (OR-Tools is a benchmark
dependency, ``pip install -e '.[bench]'``, and only :func:`solve_window` needs it).

**The problem.** Every dish of the log (its table, its ready time at the pass, its guest's
dwell) is known in advance, and so is which party is away from its table and until when. N
robots start at their homes, where they are loaded (the replay's robots load at their home
spot, beside the pass). A *plan* gives each robot a sequence of trips, each trip a sequence of
stops (a table and the dishes it gets there), at most ``capacity`` stops a trip (the replay's
``--capacity``, tables per tray). The plan is judged by :func:`evaluate` with the replay's own
rules, the very functions ``serveur replay`` uses:

* a trip leaves when staff have loaded it: they start once its robot is home and its first
  dish is ready, take the fixed part and then each plate as it is ready (a plate out while
  the robot loads goes on it, as the replay's staff do since issue 31):
  :func:`serveur.replay.model.loading_time` (10 s + 4 s a plate, times the seeded spread keyed
  by the trip's first log line, exactly as the replay's staff); all ready at the start, it is
  that loading time;
* it drives each leg in :class:`Travel` time (the planner's path length on the map, the
  distance table the server's scheduler uses, at an effective speed plus a fixed cost a leg);
* at a stop the robot waits for a party that is away (:func:`serveur.replay.model.absences`,
  the replay's own draw) and then the stop's dwell
  (:func:`serveur.replay.model.stop_dwell`: the slowest guest, 2 s a further plate), after
  which every dish of the stop is delivered; then it drives on, and home after the last stop.

A dish's wait is delivered minus ready, as in the replay's report. The objective is the mean.

**What the plan is, and what it is not.** The plan OR-Tools finds is a feasible schedule of
that problem, so its mean wait is an *upper* bound on the clairvoyant optimum, not a lower
bound: local search stops at a time limit, long services are solved in rolling windows
(:func:`plan_service`), and OR-Tools optimises a surrogate of the rules (below), not the rules
themselves. It is called *the clairvoyant plan*. What is certain is :func:`lower_bound`: no
plan of the problem, clairvoyant or not, beats it for any dish.

**The surrogate** (:func:`solve_window`): a pickup-and-delivery VRP with time windows. Each
dish is a pickup node at the robot's home (open from its ready time, 4 s of plate lifting) and
a delivery node at its table (open from its party's return if away); a route alternates runs
of pickups (a trip's loading) and runs of deliveries (its stops); consecutive deliveries at one
table are one stop. Transit times: a pickup to the first delivery costs the 10 s fixed part of
loading and the drive; a delivery to the next dish at the same table 2 s (a further plate);
a delivery to anywhere else its party's slowest guest's dwell and the drive. The cost is the
sum over dishes of (delivery node's time - ready), a soft upper bound of weight
:data:`WAIT_WEIGHT` on each delivery node's cumul, plus the driving time at weight 1 (a small
tie-break that also gives guided local search arcs to work on). A "stops" dimension counts the
tables of a trip and is reset (through its slack) at each return home, so a trip visits at most
``capacity`` tables. Where the surrogate differs from the rules: the loading spread is left out
(factor 1, its median), plates may be lifted as they become ready once the robot is home, and
a stop's dishes count as delivered a couple of seconds apart rather than together. None of this
changes the reported figure, which is always :func:`evaluate`'s.
"""

from __future__ import annotations

import bisect
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

from serveur.replay.model import ReplayOptions, absences, dish_dwell, loading_time, stop_dwell
from serveur.replay.orders import LogOrder, parties

__all__ = [
    "WAIT_WEIGHT",
    "Dish",
    "Evaluation",
    "Instance",
    "Plan",
    "Stop",
    "Travel",
    "Trip",
    "evaluate",
    "lower_bound",
    "make_instance",
    "plan_service",
    "solve_window",
]

#: A table's dishes less than this apart (s) are one batch: the kitchen sends a party's dishes
#: within 40 s (serveur.replay.orders), while the log's parties
#: (:func:`serveur.replay.orders.parties`, 10 min) can join two courses of one table.
BATCH_GAP = 60.0
#: OR-Tools counts in integer ticks: a tenth of a second.
TICK = 0.1
#: A second of a dish's wait costs this many seconds of driving in the surrogate's objective.
WAIT_WEIGHT = 10


@dataclass(frozen=True, slots=True)
class Travel:
    """Seconds a leg of ``d`` metres takes: ``d / speed + leg`` (0 when it stays put)."""

    speed: float
    leg: float

    def time(self, d: float) -> float:
        return 0.0 if d <= 0.0 else d / self.speed + self.leg


@dataclass(frozen=True, slots=True)
class Dish:
    """One dish of the log: its index in the log, its log line (the replay's seeds are keyed
    by it), table, ready time, its guest's dwell, when its party is back (0: at the table),
    and its batch: the table's dishes the kitchen sent out together (:data:`BATCH_GAP`)."""

    idx: int
    line: int
    table: str
    ready: float
    dwell: float
    back: float
    batch: int


@dataclass
class Instance:
    """A clairvoyant problem: the dishes, the robots' homes, distances, travel, replay options."""

    dishes: list[Dish]
    homes: list[str]
    distance: Callable[[str, str], float]
    travel: Travel
    opts: ReplayOptions

    def leg(self, a: str, b: str) -> float:
        return 0.0 if a == b else self.travel.time(self.distance(a, b))

    def batch_dwell(self, batch: int) -> float:
        """The slowest guest of a batch: the surrogate's dwell for each of its dishes."""
        return self._batch_dwell[batch]

    def __post_init__(self) -> None:
        self._batch_dwell: dict[int, float] = {}
        for d in self.dishes:
            self._batch_dwell[d.batch] = max(self._batch_dwell.get(d.batch, 0.0), d.dwell)


def make_instance(
    log: Sequence[LogOrder],
    homes: Sequence[str],
    distance: Callable[[str, str], float],
    travel: Travel,
    opts: ReplayOptions,
) -> Instance:
    """The problem of ``log`` (lines numbered as in its CSV) for robots at ``homes``."""
    batch_of: dict[int, int] = {}
    for i, p in enumerate(parties(log, BATCH_GAP)):
        for o in p:
            batch_of[o.line] = i
    back: dict[int, float] = {}
    for a in absences(log, opts.seed, opts.away):
        for o in log:
            if o.table == a.table and a.start <= o.ready_at < a.end:
                back[o.line] = a.end
    dishes = [
        Dish(
            i,
            o.line,
            o.table,
            o.ready_at,
            dish_dwell(opts.seed, o.line),
            back.get(o.line, 0.0),
            batch_of[o.line],
        )
        for i, o in enumerate(log)
    ]
    return Instance(dishes, list(homes), distance, travel, opts)


#: A stop: a table and the dishes (indices) it gets; a trip: its stops; a plan: each robot's
#: trips, in order.
Stop = tuple[str, tuple[int, ...]]
Trip = list[Stop]
Plan = list[list[Trip]]


@dataclass
class TripRecord:
    """One trip as :func:`evaluate` timed it."""

    robot: int
    home_at: float  # the robot was home (free) from
    depart: float
    back: float
    stops: list[Stop]
    loading: float
    arrivals: list[float] = field(default_factory=list)


@dataclass
class Evaluation:
    """A plan judged by the replay's rules: each dish's delivery, each trip, each robot's
    return home after its last trip."""

    delivered: dict[int, float]
    trips: list[TripRecord]
    free_at: list[float]

    def waits(self, inst: Instance) -> list[float]:
        return [self.delivered[d.idx] - d.ready for d in inst.dishes if d.idx in self.delivered]


def _time_trip(
    inst: Instance, robot: int, home_at: float, trip: Trip, delivered: dict[int, float]
) -> TripRecord:
    dishes = sorted((i for _, ids in trip for i in ids), key=lambda i: inst.dishes[i].ready)
    lines = [inst.dishes[i].line for i in dishes]
    load = loading_time(inst.opts, min(lines), len(dishes))
    # Staff start loading once the robot is home and the first dish is ready: the fixed part,
    # then each plate as it is ready (a plate out while the robot loads goes on it, as the
    # replay's staff do since issue 31), with the trip's seeded spread on every part.
    o = inst.opts
    base = o.load_fixed + o.load_per_dish * len(dishes)
    factor = load / base if base > 0.0 else 0.0
    depart = max(home_at, inst.dishes[dishes[0]].ready) + o.load_fixed * factor
    for i in dishes:
        depart = max(depart, inst.dishes[i].ready) + o.load_per_dish * factor
    home = inst.homes[robot]
    rec = TripRecord(robot, home_at, depart, 0.0, list(trip), load)
    here, t = home, depart
    for table, ids in trip:
        t += inst.leg(here, table)
        rec.arrivals.append(t)
        t = max([t, *(inst.dishes[i].back for i in ids)])
        t += stop_dwell(inst.opts.seed, [inst.dishes[i].line for i in ids])
        for i in ids:
            delivered[i] = t
        here = table
    rec.back = t + inst.leg(here, home)
    return rec


def evaluate(inst: Instance, plan: Plan, free_at: Sequence[float] | None = None) -> Evaluation:
    """Time ``plan`` by the replay's rules (see the module's docstring); robots free from
    ``free_at`` (0 by default)."""
    free = list(free_at) if free_at is not None else [0.0] * len(inst.homes)
    delivered: dict[int, float] = {}
    trips: list[TripRecord] = []
    for r, robot_trips in enumerate(plan):
        for trip in robot_trips:
            rec = _time_trip(inst, r, free[r], trip, delivered)
            trips.append(rec)
            free[r] = rec.back
    return Evaluation(delivered, trips, free)


def lower_bound(inst: Instance, vmax: float) -> list[float]:
    """Each dish's wait in any plan is at least this (the ride-plus-dwell bound, tightened).

    A dish leaves the pass no earlier than ready + the least loading (one plate, the spread's
    floor of 0.5: ``loading_time`` clamps its factor to [0.5, 3]), rides at least the planner's
    path from the nearest home to its table at the robots' top speed ``vmax`` (no
    acceleration, no turn: the simulated robots never go faster), cannot be collected before
    its party is back, and its guest takes at least their own dwell. Everything a schedule
    decides (queueing for a robot, other tables on the trip, the party's slowest guest) is left
    out, so no plan, clairvoyant or online, beats it.
    """
    o = inst.opts
    least_load = max(0.0, 0.5 * (o.load_fixed + o.load_per_dish))
    if o.load_spread <= 0.0:
        least_load = o.load_fixed + o.load_per_dish
    out = []
    for d in inst.dishes:
        ride = min(inst.distance(h, d.table) for h in inst.homes) / vmax
        out.append(max(least_load + ride, d.back - d.ready) + d.dwell)
    return out


# -- the OR-Tools surrogate --------------------------------------------------------------------


@dataclass(frozen=True, slots=True)
class _Unit:
    """What one pickup/delivery pair of the VRP carries: one dish, or a kitchen batch whole."""

    ids: tuple[int, ...]
    table: str
    ready: float  # the last of its dishes
    mean_ready: float
    back: float
    dwell: float  # what the robot stays at the table for it


def _units(inst: Instance, ids: Sequence[int], unit: str) -> list[_Unit]:
    groups: dict[int, list[int]] = {}
    for i in ids:
        groups.setdefault(inst.dishes[i].batch if unit == "batch" else -1 - i, []).append(i)
    out = []
    for g in groups.values():
        ds = [inst.dishes[i] for i in g]
        dwell = (
            stop_dwell(inst.opts.seed, [d.line for d in ds])
            if unit == "batch"
            else inst.batch_dwell(ds[0].batch)
        )
        out.append(
            _Unit(
                tuple(g),
                ds[0].table,
                max(d.ready for d in ds),
                sum(d.ready for d in ds) / len(ds),
                max(d.back for d in ds),
                dwell,
            )
        )
    return out


def solve_window(
    inst: Instance,
    ids: Sequence[int],
    free_at: Sequence[float],
    *,
    time_limit: float,
    initial: Plan | None = None,
    unit: str = "batch",
) -> Plan:
    """A plan for dishes ``ids`` with robots free from ``free_at``: OR-Tools' best within
    ``time_limit`` seconds of guided local search, from ``initial`` (or parallel cheapest
    insertion). ``unit``: "batch", each kitchen batch rides whole (one pickup/delivery pair,
    exact dwell and cost, far fewer nodes: the search can move a whole table onto another
    trip in one step), or "dish" (each dish its own pair: batches may be split, the dwell is
    the surrogate's). The surrogate is described in the module's docstring."""
    from ortools.constraint_solver import pywrapcp, routing_enums_pb2

    n_rob = len(inst.homes)
    units = _units(inst, ids, unit)
    n_nodes = 2 * n_rob + 2 * len(units)
    # Nodes: 0..R-1 starts, R..2R-1 ends (the robots' homes), then per unit pickup, delivery.
    starts = list(range(n_rob))
    ends = list(range(n_rob, 2 * n_rob))
    manager = pywrapcp.RoutingIndexManager(n_nodes, n_rob, starts, ends)
    routing = pywrapcp.RoutingModel(manager)

    def kind(node: int) -> tuple[str, _Unit | None]:
        if node < n_rob:
            return "start", None
        if node < 2 * n_rob:
            return "end", None
        j, off = divmod(node - 2 * n_rob, 2)
        return ("pick" if off == 0 else "drop"), units[j]

    kinds = [kind(n) for n in range(n_nodes)]
    cap = inst.opts.capacity
    ticks = lambda s: round(s / TICK)  # noqa: E731 - local shorthand
    fixed = ticks(inst.opts.load_fixed)
    per_plate = ticks(inst.opts.load_per_dish)
    big = 10**9  # an arc no plan may take
    same_table = ticks(2.0) if unit == "dish" else None

    def matrices(robot: int) -> tuple[list[list[int]], list[list[int]]]:
        home = inst.homes[robot]
        time_m = [[0] * n_nodes for _ in range(n_nodes)]
        drive_m = [[0] * n_nodes for _ in range(n_nodes)]
        for a in range(n_nodes):
            ka, ua = kinds[a]
            for b in range(n_nodes):
                kb, ub = kinds[b]
                if a == b:
                    continue
                t = d = 0
                if ka == "start":
                    if kb == "drop":
                        t = d = big
                elif ka == "end":
                    t = d = big
                elif ka == "pick":
                    assert ua is not None
                    plates = per_plate * len(ua.ids)
                    if kb == "pick":
                        t = plates
                    elif kb == "drop":
                        assert ub is not None
                        d = ticks(inst.leg(home, ub.table))
                        t = plates + fixed + d
                    else:
                        t = d = big
                else:  # a delivery
                    assert ua is not None
                    if same_table is not None and kb == "drop" and ub and ub.table == ua.table:
                        t = same_table
                    else:
                        to = ub.table if kb == "drop" and ub is not None else home
                        d = ticks(inst.leg(ua.table, to))
                        t = ticks(ua.dwell) + d
                time_m[a][b] = t
                drive_m[a][b] = d
        return time_m, drive_m

    time_cbs = []
    for r in range(n_rob):
        tm, dm = matrices(r)
        time_cbs.append(routing.RegisterTransitMatrix(tm))
        routing.SetArcCostEvaluatorOfVehicle(routing.RegisterTransitMatrix(dm), r)

    horizon = ticks(max(u.ready for u in units) + max(free_at) + 4 * 3600.0)
    routing.AddDimensionWithVehicleTransits(time_cbs, horizon, horizon, False, "time")
    time_dim = routing.GetDimensionOrDie("time")

    # Tables per trip: +1 entering a table, 0 for a further dish there, -cap back home (the
    # slack, up to cap, brings the count back to anything in [0, cap]).
    stops_m = [[0] * n_nodes for _ in range(n_nodes)]
    for a in range(n_nodes):
        ka, ua = kinds[a]
        for b in range(n_nodes):
            kb, ub = kinds[b]
            if ka == "pick" and kb == "drop":
                stops_m[a][b] = 1
            elif ka == "drop" and kb == "drop" and ua is not None and ub is not None:
                stops_m[a][b] = 0 if ua.table == ub.table else 1
            elif ka == "drop" and kb == "pick":
                stops_m[a][b] = -cap
    routing.AddDimension(routing.RegisterTransitMatrix(stops_m), cap, cap, True, "stops")

    for r in range(n_rob):
        time_dim.CumulVar(routing.Start(r)).SetMin(ticks(free_at[r]))
    for j, u in enumerate(units):
        p = manager.NodeToIndex(2 * n_rob + 2 * j)
        q = manager.NodeToIndex(2 * n_rob + 2 * j + 1)
        routing.AddPickupAndDelivery(p, q)
        routing.solver().Add(routing.VehicleVar(p) == routing.VehicleVar(q))
        routing.solver().Add(time_dim.CumulVar(p) <= time_dim.CumulVar(q))
        time_dim.CumulVar(p).SetMin(ticks(u.ready))
        time_dim.CumulVar(q).SetMin(ticks(max(u.ready, u.back)))
        # n x (arrival - mean ready) = the sum of its dishes' (arrival - ready): arrival is
        # after the last is ready, so the soft bound never clips.
        time_dim.SetCumulVarSoftUpperBound(q, ticks(u.mean_ready), WAIT_WEIGHT * len(u.ids))

    params = pywrapcp.DefaultRoutingSearchParameters()
    params.first_solution_strategy = (
        routing_enums_pb2.FirstSolutionStrategy.PARALLEL_CHEAPEST_INSERTION
    )
    params.local_search_metaheuristic = (
        routing_enums_pb2.LocalSearchMetaheuristic.GUIDED_LOCAL_SEARCH
    )
    params.time_limit.FromMilliseconds(int(time_limit * 1000))
    if initial is not None:
        routing.CloseModelWithParameters(params)
        node_of = {i: j for j, u in enumerate(units) for i in u.ids}
        routes = []
        for trips in initial:
            route: list[int] = []
            for trip in trips:
                js = list(dict.fromkeys(node_of[i] for _, dd in trip for i in dd))
                route += [2 * n_rob + 2 * j for j in js] + [2 * n_rob + 2 * j + 1 for j in js]
            routes.append([manager.NodeToIndex(n) for n in route])
        start = routing.ReadAssignmentFromRoutes(routes, True)
        if start is None:
            raise RuntimeError("OR-Tools refused the initial plan")
        solution = routing.SolveFromAssignmentWithParameters(start, params)
    else:
        solution = routing.SolveWithParameters(params)
    if solution is None:
        raise RuntimeError(f"OR-Tools found no plan for {len(ids)} dishes")
    plan: Plan = []
    for r in range(n_rob):
        trips: list[Trip] = []
        stops: list[list[int]] = []
        tables: list[str] = []
        prev = "start"
        index = routing.Start(r)
        while not routing.IsEnd(index):
            node = manager.IndexToNode(index)
            k, u = kinds[node]
            if k == "drop":
                assert u is not None
                if prev != "drop":
                    stops, tables = [], []
                    trips.append([])
                if not tables or tables[-1] != u.table:
                    stops.append([])
                    tables.append(u.table)
                stops[-1].extend(u.ids)
                trips[-1] = [(t, tuple(s)) for t, s in zip(tables, stops, strict=True)]
            prev = k
            index = solution.Value(routing.NextVar(index))
        plan.append(trips)
    return plan


def greedy_window(inst: Instance, ids: Sequence[int], free_at: Sequence[float]) -> Plan:
    """A simple clairvoyant plan to start from: each batch's dishes (of ``ids``) one trip, in
    order of its last dish's ready time, on the robot that delivers it soonest."""
    groups: dict[int, list[int]] = {}
    for i in ids:
        groups.setdefault(inst.dishes[i].batch, []).append(i)
    order = sorted(groups.values(), key=lambda g: max(inst.dishes[i].ready for i in g))
    plan: Plan = [[] for _ in inst.homes]
    free = list(free_at)
    for g in order:
        table = inst.dishes[g[0]].table
        best: tuple[float, int, TripRecord] | None = None
        for r in range(len(inst.homes)):
            rec = _time_trip(inst, r, free[r], [(table, tuple(g))], {})
            done = rec.arrivals[0]
            if best is None or done < best[0]:
                best = (done, r, rec)
        assert best is not None
        _, r, rec = best
        plan[r].append([(table, tuple(g))])
        free[r] = rec.back
    return plan


def plan_service(
    inst: Instance,
    *,
    window: float,
    overlap: float,
    time_limit: float,
    unit: str = "batch",
    progress: Callable[[str], None] | None = None,
) -> Plan:
    """The clairvoyant plan of the whole service, in rolling windows.

    Each step plans the dishes ready in ``[t, t + window + overlap)`` (plus any left over),
    from where the robots are, and keeps each robot's trips that leave before ``t + window``;
    the dishes of the trips not kept go to the next step, which starts at ``t + window``.
    ``window`` covering the service is one VRP. What windows cost: a step does not see dishes
    ready more than ``overlap`` after its cut, so a trip kept near the cut may have been worth
    changing for them — the plan is a little worse than one VRP would find with unlimited
    time, and stays a feasible plan (an upper bound on the optimum), never a bound below it.
    """
    plan: Plan = [[] for _ in inst.homes]
    free = [0.0] * len(inst.homes)
    readies = [d.ready for d in inst.dishes]  # the log is sorted by ready time
    end = readies[-1] if readies else 0.0
    t = 0.0
    carried: list[int] = []
    while True:
        cut = t + window
        last = cut >= end
        hi = math.inf if last else cut + overlap
        lo_i = bisect.bisect_left(readies, t)
        hi_i = len(readies) if last else bisect.bisect_left(readies, hi)
        ids = sorted(set(carried) | set(range(lo_i, hi_i)) - _planned(plan))
        if ids:
            # Greedy, then whole batches, then (unit "both") single dishes from there: the
            # best plan by the rules is kept (the surrogate can judge a move wrongly).
            cands = [greedy_window(inst, ids, free)]
            for u in ("batch", "dish") if unit == "both" else (unit,):
                cands.append(
                    solve_window(inst, ids, free, time_limit=time_limit, initial=cands[-1], unit=u)
                )
            found = min(cands, key=lambda c: sum(evaluate(inst, c, free).delivered.values()))
            kept: Plan = [[] for _ in inst.homes]
            ev = evaluate(inst, found, free)
            by_robot: dict[int, list[TripRecord]] = {}
            for rec in ev.trips:
                by_robot.setdefault(rec.robot, []).append(rec)
            for r, recs in by_robot.items():
                for rec in recs:
                    if not last and rec.depart >= cut:
                        break
                    kept[r].append(rec.stops)
            for r in range(len(inst.homes)):
                plan[r] += kept[r]
            free = evaluate(inst, plan).free_at
            carried = sorted(set(ids) - _planned(plan))
            if progress is not None:
                progress(
                    f"  window {t:6.0f}-{cut:6.0f} s: {len(ids)} dishes planned, "
                    f"{len(ids) - len(carried)} kept"
                )
        if last:
            break
        t = cut
    missing = set(range(len(inst.dishes))) - _planned(plan)
    if missing:
        raise RuntimeError(f"{len(missing)} dishes left out of the plan")
    return plan


def _planned(plan: Plan) -> set[int]:
    return {i for trips in plan for trip in trips for _, ids in trip for i in ids}
