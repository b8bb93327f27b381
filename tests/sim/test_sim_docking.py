"""The simulator's chargers and its docking server (issue 32, item 5).

Every simulated robot has a dock (its home unless given: ``docks`` / ``serveur sim --dock``)
and charges only standing on a charger's contacts, at a real waiter robot's rate;
``/battery_state`` says so. A ROS 2 robot made with ``docking`` serves opennav_docking's
``dock_robot`` and ``undock_robot`` over rosbridge 2.x as Nav2's docking server does (its
phases, feedback, results and error codes: serveur.sim.docking's docstring). Raw rosbridge
clients here, as in test_sim_ros2; the battery's rules on a robot stepped by hand. Nothing
sleeps to wait: each wait reads frames, or steps the clock, until a condition holds, with a
timeout; only "nothing comes" waits a short, bounded wall time for silence.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import math
from collections.abc import AsyncIterator, Callable
from typing import Any

import pytest

from serveur.clock import FakeClock
from serveur.maps.navigation import load_demo
from serveur.robot_sim import (
    TICK,
    Simulation,
    add_sim_arguments,
    parse_dock,
    run_sim_from_args,
    shared_planner,
    start_simulation,
)
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.docking import (
    INITIAL_PERCEPTION_TIMEOUT,
    STAGING_OFFSET,
    on_charger,
    staging_pose,
)
from serveur.sim.robot import FULL_CHARGE, IDLE_DRAIN, SimRobot
from tests.sim.test_sim_badinput import FAR, T1, Raw, open_raw, shut
from tests.sim.test_sim_ros2 import SILENCE, result, send_goal, start

GRID, WAYPOINTS = load_demo()
HOME1 = WAYPOINTS["home1"]
DOCK = (HOME1.x, HOME1.y, HOME1.yaw)  # robot r1's home, so its dock unless told otherwise
NOWHERE = (8.0, 5.0, 0.0)  # a free spot of the demo room with no charger
DOCK_TYPE = "nav2_msgs/action/DockRobot"
UNDOCK_TYPE = "nav2_msgs/action/UndockRobot"


def dock_goal(
    gid: str,
    at: tuple[float, float, float],
    *,
    action_type: str = DOCK_TYPE,
    use_dock_id: bool = False,
    staging: bool = True,
    feedback: bool = True,
) -> dict[str, Any]:
    return {
        "op": "send_action_goal",
        "id": gid,
        "action": "/dock_robot",
        "action_type": action_type,
        "args": {
            "use_dock_id": use_dock_id,
            "dock_id": "home1",
            "dock_pose": {
                "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "map"},
                "pose": rb.pose_msg(*at),
            },
            "navigate_to_staging_pose": staging,
        },
        "feedback": feedback,
    }


def undock_goal(gid: str, action_type: str = UNDOCK_TYPE) -> dict[str, Any]:
    return {
        "op": "send_action_goal",
        "id": gid,
        "action": "/undock_robot",
        "action_type": action_type,
        "args": {"max_undocking_time": 30.0},
        "feedback": True,
    }


async def states_until_result(c: Raw, gid: str) -> tuple[list[int], dict[str, Any]]:
    """The feedback states of goal ``gid`` in order, and its result."""
    states: list[int] = []
    while True:
        op = await c.wait_for(lambda m: m.get("id") == gid and m["op"].startswith("action_"))
        if op["op"] == "action_result":
            return states, op
        states.append(op["values"]["state"])


async def until(sim: Simulation, cond: Callable[[], Any], limit: float = 30.0) -> None:
    """Let sim time pass, a tick at a time, until ``cond()`` holds (``limit`` sim seconds)."""
    end = sim.clock.now() + limit
    while not cond():
        assert sim.clock.now() < end, "timed out"
        await sim.clock.sleep(TICK)


def staging(robot: SimRobot) -> list[Any]:
    """The navigate goals the robot's docking server sent Nav2, while the robot lists them."""
    return [g for g in robot.navigator.goals if g.id.startswith("docking-staging-")]


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start(docking=True)
    try:
        yield s
    finally:
        await shut(s)


# -- dock_robot ------------------------------------------------------------------------------


async def test_a_dock_stages_perceives_drives_on_and_charges(sim: Simulation) -> None:
    robot = sim.robots[0]
    robot.battery = 0.5
    c = await open_raw(sim)
    await c.send(send_goal("away", T1))
    assert (await result(c, "away"))["status"] == ros2.SUCCEEDED
    assert not robot.charging
    await c.send(dock_goal("d1", DOCK))
    await until(sim, lambda: staging(robot))  # Nav2 drives it to the staging pose
    [staged] = staging(robot)  # kept: the robot forgets an ended goal after 5 s
    states, res = await states_until_result(c, "d1")
    assert res["status"] == ros2.SUCCEEDED and res["result"] is True
    assert res["values"] == {"success": True, "error_code": 0, "num_retries": 0, "error_msg": ""}
    # NAV_TO_STAGING_POSE and INITIAL_PERCEPTION once each (nothing while Nav2 drives to the
    # staging pose), then CONTROLLING and WAIT_FOR_CHARGE every cycle.
    assert states[:2] == [1, 2] and states.count(1) == 1 and states.count(2) == 1
    assert set(states[2:]) == {3, 4} and states == sorted(states)
    assert staged.status is rb.GoalStatus.SUCCEEDED
    assert math.dist((staged.x, staged.y), staging_pose(*DOCK)[:2]) < 1e-9
    assert math.dist(robot.pose[:2], DOCK[:2]) < 0.05 and robot.charging
    await c.send(rb.op_subscribe("/battery_state"))
    bat = await c.topic("/battery_state", lambda m: m["power_supply_status"] == 1)
    assert bat["current"] > 0.0  # CHARGING, current flowing into the battery
    # Docked and charging already: a second goal succeeds at once, without feedback.
    await c.send(dock_goal("d2", DOCK))
    states, res = await states_until_result(c, "d2")
    assert (states, res["status"]) == ([], ros2.SUCCEEDED)


async def test_a_dock_with_no_charger_there_fails_after_looking_for_it(sim: Simulation) -> None:
    robot = sim.robots[0]
    c = await open_raw(sim)
    await c.send(dock_goal("d", NOWHERE))
    await c.wait_for(lambda m: m.get("id") == "d" and m["op"] == "action_feedback")
    looking = await c.wait_for(lambda m: m.get("id") == "d" and m["op"] == "action_feedback")
    assert looking["values"]["state"] == 2  # INITIAL_PERCEPTION, at the staging pose
    res = await result(c, "d")
    assert res["status"] == ros2.ABORTED and res["result"] is True
    assert res["values"] == {
        "success": False,
        "error_code": ros2.FAILED_TO_DETECT_DOCK,
        "num_retries": 0,
        "error_msg": "Failed initial dock detection",
    }
    assert math.dist(robot.pose[:2], staging_pose(*NOWHERE)[:2]) < 0.1
    assert not robot.charging


async def test_a_dock_by_id_is_not_in_the_sims_database(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(dock_goal("byid", DOCK, use_dock_id=True))
    res = await result(c, "byid")
    assert res["status"] == ros2.ABORTED
    assert res["values"]["error_code"] == ros2.DOCK_NOT_IN_DB and not res["values"]["success"]


async def test_a_cancelled_dock_ends_canceled_and_its_staging_drive_stops(sim: Simulation) -> None:
    robot = sim.robots[0]
    robot.teleport(*FAR)
    c = await open_raw(sim)
    await c.send(dock_goal("d", DOCK))
    await c.wait_for(lambda m: m.get("id") == "d" and m["op"] == "action_feedback")
    await until(sim, lambda: math.hypot(*robot.velocity[:2]) > 0.1)  # Nav2 drives to staging
    [staged] = staging(robot)
    await c.send({"op": "cancel_action_goal", "action": "/dock_robot", "id": "d"})
    res = await result(c, "d")
    assert res["status"] == ros2.CANCELED and res["values"]["success"] is False
    await until(sim, lambda: math.hypot(*robot.velocity) < 0.01)
    assert staged.status is rb.GoalStatus.PREEMPTED
    assert math.dist(robot.pose[:2], DOCK[:2]) > 1.0


async def test_a_navigate_goal_taking_the_base_fails_the_dock(sim: Simulation) -> None:
    robot = sim.robots[0]
    robot.teleport(*staging_pose(*DOCK))  # at the staging pose: straight to CONTROLLING
    c = await open_raw(sim)
    await c.send(dock_goal("d", DOCK))
    await c.wait_for(lambda m: m.get("id") == "d" and m.get("values", {}).get("state") == 3)
    await c.send(send_goal("other", T1))
    res = await result(c, "d")
    assert res["status"] == ros2.ABORTED
    assert res["values"]["error_code"] == ros2.FAILED_TO_CONTROL
    assert (await result(c, "other"))["status"] == ros2.SUCCEEDED


# -- undock_robot ----------------------------------------------------------------------------


async def test_undock_backs_off_the_dock_and_off_it_aborts_without_a_code(
    sim: Simulation,
) -> None:
    robot = sim.robots[0]
    robot.battery = 0.5
    await until(sim, lambda: robot.charging, 5.0)  # it starts on its dock
    c = await open_raw(sim)
    await c.send(undock_goal("u1"))
    res = await result(c, "u1")
    assert (res["status"], res["values"]) == (ros2.SUCCEEDED, {"success": True, "error_code": 0})
    assert [op for gid, op in map(action_op, c.frames) if gid == "u1"] == ["action_result"]
    assert math.dist(robot.pose[:2], DOCK[:2]) == pytest.approx(STAGING_OFFSET, abs=0.06)
    assert not robot.charging
    await c.send(rb.op_subscribe("/battery_state"))
    bat = await c.topic("/battery_state", lambda m: m["power_supply_status"] == 2)
    assert bat["current"] < 0.0  # DISCHARGING
    # Off the dock: "Robot is not in the dock, no need to undock", which Nav2 aborts.
    await c.send(undock_goal("u2"))
    res = await result(c, "u2")
    assert (res["status"], res["values"]) == (ros2.ABORTED, {"success": False, "error_code": 0})


def action_op(frame: str | bytes) -> tuple[Any, str]:
    """(goal id, op) of a frame (the id None for a frame that is no action op)."""
    op = json.loads(frame)
    return (op.get("id") if op["op"].startswith("action_") else None), op["op"]


# -- who serves what -------------------------------------------------------------------------


async def test_only_a_robot_with_docking_serves_the_docking_actions() -> None:
    s = await start(2, ros=2, docking=[False, True])
    try:
        plain, docked = await open_raw(s, 0), await open_raw(s, 1)
        await plain.send(dock_goal("d", DOCK))  # Jazzy has the type, nobody serves it
        await plain.send(rb.op_call_service("/rosapi/action_servers", id="servers"))
        servers = await plain.wait_for(lambda m: m.get("id") == "servers")
        assert servers["values"]["action_servers"] == ["/navigate_to_pose"]
        with pytest.raises(TimeoutError):
            await plain.wait_for(lambda m: m.get("id") == "d", limit=SILENCE)
        await docked.send(rb.op_call_service("/rosapi/action_servers", id="servers"))
        servers = await docked.wait_for(lambda m: m.get("id") == "servers")
        assert servers["values"]["action_servers"] == [
            "/dock_robot",
            "/navigate_to_pose",
            "/undock_robot",
        ]
    finally:
        await shut(s)


async def test_humble_docks_with_opennav_docking_msgs_and_cannot_load_nav2s() -> None:
    s = await start(2, release="humble", humble_queue=False, docking=[True, False])
    try:
        docked, plain = await open_raw(s, 0), await open_raw(s, 1)
        await docked.send(dock_goal("n", DOCK))  # Nav2's type: not on a Humble robot
        res = await result(docked, "n")
        assert res["result"] is False and "Unable to import action type" in res["values"]
        await docked.send(undock_goal("u", "opennav_docking_msgs/action/UndockRobot"))
        res = await result(docked, "u")
        assert res["status"] == ros2.SUCCEEDED
        assert res["values"] == {"success": True, "error_code": 0}
        await docked.send(dock_goal("o", DOCK, action_type="opennav_docking_msgs/DockRobot"))
        res = await result(docked, "o")
        assert res["status"] == ros2.SUCCEEDED
        assert res["values"] == {"success": True, "error_code": 0, "num_retries": 0}  # no msg
        # Without the docking server the standalone package is not even installed.
        await plain.send(dock_goal("o", DOCK, action_type="opennav_docking_msgs/DockRobot"))
        assert (await result(plain, "o"))["result"] is False
    finally:
        await shut(s)


async def test_a_dock_goal_rosbridge_cannot_fill_fails_on_the_bridge(sim: Simulation) -> None:
    c = await open_raw(sim)
    bad = dock_goal("bad", DOCK)
    bad["args"]["pose"] = bad["args"].pop("dock_pose")  # NavigateToPose's field, not DockRobot's
    await c.send(bad)
    res = await result(c, "bad")
    assert res["result"] is False and "does not have a field 'pose'" in res["values"]


def test_docking_needs_ros2() -> None:
    with pytest.raises(ValueError, match="docking"):
        asyncio.run(start_simulation(1, port=0, ros=1, docking=[True]))
    with pytest.raises(ValueError, match="docking"):
        robot(docking=True, ros=1)


# -- the charger and the battery -------------------------------------------------------------


def robot(**kw: Any) -> SimRobot:
    """One robot at home1, stepped by hand (no event loop, no bridge)."""
    return SimRobot(
        "r1",
        index=0,
        grid=GRID,
        planner=shared_planner(GRID, cache_size=32),
        home=kw.pop("home", DOCK),
        kinematics="omni",
        clock=FakeClock(),
        seed=1,
        **kw,
    )


def run(r: SimRobot, seconds: float) -> None:
    for _ in range(round(seconds / TICK)):
        r._step(TICK)


class Sink:
    """A docking goal's client, as the bridge's goal is: its feedback and its result."""

    feedback = True

    def __init__(self, r: SimRobot) -> None:
        self.robot = r
        self.states: list[tuple[float, int]] = []  # (sim time, docking state)
        self.ended: tuple[float, int, dict[str, Any]] | None = None

    def send_feedback(self, values: Any) -> None:
        self.states.append((self.robot.state.t, values["state"]))

    def end(self, status: int, values: Any, *, send: bool = True) -> None:
        self.ended = (self.robot.state.t, status, dict(values))


def dock_args(at: tuple[float, float, float], staging: bool = True) -> ros2.DockGoal:
    return ros2.dock_goal_from_args(dock_goal("g", at, staging=staging)["args"])


def test_the_dock_is_looked_for_five_seconds_then_fails_not_detected() -> None:
    r = robot(docking=True, ros=2)
    r.teleport(*staging_pose(*NOWHERE))
    sink = Sink(r)
    assert r.docking is not None
    r.docking.dock(sink, dock_args(NOWHERE))
    run(r, INITIAL_PERCEPTION_TIMEOUT + 1.0)
    assert sink.ended is not None
    at, status, values = sink.ended
    assert [s for _, s in sink.states] == [1, 2]  # staged already: straight to perception
    looked = at - sink.states[1][0]
    assert INITIAL_PERCEPTION_TIMEOUT < looked <= INITIAL_PERCEPTION_TIMEOUT + 2 * TICK
    assert (status, values["error_code"]) == (ros2.ABORTED, ros2.FAILED_TO_DETECT_DOCK)


def test_from_its_staging_pose_the_robot_drives_onto_the_contacts_and_charges() -> None:
    r = robot(docking=True, ros=2)
    r.teleport(*staging_pose(*DOCK))
    r.battery = 0.5
    sink = Sink(r)
    assert r.docking is not None
    r.docking.dock(sink, dock_args(DOCK))
    run(r, 15.0)
    assert sink.ended is not None and sink.ended[1] == ros2.SUCCEEDED
    states = [s for _, s in sink.states]
    assert states[:2] == [1, 2] and set(states[2:]) == {3, 4} and states == sorted(states)
    # 0.7 m at the docking controller's 0.25 m/s at most: a few seconds, not less.
    took = sink.ended[0] - sink.states[0][0]
    assert STAGING_OFFSET / 0.25 < took < 10.0
    assert math.dist(r.pose[:2], DOCK[:2]) < 0.02 and r.charging


def test_a_robot_charges_on_its_docks_contacts_at_a_waiter_robots_rate() -> None:
    assert FULL_CHARGE == 4.5 * 3600 and IDLE_DRAIN == 12 * 3600
    r = robot()
    assert r.dock == DOCK  # its home, by default
    r.battery = 0.5
    run(r, 60.0)
    assert r.charging
    assert r.battery == pytest.approx(0.5 + 60.0 / FULL_CHARGE)
    msg = r.sensors._build_battery(0, 0.0)
    assert msg["power_supply_status"] == rb.BatteryStatus.CHARGING == 1 and msg["current"] > 0
    r.battery = 1.0
    run(r, 1.0)
    assert r.sensors._build_battery(0, 0.0)["power_supply_status"] == rb.BatteryStatus.FULL


@pytest.mark.parametrize(
    "offset",
    [(0.04, 0.0, 0.0), (0.0, -0.03, 0.08)],  # within a few centimetres, square enough
)
def test_a_few_centimetres_off_still_touches_the_contacts(offset: tuple[float, ...]) -> None:
    r = robot()
    r.teleport(DOCK[0] + offset[0], DOCK[1] + offset[1], DOCK[2] + offset[2])
    run(r, 1.0)
    assert r.charging and on_charger(r.state) == DOCK


@pytest.mark.parametrize(
    "offset",
    [(0.1, 0.0, 0.0), (0.0, 0.25, 0.0), (0.0, 0.0, 0.3)],  # where "near home" used to charge
)
def test_off_the_contacts_the_robot_discharges(offset: tuple[float, ...]) -> None:
    r = robot()
    r.teleport(DOCK[0] + offset[0], DOCK[1] + offset[1], DOCK[2] + offset[2])
    r.battery = 0.5
    run(r, 60.0)
    assert not r.charging
    assert r.battery == pytest.approx(0.5 - 60.0 / IDLE_DRAIN)
    msg = r.sensors._build_battery(0, 0.0)
    assert msg["power_supply_status"] == rb.BatteryStatus.DISCHARGING == 2 and msg["current"] < 0


def test_a_robot_given_a_dock_charges_there_and_not_at_home() -> None:
    home2 = WAYPOINTS["home2"]
    dock = (home2.x, home2.y, home2.yaw)
    r = robot(dock=dock)
    run(r, 1.0)
    assert r.dock == dock and not r.charging  # at home, which has no charger now
    r.teleport(*dock)
    run(r, 1.0)
    assert r.charging


async def test_docks_by_robot_pose_or_waypoint_and_every_dock_is_a_charger() -> None:
    home3 = WAYPOINTS["home3"]
    s = await start(2, docks={"r1": "home3", "r2": (1.0, 2.0, 0.5)})
    try:
        r1, r2 = s.robots
        assert r1.dock == (home3.x, home3.y, home3.yaw) and r2.dock == (1.0, 2.0, 0.5)
        assert not r1.charging
        r2.teleport(*r1.dock)  # another robot's dock charges it too
        await until(s, lambda: r2.charging, 5.0)
    finally:
        await shut(s)
    with pytest.raises(ValueError, match="no such robot"):
        await start_simulation(1, port=0, docks={"r9": "home1"})
    with pytest.raises(ValueError, match="no waypoint"):
        await start_simulation(1, port=0, docks={"r1": "kitchen9"})


def test_the_command_line_takes_docks_and_docking() -> None:
    p = argparse.ArgumentParser()
    add_sim_arguments(p)
    ns = p.parse_args(["--dock", "r1=4.0,10.8,1.57", "--dock", "r2=home2", "--docking"])
    assert ns.docking is True
    assert [parse_dock(d) for d in ns.dock] == [("r1", (4.0, 10.8, 1.57)), ("r2", "home2")]
    assert p.parse_args([]).dock == [] and p.parse_args([]).docking is False
    for bad in ("r1", "r1=", "=home1", "r1=1,2", "r1=a,b,c"):
        with pytest.raises(ValueError, match="--dock"):
            parse_dock(bad)
    assert asyncio.run(run_sim_from_args(p.parse_args(["--dock", "r1=1,2"]))) == 2
