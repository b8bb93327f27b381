"""Is the robot alive, and where is its goal: the one tracker both robot links use (pure).

A link (:mod:`serveur.robots.ros1.link`, :mod:`serveur.robots.ros2.link`) reads frames and
writes ops; what those frames *mean* for the robot's liveness and for the goal under way is
decided here, once, on times the link passes in (no I/O, no asyncio, no clock of its own: a
test drives it with plain numbers). Each call returns the :data:`Instruction` objects the link
must carry out, in order: report the link up or down, (re-)send the goal, cancel goal ids on
the robot, report a goal done or lost.

**What proves the robot alive** is a *proof* (:meth:`LinkTracker.proof`): something the
robot's own ROS nodes sent. ROS1: move_base's status list (several a second even when idle)
and AMCL's pose. ROS 2: an answer of the robot's heartbeat service that says it is ready
(Nav2's ``/bt_navigator/get_state`` answering ``active``), the robot's topics (pose, battery,
scan) and our goal's feedback. What does *not* prove it (measured on a Jazzy stack,
shared/notes/ros2.md, "Liveness, measured on the same stack"):

* a ``service_response`` with ``result: false``: rosbridge stopped with SIGTERM or SIGINT
  keeps its websocket open and answers *every* call so ("rcl node's context is invalid") —
  a *refusal* (:meth:`LinkTracker.refused`), which only words the reason the link goes down;
* a rosapi answer: rosapi lives in rosbridge's process and answers (it even lists a dead node
  for ~18 s) while the robot's node is dead — it proves the *bridge*
  (:meth:`LinkTracker.bridge_answered`), which again only words the reason;
* any other frame of the bridge.

**Down.** No proof for the link's heartbeat timeout and the link is down
(:class:`LinkDown`), with a reason staff can act on (:class:`DownCause`): nothing at all came
(the network, a robot switched off), the robot's ROS side stopped (refusals), the robot's nodes
are silent behind a live bridge (rosapi answers), or Nav2 is not active. The goal under way
is given up and cancelled on the robot, best effort (the link may not carry the cancel); its
ids are kept and cancelled again at the start of each next session
(:meth:`LinkTracker.start`) until one comes up, before any new goal: a goal nobody watches
keeps running on the robot until someone cancels it (shared/notes/ros2.md). The core, told
the link is down, takes the robot Offline and keeps its trip (hand-over after a while), so a
link failure never fails a trip nor blocks a table.

**A goal** is acknowledged by the robot (ROS1: its id in move_base's status list; ROS 2: its
feedback) within ``ack_timeout`` of *proven life* after it was sent: the robot answering other
things while our goal is not seen. A link that is silent says nothing about the goal (a Wi-Fi
stall), so silence never re-sends. ``confirmations`` paced proofs (ROS1: one status list;
ROS 2: three heartbeat answers) must also have come: after a stall, a connection's queued
frames arrive in a burst and time alone would misjudge a goal whose acknowledgement travels on
another connection. Not acknowledged: re-sent under a new id (the old one cancelled), and after
``ack_retries`` re-sends lost (:attr:`GoalLoss.NOT_ACCEPTED`). With ``progress`` (ROS 2: Nav2
sends feedback while it drives), feedback that stops for as long with no result means the
result was lost (about once in 200 goals on the measured stack): a robot at the goal has
arrived, elsewhere the goal is lost (:attr:`GoalLoss.NAVIGATION`). **Every lost goal is
cancelled on the robot** (:class:`Cancel` follows every :class:`GoalLost`): a goal serveur
has given up on must not drive on to a table.

A goal may be one of another action of the same robot (a dock, :attr:`TrackedGoal.dock_id`:
opennav_docking's ``dock_robot``): the same rules hold, in its own server's words
(:attr:`TrackedGoal.stack`); a server whose progress comes in bursts says how long it may be
silent while it works (:attr:`TrackedGoal.quiet`: the docking server reports nothing while
Nav2 drives the robot to the dock's staging pose).
"""

from __future__ import annotations

import math
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass, field
from enum import Enum
from typing import Final

from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss

__all__ = [
    "RECENT_GOALS",
    "Cancel",
    "DownCause",
    "GoalDone",
    "GoalLost",
    "Instruction",
    "LinkDown",
    "LinkTracker",
    "LinkUp",
    "SendGoal",
    "TrackedGoal",
]

#: Goal ids remembered for cancelling (goals of an earlier session may still run).
RECENT_GOALS: Final = 8
#: A robot this close to its goal when the result never came has arrived (metres).
ARRIVED_WITHOUT_RESULT: Final = 0.5


class DownCause(Enum):
    """Why the link went down, for the words staff read."""

    #: Nothing at all from the robot or its bridge: the network, or the robot switched off.
    SILENT = "silent"
    #: The bridge answers, but refuses every call: its ROS side stopped (rosbridge after
    #: SIGTERM/SIGINT keeps its websocket and answers ``result: false``).
    ROS_STOPPED = "ros_stopped"
    #: The bridge (rosapi) answers; the robot's own nodes do not: the robot's node died.
    ROBOT_GONE = "robot_gone"
    #: The robot answers but says it cannot take goals (Nav2's navigator not ``active``).
    NOT_READY = "not_ready"


@dataclass(frozen=True, slots=True)
class LinkUp:
    """The robot is alive and localised: report the link up."""


@dataclass(frozen=True, slots=True)
class LinkDown:
    """Abort the connections (a dead path never answers a closing handshake) and reconnect;
    if ``report`` (the link was up), report it down with ``reason``; else the session never
    came up, and ``summary`` (the reason without its timing, the same every time) says why."""

    reason: str
    cause: DownCause
    report: bool = True
    summary: str = ""


@dataclass(frozen=True, slots=True)
class SendGoal:
    """Send the goal under its current id (a re-send)."""

    goal: TrackedGoal


@dataclass(frozen=True, slots=True)
class Cancel:
    """Cancel these goal ids on the robot (best effort: an unknown id is ignored)."""

    ids: tuple[str, ...]


@dataclass(frozen=True, slots=True)
class GoalDone:
    """Report the goal's end: ``text`` says it in its stack's own words."""

    handle: str
    status: rb.GoalStatus
    text: str


@dataclass(frozen=True, slots=True)
class GoalLost:
    """Report the goal lost, and why (a :class:`Cancel` of its ids comes with it)."""

    handle: str
    reason: str
    cause: GoalLoss


Instruction = LinkUp | LinkDown | SendGoal | Cancel | GoalDone | GoalLost


@dataclass(slots=True)
class TrackedGoal:
    """One goal: ``handle`` is what callers hold, ``id`` what is on the wire now."""

    handle: str
    id: str
    x: float
    y: float
    yaw: float
    sent_at: float
    attempts: int = 1
    acked: bool = False
    #: Since when its silence is judged: when it was (re-)sent, or its last progress.
    mark: float = 0.0
    #: Paced proofs since ``mark``.
    proofs: int = 0
    ids: list[str] = field(default_factory=list)
    #: Its server in reports ("Nav2 dock_robot"); the tracker's ``stack`` by default.
    stack: str = ""
    #: Clock seconds its server may send no progress, once it took the goal, beyond the ack
    #: timeout (a progress tracker's): 0 for a server that reports continuously.
    quiet: float = 0.0
    #: A dock goal (:meth:`~serveur.robots.driver.RobotDriver.dock`): the dock's name, and the
    #: link sends it to its docking server; None for a goal to a pose.
    dock_id: str | None = None


class LinkTracker:
    """One robot link's liveness and goal, decided on times passed in (see the module).

    ``stack`` names the goal's server in reports ("move_base", "Nav2 navigate_to_pose");
    ``proofs_words`` what proves the robot alive, for the reason of a silent link;
    ``required``: the proof kinds needed before the link is up (alive *and* localised);
    ``paced``: the kind that comes at a steady rate (ROS1 status, ROS 2 heartbeat), which
    counts towards ``confirmations``; ``progress``: the goal reports progress continuously
    (its silence is a lost result); ``cancel_replaced``: cancel a goal a new one replaces
    (a Humble bridge queues the new one behind it otherwise); ``new_id``: fresh goal ids.
    """

    def __init__(
        self,
        *,
        stack: str,
        proofs_words: str,
        required: frozenset[str],
        paced: str,
        ack_timeout: float,
        ack_retries: int,
        new_id: Callable[[], str],
        confirmations: int = 1,
        progress: bool = False,
        cancel_replaced: bool = False,
        unacked_words: str = "",
    ) -> None:
        self.stack = stack
        self._proofs_words = proofs_words
        self._required = required
        self._paced = paced
        self._ack_timeout = ack_timeout
        self._ack_retries = ack_retries
        self._new_id = new_id
        self._confirmations = confirmations
        self._progress = progress
        self._cancel_replaced = cancel_replaced
        self._unacked_words = unacked_words
        self.up = False
        self.goal: TrackedGoal | None = None
        self._heard: set[str] = set()
        self._alive_at = self._started = 0.0
        self._paced_at = -math.inf
        self._bridge_at = -math.inf
        self._refusal: tuple[float, str, DownCause] | None = None
        self._recent: deque[str] = deque(maxlen=RECENT_GOALS)
        self._stale: tuple[str, ...] = ()  # cancelled at this session's start

    # -- liveness ------------------------------------------------------------------------

    def start(self, now: float) -> list[Instruction]:
        """A session starts (connections just opened): nothing heard yet; goals of ours
        that may still run on the robot are cancelled before anything else is sent (at each
        start until a session comes up)."""
        self.up = False
        self._heard.clear()
        self._alive_at = self._started = now
        self._paced_at = self._bridge_at = -math.inf
        self._refusal = None
        # Cancelled at every start until a session comes up: sent to a bridge whose ROS side
        # is dead, a cancel goes nowhere, and the goal drives on until a live one carries it.
        self._stale = tuple(self._recent)
        return [Cancel(self._stale)] if self._stale else []

    def proof(self, now: float, kind: str, *, fresh: bool = True) -> list[Instruction]:
        """The robot's own nodes sent something of ``kind`` ("status", "pose", "heartbeat",
        "battery", "feedback"...): it is alive. ``fresh`` False: a message rosbridge held in
        a throttled queue and sent later counts for what it says, not as a sign of life now
        (its delivery time is not when the robot sent it)."""
        if fresh:
            self._alive_at = now
        self._heard.add(kind)
        if kind == self._paced:
            self._paced_at = now
            if self.goal is not None:
                self.goal.proofs += 1
        if not self.up and self._required <= self._heard:
            self.up = True
            for gid in self._stale:  # this session's bridge carried their cancels
                self._forget(gid)
            self._stale = ()
            return [LinkUp()]
        return []

    def refused(self, now: float, detail: str, cause: DownCause = DownCause.ROS_STOPPED) -> None:
        """An answer that is not life: a call answered ``result: false``, a navigator not
        active. Only words the reason if the link goes down."""
        self._refusal = (now, detail, cause)

    def bridge_answered(self, now: float) -> None:
        """The bridge itself answered (rosapi): it is alive, whatever the robot is."""
        self._bridge_at = now

    def silent(self, now: float, longer_than: float) -> bool:
        """Nothing proved the robot alive for ``longer_than`` seconds."""
        return now - self._alive_at > longer_than

    def check(
        self, now: float, timeout: float, pose: tuple[float, float, float] | None = None
    ) -> list[Instruction]:
        """The periodic judgement: the link down after ``timeout`` without proof, else the
        goal's acknowledgement and progress (``pose``: the robot's last, for a lost result)."""
        silence = now - self._alive_at
        if silence > timeout:
            summary, cause = self._why()
            reason = f"{summary} for {silence:.1f}s"
            goal, self.goal = self.goal, None
            out: list[Instruction] = [Cancel(tuple(goal.ids))] if goal is not None else []
            out.append(LinkDown(reason, cause, report=self.up, summary=summary))
            self.up = False
            return out
        if not self.up and now - self._started > timeout:
            # Alive but not all there (no pose: AMCL not localised): a fresh session
            # subscribes again, and the reason is said.
            missing = " or ".join(sorted(self._required - self._heard))
            summary = f"no {missing} from the robot"
            return [
                LinkDown(
                    f"{summary} for {now - self._started:.1f}s",
                    DownCause.NOT_READY,
                    report=False,
                    summary=summary,
                )
            ]
        return self._check_goal(now, pose)

    def quiet_until(self, timeout: float) -> float | None:
        """The earliest time :meth:`check` with ``timeout`` could say anything, whatever
        proofs come meanwhile (they only push it later): the silence limit from the last
        proof and, before the link is up, from the session's start. None while a goal is
        tracked: its acknowledgement and progress are judged as the paced proofs come."""
        if self.goal is not None:
            return None
        until = self._alive_at + timeout
        if not self.up:
            until = min(until, self._started + timeout)
        return until

    def _why(self) -> tuple[str, DownCause]:
        """Why the robot is silent, in words that do not change from one time to the next."""
        refusal = self._refusal
        if refusal is not None and refusal[0] >= self._alive_at:
            _, detail, cause = refusal
            if cause is DownCause.ROS_STOPPED:
                return (
                    f"the robot's ROS side stopped: its rosbridge answers calls with an "
                    f"error ({detail}) and nothing came from the robot",
                    cause,
                )
            return detail, cause
        if self._bridge_at >= self._alive_at:
            return (
                f"the robot's ROS nodes are silent behind a live rosbridge: no "
                f"{self._proofs_words}",
                DownCause.ROBOT_GONE,
            )
        return f"no {self._proofs_words}", DownCause.SILENT

    def link_lost(self) -> None:
        """The connection closed (or the server stops): the goal is given up without a
        report (the core hears the link is down); its ids stay to cancel at next start."""
        self.up = False
        self.goal = None

    # -- goals ---------------------------------------------------------------------------

    @property
    def recent(self) -> tuple[str, ...]:
        """Goal ids sent and not known to have ended, oldest first."""
        return tuple(self._recent)

    def new_goal(
        self,
        now: float,
        x: float,
        y: float,
        yaw: float,
        *,
        dock_id: str | None = None,
        stack: str = "",
        quiet: float = 0.0,
    ) -> tuple[TrackedGoal, list[Instruction]]:
        """A goal to send (the link sends it under ``goal.id``), after the instructions.

        ``dock_id``, ``stack`` and ``quiet`` describe a goal of another action (a dock): see
        :class:`TrackedGoal`."""
        out: list[Instruction] = []
        old = self.goal
        if old is not None and self._cancel_replaced:
            out.append(Cancel(tuple(old.ids)))
        gid = self._new_id()
        goal = TrackedGoal(
            gid,
            gid,
            x,
            y,
            yaw,
            now,
            mark=now,
            ids=[gid],
            stack=stack or self.stack,
            quiet=max(0.0, quiet),
            dock_id=dock_id,
        )
        self.goal = goal
        self._recent.append(gid)
        return goal, out

    def goal_progress(self, now: float, gid: object) -> None:
        """Feedback for goal id ``gid``: our goal is accepted and under way."""
        goal = self.goal
        if goal is not None and gid == goal.id:
            goal.acked = True
            goal.mark = now
            goal.proofs = 0

    def goal_state(self, gid: str, status: rb.GoalStatus, text: str) -> list[Instruction]:
        """Goal ``gid`` is in ``status`` (ROS1 status lists and results, ROS 2 results);
        ``text``: its end in its stack's words. A goal we replaced or gave up is ignored."""
        goal = self.goal
        if status in rb.TERMINAL_STATUSES:
            self._forget(gid)
        if goal is None or gid != goal.id:
            return []
        goal.acked = True
        if status not in rb.TERMINAL_STATUSES:
            return []
        self.goal = None
        for i in goal.ids:
            self._forget(i)
        return [GoalDone(goal.handle, status, text)]

    def goal_failed(self, gid: str, reason: str) -> list[Instruction]:
        """The bridge could not run goal ``gid`` (ROS 2 ``action_result`` with ``result``
        false: an exception, or with rosbridge's 2026 fix a goal refused or unserved). Lost:
        for the link's sake (:attr:`GoalLoss.LINK`) when the bridge is refusing calls too,
        else because the robot did not take it."""
        goal = self.goal
        if goal is None or gid != goal.id:
            return []
        self.goal = None
        refusal = self._refusal
        failing = refusal is not None and refusal[0] >= self._alive_at
        cause = GoalLoss.LINK if failing else GoalLoss.NOT_ACCEPTED
        return [GoalLost(goal.handle, reason, cause), Cancel(tuple(goal.ids))]

    def cancelled(self) -> tuple[str, ...]:
        """Our goal is cancelled (a Stop): forget it; the ids to cancel on the robot."""
        self.goal = None
        return tuple(self._recent)

    def _forget(self, gid: str) -> None:
        if gid in self._recent:
            self._recent.remove(gid)

    def _check_goal(self, now: float, pose: tuple[float, float, float] | None) -> list[Instruction]:
        goal = self.goal
        if (
            goal is None
            or goal.proofs < self._confirmations
            or self._paced_at - goal.mark <= self._ack_timeout
        ):
            return []
        if not goal.acked:
            return self._resend(now, goal)
        if not self._progress or self._paced_at - goal.mark <= self._ack_timeout + goal.quiet:
            return []
        # Progress stopped and no result came while the robot answered: where is it?
        self.goal = None
        if pose is not None and math.hypot(pose[0] - goal.x, pose[1] - goal.y) <= (
            ARRIVED_WITHOUT_RESULT
        ):
            for i in goal.ids:
                self._forget(i)
            text = f"{goal.stack} SUCCEEDED (no result came; the robot is at the goal)"
            return [GoalDone(goal.handle, rb.GoalStatus.SUCCEEDED, text)]
        reason = f"{goal.stack} stopped sending feedback away from the goal and no result came"
        return [GoalLost(goal.handle, reason, GoalLoss.NAVIGATION), Cancel(tuple(goal.ids))]

    def _resend(self, now: float, goal: TrackedGoal) -> list[Instruction]:
        if goal.attempts > self._ack_retries:
            self.goal = None
            reason = (
                f"goal not acknowledged by {goal.stack} after {goal.attempts} attempts"
                f"{self._unacked_words}"
            )
            return [GoalLost(goal.handle, reason, GoalLoss.NOT_ACCEPTED), Cancel(tuple(goal.ids))]
        old = goal.id
        goal.id = self._new_id()
        goal.ids.append(goal.id)
        self._recent.append(goal.id)
        goal.attempts += 1
        goal.sent_at = goal.mark = now
        goal.proofs = 0
        return [Cancel((old,)), SendGoal(goal)]
