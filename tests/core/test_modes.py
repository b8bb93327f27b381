"""What robots do besides delivering (issue 32), end to end on virtual time: a special
delivery waits for Done where an ordinary one times out; a cruise goes round, stops when its
screen is touched, goes on by itself, and is called back when a delivery has no robot; dishes
on the trays staff chose."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.conftest import Client, Restaurant, restaurant
from tests.core.test_service_day import site
from tests.test_e2e import activate, new_orders


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "alerts", "events")
    return c


async def robot_screen(r: Restaurant, robot: str) -> Client:
    return await r.screen("robot-screen", robot=robot)


def stop_of(c: Client, task_id: int) -> dict[str, Any]:
    task = c.task(task_id)
    return task["stops"][task["current_stop"]]


async def test_a_birthday_waits_for_done_where_a_dish_times_out(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site(table_timeout=20.0)) as r:
        c = await staff(r)
        await activate(c, "r1")
        plain = await new_orders(c, ("Satay", "T1"))
        cake = (
            await c.ok(
                "create", type="order", dish="Cake", table="T5", special="Happy birthday, Ana!"
            )
        )["order"]
        assert cake["special"] == "Happy birthday, Ana!"
        [task] = (await c.ok("create", type="task", orders=[*plain, cake["id"]]))["tasks"]
        await c.status("r1", "Loading")
        await c.ok("go", robot="r1", task=task["id"])
        # Nobody takes the satay: the table's timeout sends it back and the robot goes on.
        await c.until(lambda: c.order(plain[0]).get("status") == "returned", timeout=120)
        await c.until(lambda: stop_of(c, task["id"])["table"] == "T5")
        await c.until(lambda: stop_of(c, task["id"])["status"] == "arrived", timeout=60)
        arrived = stop_of(c, task["id"])["arrived_at"]
        await c.until(
            lambda: (
                c.robot("r1")["status"] == "Delivered" and c.robot("r1")["status_since"] >= arrived
            )
        )
        at_cake = c.robot("r1")["status_since"]
        # The robot's screen is shown the message with the dish it carries.
        screen = await robot_screen(r, "r1")
        shown = (await screen.ok("order", robot="r1"))["orders"]
        assert [o["special"] for o in shown] == ["Happy birthday, Ana!"]
        # Three table timeouts later it still waits for Done.
        await r.clock.sleep(70.0)
        assert c.robot("r1")["status"] == "Delivered"
        assert c.robot("r1")["status_since"] == at_cake
        assert c.order(cake["id"])["status"] == "assigned"
        await screen.ok("next", robot="r1", task=task["id"], stop=1)
        await c.until(lambda: c.order(cake["id"]).get("status") == "delivered")


async def test_a_cruise_goes_round_stops_when_touched_and_goes_on(tmp_path: Path) -> None:
    config = site(cruise_pause=5.0, cruise_resume=15.0)
    async with restaurant(tmp_path, robots=1, config=config) as r:
        c = await staff(r)
        await activate(c, "r1")
        await c.error("cruise", "not_found", robot="r1", route=["T1", "Bar"])
        await c.ok("cruise", robot="r1", route=["T1", "T5"])
        await c.until(lambda: c.robot("r1").get("current_task") is not None)
        task_id = c.robot("r1")["current_task"]
        assert c.task(task_id)["kind"] == "cruise"
        assert [s["purpose"] for s in c.task(task_id)["stops"]] == ["visit", "visit"]
        # A whole round, then it starts again from the first place by itself.
        await c.until(
            lambda: any(e["kind"] == "cruise.round" for e in c.records.get("events", {}).values()),
            timeout=180,
            what="a second round",
        )
        # Nobody pressed anything: each place's pause ran out, and the events say so.
        done = [e for e in c.records["events"].values() if e["kind"] == "stop.done"]
        assert done and all(e["data"].get("timed_out") is True for e in done)
        await c.until(lambda: c.robot("r1")["status"] == "Delivering", timeout=60)
        # Someone touches its screen: it stops, and goes on by itself after cruise_resume.
        screen = await robot_screen(r, "r1")
        await screen.ok("stop", robot="r1")
        await c.status("r1", "Stopped")
        stopped_at = r.clock.epoch()
        await c.status("r1", "Delivering", timeout=60)
        assert r.clock.epoch() - stopped_at >= 15.0
        # Dishes wait and the only robot is cruising: it is called back, home, then loads.
        ids = await new_orders(c, ("Laksa", "T3"))
        [trip] = (await c.ok("create", type="task", orders=ids))["tasks"]
        await c.until(lambda: c.task(task_id).get("status") == "cancelled", timeout=60)
        await c.until(lambda: c.task(trip["id"]).get("robot") == "r1", timeout=120)
        await c.status("r1", "Loading", timeout=60)


async def test_dishes_go_on_the_trays_staff_chose(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site(capacity=3)) as r:
        c = await staff(r)
        await activate(c, "r1")
        t1, t5, t5b, t9 = await new_orders(
            c, ("Satay", "T1"), ("Laksa", "T5"), ("Cendol", "T5"), ("Rendang", "T9")
        )
        # More tables than trays, or a tray the robots do not have: refused, nothing made.
        four = await new_orders(c, ("Teh", "T13"))
        await c.error(
            "create",
            "invalid_field",
            type="task",
            orders=[t1, t5, t9, *four],
            trays=[{"order": t1, "tray": 1}],
        )
        await c.error(
            "create", "invalid_field", type="task", orders=[t1], trays=[{"order": t1, "tray": 4}]
        )
        await c.error(
            "create", "invalid_field", type="task", orders=[t1], trays=[{"order": t5, "tray": 1}]
        )
        assert all(c.order(i)["status"] == "pending" for i in (t1, t5, t9))
        # Staff put the cendol on tray 3 and the satay on tray 1; the rest follows the plan.
        chosen = [{"order": t5b, "tray": 3}, {"order": t1, "tray": 1}]
        made = (await c.ok("create", type="task", orders=[t1, t5, t5b, t9], trays=chosen))["tasks"]
        assert len(made) == 1  # one trip, though the plan alone might have split it
        assert {s["table"] for s in made[0]["stops"]} == {"T1", "T5", "T9"}
        await c.until(lambda: c.order(t5b).get("tray") == 3)
        assert c.order(t1)["tray"] == 1 and c.order(t5)["tray"] is None
        screen = await robot_screen(r, "r1")
        await c.status("r1", "Loading")
        # The robot's screen is told the tray of each dish of its stop.
        on_board = {o["id"]: o["tray"] for o in (await screen.ok("order", robot="r1"))["orders"]}
        expected = {t1: 1, t5: None, t5b: 3, t9: None}
        assert on_board and on_board == {i: expected[i] for i in on_board}


async def test_a_cruising_robot_touched_at_its_place_waits_there(tmp_path: Path) -> None:
    config = site(cruise_pause=20.0, cruise_resume=60.0)
    async with restaurant(tmp_path, robots=1, config=config) as r:
        c = await staff(r)
        await activate(c, "r1")
        await c.ok("cruise", robot="r1", route=["T1", "T5"])
        await c.status("r1", "Delivered", timeout=120)  # paused at T1
        screen = await robot_screen(r, "r1")
        await screen.ok("stop", robot="r1")  # a guest takes a snack from its tray
        held = r.clock.epoch()
        await c.status("r1", "Stopped")
        # It does not leave at the end of its pause: it waits cruise_resume from the touch,
        # then pauses again before it goes on.
        await c.status("r1", "Delivered", timeout=120)
        assert r.clock.epoch() - held >= 60.0
        await c.status("r1", "Delivering", timeout=120)
        assert r.clock.epoch() - held >= 80.0
