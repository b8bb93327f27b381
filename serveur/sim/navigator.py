"""A simulated robot's move_base (or Nav2 navigator): a goal's life, its plan, its end.

Split from :mod:`serveur.sim.robot`: what happens to a goal once the action server took it
(:mod:`serveur.sim.inbox` has the rules for taking it) — planned off the event loop, followed,
cancelled (RECALLED, PREEMPTING then PREEMPTED), ended with move_base's result and status or,
on a ROS 2 robot, with the rosbridge goal's ``action_result`` (SUCCEEDED 4, CANCELED 5,
ABORTED 6 with Nav2's error code) — and replanned from a new pose after ``/initialpose``.
"""

from __future__ import annotations

import asyncio
import itertools
import math
from typing import Final

from serveur.errors import ServeurError
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.base import Goal
from serveur.sim.kinematics import PathFollower
from serveur.sim.sensors import Sensors
from serveur.sim.topics import consume_exception

__all__ = ["LAST_CANCEL_CANCELED", "SAS_ACCEPTED", "SAS_CANCELED", "Navigator"]

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


class Navigator(Sensors):
    """move_base's goal lifecycle and global planning (see the module's docstring)."""

    def _cancel_one(self, g: Goal, text: str, *, at_once: bool = False) -> None:
        """Cancel one goal: a goal never started is RECALLED; a started one PREEMPTED, either
        ``at_once`` (a newer goal took its place) or, on a cancel request, PREEMPTING until
        move_base's next control cycle stops the robot (:meth:`_command`)."""
        if g.status == GoalStatus.PENDING:
            self._finish(g, GoalStatus.RECALLED, text)
        elif at_once:
            self._finish(g, GoalStatus.PREEMPTED, text)
        elif g.status == GoalStatus.ACTIVE:
            g.status = GoalStatus.PREEMPTING
            self._publish_status()

    def _finish(self, g: Goal, status: GoalStatus, text: str, *, code: int = 0) -> None:
        """End a goal; ``code`` is the Nav2 error code of an ABORTED ROS 2 goal."""
        g.status, g.text, g.ended = status, text, self._t
        if g is self._active:
            self._active = None
            self._follower = None
            self._blocked_since = None
            self._wait_since = None
            self._replanned = -math.inf
            self._detour = None
        if g is self._pending:
            self._pending = None
        if g is self._plan_goal:
            self._plan_fut = self._plan_goal = None
        if self.ros == 2:
            self._end_nav2(g, status, text, code)
            return
        stamp = self.epoch()
        self._publish(
            "/move_base/result",
            lambda seq, _s: rb.move_base_result(
                g.id, status, text, stamp=stamp, seq=seq, goal_stamp=g.stamp
            ),
        )
        self._publish_status()

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
        if self._ros_side_dead:
            owner.end(st, values, send=False)  # the bridge's ROS side is gone: no result
            return
        send = self._drop_results == 0
        if not send:
            self._drop_results -= 1
        owner.end(st, values, send=send)

    def _plan_blocking(
        self, start: tuple[float, float], goal: tuple[float, float]
    ) -> list[tuple[float, float]]:
        with self._plan_lock:  # the shared Planner's cache is not thread-safe
            return self._planner.plan(start, goal)

    def _request_plan(self, g: Goal) -> None:
        """Plan off the event loop (a new distance field takes tens of ms, like move_base's
        global planner thread); the goal stays PENDING, or ACTIVE and stopped, meanwhile.

        With the goal's distance field cached the plan is a pointer walk of a millisecond or
        two: it runs right here. A round trip through a worker thread would cost more than
        that in GIL hand-overs, and in an accelerated replay every wall millisecond a robot
        waits for its plan is a robot standing still for a tenth of a simulated second.
        """
        x, y, _ = self.pose
        loop = asyncio.get_running_loop()
        fut: asyncio.Future[list[tuple[float, float]]]
        if self._planner.has_field((g.x, g.y)):
            fut = loop.create_future()
            try:
                fut.set_result(self._planner.plan((x, y), (g.x, g.y)))  # thread-safe
            except Exception as exc:
                fut.set_exception(exc)
        else:
            fut = loop.run_in_executor(None, self._plan_blocking, (x, y), (g.x, g.y))
        fut.add_done_callback(consume_exception)
        self._plan_fut, self._plan_goal = fut, g

    def _take_plan(self) -> None:
        fut, g = self._plan_fut, self._plan_goal
        self._plan_fut = self._plan_goal = None
        assert fut is not None and g is not None
        if g.terminal or (g is not self._pending and g is not self._active):
            return
        exc = fut.exception()
        if exc is not None:
            why = exc.message if isinstance(exc, ServeurError) else repr(exc)
            self._finish(
                g, GoalStatus.ABORTED, f"no path to the goal: {why}", code=ros2.NO_VALID_PATH
            )
            return
        path = fut.result()
        x, y, _ = self.pose
        self._follower = PathFollower(path, g.yaw, self.kinematics, self.limits)
        self._stuck_for = 0.0
        self._wait_since = None
        self._replanned = -math.inf
        self._detour = None
        length = sum(
            math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise([(x, y), *path])
        )
        self._goal_deadline = self._t + 30.0 + 3.0 * length / self.limits.max_speed
        if g is self._pending:
            self._pending = None
            self._active = g
            g.status = GoalStatus.ACTIVE
            g.text = SAS_ACCEPTED
            self._publish_status()

    def _relocalise(self, x: float, y: float, yaw: float) -> None:
        self._motion.teleport(x, y, yaw)
        self._scan_cache = None
        self._amcl_force = True  # amcl publishes the pose it was given
        g = self._active or self._pending
        if g is not None:  # move_base replans from the new pose
            self._follower = None
            self._request_plan(g)
