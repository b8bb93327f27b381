"""Trip planning (pure) and the dispatch loop against a fake fleet."""

from __future__ import annotations

import itertools
import math
from typing import Any

import pytest

from serveur.domain import Order
from serveur.scheduler import (
    Candidate,
    Dish,
    Dispatcher,
    QueuedTrip,
    TripEstimate,
    adaptive_hold,
    cart_order_trips,
    choose_robot,
    fifo_cart,
    group_by_table,
    may_bus,
    order_stops,
    plan_trips,
    rank_tables,
    route_length,
    split_trips,
    suggest_carts,
)

# Tables on a line and a grid; the pass at the origin.
POS = {"pass": (0.0, 0.0), **{f"T{i}": (float(i), 0.0) for i in range(1, 9)}}
GRID = {
    "pass": (0.0, 0.0),
    **{f"G{i}{j}": (i * 2.0, j * 2.0) for i in range(1, 4) for j in range(1, 4)},
}


def euclid(pos: dict[str, tuple[float, float]]):  # type: ignore[no-untyped-def]
    def d(a: str, b: str) -> float:
        (ax, ay), (bx, by) = pos[a], pos[b]
        return math.hypot(ax - bx, ay - by)

    return d


def order(i: int, table: str, t: float) -> Order:
    return Order(id=i, dish=f"dish{i}", table=table, ready_at=t)


def test_group_by_table_keeps_first_ready_order() -> None:
    orders = [order(1, "T3", 5), order(2, "T1", 1), order(3, "T3", 0), order(4, "T2", 9)]
    assert group_by_table(orders) == [("T3", [3, 1]), ("T1", [2]), ("T2", [4])]


def test_stops_are_ordered_by_distance_not_cart_order() -> None:
    d = euclid(POS)
    assert order_stops("pass", ["T5", "T1", "T3"], d) == ["T1", "T3", "T5"]


def test_order_stops_is_optimal_for_small_trips() -> None:
    d = euclid(GRID)
    stops = ["G33", "G11", "G21", "G13", "G32"]
    best = min(itertools.permutations(stops), key=lambda p: route_length("pass", p, d, "pass"))
    got = order_stops("pass", stops, d, end="pass")
    assert route_length("pass", got, d, "pass") == pytest.approx(
        route_length("pass", best, d, "pass")
    )


def test_order_stops_large_uses_heuristic_and_visits_all() -> None:
    d = euclid(GRID)
    stops = [n for n in GRID if n != "pass"]
    got = order_stops("pass", stops, d, end="pass")
    assert sorted(got) == sorted(stops)
    # 2-opt on a 3x3 grid finds a tour no longer than a serpentine one.
    serp = ["G11", "G12", "G13", "G23", "G22", "G21", "G31", "G32", "G33"]
    assert route_length("pass", got, d, "pass") <= route_length("pass", serp, d, "pass") + 1e-9


def test_split_trips_respects_capacity_and_groups_areas() -> None:
    d = euclid(POS)
    trips = split_trips([f"T{i}" for i in range(1, 9)], "pass", d, capacity=4)
    assert [sorted(t) for t in trips] == [["T5", "T6", "T7", "T8"], ["T1", "T2", "T3", "T4"]]
    with pytest.raises(ValueError):
        split_trips(["T1"], "pass", d, capacity=0)


def test_plan_trips_every_order_once() -> None:
    d = euclid(POS)
    orders = [order(i, f"T{1 + i % 6}", float(i)) for i in range(15)]
    trips = plan_trips(orders, "pass", d, capacity=4)
    ids = [oid for trip in trips for _, oids in trip for oid in oids]
    assert sorted(ids) == list(range(15))
    assert all(len(trip) <= 4 for trip in trips)
    for trip in trips:  # each trip in distance order from the pass
        xs = [POS[t][0] for t, _ in trip]
        assert xs == sorted(xs)


def test_choose_robot_longest_idle_and_battery() -> None:
    c = [Candidate("a", 10.0, 0.9), Candidate("b", 5.0, 0.5), Candidate("c", 5.0, 0.8)]
    assert choose_robot(c) == "c"
    assert choose_robot([Candidate("a", 1.0, 0.05)]) is None
    assert choose_robot([]) is None


class FakeFleet:
    def __init__(self, tasks: list[int], robots: list[str]) -> None:
        self.tasks = tasks
        self.free = {r: float(i) for i, r in enumerate(robots)}
        self.started: list[tuple[int, str]] = []
        self.queue_reads = 0
        self.cruisers = []
        self.recalled = []

    async def queued_tasks(self) -> list[QueuedTrip]:
        self.queue_reads += 1
        return [QueuedTrip(t, 1) for t in self.tasks if t not in {s for s, _ in self.started}]

    def free_robots(self) -> list[Candidate]:
        return [Candidate(r, t) for r, t in self.free.items()]

    async def start_trip(self, task_id: int, robot: str) -> bool:
        self.started.append((task_id, robot))
        del self.free[robot]
        return True

    async def tables_waiting(self) -> int:
        return self.tables

    def bussing_max_delay(self) -> float:
        return 90.0

    def cruising(self) -> list[str]:
        return list(self.cruisers)

    async def recall(self, robot: str) -> bool:
        self.cruisers.remove(robot)
        self.recalled.append(robot)
        return True

    tables = 1  # one table's dishes cooking
    cruisers: list[str]
    recalled: list[str]


async def test_dispatch_gives_each_trip_to_one_robot() -> None:
    fleet = FakeFleet([1, 2, 3], ["r1", "r2"])
    d = Dispatcher(fleet)
    assert await d.dispatch_once() == 2
    assert fleet.started == [(1, "r1"), (2, "r2")]
    reads = fleet.queue_reads
    assert await d.dispatch_once() == 0  # no robot left for trip 3
    assert fleet.queue_reads == reads  # ... and the queue is not even read
    fleet.free["r3"] = 9.0
    assert await d.dispatch_once() == 1
    assert fleet.started[-1] == (3, "r3")


async def test_a_trip_goes_to_a_robot_with_a_tray_for_each_table() -> None:
    class TrayFleet(FakeFleet):
        sizes = {1: 4, 2: 2}
        trays = {"small": 2, "big": 4}

        async def queued_tasks(self) -> list[QueuedTrip]:
            done = {s for s, _ in self.started}
            return [QueuedTrip(t, self.sizes[t]) for t in self.tasks if t not in done]

        def free_robots(self) -> list[Candidate]:
            return [Candidate(r, t, trays=self.trays[r]) for r, t in self.free.items()]

    # "small" has waited longest, but trip 1 has four tables: it waits for "big", and trip 2
    # behind it is not held up.
    fleet = TrayFleet([1, 2], ["small"])
    d = Dispatcher(fleet)
    assert await d.dispatch_once() == 1
    assert fleet.started == [(2, "small")]
    fleet.free["big"] = 5.0
    assert await d.dispatch_once() == 1
    assert fleet.started[-1] == (1, "big")


class ModesFleet(FakeFleet):
    """Trips 100+ are bussing trips of ``seconds[t]``; the rest deliveries."""

    seconds: dict[int, float] = {}

    async def queued_tasks(self) -> list[QueuedTrip]:
        done = {s for s, _ in self.started}
        return [
            QueuedTrip(t, 2, bussing=t >= 100, seconds=self.seconds.get(t, 0.0))
            for t in self.tasks
            if t not in done
        ]


def test_may_bus_never_holds_a_dish_beyond_the_limit() -> None:
    limits = dict(max_delay=90.0)
    assert may_bus(1, 300.0, tables_waiting=1, **limits) is False
    assert may_bus(1, 80.0, tables_waiting=1, **limits) is True  # back within the limit
    assert may_bus(2, 300.0, tables_waiting=1, **limits) is True  # a robot stays for the table
    # Two tables come out at different times: one robot left for both is not enough.
    assert may_bus(2, 300.0, tables_waiting=2, **limits) is False
    assert may_bus(3, 300.0, tables_waiting=2, **limits) is True
    assert may_bus(1, 300.0, tables_waiting=0, **limits) is True  # kitchen idle


async def test_deliveries_go_before_bussing_and_a_long_bussing_trip_waits() -> None:
    fleet = ModesFleet([100, 1], ["r1"])
    fleet.seconds = {100: 300.0}
    d = Dispatcher(fleet)
    assert await d.dispatch_once() == 1
    assert fleet.started == [(1, "r1")]  # the delivery, though queued after the bussing trip
    fleet.free["r2"] = 5.0
    assert await d.dispatch_once() == 0  # one robot, dishes cooking, 300 s > 90 s: it waits
    fleet.tables = 0
    assert await d.dispatch_once() == 1
    assert fleet.started[-1] == (100, "r2")


async def test_a_short_bussing_trip_or_a_second_free_robot_may_go() -> None:
    fleet = ModesFleet([100, 101], ["r1", "r2"])
    fleet.seconds = {100: 300.0, 101: 300.0}
    d = Dispatcher(fleet)
    assert await d.dispatch_once() == 1  # two free: one goes, the last stays for dishes
    assert fleet.started == [(100, "r1")]
    fleet.seconds[101] = 60.0
    assert await d.dispatch_once() == 1  # back within 90 s: it may take the last robot
    assert fleet.started[-1] == (101, "r2")


async def test_a_delivery_without_a_robot_calls_a_cruiser_back() -> None:
    fleet = ModesFleet([1], [])
    fleet.cruisers = ["r1", "r2"]
    d = Dispatcher(fleet)
    assert await d.dispatch_once() == 0
    assert fleet.recalled == ["r1"]  # one trip waiting: one robot called back
    assert fleet.cruisers == ["r2"]
    fleet.tasks = []
    await d.dispatch_once()
    assert fleet.recalled == ["r1"]  # nothing waiting: the other cruises on


def test_cart_order_trips_keep_the_cart_order() -> None:
    orders = [order(1, "T5", 0), order(2, "T1", 9), order(3, "T5", 1), order(4, "T3", 2)]
    assert cart_order_trips(orders, capacity=2) == [[("T5", [1, 3]), ("T1", [2])], [("T3", [4])]]
    with pytest.raises(ValueError):
        cart_order_trips(orders, capacity=0)


def test_fifo_cart_stops_at_the_first_table_that_does_not_fit() -> None:
    dishes = [Dish(1, "T1", 0), Dish(2, "T2", 1), Dish(3, "T3", 2), Dish(4, "T1", 3)]
    assert fifo_cart(dishes, capacity=2) == [1, 2]  # dish 4 (T1) waits behind T3
    assert fifo_cart(reversed(dishes), capacity=3) == [1, 2, 3, 4]
    assert fifo_cart([], capacity=4) == []


def test_suggest_carts_spreads_tables_over_free_robots() -> None:
    d = euclid(POS)
    dishes = [Dish(i, t, float(i)) for i, t in enumerate(["T1", "T8", "T2", "T7", "T1"])]
    # Two robots and nobody else coming: each table is collected soonest on its own trip
    # or as the next stop of a neighbour's, so the two robots split the room in two areas.
    assert suggest_carts(dishes, 2, d, now=10.0, origin="pass") == [[0, 4, 2], [1, 3]]
    # More robots than tables: one table each, no empty carts.
    assert len(suggest_carts(dishes, 9, d, now=10.0, origin="pass")) == 4
    assert suggest_carts(dishes, 0, d, now=10.0, origin="pass") == []
    assert suggest_carts([], 3, d, now=10.0, origin="pass") == []


def test_suggest_carts_leaves_a_table_for_a_robot_due_back() -> None:
    """The new policy's choice: a short trip now, the next table for the robot coming back.

    One robot free, T1 and T8 waiting (8 m apart). On the free robot, T8 would be collected
    after T1's guests and the drive across; a robot due back at the pass in 5 s collects it
    sooner, so the free robot leaves with T1 alone. If that robot is 5 minutes away, T8
    rides along (in a rush, the next robot is far off and the trip is shared).
    """
    d = euclid(POS)
    dishes = [Dish(1, "T1", 0.0), Dish(2, "T8", 1.0)]
    assert suggest_carts(dishes, 1, d, now=10.0, origin="pass", busy=[5.0]) == [[1]]
    assert suggest_carts(dishes, 1, d, now=10.0, origin="pass", busy=[300.0]) == [[1, 2]]
    # With no robot due back the old behaviour (one tray, capacity permitting) remains.
    assert suggest_carts(dishes, 1, d, now=10.0, origin="pass") == [[1, 2]]
    assert suggest_carts(dishes, 1, d, now=10.0, origin="pass", capacity=1) == [[1]]


def test_suggest_carts_holds_for_a_tables_next_dish_but_not_forever() -> None:
    d = euclid(POS)
    dishes = [Dish(1, "T3", 100.0)]
    coming = [Dish(2, "T3", 110.0)]
    kw = {"origin": "pass", "hold": 20.0}
    assert suggest_carts(dishes, 1, d, now=105.0, coming=coming, **kw) == []
    # Past the hold time the dish goes anyway, and a far-off next dish never holds it.
    assert suggest_carts(dishes, 1, d, now=121.0, coming=coming, **kw) == [[1]]
    late = [Dish(2, "T3", 500.0)]
    assert suggest_carts(dishes, 1, d, now=105.0, coming=late, **kw) == [[1]]
    # With a robot to spare nothing is held.
    assert suggest_carts(dishes, 2, d, now=105.0, coming=coming, **kw) == [[1]]


def test_trip_estimate_counts_legs_dwells_and_the_way_back() -> None:
    d = euclid(POS)
    est = TripEstimate(speed=1.0, per_leg=2.0, stop=10.0, per_plate=5.0)
    # pass -> T2 (2 m) -> T5 (3 m) -> pass (5 m): 3 legs, 2 stops of 1 and 3 plates.
    assert est.trip("pass", [("T2", 1), ("T5", 3)], d) == pytest.approx(10 + 6 + 15 + 25)
    assert est.leg(d, "T3", "T3") == 0.0


def test_rank_tables_by_plates_per_robot_second_starving_tables_first() -> None:
    d = euclid(POS)
    plates = {"T8": 1, "T2": 1, "T1": 3}
    oldest = {"T8": 0.0, "T2": 5.0, "T1": 10.0}
    # Plates per second of a trip of its own: T1 3 plates near the pass, then T2, then T8
    # (one plate at the far end), whatever the order they became ready in.
    kw: dict[str, Any] = {"origin": "pass", "distance": d, "starve": 120.0}
    assert rank_tables(plates, oldest, now=60.0, **kw) == ["T1", "T2", "T8"]
    # T8 has waited 2 minutes: it goes first; then T2 too: the older of the two first.
    assert rank_tables(plates, oldest, now=120.0, **kw) == ["T8", "T1", "T2"]
    assert rank_tables(plates, oldest, now=125.0, **kw) == ["T8", "T2", "T1"]
    # Equal plates and distance: the older first.
    assert rank_tables(
        {"T3": 2, "T4": 2}, {"T3": 1.0, "T4": 0.0}, now=1.0, origin="T0", distance=lambda a, b: 1.0
    ) == ["T4", "T3"]


def test_adaptive_hold_grows_as_tables_queue_beyond_the_robots() -> None:
    # 3 robots, trays of 4 tables: no queue -> the base hold; 9 tables queued beyond the
    # robots (every tray full) or more -> the longest; linear in between.
    assert adaptive_hold(10.0, 60.0, waiting=2, robots=3, capacity=4) == 10.0
    assert adaptive_hold(10.0, 60.0, waiting=3, robots=3, capacity=4) == 10.0
    assert adaptive_hold(10.0, 60.0, waiting=3 + 9, robots=3, capacity=4) == 60.0
    assert adaptive_hold(10.0, 60.0, waiting=40, robots=3, capacity=4) == 60.0
    assert adaptive_hold(10.0, 60.0, waiting=3 + 3, robots=3, capacity=4) == pytest.approx(
        10.0 + 50.0 / 3
    )
    # A maximum below the base, or no robot at all: the base hold.
    assert adaptive_hold(10.0, 5.0, waiting=20, robots=3, capacity=4) == 10.0
    assert adaptive_hold(10.0, 60.0, waiting=20, robots=0, capacity=4) == 10.0


def test_suggest_carts_gives_the_free_robot_to_the_most_plates_per_second() -> None:
    """One robot free now, one due back in 30 s; T8 (1 plate, far) has waited longest.

    First-ready order gives T8 the free robot and leaves T1's three plates for the robot
    coming back; ranked by plates per robot-second, T1 leaves now and T8 waits 30 s. The
    second collects 3 plates about 30 s sooner for 1 plate 30 s later: the better of the two
    is chosen. Once T8 has waited ``starve`` seconds it goes first whatever its plates.
    """
    d = euclid(POS)
    dishes = [Dish(1, "T8", 0.0), Dish(2, "T1", 5.0), Dish(3, "T1", 5.5), Dish(4, "T1", 6.0)]
    kw: dict[str, Any] = {"origin": "pass", "busy": [30.0]}
    assert suggest_carts(dishes, 1, d, now=10.0, rank="fifo", **kw) == [[1]]
    assert suggest_carts(dishes, 1, d, now=10.0, rank="wspt", **kw) == [[2, 3, 4]]
    assert suggest_carts(dishes, 1, d, now=10.0, **kw) == [[2, 3, 4]]
    assert suggest_carts(dishes, 1, d, now=10.0, starve=5.0, **kw) == [[1]]
    with pytest.raises(ValueError):
        suggest_carts(dishes, 1, d, now=10.0, rank="random", **kw)


def test_suggest_carts_holds_longer_when_tables_queue() -> None:
    """One robot, trays of 2 tables, three tables waiting: T1's next dish is 40 s away.

    With a fixed 10 s hold T1 rides now (and its last dish needs a second trip); with the
    hold growing to 60 s as tables queue, T1 waits for its dish and the robot takes the
    other two. After 60 s on the pass T1 goes anyway.
    """
    d = euclid(POS)
    dishes = [Dish(1, "T1", 0.0), Dish(2, "T2", 1.0), Dish(3, "T3", 2.0)]
    coming = [Dish(9, "T1", 45.0)]
    kw: dict[str, Any] = {"origin": "pass", "capacity": 2, "coming": coming, "rank": "fifo"}
    fixed = suggest_carts(dishes, 1, d, now=5.0, hold=10.0, hold_max=10.0, **kw)
    assert 1 in fixed[0]
    grown = suggest_carts(dishes, 1, d, now=5.0, hold=10.0, hold_max=60.0, **kw)
    assert grown == [[2, 3]]
    late = suggest_carts(dishes, 1, d, now=61.0, hold=10.0, hold_max=60.0, **kw)
    assert 1 in late[0]
    # Three robots for three tables: no queue, the base hold only, and T1 rides now.
    spare = suggest_carts(dishes, 3, d, now=5.0, hold=10.0, hold_max=60.0, **kw)
    assert [1] in spare
