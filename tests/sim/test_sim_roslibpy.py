"""Conformance with the real roslibpy client: what works against a ROS1 robot works here.

roslibpy runs its own event loop in a thread (transport="asyncio", which, unlike Twisted, can be
started again after ``terminate()``, so each test gets its own ``Ros`` in this process). The
simulator runs on the test's loop; the roslibpy side of a test runs in a worker thread and
blocks on threading events with timeouts, never on sleeps.
"""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import AsyncIterator, Callable
from typing import Any, TypeVar

import pytest
import roslibpy
from roslibpy.ros1.actionlib import ActionClient, Goal

from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import rosbridge as rb

SCALE = 20.0
WAIT = 10.0  # wall seconds
T1 = (2.4, 9.7, -math.pi / 2)
FAR = (12.6, 1.6, 0.0)
R = TypeVar("R")


@pytest.fixture(params=["omni"])
async def sim(request: pytest.FixtureRequest) -> AsyncIterator[Simulation]:
    s = await start_simulation(1, port=0, time_scale=SCALE, seed=11, kinematics=request.param)
    try:
        yield s
    finally:
        await s.close()


def _with_ros(port: int, body: Callable[[roslibpy.Ros], R]) -> R:
    ros = roslibpy.Ros("127.0.0.1", port, transport="asyncio")
    ros.run(timeout=WAIT)
    try:
        return body(ros)
    finally:
        closed = threading.Event()
        ros.on("close", lambda *_: closed.set())
        ros.close()
        closed.wait(WAIT)  # else the server keeps a half-open socket for seconds
        ros.terminate()


async def with_ros(sim: Simulation, body: Callable[[roslibpy.Ros], R]) -> R:
    """Run ``body(ros)`` in a thread with a fresh roslibpy connection to robot 0."""
    port = int(sim.urls[0].rsplit(":", 1)[1])
    return await asyncio.to_thread(_with_ros, port, body)


class Latest:
    """A topic callback that keeps messages and lets the thread wait for the next one (after
    the last one a wait returned) that matches."""

    def __init__(self) -> None:
        self.msgs: list[dict[str, Any]] = []
        self._cond = threading.Condition()
        self._cursor = 0

    def __call__(self, msg: dict[str, Any]) -> None:
        with self._cond:
            self.msgs.append(msg)
            self._cond.notify_all()

    def wait(self, pred: Callable[[dict[str, Any]], bool] = lambda m: True) -> dict[str, Any]:
        with self._cond:
            deadline = time.monotonic() + WAIT
            while True:
                while self._cursor < len(self.msgs):
                    m = self.msgs[self._cursor]
                    self._cursor += 1
                    if pred(m):
                        return m
                left = deadline - time.monotonic()
                assert left > 0, "no matching message in time"
                self._cond.wait(left)


def _amcl_xy(m: dict[str, Any]) -> tuple[float, float]:
    p = m["pose"]["pose"]["position"]
    return p["x"], p["y"]


async def test_amcl_pose_and_latched_map(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> tuple[dict[str, Any], dict[str, Any], float]:
        poses, maps = Latest(), Latest()
        roslibpy.Topic(ros, "/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped").subscribe(
            poses
        )
        t0 = time.monotonic()
        roslibpy.Topic(ros, "/map", "nav_msgs/OccupancyGrid").subscribe(maps)
        grid = maps.wait()
        delay = time.monotonic() - t0
        return poses.wait(), grid, delay

    pose, grid, delay = await with_ros(sim, body)
    home = sim.robots[0].home
    assert math.dist(_amcl_xy(pose), home[:2]) < 0.1
    assert pose["header"]["frame_id"] == "map" and len(pose["pose"]["covariance"]) == 36
    info = grid["info"]
    assert len(grid["data"]) == info["width"] * info["height"]
    assert set(grid["data"]) <= {-1, 0, 100}
    assert delay < 1.0  # latched: handed over on subscribe, never re-published by itself


async def test_get_topics_and_get_time(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> tuple[list[str], float, float]:
        topics = ros.get_topics()
        t = ros.get_time()
        return topics, t.secs + t.nsecs * 1e-9, sim.clock.epoch()

    topics, t, epoch = await with_ros(sim, body)
    assert set(topics) == set(rb.TOPIC_TYPES)
    assert t == pytest.approx(epoch, abs=2.0)


async def test_cmd_vel_moves_the_robot_then_it_stops(sim: Simulation) -> None:
    start = sim.robots[0].pose

    def body(ros: roslibpy.Ros) -> tuple[dict[str, Any], dict[str, Any]]:
        poses, odom = Latest(), Latest()
        roslibpy.Topic(ros, "/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped").subscribe(
            poses
        )
        roslibpy.Topic(ros, "/odom", "nav_msgs/Odometry").subscribe(odom)
        poses.wait()
        cmd = roslibpy.Topic(ros, "/cmd_vel", "geometry_msgs/Twist")
        cmd.publish(roslibpy.Message(rb.twist(-0.4, 0.0, 0.0)))  # home faces a wall: back up
        moved = poses.wait(lambda m: _amcl_xy(m)[1] < start[1] - 0.06)
        odom.wait(lambda m: abs(m["twist"]["twist"]["linear"]["x"]) > 0.05)
        stopped = odom.wait(lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
        return moved, stopped

    moved, _ = await with_ros(sim, body)
    x, y, _ = sim.robots[0].pose
    assert y < start[1] - 0.06 and abs(x - start[0]) < 0.02
    assert sim.robots[0].velocity == (0.0, 0.0, 0.0)  # the stale command timed out
    assert abs(_amcl_xy(moved)[0] - start[0]) < 0.05


def _goal(client: ActionClient, x: float, y: float, yaw: float) -> Goal:
    target = rb.pose_stamped(x, y, yaw, stamp=time.time(), frame_id="map")
    return Goal(client, roslibpy.Message({"target_pose": target}))


def _client(ros: roslibpy.Ros) -> ActionClient:
    # Blocks until /move_base/status is heard, which the robot publishes even when idle.
    return ActionClient(ros, "/move_base", "move_base_msgs/MoveBaseAction")


@pytest.mark.parametrize("sim", ["omni", "diff"], indirect=True)
async def test_action_goal_succeeds_within_tolerance(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> tuple[Any, dict[str, Any], list[int]]:
        client = _client(ros)
        goal = _goal(client, *T1)
        seen: list[int] = []
        goal.on("status", lambda s: seen.append(s["status"]))
        feedback = threading.Event()
        goal.on("feedback", lambda f: feedback.set())
        goal.send()
        result = goal.wait(WAIT)
        assert feedback.is_set()
        return result, goal.status, seen

    result, status, seen = await with_ros(sim, body)
    assert result == {}  # MoveBaseResult is empty
    assert status["status"] == rb.GoalStatus.SUCCEEDED
    assert rb.GoalStatus.ACTIVE in seen
    x, y, yaw = sim.robots[0].pose
    assert math.hypot(x - T1[0], y - T1[1]) <= 0.1
    assert abs(math.remainder(yaw - T1[2], math.tau)) <= 0.1


def _reaches(goal: Goal, status: rb.GoalStatus) -> threading.Event:
    """Set when ``goal``'s status becomes ``status``.

    On a cancel the robot lists the goal PREEMPTING, then publishes the result and PREEMPTED
    (actionlib publishes the result first): roslibpy's ``Goal.wait`` returns on the result while
    ``goal.status`` may still be PREEMPTING, as it would against a real robot.
    """
    seen = threading.Event()
    goal.on("status", lambda s: s["status"] == status and seen.set())
    return seen


async def test_action_goal_cancel_is_preempted(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> list[int]:
        client = _client(ros)
        goal = _goal(client, *FAR)
        seen: list[int] = []
        goal.on("status", lambda s: seen.append(s["status"]))
        active = _reaches(goal, rb.GoalStatus.ACTIVE)
        preempted = _reaches(goal, rb.GoalStatus.PREEMPTED)
        goal.send()
        assert active.wait(WAIT)
        goal.cancel()
        goal.wait(WAIT)
        assert preempted.wait(WAIT)
        return seen

    seen = await with_ros(sim, body)
    assert rb.GoalStatus.PREEMPTING in seen  # ACTIVE -> PREEMPTING -> PREEMPTED
    assert math.dist(sim.robots[0].pose[:2], FAR[:2]) > 1.0


async def test_action_client_cancel_all_then_unreachable_goal_aborts(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> tuple[dict[str, Any], dict[str, Any]]:
        client = _client(ros)
        first = _goal(client, *FAR)
        active = _reaches(first, rb.GoalStatus.ACTIVE)
        preempted = _reaches(first, rb.GoalStatus.PREEMPTED)
        first.send()
        assert active.wait(WAIT)
        client.cancel()  # publishes {} on /move_base/cancel
        first.wait(WAIT)
        assert preempted.wait(WAIT)
        bad = _goal(client, 100.0, 100.0, 0.0)  # off the map
        bad.send()
        bad.wait(WAIT)
        return first.status, bad.status

    first, bad = await with_ros(sim, body)
    assert first["status"] == rb.GoalStatus.PREEMPTED
    assert bad["status"] == rb.GoalStatus.ABORTED and bad["text"]


async def test_initialpose_relocalises(sim: Simulation) -> None:
    target = (6.0, 8.0, 0.5)

    def body(ros: roslibpy.Ros) -> dict[str, Any]:
        poses = Latest()
        roslibpy.Topic(ros, "/amcl_pose", "geometry_msgs/PoseWithCovarianceStamped").subscribe(
            poses
        )
        poses.wait()
        init = roslibpy.Topic(ros, "/initialpose", "geometry_msgs/PoseWithCovarianceStamped")
        init.publish(roslibpy.Message(rb.pose_with_covariance_stamped(*target, stamp=time.time())))
        return poses.wait(lambda m: math.dist(_amcl_xy(m), target[:2]) < 0.1)

    msg = await with_ros(sim, body)
    assert rb.yaw_from_quaternion(msg["pose"]["pose"]["orientation"]) == pytest.approx(
        0.5, abs=0.05
    )
    x, y, yaw = sim.robots[0].pose
    assert (x, y) == pytest.approx(target[:2]) and yaw == pytest.approx(target[2])
