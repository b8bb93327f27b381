"""A dinner service as staff run it (issue 18), against a real server and the simulator:
trips loaded at the pass then sent with Go, a table skipped or timed out with its dishes
returned, a table no robot can reach blocked until cleared, the dish's whole life, alerts
raised, acknowledged and cleared."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur.core.engine import CoreConfig
from tests.conftest import Client, Restaurant, restaurant
from tests.test_e2e import activate, new_orders

#: A site as shipped (robots wait at the pass for Go), with short service limits so that a
#: timeout or an alert happens within a test (simulated seconds; the sim runs 10x).
SITE = dict(heartbeat=2.0, ack_timeout=3.0, auto_depart=False)


def site(**limits: Any) -> CoreConfig:
    return CoreConfig(**{**SITE, **limits})


@pytest.fixture
async def pass_site(tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        yield r


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "alerts", "blocks", "menu")
    return c


async def owner_of(r: Restaurant) -> Client:
    owner = Client(await connect(r.app.url))
    r.clients.append(owner)
    await owner.ok("login", username="owner", password=r.app.first_owner_password)
    return owner


async def loaded_trip(c: Client, *items: tuple[str, str]) -> dict[str, Any]:
    """A cart given to r1, loaded at the pass (Loading), not yet sent."""
    await activate(c, "r1")
    ids = await new_orders(c, *items)
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    await c.status("r1", "Loading")
    await c.until(lambda: c.task(task["id"]).get("status") == "active")
    return c.task(task["id"])


async def test_a_trip_waits_at_the_pass_until_staff_press_go(pass_site: Restaurant) -> None:
    c = await staff(pass_site)
    task = await loaded_trip(c, ("Laksa", "T1"), ("Satay", "T12"))
    assert c.robot("r1")["current_task"] == task["id"]
    # Stops are in visiting order: tray 1 for the first table, tray 2 for the second.
    assert [s["seq"] for s in task["stops"]] == [0, 1]
    # The robot stays at the pass while staff load it: no goal was sent.
    await pass_site.clock.sleep(3.0)
    assert c.robot("r1")["status"] == "Loading"
    assert not pass_site.sim.robots[0].goal_statuses
    # A Go for a trip the screen did not show is stale; a Go without a trip is not allowed.
    err = await c.error("go", "stale", robot="r1", task=task["id"] + 1)
    assert err["details"]["task"] == task["id"] and err["details"]["status"] == "Loading"
    await c.ok("go", robot="r1", task=task["id"])
    await c.status("r1", "Delivering")
    await c.error("go", "not_allowed_in_status", robot="r1", task=task["id"])


async def test_a_plate_ready_while_loading_rides_with_its_table_until_go(
    pass_site: Restaurant,
) -> None:
    """The next plate for T1 goes on r1 while it loads, to T1's tray; a Go pressed at the same
    moment waits for it. Once r1 has left, the trip is stale and the plate stays pending."""
    c = await staff(pass_site)
    task = await loaded_trip(c, ("Laksa", "T1"), ("Satay", "T12"))
    (more, other) = await new_orders(c, ("Teh tarik", "T1"), ("Roti", "T5"))
    err = await c.error("create", "invalid_field", type="task", task=task["id"], orders=[other])
    assert err["details"] == {"field": "orders", "orders": [other], "tables": ["T1", "T12"]}
    # The join and a Go sent together: the join lands first (under r1's lock), then Go.
    join, go = await asyncio.gather(
        c.ok("create", type="task", task=task["id"], orders=[more]),
        c.ok("go", robot="r1", task=task["id"]),
    )
    [joined] = join["tasks"]
    assert go["robot"]["status"] == "Delivering"
    t1 = next(s for s in joined["stops"] if s["table"] == "T1")
    assert more in t1["orders"] and len(t1["orders"]) == 2
    await c.until(lambda: c.order(more).get("status") == "assigned")
    # Gone: the trip is stale, nothing changes.
    err = await c.error("create", "stale", type="task", task=task["id"], orders=[other])
    assert err["details"] == {"task": task["id"], "robot": "r1", "status": "Delivering"}
    assert c.order(other)["status"] == "pending"


async def test_cancel_while_loading_keeps_the_robot_at_the_pass(pass_site: Restaurant) -> None:
    c = await staff(pass_site)
    task = await loaded_trip(c, ("Laksa", "T1"))
    await c.ok("cancel", robot="r1", task=task["id"])
    await c.status("r1", "Awaiting")
    order = task["stops"][0]["orders"][0]
    await c.until(lambda: c.order(order).get("status") == "pending")


async def test_a_skipped_table_returns_its_dishes_and_the_robot_goes_on(
    pass_site: Restaurant,
) -> None:
    c = await staff(pass_site)
    task = await loaded_trip(c, ("Laksa", "T1"), ("Satay", "T12"))
    await c.ok("go", robot="r1", task=task["id"])
    await c.status("r1", "Delivered")
    first, second = task["stops"]
    # Skip needs the stop the screen saw; a skip of another stop is stale and changes nothing.
    await c.error("skip", "stale", robot="r1", task=task["id"], stop=1)
    await c.ok("skip", robot="r1", task=task["id"], stop=0)
    await c.status("r1", "Delivering")
    await c.until(lambda: c.task(task["id"])["stops"][0]["status"] == "skipped")
    [returned] = first["orders"]
    await c.until(lambda: c.order(returned).get("status") == "returned")
    assert c.order(returned)["task_id"] is None and c.order(returned)["returned_at"]
    assert c.order(returned)["delivered_at"] is None  # never counted as delivered
    # The stop already left cannot be skipped again (a duplicate press).
    await c.error("skip", "stale", robot="r1", task=task["id"], stop=0)
    await c.status("r1", "Delivered")
    await c.ok("next", robot="r1", task=task["id"], stop=1)
    await c.status("r1", "Transit")
    assert c.order(second["orders"][0])["status"] == "delivered"
    # Back at the pass, staff send the returned dish again (or void it).
    sent = (await c.ok("dish", order=returned, action="ready", status="returned"))["order"]
    assert sent["status"] == "pending"
    await c.error("dish", "conflict", order=second["orders"][0], action="void")  # delivered


async def test_nobody_collects_the_food_so_the_robot_goes_on(tmp_path: Path) -> None:
    cfg = site(table_timeout=20.0, alert_wait_at_table=8.0)
    async with restaurant(tmp_path, robots=1, config=cfg) as r:
        c = await staff(r)
        task = await loaded_trip(c, ("Laksa", "T1"), ("Satay", "T12"))
        await c.ok("go", robot="r1", task=task["id"])
        await c.status("r1", "Delivered")

        def waiting() -> list[dict[str, Any]]:
            return [
                a
                for a in c.records.get("alerts", {}).values()
                if a["kind"] == "waiting_at_table" and a["subject"] == "r1"
            ]

        # First the alert that the robot has waited long, then the timeout: on to T12.
        await c.until(lambda: waiting(), what="waiting alert")
        assert waiting()[0]["cleared_at"] is None and "T1" in waiting()[0]["message"]
        await c.until(lambda: c.task(task["id"])["stops"][0]["status"] == "skipped")
        await c.until(lambda: c.robot("r1")["status"] in ("Delivering", "Delivered"))
        [returned] = task["stops"][0]["orders"]
        await c.until(lambda: c.order(returned).get("status") == "returned")
        # The robot left the table: the alert is cleared by itself.
        await c.until(lambda: waiting()[0]["cleared_at"] is not None, what="alert cleared")


async def test_a_table_no_robot_reaches_is_blocked_until_staff_clear_it(
    pass_site: Restaurant,
) -> None:
    c = await staff(pass_site)
    task = await loaded_trip(c, ("Laksa", "T12"))
    # Another cart for T12 is queued behind it (nobody knows yet that T12 cannot be reached).
    [queued] = (await c.ok("create", type="task", orders=await new_orders(c, ("Tea", "T12"))))[
        "tasks"
    ]
    pass_site.sim.robots[0].block_path(True)
    await c.ok("go", robot="r1", task=task["id"])
    await c.status("r1", "Error")
    await c.until(lambda: "T12" in c.records.get("blocks", {}), what="T12 blocked")
    assert "r1" in c.records["blocks"]["T12"]["reason"]
    # Both alerts are up: the robot is stuck, the table cannot be reached.
    alerts = lambda: {(a["kind"], a["subject"]): a for a in c.records.get("alerts", {}).values()}  # noqa: E731
    await c.until(lambda: ("table_unreachable", "T12") in alerts(), what="table alert")
    await c.until(lambda: ("robot_error", "r1") in alerts(), what="robot alert")
    # No second robot is sent there: a new cart with T12 is refused with the reason.
    more = await new_orders(c, ("Satay", "T12"))
    err = await c.error("create", "unreachable", type="task", orders=more)
    assert err["details"]["table"] == "T12"
    # Staff take the dish back: skip from Error returns it, the robot goes home.
    pass_site.sim.robots[0].block_path(False)
    await c.ok("skip", robot="r1", task=task["id"], stop=0)
    await c.status("r1", "Transit")
    await c.status("r1", "Awaiting")
    # The robot is free, but the queued trip to T12 is not given to it: its only table is
    # blocked, so it is cancelled and its dish waits at the pass.
    await c.until(lambda: c.task(queued["id"]).get("status") == "cancelled", what="dropped")
    [tea] = queued["stops"][0]["orders"]
    await c.until(lambda: c.order(tea).get("status") == "pending")
    assert c.robot("r1")["status"] == "Awaiting"
    # The alert of the stuck robot cleared when it moved on; acknowledging the table's.
    await c.until(lambda: alerts()[("robot_error", "r1")]["cleared_at"] is not None)
    table_alert = alerts()[("table_unreachable", "T12")]
    acked = (await c.ok("ack", alert=table_alert["id"]))["alert"]
    assert acked["acked_by"].startswith("token:") and acked["acked_at"]
    await c.error("ack", "conflict", alert=table_alert["id"])  # twice
    # Cleared: robots may go there again, and the alert ends.
    assert (await c.ok("clear", table="T12"))["cleared"] is True
    await c.until(lambda: alerts()[("table_unreachable", "T12")]["cleared_at"] is not None)
    await c.ok("create", type="task", orders=[tea, *more])
    await c.status("r1", "Loading")
    await c.error("ack", "not_found", alert=table_alert["id"])  # over


async def test_a_dish_from_order_to_pass_with_quantity_note_edit_and_void(
    pass_site: Restaurant,
) -> None:
    c = await staff(pass_site)
    made = await c.ok(
        "create",
        type="order",
        dish="Laksa",
        table="T1",
        quantity=2,
        note="no chilli",
        status="ordered",
    )
    o = made["order"]
    assert (o["status"], o["quantity"], o["note"], o["ready_at"]) == (
        "ordered",
        2,
        "no chilli",
        None,
    )
    # Not ready yet: it cannot go on a trip.
    await c.error("create", "conflict", type="task", orders=[o["id"]])
    o = (await c.ok("dish", order=o["id"], action="cooking", status="ordered"))["order"]
    assert o["status"] == "cooking"
    # A screen that still shows it as ordered is behind: stale, and nothing changes.
    await c.error("dish", "stale", order=o["id"], action="cooking", status="ordered")
    o = (await c.ok("dish", order=o["id"], action="edit", quantity=3, note="", table="T2"))["order"]
    assert (o["quantity"], o["note"], o["table"], o["status"]) == (3, None, "T2", "cooking")
    o = (await c.ok("dish", order=o["id"], action="ready"))["order"]
    assert o["status"] == "pending" and o["ready_at"] is not None
    await c.error("dish", "conflict", order=o["id"], action="cooking")  # ready already
    o = (await c.ok("dish", order=o["id"], action="void"))["order"]
    assert o["status"] == "voided" and o["voided_at"] is not None
    await c.error("dish", "conflict", order=o["id"], action="void")
    await c.error("dish", "invalid_field", order=o["id"], action="edit", quantity=0)
    await c.error("dish", "not_found", order=o["id"] + 99, action="void")
    # Each step is recorded with who took it.
    rows = await pass_site.app.store.events.list_events(limit=10_000)
    steps = [(e.kind, e.data.get("by")) for e in rows if e.order_id == o["id"]]
    assert [k for k, _ in steps] == [
        "order.created",
        "order.cooking",
        "order.edited",
        "order.ready",
        "order.voided",
    ]
    assert all(by and by.startswith("token:") for k, by in steps[1:])


async def test_the_menu_is_in_the_database_and_the_owner_edits_it(pass_site: Restaurant) -> None:
    c = await staff(pass_site)
    menu = c.records["menu"]
    assert "Laksa" in menu and menu["Teh tarik"]["category"] == "Drinks"
    await c.error("create", "forbidden", type="dish", name="Mee goreng")  # staff may not
    owner = await owner_of(pass_site)
    dish = (
        await owner.ok(
            "create", type="dish", name="Mee goreng", category="Mains", price_cents=850, position=9
        )
    )["dish"]
    assert dish == {
        "dish": "Mee goreng",
        "category": "Mains",
        "price_cents": 850,
        "available": True,
        "position": 9,
    }
    await c.until(lambda: "Mee goreng" in c.records["menu"], what="menu pushed")
    await owner.ok("create", type="dish", name="Cendol", category="Desserts", available=False)
    await c.until(lambda: c.records["menu"]["Cendol"]["available"] is False)


async def test_a_trip_goes_to_a_robot_with_a_tray_for_each_of_its_tables(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=2, config=site()) as r:
        c = await staff(r)
        # r1 has one tray (registered again with trays=1); r2 the site's four.
        spec = r.specs[0]
        owner = await owner_of(r)
        again = await owner.ok(
            "create", type="robot", name=spec.name, url=spec.url, home=spec.home, trays=1
        )
        assert again["robot"]["trays"] == 1
        await activate(c, "r1")
        await activate(c, "r2")
        ids = await new_orders(c, ("Laksa", "T1"), ("Satay", "T12"))
        [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
        await c.status("r2", "Loading")
        assert c.robot("r2")["current_task"] == task["id"]
        assert c.robot("r1")["status"] == "Awaiting"  # waited longer, but has one tray


async def test_dish_edge_cases_answer_as_a_client_expects(pass_site: Restaurant) -> None:
    c = await staff(pass_site)
    o = (await c.ok("create", type="order", dish="Laksa", table="T1", key="k1"))["order"]
    # The same key for another kind of dish is a different request: refused, not merged.
    await c.error(
        "create", "conflict", type="order", dish="Laksa", table="T1", key="k1", status="ordered"
    )
    again = (await c.ok("create", type="order", dish="Laksa", table="T1", key="k1"))["order"]
    assert again["id"] == o["id"]
    # An edit that asks for what is already so is done (nothing to change), not an error.
    same = (await c.ok("dish", order=o["id"], action="edit", table="T1"))["order"]
    assert same == o
    await c.error("dish", "invalid_field", order=o["id"], action="edit")
    # Only edit takes quantity, note or table.
    err = await c.error("dish", "invalid_field", order=o["id"], action="void", table="T2")
    assert err["details"]["field"] == "action"
    assert (await c.ok("dish", order=o["id"], action="void"))["order"]["table"] == "T1"
