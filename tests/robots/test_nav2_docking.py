"""A ROS 2 robot with a docking server (link option ``docking``) docks through opennav_docking's
``dock_robot`` and ``undock_robot`` (issue 32, item 5): the real driver against a simulated robot
running the docking server (``start_simulation(..., docking=True)``), and the result shapes
the driver reads, on plain frames.

What each test proves is in its name; the facts behind them (the actions' fields, error codes
and the server's phases) are in serveur.robots.ros2.messages' and serveur.sim.docking's
docstrings, read in Nav2's sources.
"""

from __future__ import annotations

import math
from collections.abc import AsyncIterator
from typing import Any

import pytest

from serveur.errors import LinkError
from serveur.maps.navigation import demo_map_path
from serveur.robot_sim import start_simulation
from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss
from serveur.robots.ros2 import messages as m2
from serveur.robots.ros2.link import Nav2Link
from serveur.sim.docking import STAGING_OFFSET, staging_pose
from tests.conftest import test_clock
from tests.robots.test_conformance import FAR, HOME, NEAR, SimRig, distance, up

TIME_SCALE = 20.0
DOCK = (HOME.x, HOME.y, HOME.yaw)  # home1: the simulated robot's charger
NOWHERE = (8.0, 5.0, 0.0)  # a free spot of the demo room with no charger


async def rig_for(docking: str = "nav2", **sim: Any) -> SimRig:
    clock = test_clock(TIME_SCALE)
    sim.setdefault("docking", True)
    s = await start_simulation(
        sim.pop("robots", 1),
        port=0,
        map_path=demo_map_path(),
        clock=clock,
        ros=2,
        amcl="real",
        **sim,
    )
    # Every spot the tests drive to planned once now: a goal's first plan (a distance field,
    # tens of milliseconds of CPU in a worker) would otherwise delay its acknowledgement by
    # seconds of this fast clock, and a loaded machine would see goals re-sent.
    spots = (NEAR, FAR, DOCK, staging_pose(*DOCK), staging_pose(*NOWHERE))
    await s.warm_plans([p[:2] for p in spots])
    made = SimRig(s, clock, 2, docking)
    made.driver.start()
    await up(made)
    return made


@pytest.fixture
async def rig() -> AsyncIterator[SimRig]:
    made = await rig_for()
    try:
        yield made
    finally:
        await made.close()


async def end_watching_goals(rig: SimRig, handle: str, seconds: float) -> dict[str, Any]:
    """Wait for goal ``handle``'s end; every navigate goal the robot listed meanwhile, by id
    (the robot forgets an ended goal after 5 s)."""
    seen: dict[str, Any] = {}

    def ended() -> bool:
        seen.update((g.id, g) for g in rig.sim.robots[0].navigator.goals)
        return bool(rig.rec.ends(handle))

    await rig.until(ended, seconds, "the goal's end")
    return seen


async def test_a_dock_drives_through_the_staging_pose_onto_the_charger(rig: SimRig) -> None:
    link = rig.driver
    assert isinstance(link, Nav2Link)
    far = await link.send_goal(*FAR)
    await rig.until(lambda: rig.rec.ends(far), 60.0, "the robot across the room")
    handle = await link.dock(*DOCK, "home1")
    # The drive back is long, and the docking server sends no feedback meanwhile: the goal
    # must not be taken for lost (ack timeout 3 s).
    seen = await end_watching_goals(rig, handle, 120.0)
    [(kind, (_, status, text))] = rig.rec.ends(handle)
    assert (kind, status, text) == ("done", rb.GoalStatus.SUCCEEDED, "Nav2 dock_robot SUCCEEDED")
    # Through Nav2 to the staging pose, 0.7 m in front of the dock, then onto the contacts.
    [staged] = [g for gid, g in seen.items() if gid.startswith("docking-staging-")]
    assert staged.status is rb.GoalStatus.SUCCEEDED
    assert math.dist((staged.x, staged.y), staging_pose(*DOCK)[:2]) < 1e-6
    assert distance(rig.where(), DOCK) < 0.05
    await rig.until(lambda: rig.charging(), 2.0, "the robot charging")
    assert not [k for k, _ in rig.rec.events if k == "lost"]


async def test_a_dock_where_there_is_no_charger_fails_with_its_error_code_in_words(
    rig: SimRig,
) -> None:
    handle = await rig.driver.dock(*NOWHERE, "nowhere")
    await rig.until(lambda: rig.rec.ends(handle), 120.0, "the dock's end")
    [(kind, (_, status, text))] = rig.rec.ends(handle)
    assert (kind, status) == ("done", rb.GoalStatus.ABORTED)
    assert text.startswith("Nav2 dock_robot ABORTED: failed to detect the dock (904)"), text
    # It tried: Nav2 took it to the staging pose in front of where the dock should be.
    assert distance(rig.where(), staging_pose(*NOWHERE)) < 0.1
    assert not rig.charging() and rig.driver.goal_id is None
    again = await rig.driver.dock(*DOCK, "home1")  # the link is fine: dock again
    await rig.until(lambda: rig.rec.ends(again), 120.0, "the second dock's end")
    assert rig.rec.ends(again)[0][1][1] is rb.GoalStatus.SUCCEEDED


async def test_undock_backs_the_robot_off_its_charger_before_the_next_goal(rig: SimRig) -> None:
    robot = rig.sim.robots[0]
    assert rig.charging()  # it starts on its dock
    await rig.driver.undock()  # returns once off the dock
    assert not robot.charging
    assert distance(rig.where(), DOCK) == pytest.approx(STAGING_OFFSET, abs=0.06)
    assert abs(math.remainder(rig.where()[2] - DOCK[2], math.tau)) < 0.06  # straight back
    await rig.driver.undock()  # not on a dock: the server aborts without a code; no error
    handle = await rig.driver.send_goal(*NEAR)
    await rig.until(lambda: rig.rec.ends(handle), 30.0, "the goal's end")
    assert rig.rec.ends(handle)[0][1][1] is rb.GoalStatus.SUCCEEDED


async def test_an_undock_that_fails_raises_with_the_servers_words() -> None:
    # Another robot right behind: the server cannot back off (FAILED_TO_CONTROL after its
    # max_undocking_time, 30 s).
    rig = await rig_for(robots=2)
    try:
        x, y, yaw = DOCK
        rig.sim.robots[1].teleport(x, y - 0.45, yaw)
        with pytest.raises(LinkError, match=r"could not leave its dock: .*failed to control"):
            await rig.driver.undock()
        assert rig.charging()  # still on the contacts
    finally:
        await rig.close()


async def test_a_humble_robot_docks_with_the_standalone_packages_types() -> None:
    rig = await rig_for("opennav", release="humble")
    try:
        away = await rig.driver.send_goal(*NEAR)
        await rig.until(lambda: rig.rec.ends(away), 30.0, "the robot away")
        handle = await rig.driver.dock(*DOCK, "home1")
        await rig.until(lambda: rig.rec.ends(handle), 60.0, "the dock's end")
        assert rig.rec.ends(handle)[0][1][1] is rb.GoalStatus.SUCCEEDED
    finally:
        await rig.close()


async def test_nav2s_types_on_a_humble_robot_are_a_goal_the_bridge_cannot_run() -> None:
    # Humble's docking server is the standalone package's (opennav_docking_msgs): rosbridge
    # cannot load nav2_msgs/action/DockRobot there, and says so at once.
    rig = await rig_for("nav2", release="humble")
    try:
        handle = await rig.driver.dock(*DOCK, "home1")
        await rig.until(lambda: rig.rec.ends(handle), 10.0, "the dock's end")
        [(kind, (_, reason, cause))] = rig.rec.ends(handle)
        assert (kind, cause) == ("lost", GoalLoss.NOT_ACCEPTED)
        assert "Nav2 dock_robot: the bridge could not run the goal" in reason
        assert "Unable to import action type" in reason
        with pytest.raises(LinkError, match="Unable to import action type"):
            await rig.driver.undock()
    finally:
        await rig.close()


async def test_without_the_option_a_dock_is_a_goal_to_the_dock_and_undock_nothing() -> None:
    rig = await rig_for("")
    try:
        away = await rig.driver.send_goal(*NEAR)
        await rig.until(lambda: rig.rec.ends(away), 30.0, "the robot away")
        handle = await rig.driver.dock(*DOCK, "home1")
        seen = await end_watching_goals(rig, handle, 60.0)
        [(_, (_, status, text))] = rig.rec.ends(handle)
        assert (status, text) == (rb.GoalStatus.SUCCEEDED, "Nav2 navigate_to_pose SUCCEEDED")
        assert handle in seen  # a navigate goal of the driver's own
        assert not [g for g in seen if g.startswith("docking-")]  # the server was never asked
        await rig.until(lambda: rig.charging(), 2.0, "the robot charging on its home")
        await rig.driver.undock()
        assert rig.charging()  # nothing was done
    finally:
        await rig.close()


# -- the results the driver reads ---------------------------------------------------------


def result(status: int, values: Any, **op: Any) -> dict[str, Any]:
    return {
        "op": "action_result",
        "action": "/dock_robot",
        "id": "g",
        "status": status,
        "values": values,
        "result": True,
        **op,
    }


@pytest.mark.parametrize(
    ("op", "status", "text"),
    [
        (
            result(4, {"success": True, "error_code": 0, "num_retries": 0}),
            rb.GoalStatus.SUCCEEDED,
            "Nav2 dock_robot SUCCEEDED",
        ),
        (
            result(6, {"success": False, "error_code": 904, "num_retries": 0, "error_msg": ""}),
            rb.GoalStatus.ABORTED,
            "Nav2 dock_robot ABORTED: failed to detect the dock (904)",
        ),
        (  # success false is a failure whatever the status says
            result(4, {"success": False, "error_code": 906}),
            rb.GoalStatus.ABORTED,
            "Nav2 dock_robot ABORTED: the robot did not start charging (906)",
        ),
        (  # Jazzy's error_msg is added; an older bridge nests the status and the result
            {
                "op": "action_result",
                "id": "g",
                "result": True,
                "values": {
                    "status": 6,
                    "result": {
                        "success": False,
                        "error_code": 903,
                        "error_msg": "Failed to navigate to staging pose",
                    },
                },
            },
            rb.GoalStatus.ABORTED,
            "Nav2 dock_robot ABORTED: failed to reach the staging pose (903): "
            "Failed to navigate to staging pose",
        ),
        (result(5, {"success": False}), rb.GoalStatus.PREEMPTED, "Nav2 dock_robot CANCELED"),
        (
            result(0, "boom", result=False),
            rb.GoalStatus.ABORTED,
            "Nav2 dock_robot failed on the bridge: boom",
        ),
    ],
)
def test_what_a_dock_result_says(op: dict[str, Any], status: rb.GoalStatus, text: str) -> None:
    assert m2.dock_outcome(op) == (status, text)


@pytest.mark.parametrize(
    ("op", "off"),
    [
        (result(4, {"success": True, "error_code": 0}), True),
        (result(6, {"success": False, "error_code": 0}), True),  # was not on a dock
        (result(6, {"success": False, "error_code": 905}), False),
        (result(6, {"success": False, "error_code": 902}), False),
        (result(5, {"success": False, "error_code": 0}), False),  # cancelled: still on it
        (result(0, "Unable to import action type", result=False), False),
    ],
)
def test_when_an_undock_leaves_the_robot_off_its_dock(op: dict[str, Any], off: bool) -> None:
    assert m2.undock_verdict(op)[0] is off


def test_the_dock_goal_the_driver_sends() -> None:
    op = m2.op_send_dock_goal(
        "/r2/dock_robot",
        "nav2_msgs/action/DockRobot",
        "id-1",
        4.0,
        10.8,
        math.pi / 2,
        dock_id="home1",
        frame_id="map",
        max_staging_time=300.0,
    )
    assert op["action"] == "/r2/dock_robot" and op["feedback"] is True
    args = op["args"]
    assert args["use_dock_id"] is False and args["navigate_to_staging_pose"] is True
    assert args["dock_pose"]["header"] == {"stamp": {"sec": 0, "nanosec": 0}, "frame_id": "map"}
    assert args["dock_pose"]["pose"] == rb.pose_msg(4.0, 10.8, math.pi / 2)
    assert set(args) == {
        "use_dock_id",
        "dock_id",
        "dock_pose",
        "dock_type",
        "max_staging_time",
        "navigate_to_staging_pose",
    }
    undock = m2.op_send_undock_goal(
        "/undock_robot", "nav2_msgs/action/UndockRobot", "id-2", max_undocking_time=30.0
    )
    assert undock["args"] == {"dock_type": "", "max_undocking_time": 30.0}
    assert undock["feedback"] is False  # UndockRobot has no feedback
