"""A simulated ROS 2 robot (``ros=2``) against what rosbridge 2.x and Nav2 really do.

Each fact of shared/notes/ros2.md the simulator models has a test here that fails if the
simulator ignored it; the rules' sources are in serveur.sim.ros2's, serveur.sim.robot's and
serveur.sim.bridge's docstrings. Every test talks to a simulated robot over a real websocket.
Nothing sleeps to wait: each wait reads frames until a condition holds, with a wall-clock
timeout; only the two "nothing ever comes" facts wait a short, bounded wall time for silence.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import os
import signal
import sys
from collections.abc import AsyncIterator
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur.clock import ScaledClock
from serveur.robot_sim import Simulation, add_sim_arguments, start_simulation
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from tests.sim.test_sim_badinput import FAR, T1, Raw, open_raw, shut

SCALE = 20.0
NAV = "/navigate_to_pose"
TYPE = "nav2_msgs/action/NavigateToPose"
SILENCE = 0.5  # wall seconds a test waits to see that nothing comes (only where nothing should)


async def start(n: int = 1, **kw: Any) -> Simulation:
    kw.setdefault("ros", 2)
    kw.setdefault("amcl", "real")
    return await start_simulation(n, port=0, clock=ScaledClock(SCALE), seed=5, **kw)


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start()
    try:
        yield s
    finally:
        await shut(s)


@pytest.fixture
async def humble() -> AsyncIterator[Simulation]:
    """Humble: rosbridge 2.0 with send_action_goals_in_new_thread false (the queue trap)."""
    s = await start(release="humble")
    try:
        yield s
    finally:
        await shut(s)


def goal_args(x: float, y: float, yaw: float, frame: str = "map") -> dict[str, Any]:
    stamp = {"sec": 0, "nanosec": 0}
    return {
        "pose": {"header": {"stamp": stamp, "frame_id": frame}, "pose": rb.pose_msg(x, y, yaw)},
        "behavior_tree": "",
    }


def send_goal(
    gid: str | None,
    at: tuple[float, float, float],
    *,
    feedback: bool = False,
    action: str = NAV,
    action_type: str = TYPE,
    args: Any = None,
) -> dict[str, Any]:
    op: dict[str, Any] = {
        "op": "send_action_goal",
        "action": action,
        "action_type": action_type,
        "args": goal_args(*at) if args is None else args,
        "feedback": feedback,
    }
    if gid is not None:
        op["id"] = gid
    return op


def cancel_goal(gid: str, action: str = NAV) -> dict[str, Any]:
    return {"op": "cancel_action_goal", "action": action, "id": gid}


async def result(c: Raw, gid: str) -> dict[str, Any]:
    return await c.wait_for(lambda m: m["op"] == "action_result" and m.get("id") == gid)


async def feedback(c: Raw, gid: str) -> dict[str, Any]:
    op = await c.wait_for(lambda m: m["op"] == "action_feedback" and m.get("id") == gid)
    return op["values"]  # type: ignore[no-any-return]


def ops_about(c: Raw, gid: str) -> list[str]:
    """The ops of every frame received so far that carried ``gid``."""
    out = []
    for f in c.frames:
        m = json.loads(f)
        if m.get("id") == gid:
            out.append(m["op"])
    return out


async def ping2(c: Raw, rid: str = "ping") -> dict[str, Any]:
    """A get_time round trip; a ROS 2 rosapi answers builtin_interfaces/Time."""
    await c.send(rb.op_call_service("/rosapi/get_time", id=rid))
    reply = await c.wait_for(lambda m: m["op"] == "service_response" and m.get("id") == rid)
    assert reply["result"] is True and set(reply["values"]["time"]) == {"sec", "nanosec"}
    return reply


def xy(pose_msg: dict[str, Any]) -> tuple[float, float]:
    p = pose_msg["pose"]["pose"]["position"]
    return p["x"], p["y"]


def is_ros2_header(h: dict[str, Any]) -> bool:
    return set(h) == {"stamp", "frame_id"} and set(h["stamp"]) == {"sec", "nanosec"}


# -- navigate_to_pose: the ops --------------------------------------------------------------


async def test_goal_gets_feedback_then_succeeded_and_no_acknowledgement(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(send_goal("g1", T1, feedback=True))
    first = await feedback(c, "g1")
    later = await feedback(c, "g1")
    assert set(first) == {
        "current_pose",
        "navigation_time",
        "estimated_time_remaining",
        "number_of_recoveries",
        "distance_remaining",
    }
    assert is_ros2_header(first["current_pose"]["header"])
    assert first["current_pose"]["header"]["frame_id"] == "map"
    assert set(first["navigation_time"]) == {"sec", "nanosec"}
    assert first["distance_remaining"] > 0.5 and first["number_of_recoveries"] == 0
    t = [
        v["navigation_time"]["sec"] + v["navigation_time"]["nanosec"] * 1e-9 for v in (first, later)
    ]
    assert t[1] > t[0]
    res = await result(c, "g1")
    assert res == {
        "op": "action_result",
        "action": NAV,
        "id": "g1",
        "values": {"error_code": 0, "error_msg": ""},  # Jazzy's NavigateToPose result
        "status": ros2.SUCCEEDED,
        "result": True,
    }
    ops = ops_about(c, "g1")
    assert ops[0] == "action_feedback" and ops[-1] == "action_result"  # no acknowledgement
    assert set(ops) == {"action_feedback", "action_result"}
    x, y, _ = sim.robots[0].pose
    assert math.hypot(x - T1[0], y - T1[1]) <= 0.1
    # The robot lists the goal under the id the client gave it.
    assert sim.robots[0].goal_statuses[-1][:2] == ("g1", rb.GoalStatus.SUCCEEDED)


async def test_no_feedback_unless_asked_and_humble_result_is_empty() -> None:
    s = await start(release="humble", humble_queue=False)
    try:
        c = await open_raw(s)
        await c.send(send_goal("quiet", T1, action_type="nav2_msgs/NavigateToPose"))
        res = await result(c, "quiet")
        assert res["status"] == ros2.SUCCEEDED and res["result"] is True
        assert res["values"] == {"result": {}}  # Humble: std_msgs/Empty result
        assert ops_about(c, "quiet") == ["action_result"]
    finally:
        await shut(s)


async def test_cancel_gives_canceled_and_an_unknown_cancel_nothing(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(cancel_goal("nobody"))  # silently ignored
    await c.send(send_goal("far", FAR, feedback=True))
    await feedback(c, "far")
    await c.send(cancel_goal("far"))
    res = await result(c, "far")
    assert res["status"] == ros2.CANCELED and res["result"] is True
    assert ops_about(c, "nobody") == []
    assert math.dist(sim.robots[0].pose[:2], FAR[:2]) > 1.0


async def test_a_new_goal_aborts_the_active_one(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(send_goal("a", FAR, feedback=True))
    await feedback(c, "a")
    await c.send(send_goal("b", T1))
    a = await result(c, "a")
    assert a["status"] == ros2.ABORTED and a["result"] is True
    b = await result(c, "b")
    assert b["status"] == ros2.SUCCEEDED


async def test_a_goal_the_robot_cannot_take_gets_no_frame_at_all(sim: Simulation) -> None:
    c = await open_raw(sim, level="error")
    await c.send(send_goal("offmap", (100.0, 100.0, 0.0)))
    nan = goal_args(*T1)
    nan["pose"]["pose"]["position"]["x"] = None  # NaN travels as null
    await c.send(send_goal("nan", T1, args=nan))
    await c.send(send_goal("odom", T1, args=goal_args(*T1, frame="odom")))
    await c.send(send_goal("ok", T1))
    assert (await result(c, "ok"))["status"] == ros2.SUCCEEDED
    for gid in ("offmap", "nan", "odom"):
        assert ops_about(c, gid) == []
    assert not any(json.loads(f)["op"] == "status" for f in c.frames)


async def test_with_rosbridges_fix_rejected_and_unserved_goals_fail_and_free_the_queue() -> None:
    s = await start(release="humble", rosbridge_fix=True)
    try:
        c = await open_raw(s)
        await c.send(send_goal("offmap", (100.0, 100.0, 0.0)))
        await c.send(send_goal("nobody", T1, action="/follow_waypoints"))
        await c.send(rb.op_call_service("/rosapi/get_time", id="after"))
        for gid, text in (("offmap", "rejected"), ("nobody", "No action server")):
            res = await result(c, gid)
            assert res["result"] is False and res["status"] == 0 and text in res["values"]
        await c.wait_for(lambda m: m.get("id") == "after")  # the queue trap let go of both
    finally:
        await shut(s)


async def test_unknown_action_type_fails_and_an_unserved_action_is_silent(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(send_goal("typo", T1, action_type="nav2_msgs/action/NavigateToPlace"))
    bad = await result(c, "typo")
    assert bad["result"] is False and bad["status"] == 0 and isinstance(bad["values"], str)
    await c.send(send_goal("nobody", T1, action="/follow_waypoints"))
    await c.send(send_goal("ok", T1))
    assert (await result(c, "ok"))["status"] == ros2.SUCCEEDED
    assert ops_about(c, "nobody") == []


async def test_malformed_action_ops_answer_errors_and_hold_nothing(humble: Simulation) -> None:
    c = await open_raw(humble, level="error")
    await c.send({"op": "send_action_goal", "id": "b1", "action_type": TYPE})  # no action
    assert (await c.wait_for(lambda m: m["op"] == "status"))["id"] == "b1"
    await c.send({"op": "cancel_action_goal", "id": "b2"})
    assert (await c.wait_for(lambda m: m["op"] == "status"))["id"] == "b2"
    await c.send(send_goal("b3", T1, args={"pose": "T1"}))  # rosbridge cannot fill the goal
    bad = await result(c, "b3")
    assert bad["result"] is False and bad["status"] == 0 and "pose" in bad["values"]
    await ping2(c)  # and the connection is not held


async def test_ids_are_global_and_closing_does_not_cancel(sim: Simulation) -> None:
    a, b = await open_raw(sim), await open_raw(sim)
    # A cancel from another connection cancels by id; the result goes to the goal's sender.
    await a.send(send_goal("shared-1", FAR, feedback=True))
    await feedback(a, "shared-1")
    await b.send(cancel_goal("shared-1"))
    assert (await result(a, "shared-1"))["status"] == ros2.CANCELED
    # A goal whose sender went away drives on to its end.
    await b.send(rb.op_subscribe("/amcl_pose"))
    await a.send(send_goal("orphan", T1, feedback=True))
    await feedback(a, "orphan")
    await a.ws.close()
    await b.topic("/amcl_pose", lambda m: math.dist(xy(m), T1[:2]) < 0.3)
    assert ops_about(b, "orphan") == []


async def test_namespaced_robot_serves_its_own_action() -> None:
    s = await start(namespaced=True)
    try:
        c = await open_raw(s)
        await c.send(send_goal("bare", T1))  # /navigate_to_pose: nobody serves it here
        await c.send(send_goal("ns", T1, action="/r1/navigate_to_pose"))
        res = await result(c, "ns")
        assert res["status"] == ros2.SUCCEEDED and res["action"] == "/r1/navigate_to_pose"
        assert ops_about(c, "bare") == []
        await c.send(rb.op_call_service("/rosapi/action_servers", id="as"))
        reply = await c.wait_for(lambda m: m.get("id") == "as")
        assert reply["values"] == {"action_servers": ["/r1/navigate_to_pose"]}
    finally:
        await shut(s)


# -- the queue trap (send_action_goals_in_new_thread false) ------------------------------------


async def test_queue_trap_holds_the_connection_until_arrival(humble: Simulation) -> None:
    robot = humble.robots[0]
    c, other = await open_raw(humble), await open_raw(humble)
    await c.send(send_goal("held", FAR, feedback=True))  # far: it drives ~1 s of wall time
    await feedback(c, "held")
    await c.send(cancel_goal("held"))  # waits behind the goal
    await c.send(rb.op_call_service("/rosapi/get_time", id="behind"))
    await ping2(other, "free")  # another connection is not held
    assert robot.goal_statuses[-1][1] == rb.GoalStatus.ACTIVE
    res = await result(c, "held")
    assert res["status"] == ros2.SUCCEEDED  # the cancel came too late
    await c.wait_for(lambda m: m.get("id") == "behind")
    order = [json.loads(f).get("id") for f in c.frames]
    assert max(i for i, g in enumerate(order) if g == "held") < order.index("behind")


async def test_queue_trap_a_second_goal_waits_but_another_connection_preempts(
    humble: Simulation,
) -> None:
    c, other = await open_raw(humble), await open_raw(humble)
    await c.send(send_goal("a", FAR, feedback=True))
    await feedback(c, "a")
    now = goal_args(*T1)
    now["pose"]["header"]["stamp"] = "now"  # rosbridge fills "now" (and {secs, nsecs}) in
    await c.send(send_goal("b", T1, args=now))  # same connection: waits for "a" to end
    old = goal_args(*T1)
    old["pose"]["header"]["stamp"] = {"secs": 0, "nsecs": 0}
    await other.send(send_goal("c", T1, args=old, feedback=True))  # preempts "a" at once
    assert (await result(c, "a"))["status"] == ros2.ABORTED
    assert (await result(other, "c"))["status"] == ros2.ABORTED  # then "b" came through
    assert (await result(c, "b"))["status"] == ros2.SUCCEEDED


async def test_queue_trap_cmd_vel_waits_but_a_cancel_from_elsewhere_works(
    humble: Simulation,
) -> None:
    robot = humble.robots[0]
    c, other = await open_raw(humble), await open_raw(humble)
    await c.send(send_goal("far", FAR, feedback=True))
    await feedback(c, "far")
    await c.send(rb.op_publish("/cmd_vel", rb.twist(0.3, 0.0, 0.0)))  # held behind the goal
    await ping2(other)
    assert robot.state.teleop is None and len(humble._endpoints[0].clients) == 2
    await other.send(cancel_goal("far"))
    assert (await result(c, "far"))["status"] == ros2.CANCELED
    await ping2(c)  # queued after the twist
    assert robot.state.teleop == (0.3, 0.0, 0.0)  # handled only once the goal ended: it drives


async def test_without_the_trap_a_cancel_on_the_same_connection_is_at_once(
    sim: Simulation,
) -> None:
    c = await open_raw(sim)
    await c.send(send_goal("g", FAR, feedback=True))
    await feedback(c, "g")
    await c.send(cancel_goal("g"))
    assert (await result(c, "g"))["status"] == ros2.CANCELED


async def test_queue_trap_a_rejected_goal_wedges_the_connection(humble: Simulation) -> None:
    c, other = await open_raw(humble), await open_raw(humble)
    await c.send(send_goal("offmap", (100.0, 100.0, 0.0)))
    await c.send(rb.op_call_service("/rosapi/get_time", id="stuck"))
    await ping2(other)
    with pytest.raises(TimeoutError):
        await c.wait_for(lambda m: True, limit=SILENCE)


# -- topics: ROS 2 shapes, AMCL, teleop ------------------------------------------------------


async def test_amcl_pose_is_latched_sparse_and_ros2_shaped(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/amcl_pose"))
    first = await c.topic("/amcl_pose")  # parked: only the latched pose comes
    assert is_ros2_header(first["header"]) and first["header"]["frame_id"] == "map"
    assert len(first["pose"]["covariance"]) == 36
    await c.send(send_goal("g", FAR))
    poses = [first]
    while True:
        op = await c.wait_for(
            lambda m: m.get("topic") == "/amcl_pose" or m["op"] == "action_result"
        )
        if op["op"] == "action_result":
            break
        poses.append(op["msg"])
    steps = []
    for p, q in itertools.pairwise(poses):
        turn = abs(
            math.remainder(
                rb.yaw_from_quaternion(q["pose"]["pose"]["orientation"])
                - rb.yaw_from_quaternion(p["pose"]["pose"]["orientation"]),
                math.tau,
            )
        )
        if turn < 0.15:  # published for distance, not for turning
            steps.append(math.dist(xy(p), xy(q)))
    assert len(steps) > 5
    # Nav2 amcl: after 0.25 m (ROS1 amcl's 0.2 m would put the median near 0.23 m)
    assert sorted(steps)[len(steps) // 2] > 0.25 and min(steps) > 0.21
    late = await open_raw(sim)  # a new subscriber gets the last pose at once
    await late.send(rb.op_subscribe("/amcl_pose"))
    assert xy(await late.topic("/amcl_pose")) == xy(poses[-1])


async def test_goal_pose_topic_drives_the_robot_like_rviz2(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.topic("/amcl_pose")
    await c.send(rb.op_publish("/goal_pose", goal_args(*T1)["pose"]))
    await c.topic("/amcl_pose", lambda m: math.dist(xy(m), T1[:2]) < 0.3)
    assert not any(json.loads(f)["op"].startswith("action_") for f in c.frames)


async def test_initialpose_outside_map_frame_is_ignored_without_error(sim: Simulation) -> None:
    c = await open_raw(sim, level="error")
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.topic("/amcl_pose")
    home = sim.robots[0].pose
    for frame in ("odom", ""):
        msg = ros2.to_ros2(rb.pose_with_covariance_stamped(6.0, 8.0, 0.5, stamp=0.0))
        msg["header"]["frame_id"] = frame
        await c.send(rb.op_publish("/initialpose", msg))
    await ping2(c)
    assert sim.robots[0].pose == home
    good = ros2.to_ros2(rb.pose_with_covariance_stamped(6.0, 8.0, 0.5, stamp=0.0))
    await c.send(rb.op_publish("/initialpose", good))
    await c.topic("/amcl_pose", lambda m: math.dist(xy(m), (6.0, 8.0)) < 0.1)
    assert not any(json.loads(f)["op"] == "status" for f in c.frames)


async def test_cmd_vel_twist_drives_when_idle_then_the_watchdog_stops_it(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_call_service("/rosapi/topic_type", args={"topic": "/cmd_vel"}, id="t"))
    assert (await c.wait_for(lambda m: m.get("id") == "t"))["values"] == {
        "type": "geometry_msgs/msg/Twist"
    }
    await c.send(rb.op_subscribe("/odom"))
    y0 = sim.robots[0].pose[1]
    await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.0)))
    await c.topic("/odom", lambda m: abs(m["twist"]["twist"]["linear"]["x"]) > 0.05)
    await c.topic("/odom", lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
    assert sim.robots[0].pose[1] < y0 - 0.02


async def test_cmd_vel_is_ignored_while_a_goal_drives(sim: Simulation) -> None:
    robot = sim.robots[0]
    c = await open_raw(sim)
    await c.send(send_goal("g", FAR, feedback=True))
    await feedback(c, "g")
    for i in range(3):
        await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.7)))
        await ping2(c, f"p{i}")  # handled
        assert robot.navigator.active is not None and robot.state.teleop is None
    assert (await result(c, "g"))["status"] == ros2.SUCCEEDED
    assert math.hypot(robot.pose[0] - FAR[0], robot.pose[1] - FAR[1]) <= 0.1


async def test_twist_stamped_switch() -> None:
    s = await start(twist_stamped=True)
    try:
        c = await open_raw(s, level="error")
        await c.send(rb.op_call_service("/rosapi/topic_type", args={"topic": "/cmd_vel"}, id="t"))
        reply = await c.wait_for(lambda m: m.get("id") == "t")
        assert reply["values"] == {"type": "geometry_msgs/msg/TwistStamped"}
        await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.0)) | {"id": "plain"})
        err = await c.wait_for(lambda m: m["op"] == "status")
        assert err["id"] == "plain" and "does not have a field" in err["msg"]
        assert s.robots[0].state.teleop is None
        await c.send(rb.op_subscribe("/odom"))
        stamped = {"header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "base_link"}}
        stamped["twist"] = rb.twist(-0.4, 0.0, 0.0)
        await c.send(rb.op_publish("/cmd_vel", stamped))
        await c.topic("/odom", lambda m: abs(m["twist"]["twist"]["linear"]["x"]) > 0.05)
    finally:
        await shut(s)


async def test_battery_scan_map_and_rosapi_are_ros2_shaped(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/map"))
    grid = await c.topic("/map")  # latched: handed over on subscribe
    assert is_ros2_header(grid["header"]) and set(grid["info"]["map_load_time"]) == {
        "sec",
        "nanosec",
    }
    # Types in either spelling (rosbridge's loaders take both).
    await c.send(rb.op_subscribe("/battery_state", "sensor_msgs/msg/BatteryState"))
    await c.send(rb.op_subscribe("/scan", "sensor_msgs/LaserScan"))
    bat = await c.topic("/battery_state")
    assert 0.0 <= bat["percentage"] <= 1.0 and bat["power_supply_status"] in (1, 2, 3, 4)
    assert bat["temperature"] is None  # unmeasured: NaN -> null
    assert is_ros2_header(bat["header"])
    scan = await c.topic("/scan")
    assert is_ros2_header(scan["header"]) and len(scan["ranges"]) == 360
    await c.send(rb.op_call_service("/rosapi/topics", id="topics"))
    topics = (await c.wait_for(lambda m: m.get("id") == "topics"))["values"]
    types = dict(zip(topics["topics"], topics["types"], strict=True))
    assert types["/amcl_pose"] == "geometry_msgs/msg/PoseWithCovarianceStamped"
    assert types["/battery_state"] == "sensor_msgs/msg/BatteryState"
    assert not any(t.startswith("/move_base") for t in types)
    reply = await ping2(c)
    assert reply["values"]["time"]["sec"] == pytest.approx(sim.robots[0].epoch(), abs=2.0)


# -- fault hooks --------------------------------------------------------------------------------


async def test_block_path_aborts_with_nav2_error_code(sim: Simulation) -> None:
    sim.robots[0].block_path(True)
    c = await open_raw(sim)
    await c.send(send_goal("blocked", T1))
    res = await result(c, "blocked")
    assert res["status"] == ros2.ABORTED and res["result"] is True
    assert res["values"]["error_code"] == ros2.NO_VALID_PATH and res["values"]["error_msg"]


async def test_ignore_goals_and_drop_results(sim: Simulation) -> None:
    robot = sim.robots[0]
    c = await open_raw(sim)
    robot.ignore_goals(True)
    await c.send(send_goal("hung", T1))
    await ping2(c)
    assert [(g, st) for g, st, _ in robot.goal_statuses] == [("hung", rb.GoalStatus.PENDING)]
    robot.ignore_goals(False)
    robot.drop_results(1)
    await c.send(send_goal("lost", FAR, feedback=True))
    await feedback(c, "lost")
    await c.send(send_goal("next", T1))  # aborts "lost", whose result is dropped
    assert (await result(c, "next"))["status"] == ros2.SUCCEEDED
    assert ops_about(c, "hung") == []
    assert "action_result" not in ops_about(c, "lost")


# -- fleets and the command line ------------------------------------------------------------


async def test_mixed_fleet_ros1_and_ros2() -> None:
    s = await start(2, ros=[1, 2])
    try:
        one, two = await open_raw(s, 0, level="error"), await open_raw(s, 1)
        await one.send(send_goal("g", T1) | {"id": "g"})
        err = await one.wait_for(lambda m: m["op"] == "status")
        assert err["id"] == "g" and "unknown op" in err["msg"]  # rosbridge 0.11
        await one.send(rb.op_subscribe("/move_base/status"))
        await one.topic("/move_base/status")
        await two.send(send_goal("g", T1))
        assert (await result(two, "g"))["status"] == ros2.SUCCEEDED
        assert [r.ros for r in s.robots] == [1, 2]
    finally:
        await shut(s)


def test_start_simulation_checks_ros() -> None:
    with pytest.raises(ValueError, match="ros"):
        asyncio.run(start_simulation(2, port=0, ros=[1]))
    with pytest.raises(ValueError, match="release"):
        asyncio.run(start_simulation(1, port=0, ros=2, release="iron"))


def test_cli_options_parse() -> None:
    import argparse

    p = argparse.ArgumentParser()
    add_sim_arguments(p)
    ns = p.parse_args(["--ros", "1,2", "--release", "humble", "--no-humble-queue"])
    assert (ns.ros, ns.release, ns.humble_queue, ns.twist_stamped) == ("1,2", "humble", False, None)


async def test_sim_command_serves_ros2() -> None:
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "sim",
        "--robots",
        "2",
        "--port",
        "0",
        "--ros",
        "1,2",
        "--twist-stamped",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        assert proc.stdout is not None
        urls: list[str] = []
        while len(urls) < 2:  # the URLs, between log lines
            line = (await asyncio.wait_for(proc.stdout.readline(), 30)).decode().strip()
            assert line, "serveur sim ended before printing its URLs"
            if line.startswith("ws://"):
                urls.append(line)
        types = []
        for url in urls:
            async with connect(url) as ws:
                await ws.send(
                    json.dumps(
                        rb.op_call_service("/rosapi/topic_type", args={"topic": "/cmd_vel"}, id=1)
                    )
                )
                types.append(json.loads(await asyncio.wait_for(ws.recv(), 10))["values"]["type"])
        assert types == ["geometry_msgs/Twist", "geometry_msgs/msg/TwistStamped"]
        proc.send_signal(signal.SIGINT)
        assert await asyncio.wait_for(proc.wait(), 20) in (0, 130)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
