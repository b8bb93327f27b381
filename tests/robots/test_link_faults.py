"""A robot that misbehaves or vanishes: every case ends in a defined status, never a hang."""

from __future__ import annotations

import pytest

from tests.conftest import Client, Restaurant
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

# Link faults happen to ROS1 and ROS 2 robots alike (and to a mixed fleet): issue 19.


@pytest.fixture
def one_robot(any_robot: Restaurant) -> Restaurant:
    return any_robot


@pytest.fixture
def two_robots(any_two_robots: Restaurant) -> Restaurant:
    return any_two_robots


pytestmark = pytest.mark.cuts_links  # robots drop off the network on purpose


async def start_delivery(r: Restaurant, table: str = "T6") -> tuple[Client, list[int]]:
    c = await staff(r)
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", table))
    await c.ok("create", type="task", orders=ids)
    return c, ids


async def test_goal_never_acknowledged_ends_in_error_then_cancel_returns_orders(
    one_robot: Restaurant,
) -> None:
    one_robot.sim.robots[0].ignore_goals(True)
    c, ids = await start_delivery(one_robot)
    robot = await c.status("r1", "Error")
    assert "not acknowledged" in robot["last_error"]
    assert c.order(ids[0])["status"] == "assigned"  # still aboard until staff decide
    one_robot.sim.robots[0].ignore_goals(False)
    await c.ok("cancel", robot="r1")
    await c.until(lambda: c.order(ids[0]).get("status") == "pending", what="order pending again")
    await c.status("r1", "Awaiting")  # it went home after all


async def test_aborted_goal_is_error_and_continue_retries(one_robot: Restaurant) -> None:
    sim_robot = one_robot.sim.robots[0]
    sim_robot.block_path(True)
    c, ids = await start_delivery(one_robot)
    robot = await c.status("r1", "Error")
    assert "ABORTED" in robot["last_error"]
    sim_robot.block_path(False)
    await c.ok("continue", robot="r1")
    assert (await serve_current_stop(c, "r1"))["table"] == "T6"
    await c.status("r1", "Awaiting")
    await c.until(lambda: c.order(ids[0]).get("status") == "delivered")


async def test_robot_dropping_off_the_network_resumes_its_trip(one_robot: Restaurant) -> None:
    c, ids = await start_delivery(one_robot, "T16")
    await c.status("r1", "Delivering")
    await one_robot.sim.stop_endpoint(0)
    robot = await c.status("r1", "Offline")
    assert robot["current_task"] is not None  # the dishes stay with the robot
    drops = [
        e
        for e in await one_robot.app.store.events.list_events()
        if e.kind == "robot.status" and e.data.get("status") == "Offline"
    ]
    assert drops and drops[-1].data["event"] == "link_down", drops
    assert c.order(ids[0])["status"] == "assigned"
    await one_robot.sim.start_endpoint(0)
    await c.status("r1", "Delivering")
    assert (await serve_current_stop(c, "r1"))["table"] == "T16"
    await c.status("r1", "Awaiting")
    await c.until(lambda: c.order(ids[0]).get("status") == "delivered")


async def test_offline_detected_within_two_simulated_seconds(one_robot: Restaurant) -> None:
    c = await staff(one_robot)
    await c.status("r1", "Ready")
    clock = one_robot.clock
    await one_robot.sim.stop_endpoint(0)
    t0 = clock.now()
    await c.status("r1", "Offline")
    # Closing the endpoint closes the socket, so this is fast; the heartbeat bounds the rest.
    assert clock.now() - t0 <= 2.0 + 0.5
    await one_robot.sim.start_endpoint(0)
    await c.status("r1", "Ready")
