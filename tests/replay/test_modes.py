"""The replay with guests' calls and bussing (issue 32): the calls' models, then a short
service in virtual time through ``serveur replay`` (four parties at four tables, two robots,
about twenty simulated minutes) whose report puts the dish waits with calls and bussing
beside those of the same service with deliveries alone, and in which every plates call was
answered by the bussing robot that reached the table.
"""

from __future__ import annotations

import asyncio
import json
import re
import shutil
from dataclasses import replace
from pathlib import Path
from typing import Any

import pytest

from serveur.cli import main
from serveur.maps.mapio import demo_map_path, demo_waypoints_path
from serveur.replay.model import (
    ReplayOptions,
    answer_delay,
    forgets_done,
    plates_dwell,
    unload_time,
)
from serveur.replay.orders import LogOrder, generate_orders, guest_calls, parse_orders, parties
from serveur.replay.service import run_replay
from serveur.scheduler import Dish

# Four parties: T2 (three dishes), T7 (two), T3 (two) and T6 (three).
LOG = """ready_at,table,dish
5.0,T2,Laksa
6.5,T2,Satay
8.0,T2,Kopi
20.0,T7,Teh tarik
21.5,T7,Mee goreng
90.0,T3,Laksa
95.0,T3,Rendang
200.0,T6,Kopi
205.0,T6,Satay
210.0,T6,Popiah
"""
# Every party calls for its plates 1-4 min after its last dish, a waiter and the bill.
CALLS = ["--calls-plates", "1", "--calls-waiter", "1", "--calls-bill", "1", "--eat", "1,4"]
ARGS = ["--robots", "2", "--seed", "1", "--away", "0", "--policy", "serveur", "--quiet"]


def test_each_party_calls_as_seeded() -> None:
    orders = generate_orders(["T1", "T2", "T3", "T4", "T5"], 2.0, 60.0, seed=4)
    numbered = [replace(o, line=i + 2) for i, o in enumerate(orders)]
    calls = guest_calls(numbered, seed=1)
    assert calls == guest_calls(numbered, seed=1)  # the same guests, call for call
    assert calls != guest_calls(numbered, seed=2)
    assert [c.lines for c in calls] == [tuple(o.line for o in p) for p in parties(numbered)]
    kinds = [k for c in calls for _, k in c.calls]
    n = len(calls)
    assert 0.6 * n <= kinds.count("plates") <= n and kinds.count("waiter") < kinds.count("bill")
    for c in calls:
        times = dict((k, t) for t, k in c.calls)
        assert [t for t, _ in c.calls] == sorted(t for t, _ in c.calls)
        if "plates" in times:  # the meal: 12-30 min after the last dish
            assert 720.0 <= times["plates"] <= 1800.0
            assert times.get("waiter", 0.0) <= times["plates"]
            if "bill" in times:  # 3-12 min after the meal
                assert 180.0 <= times["bill"] - times["plates"] <= 720.0
    # Off, kind by kind, leaving the other calls where they were.
    none = guest_calls(numbered, 1, plates=0.0, waiter=0.0, bill=0.0)
    assert all(c.calls == () for c in none)
    plates = guest_calls(numbered, 1, waiter=0.0, bill=0.0)
    assert [c.calls for c in plates] == [
        tuple(x for x in c.calls if x[1] == "plates") for c in calls
    ]
    # Each party once, keyed by its first dish, its plates counted.
    log = [LogOrder(5.0, "T2", "a", 2), LogOrder(6.0, "T2", "b", 3), LogOrder(9.0, "T3", "c", 4)]
    two = guest_calls(log, 0, plates=1.0, eat=(60.0, 60.0))
    assert [(c.table, c.line, c.plates, c.calls[0]) for c in two] == [
        ("T2", 2, 2, (60.0, "plates")),
        ("T3", 4, 1, (60.0, "plates")),
    ]


def test_staff_and_guests_take_a_while() -> None:
    answers = [answer_delay(0, f"T{i}:waiter:1") for i in range(400)]
    assert answers == [answer_delay(0, f"T{i}:waiter:1") for i in range(400)]
    assert all(15.0 <= a <= 600.0 for a in answers)
    assert 45.0 <= sorted(answers)[200] <= 65.0  # median: 15 s + 40 s
    assert sum(a > 120.0 for a in answers) >= 4  # a few past the server's call_escalate
    assert all(8.0 + 3.0 * 4 <= plates_dwell(0, n, 4) <= 90.0 for n in range(100))
    assert plates_dwell(0, 7, 6) > plates_dwell(0, 7, 1)
    share = sum(forgets_done(0, n, 0.15) for n in range(1000)) / 1000
    assert 0.1 <= share <= 0.2 and not any(forgets_done(0, n, 0.0) for n in range(100))
    exact = ReplayOptions(load_spread=0.0)
    assert unload_time(exact, 3, 1) == 30.0 and unload_time(exact, 3, 3) == 50.0
    assert unload_time(ReplayOptions(), 3, 2) != unload_time(ReplayOptions(), 4, 2)


def _row(summary: str, name: str) -> list[str]:
    [line] = [x for x in summary.splitlines() if x.startswith(name)]
    return re.split(r"\s{2,}", line[len(name) :].strip())


def test_a_service_with_calls_and_bussing_beside_deliveries_alone(tmp_path: Path) -> None:
    log = tmp_path / "orders.csv"
    log.write_text(LOG)
    out = tmp_path / "out"
    assert main(["replay", str(log), *ARGS, *CALLS, "--out", str(out)]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["options"]["calls"] is True
    pol = report["policies"]["serveur"]
    modes = pol["modes"]
    # 15-30 simulated minutes: the last party's bill comes 3-12 min after its meal.
    assert 15 * 60 <= pol["sim_seconds"] <= 30 * 60

    # The dish waits, with calls and bussing and with deliveries alone: the same ten dishes.
    waits = modes["dish_waits"]
    both, alone = waits["calls_and_bussing"], waits["deliveries_alone"]
    assert both["delivered"] == alone["delivered"] == 10
    assert both["undelivered"] == alone["undelivered"] == 0
    for k in ("mean", "p50", "p95", "max"):
        assert both[k] > 0 and alone[k] > 0, k
    assert both["mean"] == pol["summary"]["wait_mean"]
    assert alone["mean"] == pol["alone"]["summary"]["wait_mean"]
    assert sorted(o["line"] for o in pol["alone"]["orders"]) == list(range(2, 12))
    assert all(t["kind"] == "delivery" for t in pol["alone"]["trips"])  # no bussing there

    # Every party called for its plates, a waiter and the bill: twelve calls, all closed.
    calls = pol["calls"]
    assert sorted((c["table"], c["kind"]) for c in calls) == sorted(
        (t, k) for t in ("T2", "T7", "T3", "T6") for k in ("plates", "waiter", "bill")
    )
    assert all(c["answered"] is not None and c["cancelled"] is None for c in calls)
    # Every plates call was answered by the bussing robot sent for it, when it reached the
    # table: the trip's own stop says so (the stop's arrival against the call's answer).
    bussing = {b["id"]: b for b in pol["bussing"]}
    plates = [c for c in calls if c["kind"] == "plates"]
    for c in plates:
        assert c["by"].startswith("robot:"), c
        b = bussing[c["task"]]
        [stop] = [s for s in b["stops"] if s["table"] == c["table"]]
        assert stop["call"] == c["id"] and stop["status"] == "done"
        assert stop["arrived"] == pytest.approx(c["answered"], abs=0.01)
        assert stop["call_to_robot"] == pytest.approx(c["after"], abs=0.01)
        assert b["robot"] == c["by"].removeprefix("robot:") and b["status"] == "done"
        assert b["unloaded"] is not None and b["unloaded"] >= stop["done"]
    # Waiters and bills: staff, a while after the call.
    for c in calls:
        if c["kind"] != "plates":
            assert c["by"].startswith("token:") and c["after"] >= 15.0, c
    assert modes["dish_return"] == "dish return"

    # The figures per mode.
    assert modes["calls"]["plates"]["calls"] == modes["calls"]["plates"]["by_robot"] == 4
    for kind in ("waiter", "bill"):
        k = modes["calls"][kind]
        assert (k["calls"], k["by_staff"], k["by_robot"], k["open"]) == (4, 4, 0, 0)
        assert k["answer_p50"] <= k["answer_p90"] <= k["answer_max"]
    reach = sorted(c["after"] for c in plates)
    assert modes["bussing"]["trips"] == modes["bussing"]["done"] == 4
    assert modes["bussing"]["call_to_robot_p50"] == pytest.approx(reach[1], abs=0.01)
    assert modes["bussing"]["call_to_robot_max"] == pytest.approx(reach[-1], abs=0.01)
    players = pol["callers"]
    assert players["calls_made"] == 12 and players["answered_by_staff"] == 8
    assert players["unloaded"] == 4
    assert players["plates_done_pressed"] + players["plates_left_to_the_wait"] == 4
    # Trips are deliveries: the bussing trips are counted apart.
    s = pol["summary"]
    delivery = [t for t in pol["trips"] if t["kind"] == "delivery" and t["status"] == "done"]
    assert s["trips"] == len(delivery) == sum(r["trips"] for r in pol["robots"])
    assert sum(r["bussing"] for r in pol["robots"]) == 4

    # The summary: both dish-wait columns, the calls and the bussing trips.
    text = (out / "summary.txt").read_text()
    head = [x for x in text.splitlines() if "deliveries alone" in x and "calls+bussing" in x]
    assert head, text
    mean = _row(text, "dish wait mean")
    assert mean == [f"{round(both['mean'])} s", f"{round(alone['mean'])} s"]
    assert _row(text, "calls: plates / waiter / bill") == ["4 / 4 / 4", "-"]
    assert _row(text, "plates answered: robot / staff / open") == ["4 / 0 / 0", "-"]
    assert _row(text, "bussing trips: done / sent") == ["4 / 4", "-"]
    for name in ("time to answer waiter", "time to answer bill", "plates call -> robot"):
        assert any(x.startswith(name) for x in text.splitlines()), name


def test_guests_who_leave_done_to_the_bussing_wait(tmp_path: Path) -> None:
    """A party that never presses Done: the robot goes on after the server's bussing wait
    (120 s) with the plates, and staff empty it at the dish return."""
    opts = ReplayOptions(
        robots=1, seed=2, away=0.0, progress=False, calls=True, call_plates=1.0,
        call_waiter=0.0, call_bill=0.0, eat=(30.0, 30.0), forget_done=1.0,
    )  # fmt: skip
    r = run_replay(parse_orders(LOG.splitlines()[0] + "\n5.0,T2,Laksa\n"), opts, ["serveur"])
    result = r["serveur"]
    [b] = result.bussing
    [stop] = b["stops"]
    assert b["status"] == "done" and stop["status"] == "done"
    assert stop["done"] - stop["arrived"] == pytest.approx(120.0, abs=1.0)
    assert result.callers["plates_left_to_the_wait"] == 1
    assert result.callers["plates_done_pressed"] == 0 and result.callers["unloaded"] == 1
    assert result.alone is not None and result.alone.bussing == []


def test_a_map_without_a_dish_return_is_refused_unless_calls_are_off(tmp_path: Path) -> None:
    room = tmp_path / "room.yaml"
    shutil.copy(demo_map_path(), room)
    image = demo_map_path().with_name(
        next(
            line.split(":", 1)[1].strip()
            for line in demo_map_path().read_text().splitlines()
            if line.startswith("image:")
        )
    )
    shutil.copy(image, tmp_path / image.name)
    shutil.copy(demo_waypoints_path(), tmp_path / "room_waypoints.json")
    log = tmp_path / "orders.csv"
    log.write_text(LOG)
    out = tmp_path / "out"
    assert main(["replay", str(log), *ARGS, "--map", str(room), "--out", str(out)]) == 2
    assert not out.exists()


async def test_staff_on_the_floor_and_at_the_pass_with_bussing_trips() -> None:
    """What the console shows decides: waiter and bill calls are staff's, plates calls the
    robots' unless their bussing trip was cancelled (nobody is coming: staff go); a queued
    bussing trip neither takes a free robot from the pass's carts nor a table from them."""
    from serveur.replay.client import Console
    from serveur.replay.staff import Floor, Staff

    c = Console(None)
    jobs: list[Any] = []
    floor = Floor(c, ReplayOptions(), jobs.append)

    def call(cid: int, kind: str, task: int | None = None, **more: Any) -> dict[str, Any]:
        record = {"id": cid, "table": "T3", "kind": kind, "task_id": task, "answered_at": None,
                  "cancelled_at": None, **more}  # fmt: skip
        c.calls[cid] = record
        floor.on_call(record)
        return record

    call(1, "waiter")
    call(2, "bill")
    call(1, "waiter")  # seen again (an update): answered once
    call(3, "waiter", answered_at=5.0)  # already closed
    assert len(jobs) == 2
    call(4, "plates", task=10)
    assert len(jobs) == 2  # the robot's
    c.tasks[10] = {"id": 10, "kind": "bussing", "status": "cancelled", "stops": []}
    floor.trip_cancelled(10)
    assert len(jobs) == 3  # staff take those plates by hand
    c.tasks[11] = {"id": 11, "kind": "bussing", "status": "cancelled", "stops": []}
    call(5, "plates", task=11)  # its trip cancelled before the call showed it
    assert len(jobs) == 4
    for job in jobs:
        job.close()

    staff = Staff(c, [], ReplayOptions(), "serveur", asyncio.Event(), jobs.append)
    c.robots = {
        "r1": {"name": "r1", "status": "Awaiting", "current_task": None, "home": "home1"},
        "r2": {"name": "r2", "status": "Delivering", "current_task": 12, "home": "home2"},
    }
    stop = {"status": "pending", "orders": []}
    collect = [
        {**stop, "table": "T6", "purpose": "collect"},
        {**stop, "table": "dish return", "purpose": "unload"},
    ]
    c.tasks = {
        12: {"id": 12, "kind": "bussing", "status": "active", "robot": "r2", "stops": collect},
        13: {"id": 13, "kind": "bussing", "status": "queued", "robot": None,
             "stops": [{**collect[0], "table": "T8"}, collect[1]]},
    }  # fmt: skip
    assert staff.free_robots() == 1  # the queued bussing trip waits for the dishes
    assert "T6" in staff.tables_taken() and "T8" not in staff.tables_taken()
    staff.pending[1] = Dish(1, "T8", 0.0)
    await staff._join()  # no dish goes on a bussing trip (nothing is sent: no connection)
    assert staff.joined == 0 and 1 in staff.pending
