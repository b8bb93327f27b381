"""The liveness-and-goal tracker both robot links share (issue 27, item 4), on plain numbers.

No socket, no event loop, no clock: each test passes the times in and reads the instructions
the tracker gives its link. Each rule here is one of serveur.robots.liveness's docstring, and
the liveness facts are the ones measured on a real ROS 2 stack (shared/notes/ros2.md).
"""

from __future__ import annotations

import itertools
from typing import Any

import pytest

from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss
from serveur.robots.liveness import (
    Cancel,
    DownCause,
    GoalDone,
    GoalLost,
    Instruction,
    LinkDown,
    LinkTracker,
    LinkUp,
    SendGoal,
)
from serveur.robots.ros2 import messages as m2

TIMEOUT = 2.0  # the link's heartbeat timeout
ACK = 2.0  # ack_timeout


def ros2(**kw: Any) -> LinkTracker:
    """A tracker set up as the ROS 2 link sets it up."""
    ids = (f"g{i}" for i in itertools.count(1))
    options: dict[str, Any] = {
        "stack": "Nav2 navigate_to_pose",
        "proofs_words": "answer from /bt_navigator/get_state, pose or battery",
        "required": frozenset({"heartbeat", "pose"}),
        "paced": "heartbeat",
        "ack_timeout": ACK,
        "ack_retries": 2,
        "new_id": lambda: next(ids),
        "confirmations": 3,
        "progress": True,
        "cancel_replaced": True,
        "unacked_words": " (no feedback)",
    }
    options.update(kw)
    return LinkTracker(**options)


def ros1() -> LinkTracker:
    ids = (f"g{i}" for i in itertools.count(1))
    return LinkTracker(
        stack="move_base",
        proofs_words="move_base status",
        required=frozenset({"status", "pose"}),
        paced="status",
        ack_timeout=ACK,
        ack_retries=2,
        new_id=lambda: next(ids),
    )


def up(t: LinkTracker, now: float = 0.0) -> None:
    t.start(now)
    paced = "heartbeat" if "heartbeat" in t._required else "status"
    t.proof(now, "pose")
    assert t.proof(now, paced) == [LinkUp()]
    assert t.up


def beat(t: LinkTracker, start: float, end: float, every: float = 0.5) -> list[Instruction]:
    """Heartbeat answers (proofs) from ``start`` to ``end``, the tracker checked after each."""
    out: list[Instruction] = []
    now = start
    while now <= end + 1e-9:
        out += t.proof(now, t._paced)
        out += t.check(now, TIMEOUT)
        now += every
    return out


# -- what proves the robot alive ---------------------------------------------------------


def test_up_needs_a_proof_of_life_and_a_pose() -> None:
    t = ros2()
    t.start(0.0)
    assert t.proof(0.1, "heartbeat") == []
    assert not t.up
    assert t.proof(0.2, "pose") == [LinkUp()]
    assert t.proof(0.3, "pose") == []  # said once


def test_a_refused_call_is_not_life_and_says_the_ros_side_stopped() -> None:
    # rosbridge after SIGTERM/SIGINT: socket open, every call answered result: false.
    t = ros2()
    up(t)
    now = 0.0
    for _ in range(4):
        now += 0.5
        t.refused(now, "rcl node's context is invalid")
        assert t.check(now, TIMEOUT) == []
    now += 0.5
    t.refused(now, "rcl node's context is invalid")
    [down] = t.check(now, TIMEOUT)
    assert isinstance(down, LinkDown) and down.report
    assert down.cause is DownCause.ROS_STOPPED
    assert "ROS side stopped" in down.reason and "context is invalid" in down.reason
    assert not t.up


def test_a_rosapi_answer_proves_the_bridge_not_the_robot() -> None:
    # The robot's node dead behind a live rosbridge: rosapi still answers.
    t = ros2()
    up(t)
    for now in (0.5, 1.0, 1.5, 2.0):
        t.bridge_answered(now)
        assert t.check(now, TIMEOUT) == []
    t.bridge_answered(2.5)
    [down] = t.check(2.5, TIMEOUT)
    assert isinstance(down, LinkDown) and down.cause is DownCause.ROBOT_GONE
    assert "silent behind a live rosbridge" in down.reason


def test_nothing_at_all_is_silence() -> None:
    t = ros1()
    up(t)
    assert t.check(2.0, TIMEOUT) == []
    [down] = t.check(2.1, TIMEOUT)
    assert down == LinkDown(
        "no move_base status for 2.1s", DownCause.SILENT, summary="no move_base status"
    )


def test_a_navigator_not_active_is_not_ready() -> None:
    t = ros2()
    up(t)
    alive, why, cause = m2.heartbeat_verdict(
        {
            "op": "service_response",
            "result": True,
            "values": {"current_state": {"id": 2, "label": "inactive"}},
        }
    )
    assert not alive
    t.refused(2.5, why, cause)
    [down] = t.check(2.5, TIMEOUT)
    assert isinstance(down, LinkDown) and down.cause is DownCause.NOT_READY
    assert "inactive, not active" in down.reason


def test_a_session_that_never_comes_up_is_aborted_without_a_report() -> None:
    t = ros2()
    t.start(0.0)
    t.refused(2.0, "rcl node's context is invalid")
    [down] = t.check(2.5, TIMEOUT)
    assert isinstance(down, LinkDown) and not down.report
    # Its summary is the same every time (the link says it once as a failure to connect).
    t.start(3.0)
    t.refused(5.2, "rcl node's context is invalid")
    [again] = t.check(5.7, TIMEOUT)
    assert isinstance(again, LinkDown) and again.summary == down.summary
    assert again.summary.startswith("the robot's ROS side stopped")


def test_a_robot_alive_but_never_localised_is_said_and_retried() -> None:
    t = ros2()
    t.start(0.0)
    assert beat(t, 0.5, 2.0) == []  # the heartbeat answers; no pose yet
    [down] = t.check(2.5, TIMEOUT)
    assert isinstance(down, LinkDown) and not down.report
    assert down.summary == "no pose from the robot"


def test_a_proof_keeps_the_link_up() -> None:
    t = ros2()
    up(t)
    assert beat(t, 0.5, 10.0) == []
    t.proof(11.0, "battery")  # any of the robot's own topics
    assert t.check(12.9, TIMEOUT) == []


@pytest.mark.parametrize(
    ("reply", "alive"),
    [
        ({"result": True, "values": {"current_state": {"id": 3, "label": "active"}}}, True),
        ({"result": True, "values": {"success": True, "message": ""}}, True),  # std_srvs/Trigger
        ({"result": True, "values": {"success": False, "message": "docking"}}, False),
        ({"result": False, "values": "rcl node's context is invalid"}, False),
        ({"result": False, "values": "Service /bt_navigator/get_state does not exist"}, False),
        ({"result": True, "values": {}}, False),
    ],
)
def test_what_a_heartbeat_reply_means(reply: dict[str, Any], alive: bool) -> None:
    assert m2.heartbeat_verdict({"op": "service_response", **reply})[0] is alive


# -- goals -------------------------------------------------------------------------------


def test_an_unacknowledged_goal_is_resent_then_lost_and_cancelled() -> None:
    t = ros2()
    up(t)
    goal, todo = t.new_goal(0.0, 1.0, 2.0, 0.0)
    assert todo == [] and goal.id == "g1"
    out = beat(t, 0.5, 2.5)
    assert out == [Cancel(("g1",)), SendGoal(goal)] and goal.id == "g2" and goal.attempts == 2
    out = beat(t, 3.0, 5.5)
    assert out == [Cancel(("g2",)), SendGoal(goal)] and goal.id == "g3"
    out = beat(t, 6.0, 9.0)
    [lost, cancel] = out
    assert lost == GoalLost(
        "g1",
        "goal not acknowledged by Nav2 navigate_to_pose after 3 attempts (no feedback)",
        GoalLoss.NOT_ACCEPTED,
    )
    assert cancel == Cancel(("g1", "g2", "g3"))  # every id it went out under
    assert t.goal is None


def test_silence_never_resends_a_goal() -> None:
    # A Wi-Fi stall says nothing about the goal: re-sending would preempt the one under way.
    t = ros1()
    up(t)
    t.new_goal(0.0, 1.0, 2.0, 0.0)
    assert t.check(1.9, TIMEOUT) == []
    assert t.goal is not None and t.goal.attempts == 1


def test_ros2_waits_for_three_heartbeats_past_the_deadline() -> None:
    # After a stall, queued heartbeat answers may come before the feedback of the goal
    # connection: one answer late is not enough.
    t = ros2()
    up(t)
    t.new_goal(0.0, 1.0, 2.0, 0.0)
    t.proof(3.0, "heartbeat")
    assert t.check(3.0, TIMEOUT) == []
    t.proof(3.0, "heartbeat")
    t.goal_progress(3.01, "g1")  # the feedback came after all
    t.proof(3.02, "heartbeat")
    assert t.check(3.02, TIMEOUT) == []
    assert t.goal is not None and t.goal.attempts == 1 and t.goal.acked


def test_ros1_acknowledges_by_the_status_list_and_ends_by_it() -> None:
    t = ros1()
    up(t)
    t.new_goal(0.0, 1.0, 2.0, 0.0)
    assert t.goal_state("g1", rb.GoalStatus.ACTIVE, "move_base ACTIVE") == []
    assert beat(t, 0.2, 6.0, 0.2) == []  # acknowledged: no re-send however long it drives
    done = t.goal_state("g1", rb.GoalStatus.ABORTED, "move_base ABORTED: path blocked")
    assert done == [GoalDone("g1", rb.GoalStatus.ABORTED, "move_base ABORTED: path blocked")]
    assert t.goal is None and t.recent == ()


def test_feedback_that_stops_away_from_the_goal_is_a_lost_goal_cancelled() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.goal_progress(0.2, "g1")
    out: list[Instruction] = []
    for now in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0):
        t.proof(now, "heartbeat")
        out += t.check(now, TIMEOUT, pose=(4.0, 2.0, 0.0))
    [lost, cancel] = out
    assert isinstance(lost, GoalLost) and lost.cause is GoalLoss.NAVIGATION
    assert lost.reason.startswith("Nav2 navigate_to_pose stopped sending feedback")
    assert cancel == Cancel(("g1",))


def test_feedback_that_stops_at_the_goal_is_an_arrival() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.goal_progress(0.2, "g1")
    out: list[Instruction] = []
    for now in (0.5, 1.0, 1.5, 2.0, 2.5, 3.0):
        t.proof(now, "heartbeat")
        out += t.check(now, TIMEOUT, pose=(10.1, 2.0, 0.0))
    [done] = out
    assert isinstance(done, GoalDone) and done.status is rb.GoalStatus.SUCCEEDED


def test_a_dock_goal_may_be_silent_while_nav2_drives_to_its_staging_pose() -> None:
    # opennav_docking sends one feedback as it starts the staging drive, then nothing until
    # the dock's perception: its goal's silence is believed only after its ``quiet``.
    t = ros2()
    up(t)
    goal, _ = t.new_goal(0.0, 4.0, 10.8, 1.57, dock_id="home1", stack="Nav2 dock_robot", quiet=30)
    assert (goal.dock_id, goal.stack) == ("home1", "Nav2 dock_robot")
    t.goal_progress(0.2, "g1")  # NAV_TO_STAGING_POSE: acknowledged
    assert beat(t, 0.5, 30.0) == []  # 30 s of silence: the staging drive
    [lost, cancel] = beat(t, 30.5, 34.0)
    assert isinstance(lost, GoalLost) and lost.cause is GoalLoss.NAVIGATION
    assert lost.reason.startswith("Nav2 dock_robot stopped sending feedback")
    assert cancel == Cancel(("g1",))


def test_a_dock_goal_is_resent_and_lost_in_its_own_servers_words() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 4.0, 10.8, 1.57, dock_id="home1", stack="Nav2 dock_robot", quiet=300)
    out = beat(t, 0.5, 20.0)  # no feedback at all: the quiet is not an ack's allowance
    assert [type(i).__name__ for i in out] == [
        "Cancel",
        "SendGoal",
        "Cancel",
        "SendGoal",
        "GoalLost",
        "Cancel",
    ]
    resent = out[1]
    assert isinstance(resent, SendGoal) and resent.goal.dock_id == "home1"
    lost = out[4]
    assert isinstance(lost, GoalLost) and lost.cause is GoalLoss.NOT_ACCEPTED
    assert lost.reason == "goal not acknowledged by Nav2 dock_robot after 3 attempts (no feedback)"


def test_a_link_going_down_cancels_the_goal_and_again_when_it_comes_back() -> None:
    # A goal nobody watches keeps running on the robot until someone cancels it.
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.goal_progress(0.5, "g1")
    out = t.check(3.0, TIMEOUT)
    assert out[0] == Cancel(("g1",))  # best effort, before the sockets are aborted
    assert isinstance(out[1], LinkDown) and t.goal is None
    # Nothing about the goal is reported: the core hears the link is down and keeps the trip.
    assert not [a for a in out if isinstance(a, GoalLost | GoalDone)]
    assert t.start(10.0) == [Cancel(("g1",))]
    # That session never came up (a bridge whose ROS side is dead carries no cancel): the
    # next one cancels again; once one comes up, the goal is not cancelled any more.
    assert t.start(20.0) == [Cancel(("g1",))]
    t.proof(20.1, "pose")
    assert t.proof(20.2, "heartbeat") == [LinkUp()]
    t.link_lost()
    assert t.start(30.0) == []


def test_a_closed_connection_keeps_the_goal_to_cancel_at_next_start() -> None:
    t = ros1()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.link_lost()
    assert not t.up and t.goal is None
    assert t.start(1.0) == [Cancel(("g1",))]


def test_a_goal_that_ended_is_not_cancelled_again() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.goal_state("g1", rb.GoalStatus.SUCCEEDED, "Nav2 navigate_to_pose SUCCEEDED")
    t.link_lost()
    assert t.start(1.0) == []


def test_a_replaced_goal_is_cancelled_first_on_ros2_only() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    _, todo = t.new_goal(1.0, 1.0, 2.0, 0.0)
    assert todo == [Cancel(("g1",))]
    # The replaced goal's abort (Nav2 aborts it for the new one) is not the new goal's end.
    assert t.goal_state("g1", rb.GoalStatus.ABORTED, "Nav2 navigate_to_pose ABORTED") == []
    t1 = ros1()
    up(t1)
    t1.new_goal(0.0, 10.0, 2.0, 0.0)
    assert t1.new_goal(1.0, 1.0, 2.0, 0.0)[1] == []  # move_base preempts by itself


def test_a_goal_the_bridge_could_not_run_is_lost_with_its_cause() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    [lost, cancel] = t.goal_failed("g1", "Action goal was rejected")
    assert isinstance(lost, GoalLost) and lost.cause is GoalLoss.NOT_ACCEPTED
    assert cancel == Cancel(("g1",))
    # The same while the bridge refuses every call: the link's fault, not the robot's.
    t.new_goal(1.0, 10.0, 2.0, 0.0)
    t.refused(1.1, "rcl node's context is invalid")
    [lost, _] = t.goal_failed("g2", "rcl node's context is invalid")
    assert isinstance(lost, GoalLost) and lost.cause is GoalLoss.LINK


def test_a_stop_forgets_the_goal_and_names_every_id_to_cancel() -> None:
    t = ros2()
    up(t)
    t.new_goal(0.0, 10.0, 2.0, 0.0)
    t.new_goal(1.0, 1.0, 2.0, 0.0)
    assert t.cancelled() == ("g1", "g2") and t.goal is None


def test_nothing_can_be_judged_before_the_silence_limit_unless_a_goal_is_out() -> None:
    """What lets a parked robot's watchdog sleep for seconds instead of polling 8 times per
    timeout (issue 31: an idle server's wake-ups): :meth:`LinkTracker.quiet_until` is never
    later than the first time :meth:`LinkTracker.check` says something."""
    t = ros1()
    t.start(10.0)
    assert t.quiet_until(TIMEOUT) == 12.0  # before up: the session's start
    t.proof(10.5, "status")
    assert t.quiet_until(TIMEOUT) == 12.0  # still not up: not ready by 12.0 either
    t.proof(10.6, "pose")
    assert t.up and t.quiet_until(TIMEOUT) == 12.6
    for now in (11.0, 12.0, 12.6):
        assert t.check(now, TIMEOUT) == []  # nothing before it...
    assert isinstance(t.check(12.61, TIMEOUT)[-1], LinkDown)  # ...and the limit is the limit
    t = ros1()
    t.start(0.0)
    t.proof(0.1, "status")
    t.proof(0.1, "pose")
    t.new_goal(0.2, 1.0, 2.0, 0.0)
    assert t.quiet_until(TIMEOUT) is None  # a goal's ack is judged as proofs come
