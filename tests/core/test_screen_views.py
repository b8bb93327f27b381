"""A screen bound to one robot or one table sees the update that takes a record out of its view.

The orders topic sends "one Order, whole, after any change". A robot screen shows the dishes on
its robot's trips; when a dish leaves the trip (skipped at its table: ``returned``; the trip
cancelled: back to ``pending``), the update saying so is about a dish no longer on the robot's
trip, and was filtered out: the screen kept the dish ``assigned`` for good (issue 26). Real
server, real simulated robot, screens logged in with their own tokens.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from serveur.core.runtime import CoreConfig
from serveur.security.auth import Principal, Role, ScreenView
from tests.conftest import Client, restaurant

R1 = Principal(Role.ROBOT_SCREEN, 3, robot="r1")
T1 = Principal(Role.TABLE_SCREEN, 5, table="T1")


class _Rec:
    def __init__(self, **kw: Any) -> None:
        self.__dict__.update(kw)


async def _screen(r: Any, **token: Any) -> Client:
    from websockets.asyncio.client import connect

    role = "robot-screen" if "robot" in token else "table-screen"
    headers = {"Authorization": f"Bearer {await r.app.issue_token(role, **token)}"}
    c = Client(await connect(r.app.url, additional_headers=headers))
    r.clients.append(c)
    return c


def test_a_robot_screen_sees_a_dish_leave_its_trip_once() -> None:
    trips = {10: "r1", 11: "r2"}
    view = ScreenView(R1, trips.get)
    snap = view.snapshot("orders", [_Rec(id=1, task_id=10), _Rec(id=2, task_id=11)])
    assert [x.id for x in snap] == [1]
    assert view("orders", _Rec(id=1, task_id=None))  # leaves the trip: told once
    assert not view("orders", _Rec(id=1, task_id=None))  # then nothing more of it
    assert not view("orders", _Rec(id=2, task_id=None))  # never shown: never told
    assert view("orders", _Rec(id=1, task_id=10))  # back on a trip of r1
    assert view("tasks", _Rec(id=10, robot="r1"))
    assert view("tasks", _Rec(id=10, robot="r2"))  # handed to another robot: told once
    assert not view("tasks", _Rec(id=10, robot="r2"))
    assert view("robots", _Rec(name="r1")) and not view("robots", _Rec(name="r2"))


def test_a_table_screen_sees_a_dish_or_trip_leave_its_table_once() -> None:
    view = ScreenView(T1, {}.get)
    assert view("orders", _Rec(id=5, table="T1"))
    assert view("orders", _Rec(id=5, table="T2"))  # moved to another table: told once
    assert not view("orders", _Rec(id=5, table="T2"))
    stop = _Rec(table="T1")
    snap = view.snapshot("tasks", [_Rec(id=7, stops=[stop]), _Rec(id=8, stops=[])])
    assert [x.id for x in snap] == [7]
    assert view("tasks", _Rec(id=7, stops=[_Rec(table="T2")]))  # its stop for T1 dropped
    assert not view("tasks", _Rec(id=8, stops=[_Rec(table="T2")]))  # never T1's
    assert view("menu", _Rec(dish="soup"))


def test_a_screens_memory_is_bounded() -> None:
    view = ScreenView(T1, {}.get, memory=3)
    for i in range(10):
        assert view("orders", _Rec(id=i, table="T1"))
    assert not view("orders", _Rec(id=0, table="T2"))  # forgotten: the oldest go first
    assert view("orders", _Rec(id=9, table="T2"))


async def test_a_robot_screen_sees_its_dishes_returned_and_put_back(tmp_path: Path) -> None:
    config = CoreConfig(heartbeat=2.0, ack_timeout=3.0)  # trips wait at the pass for Go
    async with restaurant(tmp_path, robots=1, config=config) as r:
        staff = await r.client()
        await staff.subscribe("robots", "orders", "tasks")
        await staff.status("r1", "Ready")
        screen = await _screen(r, robot="r1")
        await screen.subscribe("robots", "orders", "tasks")
        await staff.ok("control", robot="r1", action="auto")
        o1 = (await staff.ok("create", type="order", dish="soup", table="T1"))["order"]["id"]
        o2 = (await staff.ok("create", type="order", dish="cake", table="T2"))["order"]["id"]
        task = (await staff.ok("create", type="task", orders=[o1, o2]))["tasks"][0]["id"]
        await screen.until(
            lambda: {screen.order(o).get("status") for o in (o1, o2)} == {"assigned"},
            what="both dishes on r1's trip, on its screen",
        )
        await staff.status("r1", "Loading")
        await staff.ok("go", robot="r1", task=task, stop=0)
        await staff.status("r1", "Delivered")
        skipped = staff.task(task)["current_stop"]
        await staff.ok("skip", robot="r1", task=task, stop=skipped)
        gone = o1 if staff.task(task)["stops"][skipped]["table"] == "T1" else o2
        kept = o2 if gone == o1 else o1
        await screen.until(
            lambda: screen.order(gone).get("status") == "returned",
            what=f"the skipped dish {gone} returned on r1's screen (was {screen.order(gone)})",
        )
        assert screen.order(gone)["task_id"] is None
        await staff.status("r1", "Delivering")
        await staff.ok("stop", robot="r1")
        await staff.status("r1", "Stopped")
        await staff.ok("cancel", robot="r1")
        await screen.until(
            lambda: screen.order(kept).get("status") == "pending",
            what=f"the cancelled trip's dish {kept} back at the pass on r1's screen",
        )
        assert screen.order(kept)["task_id"] is None
        await screen.until(lambda: screen.task(task).get("status") == "cancelled")
        # A dish the screen was never shown is never sent to it.
        other = (await staff.ok("create", type="order", dish="tea", table="T3"))["order"]["id"]
        await staff.ok("dish", order=other, action="void")
        await staff.until(lambda: staff.order(other).get("status") == "voided")
        await staff.ok("ping")
        await screen.ok("ping")
        assert other not in screen.records.get("orders", {})


async def test_a_table_screen_sees_its_dish_moved_to_another_table(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1) as r:
        staff = await r.client()
        screen = await _screen(r, table="T1")
        await screen.subscribe("orders", "tasks")
        oid = (await staff.ok("create", type="order", dish="soup", table="T1"))["order"]["id"]
        await screen.until(lambda: screen.order(oid).get("table") == "T1")
        await staff.ok("dish", order=oid, action="edit", table="T2")
        await screen.until(
            lambda: screen.order(oid).get("table") == "T2",
            what="the dish moved to T2, on T1's screen (it showed it at T1 for good)",
        )
        await staff.ok("dish", order=oid, action="void")
        await staff.ok("ping")
        await screen.ok("ping")
        assert screen.order(oid)["status"] == "pending"  # not T1's any more: no later news
