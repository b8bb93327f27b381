"""Commands name the trip and stop they act on; one aimed at a stop the robot has left is
refused with ``stale`` and changes nothing (issue 18: a stalled tablet's "Food collected",
carried out late, released the robot at the wrong table)."""

from __future__ import annotations

import json
from typing import Any

from websockets.asyncio.client import connect

from tests.conftest import Client, Restaurant
from tests.test_e2e import activate, new_orders, staff


async def two_stop_trip(c: Client) -> dict[str, Any]:
    await activate(c, "r1")
    ids = await new_orders(c, ("Pho", "T1"), ("Satay", "T12"))
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    await c.status("r1", "Delivered")
    return c.task(task["id"])


async def test_a_second_food_collected_for_the_same_stop_is_stale(one_robot: Restaurant) -> None:
    tablet, phone = await staff(one_robot), await staff(one_robot)
    task = await two_stop_trip(tablet)
    await phone.until(lambda: phone.robot("r1").get("status") == "Delivered")
    seen = {"task": task["id"], "stop": 0}
    await tablet.ok("next", robot="r1", **seen)  # the robot leaves for the second table
    await tablet.status("r1", "Delivering")
    # The phone, a moment behind, presses "Food collected" for the stop it still shows.
    err = await phone.error("next", "stale", robot="r1", **seen)
    assert err["details"] == {"robot": "r1", "task": task["id"], "stop": 1, "status": "Delivering"}
    # Nothing changed: the second table's dishes are still aboard, the robot still on its way.
    await tablet.until(lambda: tablet.task(task["id"])["current_stop"] == 1)
    second = tablet.task(task["id"])["stops"][1]
    assert second["status"] == "pending"
    assert all(tablet.order(o)["status"] == "assigned" for o in second["orders"])
    await tablet.status("r1", "Delivered")
    await tablet.ok("next", robot="r1", task=task["id"], stop=1)
    await tablet.status("r1", "Transit")


async def test_stop_and_cancel_for_a_trip_the_robot_no_longer_has_are_stale(
    one_robot: Restaurant,
) -> None:
    c = await staff(one_robot)
    task = await two_stop_trip(c)
    # A screen that saw the robot idle (no trip) sends stop: the robot is on a trip now.
    err = await c.error("stop", "stale", robot="r1", task=None)
    assert err["details"]["task"] == task["id"]
    err = await c.error("cancel", "stale", robot="r1", task=task["id"] + 1)
    assert err["details"]["task"] == task["id"]
    assert c.robot("r1")["status"] == "Delivered"  # untouched
    await c.ok("next", robot="r1", task=task["id"], stop=0)
    await c.status("r1", "Delivering")
    await c.ok("stop", robot="r1", task=task["id"])
    await c.status("r1", "Stopped")
    await c.error("cancel", "stale", robot="r1", task=task["id"], stop=0)
    await c.ok("cancel", robot="r1", task=task["id"], stop=1)
    await c.status("r1", "Transit")


async def test_commands_without_a_target_work_as_before(one_robot: Restaurant) -> None:
    c = await staff(one_robot)
    await two_stop_trip(c)
    await c.ok("next", robot="r1")  # scripts that do not name the stop are not refused
    await c.status("r1", "Delivering")


async def test_ping_answers_with_the_servers_time_and_needs_a_login(one_robot: Restaurant) -> None:
    # The pages' heartbeat: any logged-in connection may ping; the reply proves the link alive.
    c = await staff(one_robot)
    reply = await c.ok("ping")
    assert abs(reply["time"] - one_robot.clock.epoch()) < 5.0 * one_robot.clock.time_scale
    async with connect(one_robot.app.url) as ws:
        await ws.send('{"clientmsg":"ping","id":1}')
        refused = json.loads(await ws.recv())
    assert (refused["id"], refused["code"]) == (1, "unauthorized")
