"""The three failures a real ROS 2 stack found (issue 27), against the real server and the
simulator, which models each point by point (shared/notes/ros2.md, "Liveness, measured on the
same stack"; serveur.sim.robot's ``stop_bridge_ros_side`` and ``kill_node``):

1. rosbridge stopped with SIGTERM/SIGINT keeps its websocket and answers every call
   ``result: false``: the robot was kept "alive" on those replies, its goal declared lost, the
   robot put in Error and the table blocked while it drove on. Now it is Offline, its trip
   kept, and it resumes once a new rosbridge runs.
2. The robot's node dead behind a live rosbridge and rosapi: a rosapi heartbeat kept it
   "alive", the next trip failed "not acknowledged after 3 attempts" and blocked a healthy
   table. Now the heartbeat is the navigator's lifecycle state: the robot is Offline and the
   trip waits for it (or another robot).
3. Failures read "move_base ABORTED: navigate_to_pose ABORTED...", and nothing said whether a
   lost goal was the link's fault or the way's: each driver's words name its stack, and a lost
   goal carries a typed cause (:class:`serveur.robots.driver.GoalLoss`).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest

from serveur.core.engine import CoreConfig
from serveur.maps.navigation import demo_map_path
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss
from serveur.robots.names import RosNames
from serveur.robots.ros1.link import RobotLink
from serveur.robots.ros2.link import Nav2Link
from serveur.sim.bridge import BridgeClient
from tests.conftest import Client, Restaurant, poll_until, restaurant, test_clock
from tests.robots.test_conformance import Recorder
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

CONFIG = CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=True)
#: Wall seconds the server is given to see a failure (its heartbeat is ~3 s of a 10x clock).
NOTICE = 20.0


@pytest.fixture
async def humble(tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=1, config=CONFIG, ros=2, release="humble") as r:
        yield r


def statuses_since(c: Client, robot: str, mark: int) -> list[str]:
    return [
        f["data"]["status"]
        for f in c.frames[mark:]
        if f["servermsg"] == "update" and f["topic"] == "robots" and f["data"]["name"] == robot
    ]


def blocked(c: Client) -> list[str]:
    return [t for t, b in c.records.get("blocks", {}).items() if b.get("reason")]


def speed(r: Restaurant) -> float:
    vx, vy, _ = r.sim.robots[0].velocity
    return math.hypot(vx, vy)


async def delivering(r: Restaurant, table: str) -> tuple[Client, list[int]]:
    c = await staff(r)
    await c.subscribe("blocks")
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", table))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    await poll_until(lambda: speed(r) > 0.1, 10, "the robot moving")
    return c, ids


@pytest.mark.cuts_links
async def test_a_bridge_whose_ros_side_stopped_takes_the_robot_offline_not_to_error(
    humble: Restaurant,
) -> None:
    c, ids = await delivering(humble, "T12")
    mark = len(c.frames)
    humble.sim.robots[0].stop_bridge_ros_side()
    robot = await c.status("r1", "Offline", timeout=NOTICE)
    assert "ROS side stopped" in robot["last_error"], robot["last_error"]
    assert "context is invalid" in robot["last_error"]
    assert "Error" not in statuses_since(c, "r1", mark)
    assert blocked(c) == []
    assert robot["current_task"] is not None  # the dishes stay with the robot
    assert c.order(ids[0])["status"] == "assigned"
    # A new rosbridge: the robot is back, the goal it drove on with is cancelled, the trip
    # resumes and ends at the table.
    await humble.sim.restart_rosbridge(0)
    assert (await serve_current_stop(c, "r1"))["table"] == "T12"
    await c.status("r1", "Awaiting")
    await c.until(lambda: c.order(ids[0]).get("status") == "delivered")
    assert "Error" not in statuses_since(c, "r1", mark)
    assert blocked(c) == []


@pytest.mark.cuts_links
async def test_a_dead_robot_node_behind_a_live_bridge_is_offline_and_its_trip_waits(
    humble: Restaurant,
) -> None:
    c = await staff(humble)
    await c.subscribe("blocks")
    await activate(c, "r1")
    mark = len(c.frames)
    humble.sim.robots[0].kill_node()
    robot = await c.status("r1", "Offline", timeout=NOTICE)
    assert "silent behind a live rosbridge" in robot["last_error"], robot["last_error"]
    # A trip made meanwhile is not given to a robot that cannot take it: it waits.
    ids = await new_orders(c, ("Laksa", "T12"))
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    humble.sim.robots[0].restart_node()
    assert (await serve_current_stop(c, "r1"))["table"] == "T12"
    await c.status("r1", "Awaiting")
    assert c.task(task["id"])["status"] == "done"
    seen = statuses_since(c, "r1", mark)
    assert "Error" not in seen, seen
    assert blocked(c) == []


@pytest.mark.cuts_links
async def test_a_robot_node_dying_mid_trip_is_offline_and_the_table_stays_open(
    humble: Restaurant,
) -> None:
    c, ids = await delivering(humble, "T12")
    mark = len(c.frames)
    humble.sim.robots[0].kill_node()
    robot = await c.status("r1", "Offline", timeout=NOTICE)
    assert robot["current_task"] is not None
    assert "Error" not in statuses_since(c, "r1", mark)
    assert blocked(c) == []
    humble.sim.robots[0].restart_node()
    assert (await serve_current_stop(c, "r1"))["table"] == "T12"
    await c.until(lambda: c.order(ids[0]).get("status") == "delivered")


# -- 3. the words and the cause, at the driver ------------------------------------------


async def until(cond: Callable[[], Any], what: str, timeout: float = 30.0) -> None:
    await poll_until(cond, timeout, what)


@pytest.fixture
async def nav2(
    monkeypatch: pytest.MonkeyPatch,
) -> AsyncIterator[tuple[Simulation, Nav2Link, Recorder, list[str]]]:
    """A Nav2 link to a simulated Jazzy robot; the list holds every goal id its bridge was
    asked to cancel (``cancel_action_goal``), whatever the navigator made of it."""
    cancels: list[str] = []
    original = BridgeClient._cancel_action_goal

    def record(self: BridgeClient, msg: Any, oid: str | int | None) -> None:
        cancels.append(str(msg.get("id")))
        original(self, msg, oid)

    monkeypatch.setattr(BridgeClient, "_cancel_action_goal", record)
    clock = test_clock(10.0)
    sim = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=clock, ros=2, release="jazzy", amcl="real"
    )
    rec = Recorder()
    link = Nav2Link("r1", sim.urls[0], rec, clock, ack_timeout=3.0, names=RosNames(ros=2))
    link.start()
    try:
        await until(lambda: link.up, "the link up")
        yield sim, link, rec, cancels
    finally:
        await link.close()
        await sim.close()


FAR = (12.6, 1.6, 0.0)  # T16


async def test_a_ros2_failure_names_nav2_and_a_lost_goal_says_why(
    nav2: tuple[Simulation, Nav2Link, Recorder, list[str]],
) -> None:
    sim, link, rec, cancels = nav2
    robot = sim.robots[0]
    robot.block_path(True)
    first = await link.send_goal(*FAR)
    await until(lambda: rec.of("done"), "the blocked goal's end")
    [(handle, status, text)] = rec.of("done")
    assert (handle, status) == (first, rb.GoalStatus.ABORTED)
    assert text.startswith("Nav2 navigate_to_pose ABORTED: path blocked"), text
    assert "move_base" not in text
    robot.block_path(False)
    robot.ignore_goals(True)
    second = await link.send_goal(*FAR)
    await until(lambda: rec.of("lost"), "the unacknowledged goal lost", 60.0)
    [(handle, reason, cause)] = rec.of("lost")
    assert handle == second and cause is GoalLoss.NOT_ACCEPTED
    assert reason.startswith("goal not acknowledged by Nav2 navigate_to_pose after 3 attempts")
    # Given up, and every id it went out under cancelled on the robot.
    sent = [gid for gid, st, _ in robot.goal_statuses if st is rb.GoalStatus.PENDING]
    assert len(sent) == 3
    await until(lambda: set(sent) <= set(cancels), "every id of the lost goal cancelled")


async def test_a_lost_goal_is_cancelled_on_the_robot(
    nav2: tuple[Simulation, Nav2Link, Recorder, list[str]],
) -> None:
    # Feedback stops and no result comes while the heartbeat answers, the robot away from
    # its goal: lost — and stopped, not left driving to a table serveur gave up on.
    sim, link, rec, cancels = nav2
    robot = sim.robots[0]
    handle = await link.send_goal(*FAR)
    await until(lambda: math.hypot(*robot.velocity[:2]) > 0.1, "the robot moving")
    for goal in sim._endpoints[0].actions.values():
        goal.feedback = False  # its feedback no longer reaches the link...
    robot.drop_results(1)  # ...nor will its result
    await until(lambda: rec.of("lost"), "the silent goal lost", 60.0)
    [(lost, reason, cause)] = rec.of("lost")
    assert lost == handle and cause is GoalLoss.NAVIGATION, reason
    assert "stopped sending feedback" in reason
    assert handle in cancels
    await until(lambda: math.hypot(*robot.velocity[:2]) < 0.01, "the robot stopped", 10.0)
    assert [s for _, s, _ in robot.goal_statuses][-1] is rb.GoalStatus.PREEMPTED


async def test_a_ros1_failure_names_move_base() -> None:
    clock = test_clock(10.0)
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), clock=clock, amcl="real")
    rec = Recorder()
    link = RobotLink("r1", sim.urls[0], rec, clock, ack_timeout=3.0)
    link.start()
    try:
        await until(lambda: link.up, "the link up")
        sim.robots[0].block_path(True)
        await link.send_goal(*FAR)
        await until(lambda: rec.of("done"), "the blocked goal's end")
        [(_, status, text)] = rec.of("done")
        assert status is rb.GoalStatus.ABORTED
        assert text.startswith("move_base ABORTED: path blocked"), text
    finally:
        await link.close()
        await sim.close()


async def test_staff_read_nav2s_words_for_a_ros2_robot(humble: Restaurant) -> None:
    c = await staff(humble)
    await activate(c, "r1")
    humble.sim.robots[0].block_path(True)
    ids = await new_orders(c, ("Laksa", "T12"))
    await c.ok("create", type="task", orders=ids)
    robot = await c.status("r1", "Error")
    assert robot["last_error"].startswith("Nav2 navigate_to_pose ABORTED"), robot["last_error"]
    await asyncio.sleep(0)


async def test_a_robot_that_never_comes_up_says_why_once() -> None:
    # The bridge accepts connections but its ROS side is dead from the start: the robot stays
    # Offline, and staff read why (link_failed, once), not nothing.
    clock = test_clock(10.0)
    sim = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=clock, ros=2, release="jazzy", amcl="real"
    )
    sim.robots[0].stop_bridge_ros_side()
    rec = Recorder()
    link = Nav2Link("r1", sim.urls[0], rec, clock, ack_timeout=3.0, names=RosNames(ros=2))
    link.start()
    try:
        await until(lambda: link.connects >= 3, "three sessions that never came up")
        [(reason,)] = rec.of("failed")
        assert reason.startswith("the robot never came up: the robot's ROS side stopped"), reason
        assert "context is invalid" in reason and link.last_failure == reason
        assert not link.up and rec.of("up") == []
        await sim.restart_rosbridge(0)
        await until(lambda: link.up, "the link up once a new rosbridge runs")
        assert link.last_failure == ""
    finally:
        await link.close()
        await sim.close()


@pytest.mark.cuts_links
@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
async def test_a_goal_left_running_by_a_dropped_link_is_cancelled_when_it_is_back(
    ros: int,
) -> None:
    # Closing a connection cancels nothing: the robot drives on with nobody watching. When
    # the link is back, the goal it was given is cancelled before anything else.
    clock = test_clock(10.0)
    sim = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=clock, ros=ros, amcl="real"
    )
    rec = Recorder()
    names = RosNames(ros=ros)
    link: RobotLink | Nav2Link = (
        Nav2Link("r1", sim.urls[0], rec, clock, names=names)
        if ros == 2
        else RobotLink("r1", sim.urls[0], rec, clock, names=names)
    )
    robot = sim.robots[0]
    link.start()
    try:
        await until(lambda: link.up, "the link up")
        await link.send_goal(*FAR)
        await until(lambda: math.hypot(*robot.velocity[:2]) > 0.1, "the robot moving")
        await sim.stop_endpoint(0)
        await until(lambda: not link.up, "the link down")
        assert math.hypot(*robot.velocity[:2]) > 0.1  # it drives on
        await sim.start_endpoint(0)
        await until(lambda: link.up, "the link back")
        await until(lambda: math.hypot(*robot.velocity[:2]) < 0.01, "the robot stopped")
        assert math.hypot(robot.pose[0] - FAR[0], robot.pose[1] - FAR[1]) > 1.0
        assert [s for _, s, _ in robot.goal_statuses][-1] is rb.GoalStatus.PREEMPTED
        assert rec.of("done") == [] and rec.of("lost") == []  # the core heard "down" instead
    finally:
        await link.close()
        await sim.close()
