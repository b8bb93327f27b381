"""Real third-party ROS 2 clients against a simulated ROS 2 robot: roslibpy's
``roslibpy.ActionClient`` (in this process, on its own thread, as in test_sim_roslibpy.py) and
roslibjs (npm ``roslib`` 2.x, under Node, in a subprocess: tests/node/nav_goal.mjs).

The Node test needs ``node`` and tests/node's packages: without ``node`` it is skipped, except
in CI (``$CI`` set), where it fails, as tests/mariadb_server.py does for ``mariadbd``; missing
packages are installed with ``npm ci`` into the git-ignored tests/node/node_modules.
"""

from __future__ import annotations

import asyncio
import json
import math
import os
import shutil
import subprocess
import threading
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import roslibpy

from serveur.clock import ScaledClock
from serveur.robot_sim import Simulation, start_simulation
from tests.sim.test_sim_badinput import FAR, T1
from tests.sim.test_sim_roslibpy import WAIT, with_ros

SCALE = 20.0
NODE_DIR = Path(__file__).resolve().parents[1] / "node"


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    # The default (continuous) AMCL here: test_sim_ros2.py runs the "real" one.
    s = await start_simulation(1, port=0, clock=ScaledClock(SCALE), seed=3, ros=2)
    try:
        yield s
    finally:
        await s.close()


def _goal(x: float, y: float, yaw: float) -> roslibpy.Goal:
    pose = {
        "header": {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "map"},
        "pose": {
            "position": {"x": x, "y": y, "z": 0.0},
            "orientation": {"x": 0.0, "y": 0.0, "z": math.sin(yaw / 2), "w": math.cos(yaw / 2)},
        },
    }
    return roslibpy.Goal({"pose": pose, "behavior_tree": ""})


class Outcome:
    """What roslibpy's callbacks saw of one goal."""

    def __init__(self) -> None:
        self.feedback: list[dict[str, Any]] = []
        self.first_feedback = threading.Event()
        self.result: dict[str, Any] | None = None
        self.error: dict[str, Any] | None = None

    def on_result(self, r: Any) -> None:
        self.result = dict(r)

    def on_feedback(self, f: Any) -> None:
        self.feedback.append(dict(f))
        self.first_feedback.set()

    def on_error(self, e: Any) -> None:
        self.error = dict(e)


def _client(ros: roslibpy.Ros) -> roslibpy.ActionClient:
    return roslibpy.ActionClient(ros, "/navigate_to_pose", "nav2_msgs/action/NavigateToPose")


async def test_roslibpy_action_client_goal_succeeds_with_feedback(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> Outcome:
        client, out = _client(ros), Outcome()
        gid = client.send_goal(_goal(*T1), out.on_result, out.on_feedback, out.on_error)
        client.wait_goal(gid, timeout=WAIT)
        return out

    out = await with_ros(sim, body)
    assert out.error is None and out.result is not None
    assert out.result["status"] == roslibpy.GoalStatus.SUCCEEDED
    assert out.result["values"] == {"error_code": 0, "error_msg": ""}
    assert out.feedback and out.feedback[0]["distance_remaining"] > 0.0
    x, y, _ = sim.robots[0].pose
    assert math.hypot(x - T1[0], y - T1[1]) <= 0.1


async def test_roslibpy_action_client_cancel_is_canceled(sim: Simulation) -> None:
    def body(ros: roslibpy.Ros) -> Outcome:
        client, out = _client(ros), Outcome()
        gid = client.send_goal(_goal(*FAR), out.on_result, out.on_feedback, out.on_error)
        assert out.first_feedback.wait(WAIT)
        client.cancel_goal(gid)
        client.wait_goal(gid, timeout=WAIT)
        return out

    out = await with_ros(sim, body)
    assert out.error is None and out.result is not None  # result true: not an error
    assert out.result["status"] == roslibpy.GoalStatus.CANCELED
    assert math.dist(sim.robots[0].pose[:2], FAR[:2]) > 1.0


# -- roslibjs under Node ------------------------------------------------------------------------


@pytest.fixture(scope="module")
def node() -> str:
    """The ``node`` binary, with tests/node's packages installed."""

    def missing(what: str) -> None:
        if os.environ.get("CI"):
            pytest.fail(f"the Node test must run in CI: {what} (.ci/run installs nodejs and npm)")
        pytest.skip(what)

    exe = shutil.which("node")
    if exe is None:
        missing("node not found: the roslibjs test needs Debian's nodejs package")
    if not (NODE_DIR / "node_modules" / "roslib").is_dir():
        npm = shutil.which("npm")
        if npm is None:
            missing("tests/node has no node_modules and npm is not found: apt-get install npm")
        subprocess.run(
            [npm, "ci", "--no-audit", "--no-fund", "--silent"],
            cwd=NODE_DIR,
            check=True,
            timeout=300,
        )
    assert exe is not None
    return exe


async def roslibjs(node: str, url: str, at: tuple[float, float, float], *mode: str) -> list[Any]:
    proc = await asyncio.create_subprocess_exec(
        node,
        str(NODE_DIR / "nav_goal.mjs"),
        url,
        *(str(v) for v in at),
        *mode,
        cwd=NODE_DIR,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        out, err = await asyncio.wait_for(proc.communicate(), 30)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
    assert proc.returncode == 0, (out.decode(), err.decode())
    return [json.loads(line) for line in out.decode().splitlines()]


async def test_roslibjs_action_goal_succeeds(sim: Simulation, node: str) -> None:
    events = await roslibjs(node, sim.urls[0], T1)
    sent, fb, last = events[0], events[1], events[-1]
    assert sent["event"] == "sent" and sent["id"].startswith("send_action_goal:/navigate_to_pose:")
    assert (
        fb["event"] == "feedback" and fb["feedback"]["current_pose"]["header"]["frame_id"] == "map"
    )
    assert last["event"] == "result" and last["result"] == {"error_code": 0, "error_msg": ""}
    x, y, _ = sim.robots[0].pose
    assert math.hypot(x - T1[0], y - T1[1]) <= 0.1


async def test_roslibjs_action_goal_cancel(sim: Simulation, node: str) -> None:
    events = await roslibjs(node, sim.urls[0], FAR, "cancel")
    last = events[-1]
    # roslibjs calls the failed callback for any status but SUCCEEDED (CANCELED here).
    assert last["event"] == "failed" and "Action was canceled" in last["error"]
    assert last["feedbacks"] >= 1
    assert math.dist(sim.robots[0].pose[:2], FAR[:2]) > 1.0
