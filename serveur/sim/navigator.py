"""A simulated robot's move_base (or Nav2 navigator): a goal's life, its plan, its end.

Split from :mod:`serveur.sim.robot`: what happens to a goal once the action server took it
(:mod:`serveur.sim.inbox` has the rules for taking it) — planned off the event loop, followed,
cancelled (RECALLED, PREEMPTING then PREEMPTED), ended with move_base's result and status or,
on a ROS 2 robot, with the rosbridge goal's ``action_result`` (SUCCEEDED 4, CANCELED 5,
ABORTED 6 with Nav2's error code) — and replanned from a new pose after ``/initialpose``.
:class:`Navigator` owns the goals and the path being followed; the robot's control cycle
(:mod:`serveur.sim.robot`) drives it, the floor (:mod:`serveur.sim.floor`) waits on and plans
around other robots on its path (:class:`Wait`, reset with each new path).
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import math
import threading
from dataclasses import dataclass
from typing import Any, Final

from serveur.errors import ServeurError
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.kinematics import Kind, Limits, PathFollower
from serveur.sim.outbox import Outbox
from serveur.sim.state import Goal, RobotState
from serveur.sim.topics import consume_exception

__all__ = ["LAST_CANCEL_CANCELED", "SAS_ACCEPTED", "SAS_CANCELED", "Navigator", "Wait"]

#: actionlib SimpleActionServer's texts (simple_action_server.py), word for word.
SAS_CANCELED: Final = (
    "This goal was canceled because another goal was received by the simple action server"
)
SAS_ACCEPTED: Final = "This goal has been accepted by the simple action server"
#: actionlib ActionServer's text for a goal stamped at or before the last cancel's stamp.
LAST_CANCEL_CANCELED: Final = (
    "This goal handle was canceled by the action server because its timestamp is before the "
    "timestamp of the last cancel request"
)


@dataclass(slots=True)
class Wait:
    """The robot's wait for other robots in the way of its path (:mod:`serveur.sim.floor`)."""

    since: float | None = None  # sim time a robot in the way stopped this one
    at: tuple[float, float] = (0.0, 0.0)  # where it stopped
    replanned: float = -math.inf  # sim time of the last plan around standing robots
    #: A plan around robots under way: (sim time to take it, where it starts, the plan).
    detour: (
        tuple[float, tuple[float, float], concurrent.futures.Future[list[tuple[float, float]]]]
        | None
    ) = None


class Navigator:
    """move_base's goal lifecycle and global planning (see the module's docstring)."""

    def __init__(
        self,
        state: RobotState,
        outbox: Outbox,
        *,
        kinematics: Kind,
        limits: Limits,
        release: str,
        plan_lock: threading.Lock,
    ) -> None:
        self.state = state
        self.outbox = outbox
        self.kinematics = kinematics
        self.limits = limits
        self.release = release
        self._plan_lock = plan_lock
        #: Every goal move_base lists (terminal ones kept ``TERMINAL_KEEP`` s).
        self.goals: list[Goal] = []
        self.pending: Goal | None = None  # taken, waiting for its plan
        self.active: Goal | None = None  # being driven
        self.plan_fut: asyncio.Future[list[tuple[float, float]]] | None = None
        self.plan_goal: Goal | None = None
        self.follower: PathFollower | None = None
        self.goal_deadline = math.inf
        self.blocked_since: float | None = None  # block_path's fault: when the robot stopped
        self.stuck_for = 0.0  # s sim pushing against an obstacle
        self.wait = Wait()
        #: ROS 2 fault: this many next results never reach the client (``drop_results``).
        self.drop_results = 0

    def cancel_one(self, g: Goal, text: str, *, at_once: bool = False) -> None:
        """Cancel one goal: a goal never started is RECALLED; a started one PREEMPTED, either
        ``at_once`` (a newer goal took its place) or, on a cancel request, PREEMPTING until
        move_base's next control cycle stops the robot (``SimRobot._command``)."""
        if g.status == GoalStatus.PENDING:
            self.finish(g, GoalStatus.RECALLED, text)
        elif at_once:
            self.finish(g, GoalStatus.PREEMPTED, text)
        elif g.status == GoalStatus.ACTIVE:
            g.status = GoalStatus.PREEMPTING
            self.publish_status()

    def finish(self, g: Goal, status: GoalStatus, text: str, *, code: int = 0) -> None:
        """End a goal; ``code`` is the Nav2 error code of an ABORTED ROS 2 goal."""
        g.status, g.text, g.ended = status, text, self.state.t
        if g is self.active:
            self.active = None
            self.follower = None
            self.blocked_since = None
            self.wait.since = None
            self.wait.replanned = -math.inf
            self.wait.detour = None
        if g is self.pending:
            self.pending = None
        if g is self.plan_goal:
            self.plan_fut = self.plan_goal = None
        if self.state.ros == 2:
            self._end_nav2(g, status, text, code)
            return
        stamp = self.state.epoch()
        self.outbox.publish(
            "/move_base/result",
            lambda seq, _s: rb.move_base_result(
                g.id, status, text, stamp=stamp, seq=seq, goal_stamp=g.stamp
            ),
        )
        self.publish_status()

    def _end_nav2(self, g: Goal, status: GoalStatus, text: str, code: int) -> None:
        """The rosbridge goal's ``action_result``: SUCCEEDED 4, a cancel CANCELED 5, else 6."""
        owner = g.owner
        if owner is None:
            return
        if status == GoalStatus.SUCCEEDED:
            st, values = ros2.SUCCEEDED, ros2.nav2_result(self.release)
        elif status in (GoalStatus.PREEMPTED, GoalStatus.RECALLED):
            st, values = ros2.CANCELED, ros2.nav2_result(self.release)
        else:
            st, values = ros2.ABORTED, ros2.nav2_result(self.release, code, text)
        if self.state.ros_side_dead:
            owner.end(st, values, send=False)  # the bridge's ROS side is gone: no result
            return
        send = self.drop_results == 0
        if not send:
            self.drop_results -= 1
        owner.end(st, values, send=send)

    def publish_status(self, stamp: float | None = None) -> None:
        """move_base's ``/move_base/status`` (a ROS1 robot's; stamped now by default)."""
        if self.state.ros == 1:
            self.outbox.publish("/move_base/status", self._build_status, stamp)

    def _build_status(self, seq: int, stamp: float) -> dict[str, Any]:
        return rb.goal_status_array(
            [(g.id, g.status, g.text, g.stamp) for g in self.goals], stamp=stamp, seq=seq
        )

    def plan_blocking(
        self, start: tuple[float, float], goal: tuple[float, float]
    ) -> list[tuple[float, float]]:
        with self._plan_lock:  # the shared Planner's cache is not thread-safe
            return self.state.planner.plan(start, goal)

    def request_plan(self, g: Goal) -> None:
        """Plan off the event loop (a new distance field takes tens of ms, like move_base's
        global planner thread); the goal stays PENDING, or ACTIVE and stopped, meanwhile.

        With the goal's distance field cached the plan is a pointer walk of a millisecond or
        two: it runs right here. A round trip through a worker thread would cost more than
        that in GIL hand-overs, and in an accelerated replay every wall millisecond a robot
        waits for its plan is a robot standing still for a tenth of a simulated second.
        """
        x, y, _ = self.state.pose
        planner = self.state.planner
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[list[tuple[float, float]]]
        if planner.has_field((g.x, g.y)):
            fut = loop.create_future()
            try:
                fut.set_result(planner.plan((x, y), (g.x, g.y)))  # thread-safe
            except Exception as exc:
                fut.set_exception(exc)
        else:
            fut = loop.run_in_executor(None, self.plan_blocking, (x, y), (g.x, g.y))
        fut.add_done_callback(consume_exception)
        self.plan_fut, self.plan_goal = fut, g

    def take_plan(self) -> None:
        fut, g = self.plan_fut, self.plan_goal
        self.plan_fut = self.plan_goal = None
        assert fut is not None and g is not None
        if g.terminal or (g is not self.pending and g is not self.active):
            return
        exc = fut.exception()
        if exc is not None:
            why = exc.message if isinstance(exc, ServeurError) else repr(exc)
            self.finish(
                g, GoalStatus.ABORTED, f"no path to the goal: {why}", code=ros2.NO_VALID_PATH
            )
            return
        path = fut.result()
        x, y, _ = self.state.pose
        self.follower = PathFollower(path, g.yaw, self.kinematics, self.limits)
        self.stuck_for = 0.0
        self.wait.since = None
        self.wait.replanned = -math.inf
        self.wait.detour = None
        length = sum(
            math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise([(x, y), *path])
        )
        self.goal_deadline = self.state.t + 30.0 + 3.0 * length / self.limits.max_speed
        if g is self.pending:
            self.pending = None
            self.active = g
            g.status = GoalStatus.ACTIVE
            g.text = SAS_ACCEPTED
            self.publish_status()

    def replan(self) -> None:
        """The robot was put elsewhere (``/initialpose``): move_base replans from there."""
        g = self.active or self.pending
        if g is not None:
            self.follower = None
            self.request_plan(g)
