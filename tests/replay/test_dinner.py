"""The replay's dinner service: loading at the pass, guests away, table timeouts, re-sends.

The models are pure and checked on their own; then one short service in virtual time where a
known party (T2) is away long enough for its table to time out: the robot must wait Loading at
the pass until the replay's staff press Go, skip T2 after the server's timeout, bring the
dishes back, and staff must send them again until the guests, back, collect them. The report's
counts come from the server's event log; the players' own counts must agree with them.
"""

from __future__ import annotations

import asyncio
import itertools
from dataclasses import replace

import pytest

from serveur.replay.model import (
    AWAY_FOR,
    ReplayOptions,
    absences,
    loading_time,
    service_events,
)
from serveur.replay.orders import LogOrder, generate_orders, parse_orders, parties
from serveur.replay.service import PolicyResult, run_replay

# Two parties: T2 (three dishes) and T7 (two), ten seconds apart.
LOG = """ready_at,table,dish
5.0,T2,Laksa
6.5,T2,Satay
8.0,T2,Kopi
20.0,T7,Teh tarik
21.5,T7,Mee goreng
"""
#: With seed 1 and half the parties away, T2's party is away for 543 s from its first dish;
#: T7's is at its table (test_the_away_party_is_known checks it).
SEED, AWAY = 1, 0.5


def test_loading_time_is_a_fixed_part_and_a_part_per_plate_with_a_seeded_spread() -> None:
    exact = ReplayOptions(load_fixed=10.0, load_per_dish=4.0, load_spread=0.0)
    assert loading_time(exact, 7, 1) == 14.0 and loading_time(exact, 7, 5) == 30.0
    assert loading_time(replace(exact, load_fixed=0.0, load_per_dish=0.0), 7, 5) == 0.0
    spread = ReplayOptions(seed=3)
    assert loading_time(spread, 7, 3) == loading_time(spread, 7, 3)  # seeded
    draws = [loading_time(spread, k, 3) for k in range(400)]
    assert len(set(draws)) > 100  # spread
    assert all(0.5 * 22.0 <= d <= 3.0 * 22.0 for d in draws)  # bounded
    assert 20.0 <= sorted(draws)[200] <= 24.0  # median: the fixed part + 3 plates
    assert draws != [loading_time(replace(spread, seed=4), k, 3) for k in range(400)]
    # More plates take longer, key for key.
    assert all(loading_time(spread, k, 6) > loading_time(spread, k, 2) for k in range(50))


def test_parties_are_a_tables_dishes_that_come_out_together() -> None:
    orders = [
        LogOrder(5.0, "T1", "a", 2),
        LogOrder(9.0, "T2", "b", 3),
        LogOrder(30.0, "T1", "c", 4),
        LogOrder(3000.0, "T1", "d", 5),  # the table's next party, 50 min on
    ]
    assert [[o.line for o in p] for p in parties(orders)] == [[2, 4], [3], [5]]
    # A generated service with tables to spare: each party is one of the generator's (its
    # dishes within 40 s). Busier, parties squeezed in at a taken table read as one with it.
    log = generate_orders([f"T{i}" for i in range(1, 17)], 2.0, 60.0, seed=5)
    found = parties(log)
    assert len(found) > 20 and all(p[-1].ready_at - p[0].ready_at <= 40.0 for p in found)
    for p in found:
        assert {o.table for o in p} == {p[0].table}
        assert all(b.ready_at - a.ready_at <= 600.0 for a, b in itertools.pairwise(p))


def test_absences_are_seeded_per_party_at_the_given_rate() -> None:
    log = generate_orders([f"T{i}" for i in range(1, 17)], 4.0, 300.0, seed=2)
    for i, o in enumerate(log):
        log[i] = replace(o, line=i + 2)
    n = len(parties(log))
    away = absences(log, 0, 0.1)
    assert away == absences(log, 0, 0.1)
    assert away != absences(log, 1, 0.1)
    assert 0.05 * n <= len(away) <= 0.15 * n
    assert not absences(log, 0, 0.0) and len(absences(log, 0, 1.0)) == n
    firsts = {(p[0].table, p[0].ready_at) for p in parties(log)}
    for a in away:  # away from the party's first dish, for 3-12 minutes
        assert (a.table, a.start) in firsts
        assert AWAY_FOR[0] <= a.end - a.start <= AWAY_FOR[1]
    # A higher rate keeps the same parties away and adds some (one draw per party).
    assert {a.line for a in away} <= {a.line for a in absences(log, 0, 0.3)}


def test_the_away_party_is_known() -> None:
    [away] = absences(parse_orders(LOG), SEED, AWAY)
    assert away.table == "T2" and away.start == 5.0 and round(away.end - away.start) == 543


def test_service_events_read_the_event_log() -> None:
    def ev(ts: float, kind: str, **kw: object) -> dict[str, object]:
        return {"ts": ts, "kind": kind, "robot": kw.pop("robot", None), **kw}

    events = [
        ev(0.0, "robot.status", robot="r1", data={"status": "Awaiting"}),
        ev(10.0, "robot.status", robot="r1", data={"status": "Loading"}),
        ev(25.0, "robot.status", robot="r1", data={"status": "Delivering"}),
        ev(30.0, "robot.status", robot="r2", data={"status": "Loading"}),
        ev(50.0, "stop.skipped", robot="r1", data={"orders": [4, 5], "by": None}),
        ev(60.0, "stop.skipped", robot="r1", data={"orders": [6], "by": "user:ana"}),
        ev(90.0, "order.ready", order_id=4, data={"from": "returned"}),
        ev(91.0, "order.ready", order_id=7, data={"from": "cooking"}),
        ev(95.0, "robot.status", robot="r1", data={"status": "Loading"}),
        ev(99.0, "robot.status", robot="r1", data={"status": "Manual"}),
    ]
    got = service_events(events, end=40.0 + 60.0)
    assert got.loading == {"r1": 15.0 + 4.0, "r2": 70.0}  # r2 still loading at the end
    assert got.timeouts == 1 and got.skips == 1
    assert got.returned == {4: 1, 5: 1, 6: 1} and got.resent == {4: 1}


@pytest.fixture(scope="module")
def away_service() -> PolicyResult:
    opts = ReplayOptions(robots=2, seed=SEED, away=AWAY, progress=False)
    return run_replay(parse_orders(LOG), opts, ["serveur"])["serveur"]


@pytest.mark.slow
def test_a_party_away_times_out_its_dishes_come_back_and_are_sent_again(
    away_service: PolicyResult,
) -> None:
    r = away_service
    s = r.stats()
    # Every dish reached its guests in the end: T2's after they came back.
    assert s["orders"] == s["delivered"] == 5 and s["undelivered"] == 0
    t2 = [o for o in r.orders if o["table"] == "T2"]
    t7 = [o for o in r.orders if o["table"] == "T7"]
    assert all(o["status"] == "delivered" for o in r.orders)
    # T2's table timed out at least once: its dishes were returned, then sent again.
    assert s["table_timeouts"] >= 1 and s["staff_skips"] == 0
    assert all(o["returned"] >= 1 and o["resent"] == o["returned"] for o in t2)
    assert all(o["returned"] == o["resent"] == 0 for o in t7)
    assert s["returned"] == s["resent"] == sum(o["returned"] for o in r.orders) >= 3
    assert s["resent_delivered"] == 3
    # They were collected once the party was back, and their wait counts from the first
    # time they were ready (not from the re-send).
    back = 5.0 + 543.0
    for o in t2:
        assert o["collected"] >= back
        assert o["created"] == pytest.approx(o["ready_at"], abs=0.5)
        assert o["wait"] == pytest.approx(o["collected"] - o["created"], abs=1e-6)
        assert o["wait"] >= back - o["ready_at"]
    assert all(o["collected"] < back for o in t7)  # the party at its table: the first time
    # The robot waited the server's 180 s at T2 before going on: at least that long out.
    assert any(b - a >= 180.0 for rb in r.robots for a, b in rb["busy_spans"])


@pytest.mark.slow
def test_robots_wait_loading_at_the_pass_and_the_counts_match_the_event_log(
    away_service: PolicyResult,
) -> None:
    r = away_service
    s = r.stats()
    p = r.players
    started = [t for t in r.trips if t["started"] is not None]
    # Each trip waited at the pass until staff pressed Go, for the modelled loading time.
    assert p["go_pressed"] == len(started) >= 3
    assert s["loading_s"] > 0 and s["loading_s"] == pytest.approx(p["loading_s"], abs=0.1)
    assert sum(rb["loading"] for rb in r.robots) == pytest.approx(s["loading_s"])
    assert all(rb["loading"] > 0 for rb in r.robots if rb["trips"])
    # The event log's timeouts are the stops the guests were too late for, its re-sent
    # dishes those staff sent again, its returned dishes those of the timed-out stops.
    assert p["guests_missed"] == s["table_timeouts"]
    assert p["resent"] == s["resent"]
    assert p["parties_away"] == 1


async def test_staff_expect_a_loading_robot_back_after_its_loading_and_trip() -> None:
    from serveur.replay.client import Console
    from serveur.replay.staff import Staff

    class Clock:
        def now(self) -> float:
            return 100.0

    c = Console(Clock())
    c.distance = lambda a, b: 7.0
    c.tasks[5] = {"id": 5, "robot": "r1", "stops": [{"table": "T2", "orders": [1, 2, 3]}]}
    jobs: list[object] = []
    staff = Staff(c, [], ReplayOptions(), "serveur", asyncio.Event(), jobs.append)
    robot = {"name": "r1", "status": "Loading", "current_task": 5, "home": "home1"}
    c.robots["r1"] = robot
    staff.robot_left("r1", robot)
    # Loading: the model's mean for three plates (22 s) before the trip's own estimate.
    eta = staff.eta["r1"]
    assert eta > 100.0 + 22.0
    staff.robot_loading("r1", robot)  # staff go and load it: still expected back at eta
    assert staff.eta == {"r1": eta} and len(jobs) == 1
    for job in jobs:
        job.close()  # type: ignore[attr-defined]
    staff.robot_home("r1")
    assert staff.eta == {}


# T3's second plate comes out while the first is still being loaded (10 s + 4 s a plate).
JOIN_LOG = """ready_at,table,dish
5.0,T3,Laksa
12.0,T3,Satay
"""


@pytest.mark.slow
@pytest.mark.parametrize("join", [True, False])
def test_a_plate_out_while_its_tables_robot_loads_rides_with_it(join: bool) -> None:
    """With ``join`` the staff put T3's second plate on the robot still loading for T3: one
    trip, both plates collected together. Without it the plate waits for that robot to
    leave T3 (a second robot may not stand there), then rides a trip of its own."""
    opts = ReplayOptions(robots=2, seed=SEED, away=0.0, load_spread=0.0, join=join, progress=False)
    r = run_replay(parse_orders(JOIN_LOG), opts, ["serveur"])["serveur"]
    s = r.stats()
    assert s["delivered"] == 2
    trips = [t for t in r.trips if t["status"] == "done"]
    first, second = sorted(r.orders, key=lambda o: o["ready_at"])
    if join:
        assert s["joined"] == r.players["joined"] == 1 and len(trips) == 1
        assert first["task"] == second["task"]
        # Loading counted the added plate too: 10 s + 4 s x 2.
        assert r.players["loading_s"] == pytest.approx(18.0)
        assert second["collected"] == pytest.approx(first["collected"], abs=0.5)
    else:
        assert s["joined"] == r.players["joined"] == 0 and len(trips) == 2
        assert second["collected"] > first["collected"] + 20.0
