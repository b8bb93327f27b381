"""Charging (issue 32): a free robot below the site's level goes to its dock by itself, charges
(the simulator charges a robot standing on its charger), comes back into service when charged;
staff send one to charge and take it off; a robot on a dock that does not charge raises an
alert. Real server, real simulator, virtual time."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.conftest import Client, Restaurant, restaurant
from tests.core.test_service_day import owner_of, site
from tests.test_e2e import activate


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "alerts", "events")
    return c


async def with_dock(r: Restaurant, c: Client, robot: str = "r1") -> None:
    """A dock where the robot's charger is: the simulator's charger is at its home."""
    home = r.app.core.places.waypoint(r.specs[0].home or "")  # type: ignore[union-attr]
    await c.ok(
        "create", type="waypoint", name="dock1", x=home.x, y=home.y, yaw=home.yaw, kind="dock"
    )
    owner = await owner_of(r)
    await owner.error("site", "invalid_field", action="edit_robot", robot=robot, dock="T1")
    await owner.ok("site", action="edit_robot", robot=robot, dock="dock1")


async def test_a_low_robot_charges_by_itself_and_comes_back(tmp_path: Path) -> None:
    config = site(charge_below=0.4, charge_until=0.45)
    async with restaurant(tmp_path, robots=1, config=config) as r:
        c = await staff(r)
        await with_dock(r, c)
        r.sim.robots[0].battery = 0.3
        await activate(c, "r1")
        await c.status("r1", "Charging", timeout=120)
        assert c.robot("r1")["dock"] == "dock1"
        # No trip for a charging robot: staff see it charging, the battery rising.
        await c.until(lambda: (c.robot("r1").get("battery") or 0) > 0.31, timeout=600)
        await c.status("r1", "Awaiting", timeout=1200)
        assert (c.robot("r1")["battery"] or 0) >= 0.45
        kinds = [e["data"].get("status") for e in c.records["events"].values()]
        assert kinds.count("Charging") == 1


async def test_staff_send_a_robot_to_charge_and_back_to_work(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        await activate(c, "r1")
        # No dock yet: said plainly, nothing changes.
        refused = await c.error("charge", "conflict", robot="r1")
        assert refused["details"]["reason"] == "no_dock"
        assert c.robot("r1")["status"] == "Awaiting"
        await with_dock(r, c)
        going = (await c.ok("charge", robot="r1"))["robot"]
        # On its way the screens can tell it is going to charge, not home.
        assert (going["status"], going["to_dock"]) == ("Transit", True)
        await c.status("r1", "Charging", timeout=120)
        assert c.robot("r1")["to_dock"] is False
        await c.error("go", "not_allowed_in_status", robot="r1")
        await c.error("cruise", "not_allowed_in_status", robot="r1", route=["T1"])
        await c.ok("work", robot="r1")
        await c.status("r1", "Awaiting", timeout=120)
        await c.error("work", "not_allowed_in_status", robot="r1")


async def test_a_dock_that_does_not_charge_raises_an_alert(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        await activate(c, "r1")
        r.sim.robots[0].battery = 0.5  # a full battery has nothing to rise by
        # A dock drawn away from the charger: the robot sits there, its battery falls.
        await c.ok("create", type="waypoint", name="dock1", x=4.0, y=8.6, kind="dock")
        owner = await owner_of(r)
        await owner.ok("site", action="edit_robot", robot="r1", dock="dock1")
        await c.ok("charge", robot="r1")
        await c.status("r1", "Charging", timeout=120)

        def alert() -> bool:
            return any(
                a["kind"] == "not_charging" and a["subject"] == "r1" and a["cleared_at"] is None
                for a in c.records.get("alerts", {}).values()
            )

        await c.until(alert, timeout=1200, what="the not-charging alert")
        await c.ok("work", robot="r1")
        await c.until(lambda: not alert(), timeout=60, what="the alert cleared")


async def test_a_nav2_robot_docks_with_its_docking_server(tmp_path: Path) -> None:
    # A charger away from home, a ROS 2 robot whose Nav2 has opennav_docking: the server
    # sends DockRobot (staging pose, approach, on the contacts) and UndockRobot, not a goal.
    dock = (2.6, 10.8, 1.570796)
    config = site(charge_below=0.4, charge_until=0.41)
    async with restaurant(
        tmp_path,
        robots=1,
        config=config,
        ros=2,
        docking=True,
        docks={"r1": dock},
        link={"docking": "nav2"},
    ) as r:
        robot = r.sim.robots[0]
        server = robot.docking
        assert server is not None
        asked: list[str] = []
        dock_robot, undock_robot = server.dock, server.undock

        def docked(*a: Any) -> None:
            asked.append("dock_robot")
            dock_robot(*a)

        def undocked(*a: Any) -> None:
            asked.append("undock_robot")
            undock_robot(*a)

        server.dock, server.undock = docked, undocked  # type: ignore[method-assign]
        c = await staff(r)
        await c.ok(
            "create", type="waypoint", name="dock1", x=dock[0], y=dock[1], yaw=dock[2], kind="dock"
        )
        owner = await owner_of(r)
        await owner.ok("site", action="edit_robot", robot="r1", dock="dock1")
        robot.battery = 0.395
        await activate(c, "r1")
        await c.status("r1", "Charging", timeout=300)
        assert asked == ["dock_robot"]
        assert abs(robot.pose[0] - dock[0]) < 0.06 and abs(robot.pose[1] - dock[1]) < 0.06
        await c.status("r1", "Awaiting", timeout=1200)
        assert asked == ["dock_robot", "undock_robot"]
        home = r.app.core.places.waypoint("home1")  # type: ignore[union-attr]
        assert abs(robot.pose[0] - home.x) < 0.4 and abs(robot.pose[1] - home.y) < 0.4
