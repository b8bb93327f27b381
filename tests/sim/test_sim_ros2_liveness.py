"""A simulated ROS 2 robot's liveness, as measured on a real Jazzy stack (shared/notes/ros2.md,
"Liveness, measured on the same stack"), each fact a test over a real websocket:

* Nav2's ``/bt_navigator/get_state`` answers ``active`` (lifecycle_msgs/srv/GetState);
* rosbridge stopped with SIGTERM/SIGINT keeps its websocket open, answers every call
  ``result: false`` ("rcl node's context is invalid"), its topics go quiet and feedback stops,
  while the robot drives on; only a new rosbridge heals it;
* the robot's node dead behind a live bridge: rosapi still answers, the robot's topics stop,
  its service is never answered, a goal gets no frame at all.

Nothing sleeps to wait; "nothing comes" is a short bounded wait for silence (``SILENCE``).
"""

from __future__ import annotations

import math
from collections.abc import AsyncIterator

import pytest
from websockets.exceptions import ConnectionClosed

from serveur.robot_sim import Simulation
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from tests.conftest import poll_until
from tests.sim.test_sim_badinput import FAR, T1, Raw, open_raw, shut
from tests.sim.test_sim_ros2 import SILENCE, feedback, ping2, result, send_goal, start

GET_STATE = "/bt_navigator/get_state"


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start()
    try:
        yield s
    finally:
        await shut(s)


async def get_state(c: Raw, rid: str = "state") -> dict[str, object]:
    await c.send(rb.op_call_service(GET_STATE, {}, id=rid))
    return await c.wait_for(lambda m: m["op"] == "service_response" and m.get("id") == rid)


async def nothing(c: Raw) -> None:
    with pytest.raises(TimeoutError):
        await c.wait_for(lambda m: True, limit=SILENCE)


async def test_the_navigator_says_it_is_active(sim: Simulation) -> None:
    c = await open_raw(sim)
    reply = await get_state(c)
    assert reply["result"] is True
    assert reply["values"] == {"current_state": {"id": 3, "label": "active"}}
    await c.send(rb.op_call_service("/rosapi/services", id="s"))
    services = await c.wait_for(lambda m: m.get("id") == "s")
    assert GET_STATE in services["values"]["services"]


async def test_a_ros1_robot_has_no_lifecycle_service() -> None:
    s = await start(ros=1)
    try:
        c = await open_raw(s)
        reply = await get_state(c)
        assert reply["result"] is False
    finally:
        await shut(s)


async def test_a_bridge_whose_ros_side_stopped_refuses_every_call_and_goes_quiet(
    sim: Simulation,
) -> None:
    robot = sim.robots[0]
    c = await open_raw(sim)
    await c.send(send_goal("g", FAR, feedback=True))
    await feedback(c, "g")
    await c.send(rb.op_subscribe("/battery_state"))
    await c.topic("/battery_state")
    robot.stop_bridge_ros_side()
    # Every call, rosapi's too, is answered result: false with the measured text.
    for service in (GET_STATE, "/rosapi/get_time"):
        await c.send(rb.op_call_service(service, {}, id=service))
        reply = await c.wait_for(lambda m, s=service: m.get("id") == s)  # type: ignore[misc]
        assert reply == {
            "op": "service_response",
            "service": service,
            "id": service,
            "values": ros2.ROS_SIDE_DEAD,
            "result": False,
        }
    # Nothing else: no feedback, no topic.
    await nothing(c)
    # A new goal gets result false with the same words; a subscription gets nothing.
    await c.send(send_goal("h", T1))
    failed = await result(c, "h")
    assert failed["result"] is False and failed["values"] == ros2.ROS_SIDE_DEAD
    # The robot itself (Nav2) drives on: a goal nobody can cancel any more.
    x0 = robot.pose
    await c.send({"op": "cancel_action_goal", "action": "/navigate_to_pose", "id": "g"})
    moved = await _moves(sim, x0)
    assert moved > 0.05
    # A new rosbridge: the old connection closes, a new one works.
    await sim.restart_rosbridge(0)
    with pytest.raises(ConnectionClosed):
        await c.wait_for(lambda m: False, limit=5.0)
    d = await open_raw(sim)
    assert (await get_state(d))["result"] is True
    await ping2(d)


async def _moves(sim: Simulation, x0: tuple[float, float, float]) -> float:
    """How far the robot got from ``x0`` once it has moved (waits on the simulator)."""
    robot = sim.robots[0]
    await poll_until(
        lambda: math.hypot(robot.pose[0] - x0[0], robot.pose[1] - x0[1]) > 0.05, 10, "moving"
    )
    return math.hypot(robot.pose[0] - x0[0], robot.pose[1] - x0[1])


async def test_a_dead_robot_node_behind_a_live_bridge(sim: Simulation) -> None:
    robot = sim.robots[0]
    c = await open_raw(sim)
    await c.send(send_goal("g", FAR, feedback=True))
    await feedback(c, "g")
    robot.kill_node()
    await ping2(c)  # rosapi answers (feedback sent before it came before it)
    await c.send(rb.op_call_service(GET_STATE, {}, id="state"))
    await c.send(rb.op_subscribe("/amcl_pose"))  # latched, but its publisher is dead
    await c.send(send_goal("h", T1, feedback=True))  # no action server: no frame at all
    await nothing(c)  # no state, no pose, nothing of either goal
    # The navigator is gone: the base stops (waited on: a loaded box slows the simulation).
    await poll_until(lambda: math.hypot(*robot.velocity[:2]) < 0.01, 10, "the base stopped")
    robot.restart_node()
    # AMCL publishes its pose once at start, maybe before a state request is answered: wait
    # for it first (a frame not yet looked at is kept), then ask, so neither wait skips it.
    await c.topic("/amcl_pose")
    assert (await get_state(c, "again"))["result"] is True
