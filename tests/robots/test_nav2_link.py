"""ROS 2 robots (Nav2 over rosbridge 2.x) driven through the same robot-driver interface as ROS1
ones (issue 19): a real server against the simulator's ROS 2 dialect, one test per fact of
../shared/notes/ros2.md that the driver must handle."""

from __future__ import annotations

import asyncio
import math
import time
import uuid
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from serveur.core.engine import CoreConfig
from serveur.robots.ros2.link import Nav2Link
from tests.conftest import Restaurant, poll_until, restaurant
from tests.test_e2e import activate, near, new_orders, serve_current_stop, staff

CONFIG = CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=True)


@pytest.fixture
async def humble(tmp_path: Path) -> AsyncIterator[Restaurant]:
    """A Humble robot: rosbridge's goal thread off, so a goal holds its connection's queue."""
    async with restaurant(tmp_path, robots=1, config=CONFIG, ros=2, release="humble") as r:
        yield r


def sim(r: Restaurant, i: int = 0) -> Any:
    return r.sim.robots[i]


async def test_a_ros2_robot_serves_a_trip_like_a_ros1_one(humble: Restaurant) -> None:
    assert isinstance(humble.app.core._rt["r1"].link, Nav2Link)
    c = await staff(humble)
    assert c.robot("r1")["link"] == {"ros": "2"}
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T1"), ("Satay", "T12"))
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    await serve_current_stop(c, "r1")
    await serve_current_stop(c, "r1")
    await c.status("r1", "Transit")
    await c.status("r1", "Awaiting")
    assert all(c.order(o)["status"] == "delivered" for o in ids)
    assert c.task(task["id"])["status"] == "done"


async def test_stop_works_while_a_goal_holds_humbles_queue(humble: Restaurant) -> None:
    """With send_action_goals_in_new_thread false, a cancel sent behind the goal on the same
    connection would wait until the robot arrived: the driver's control connection does not."""
    assert sim(humble).humble_queue
    c = await staff(humble)
    await activate(c, "r1")
    await new_orders(c, ("Laksa", "T12"))
    ids = [o["id"] for o in c.records["orders"].values()]
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    await poll_until(lambda: math.hypot(*sim(humble).velocity[:2]) > 0.1, 10, "moving")
    await c.ok("stop", robot="r1")
    await c.status("r1", "Stopped")
    # Cancelled on the robot and standing still, long before it could have reached T12.
    await poll_until(lambda: math.hypot(*sim(humble).velocity[:2]) < 0.01, 5, "stopped")
    assert [s.name for _, s, _ in sim(humble).goal_statuses][-1:] == ["PREEMPTED"]


async def test_an_aborted_goal_is_a_failure_and_its_status_is_the_outcome(
    humble: Restaurant,
) -> None:
    # action_result says result: true for an abort; the outcome is its status (6).
    c = await staff(humble)
    await activate(c, "r1")
    sim(humble).block_path(True)
    ids = await new_orders(c, ("Laksa", "T12"))
    await c.ok("create", type="task", orders=ids)
    robot = await c.status("r1", "Error")
    assert "navigate_to_pose ABORTED" in robot["last_error"]


async def test_a_goal_replaced_by_a_new_one_is_not_a_failure(humble: Restaurant) -> None:
    # Nav2 aborts the running goal when a new one comes: the driver must not take that abort
    # for the new goal's failure.
    c = await staff(humble)
    await c.status("r1", "Ready")
    await c.ok("control", robot="r1", action="manual")
    await c.status("r1", "Manual")
    await c.ok("control", robot="r1", action="goto", waypoint="T12")
    await poll_until(lambda: math.hypot(*sim(humble).velocity[:2]) > 0.1, 10, "moving")
    await c.ok("control", robot="r1", action="goto", waypoint="T1")
    await c.until(lambda: c.robot("r1").get("last_error") is None and near(c.robot("r1"), "T1"))
    assert c.robot("r1")["status"] == "Manual" and c.robot("r1")["last_error"] is None


async def test_a_goal_nobody_answers_times_out_instead_of_waiting_for_ever(
    humble: Restaurant,
) -> None:
    # A rejected or unserved goal gets no frame at all: no feedback within the ack timeout,
    # re-sent under a new id, then the robot is in Error with the reason.
    c = await staff(humble)
    await activate(c, "r1")
    sim(humble).ignore_goals(True)
    ids = await new_orders(c, ("Laksa", "T12"))
    await c.ok("create", type="task", orders=ids)
    robot = await c.status("r1", "Error", timeout=60)
    assert "not acknowledged by Nav2" in robot["last_error"]
    sent = [gid for gid, _, _ in sim(humble).goal_statuses]
    # Goal ids are UUIDs: the bridge's goal table is shared by every client.
    assert all(uuid.UUID(g) for g in sent)


async def test_a_lost_result_at_the_goal_counts_as_arrival(humble: Restaurant) -> None:
    c = await staff(humble)
    await activate(c, "r1")
    sim(humble).drop_results(1)
    ids = await new_orders(c, ("Laksa", "T1"))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivered", timeout=60)
    assert c.robot("r1")["last_error"] is None


async def test_teleop_speaks_twiststamped_when_the_robot_wants_it(tmp_path: Path) -> None:
    # Kilted's Nav2 (and Jazzy's diff_drive_controller) take TwistStamped on /cmd_vel: the
    # driver asks rosapi for the type; a plain Twist would not move the robot.
    async with restaurant(tmp_path, robots=1, config=CONFIG, ros=2, release="kilted") as r:
        assert r.sim.robots[0].twist_stamped
        c = await staff(r)
        await c.status("r1", "Ready")
        await c.ok("control", robot="r1", action="manual")
        await c.status("r1", "Manual")
        p0 = r.sim.robots[0].pose

        def moved() -> float:
            p = r.sim.robots[0].pose
            return math.hypot(p[0] - p0[0], p[1] - p0[1])

        # A finger on the joystick: the console repeats the command at 5 Hz (wall time).
        # Backwards: home faces the counter.
        for _ in range(50):
            await c.ok("control", robot="r1", action="teleop", vx=-0.5, vy=0.0, wz=0.0)
            if moved() > 0.1:
                break
            await asyncio.sleep(0.2)  # the joystick's period, not a wait for a result
        assert moved() > 0.1, "the robot did not move"


async def test_calibration_is_in_the_map_frame(humble: Restaurant) -> None:
    # AMCL ignores an /initialpose whose frame is not "map".
    c = await staff(humble)
    await c.status("r1", "Ready")
    await c.ok("control", robot="r1", action="manual")
    await c.status("r1", "Manual")
    await c.ok("control", robot="r1", action="initialpose", x=3.0, y=4.0, yaw=0.5)
    await poll_until(
        lambda: math.hypot(sim(humble).pose[0] - 3.0, sim(humble).pose[1] - 4.0) < 0.05,
        10,
        "relocalised",
    )


@pytest.mark.cuts_links
async def test_a_silent_ros2_robot_goes_offline_and_comes_back(humble: Restaurant) -> None:
    c = await staff(humble)
    await c.status("r1", "Ready")
    await humble.sim.stop_endpoint(0)
    await c.status("r1", "Offline", timeout=30)
    await humble.sim.start_endpoint(0)
    await c.status("r1", "Ready", timeout=30)


async def test_a_mixed_fleet_serves_a_dinner_service(tmp_path: Path) -> None:
    """One ROS1 robot and one ROS 2 robot: the server cannot tell them apart."""
    async with restaurant(tmp_path, robots=2, config=CONFIG, ros=[1, 2]) as r:
        kinds = {n: type(rt.link).__name__ for n, rt in r.app.core._rt.items()}
        assert kinds == {"r1": "RobotLink", "r2": "Nav2Link"}
        c = await staff(r)
        await activate(c, "r1")
        await activate(c, "r2")
        ids = await new_orders(c, ("Laksa", "T1"), ("Satay", "T12"))
        await c.ok("create", type="task", orders=ids[:1])
        await c.ok("create", type="task", orders=ids[1:])
        for name in ("r1", "r2"):
            await serve_current_stop(c, name)
        for name in ("r1", "r2"):
            await c.status(name, "Awaiting", timeout=60)
        assert all(c.order(o)["status"] == "delivered" for o in ids)


@pytest.mark.cuts_links
async def test_wifi_that_stops_forwarding_takes_a_ros2_robot_offline_in_time(
    tmp_path: Path,
) -> None:
    # No frame, no close: only the rosapi heartbeat can tell. Offline within the heartbeat
    # timeout (not websockets' 10 s closing handshake), back when the path returns.
    async with restaurant(tmp_path, robots=1, config=CONFIG, ros=2, proxied=True) as r:
        c = await staff(r)
        await c.status("r1", "Ready")
        link = r.app.core._rt["r1"].link
        assert link is not None
        limit = link.heartbeat_timeout() / r.clock.time_scale  # wall seconds
        t0 = time.monotonic()
        r.proxies[0].blackhole()
        await c.status("r1", "Offline", timeout=limit + 5.0)
        took = time.monotonic() - t0
        assert took <= limit + 0.8, f"Offline after {took:.1f}s (heartbeat {limit:.1f}s)"
        r.proxies[0].resume()
        await c.status("r1", "Ready")


async def test_shutdown_cancels_the_goal_itself(humble: Restaurant) -> None:
    # Closing the websocket does not cancel a Nav2 goal: a server going down must cancel it,
    # or the robot drives on with nobody watching.
    c = await staff(humble)
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T12"))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    await poll_until(lambda: math.hypot(*sim(humble).velocity[:2]) > 0.1, 10, "moving")
    await humble.app.core.halt_robots()
    await poll_until(lambda: math.hypot(*sim(humble).velocity[:2]) < 0.01, 5, "stopped")
    assert [s.name for _, s, _ in sim(humble).goal_statuses][-1:] == ["PREEMPTED"]


async def test_jazzys_error_message_reaches_staff(tmp_path: Path) -> None:
    # Jazzy's NavigateToPose result carries error_code/error_msg (Humble's is empty): staff
    # see Nav2's own reason.
    async with restaurant(tmp_path, robots=1, config=CONFIG, ros=2, release="jazzy") as r:
        c = await staff(r)
        await activate(c, "r1")
        r.sim.robots[0].block_path(True)
        ids = await new_orders(c, ("Laksa", "T12"))
        await c.ok("create", type="task", orders=ids)
        robot = await c.status("r1", "Error")
        assert "navigate_to_pose ABORTED:" in robot["last_error"]
        assert "(error 208)" in robot["last_error"]
