"""What a simulated robot does with the messages clients send it: goals, cancels, teleop, poses.

Split from :mod:`serveur.sim.robot`: the topics the robot subscribes to (``/move_base/goal``,
``/move_base_simple/goal``, ``/move_base/cancel``, ``/cmd_vel``, ``/initialpose``; a ROS 2
robot's ``/cmd_vel``, ``/initialpose``, ``/goal_pose``) and Nav2's ``navigate_to_pose`` goals
and cancels; a shape the ROS type cannot hold raises :class:`~serveur.errors.RosbridgeError`.
A goal once taken is the navigator's (:mod:`serveur.sim.navigator`); :class:`Inbox` keeps the
action server's own memory (the goal ids it made, the last goal's and the last cancel's stamps).

move_base's goals follow actionlib's ActionServer and SimpleActionServer (actionlib
``action_server.py``, ``status_tracker.py``, ``simple_action_server.py``; C++ move_base uses
the same rules) and shared/notes/rosbridge.md, checked on a real ROS1 stack:

* A goal with a zero ``goal_id.stamp`` (roslibpy, roslibjs, ``/move_base_simple/goal``) is
  stamped with the robot's own clock on arrival (StatusTracker). A goal with an empty id gets
  ``/move_base-N-STAMP`` (GoalIDGenerator).
* A goal with a non-zero stamp at or before the last cancel-by-stamp is RECALLED at once
  (ActionServer ``internal_goal_callback``).
* A goal stamped earlier than the last goal the SimpleActionServer took (``goalCallback``:
  ``stamp >= current_goal's and >= next_goal's``) is RECALLED at once with
  :data:`SAS_CANCELED`; the running goal goes on.
* A newer goal preempts the running one: PREEMPTED, or RECALLED if it had not started, with
  :data:`SAS_CANCELED` (``accept_new_goal``, ``internal_goal_callback``).
* ``/move_base/cancel`` with an empty id and a zero stamp cancels every goal, by id that goal,
  with a stamp every goal stamped at or before it (``internal_cancel_callback``): an ACTIVE
  goal becomes PREEMPTING at once and PREEMPTED at move_base's next control cycle (its
  ``executeCb`` checks ``isPreemptRequested`` each cycle and calls ``setPreempted()``, empty
  text); a goal still PENDING is RECALLED.
* move_base does not subscribe to ``/cmd_vel``; it publishes there. While it drives a goal its
  controller's commands override a teleop ``/cmd_vel`` every cycle, so teleop neither preempts
  nor moves the robot; only with no goal does ``/cmd_vel`` drive it.
"""

from __future__ import annotations

import itertools
import logging
import math
from collections.abc import Mapping
from typing import Any, Final

from serveur.errors import RosbridgeError
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.navigator import LAST_CANCEL_CANCELED, SAS_CANCELED, Navigator
from serveur.sim.outbox import Outbox
from serveur.sim.sensors import Sensors
from serveur.sim.state import Goal, RobotState
from serveur.sim.topics import ActionSink

__all__ = ["Inbox"]

log = logging.getLogger("serveur.robot_sim")

_MAP_FRAMES: Final = frozenset({"map", "/map", ""})


class Inbox:
    """The robot's subscriptions' handlers and Nav2's goal and cancel (module's docstring)."""

    def __init__(
        self,
        state: RobotState,
        outbox: Outbox,
        navigator: Navigator,
        sensors: Sensors,
        *,
        twist_stamped: bool,
    ) -> None:
        self.state = state
        self.outbox = outbox
        self.navigator = navigator
        self.sensors = sensors
        #: ROS 2: ``/cmd_vel`` is geometry_msgs/msg/TwistStamped.
        self.twist_stamped = twist_stamped
        #: Fault (``SimRobot.ignore_goals``): goals are listed, never run nor answered.
        self.ignore_goals = False
        self._goal_counter = itertools.count(1)
        #: Stamp of the last goal the SimpleActionServer took (its current or next goal).
        self._sas_stamp = 0.0
        #: Latest stamp of a cancel-by-stamp (ActionServer's ``last_cancel``).
        self._last_cancel = 0.0

    def relocalise(self, x: float, y: float, yaw: float) -> None:
        """The robot is at (x, y, yaw) now (an initial pose; a test's teleport)."""
        self.state.motion.teleport(x, y, yaw)
        self.sensors.relocalised()
        self.navigator.replan()

    # -- incoming messages (raise RosbridgeError on shapes the ROS type cannot hold) ----------

    def handle_publish(self, topic: str, msg: Mapping[str, Any]) -> str | None:
        """Apply a client's message on a topic the robot subscribes; returns a warning or None."""
        if self.state.ros == 2:
            return self._handle_publish2(topic, msg)
        if topic == "/cmd_vel":
            warn = self._on_cmd_vel(msg)
        elif topic == "/move_base/goal":
            warn = self._on_action_goal(msg)
        elif topic == "/move_base_simple/goal":
            warn = self._on_simple_goal(msg)
        elif topic == "/move_base/cancel":
            warn = self._on_cancel(msg)
        elif topic == "/initialpose":
            warn = self._on_initialpose(msg)
        else:  # pragma: no cover - the endpoint checks ROBOT_SUBSCRIBES first
            raise RosbridgeError(f"the robot does not subscribe to {topic}")
        self.outbox.relay(topic, msg)
        return warn

    def _handle_publish2(self, topic: str, msg: Mapping[str, Any]) -> str | None:
        """A ROS 2 robot's subscriptions: teleop, AMCL's initial pose, RViz2's goal_pose."""
        if topic == "/cmd_vel":
            # rosbridge 2.x fills the topic's existing type and refuses fields it lacks: a
            # Twist sent to a TwistStamped /cmd_vel (or the reverse) is an error, nothing moves.
            if self.twist_stamped:
                _only(msg, {"header", "twist"}, "geometry_msgs/msg/TwistStamped")
                self._on_cmd_vel(_obj(msg.get("twist"), "twist"))
            else:
                _only(msg, {"linear", "angular"}, "geometry_msgs/msg/Twist")
                self._on_cmd_vel(msg)
        elif topic == "/initialpose":
            self._on_initialpose2(msg)
        elif topic == "/goal_pose":
            frame, x, y, q = ros2.goal_from_args({"pose": msg})
            self.nav2_goal(None, frame, x, y, q)
        else:  # pragma: no cover - the endpoint checks subscribes first
            raise RosbridgeError(f"the robot does not subscribe to {topic}")
        self.outbox.relay(topic, msg)
        return None

    def _on_initialpose2(self, msg: Mapping[str, Any]) -> None:
        """Nav2's amcl ``initialPoseReceived``: a pose whose frame is not ``map`` (a leading
        ``/`` stripped; an empty frame too), or with a NaN, or off the map, is ignored with only
        a log line on the robot: no error reaches the client (shared/notes/ros2.md)."""
        m = _obj(msg, "initialpose")
        frame = _header_frame(m)
        x, y, yaw = rb.pose_from_msg(_obj(_obj(m.get("pose"), "pose").get("pose"), "pose.pose"))
        if frame.lstrip("/") != "map":
            log.warning("%s: amcl ignores an initial pose in frame %r", self.state.name, frame)
            return
        if not all(math.isfinite(v) for v in (x, y, yaw)) or not self._on_map(x, y):
            log.warning("%s: amcl ignores an initial pose off the map or with NaN", self.state.name)
            return
        self.relocalise(x, y, yaw)

    def _on_map(self, x: float, y: float) -> bool:
        g = self.state.map
        ox, oy = g.origin[0], g.origin[1]
        return ox <= x < ox + g.width * g.resolution and oy <= y < oy + g.height * g.resolution

    # -- Nav2's navigate_to_pose (ROS 2) -----------------------------------------------------

    def nav2_goal(
        self,
        owner: ActionSink | None,
        frame: str,
        x: float,
        y: float,
        q: tuple[float, float, float, float],
        gid: str | None = None,
    ) -> Goal | None:
        """A NavigateToPose goal reaching the navigator (the goal); None if it is rejected.

        ``gid`` is the id the client gave the goal (rosbridge's op id):
        ``SimRobot.goal_statuses`` lists the goal under it, so a test sees which ids a driver
        sent (else ``nav2-N``).

        A goal the navigator cannot take (not in the map frame, NaN, not a rotation about z,
        off the map) is rejected: rosbridge before its 2026 fix then sends no frame at all
        (shared/notes/ros2.md), so the owner never hears of it. A taken goal aborts (status 6)
        the one the navigator was driving: a new goal to Nav2's navigator is not a cancel.
        """
        nav = self.navigator
        gid = gid if gid is not None else f"nav2-{next(self._goal_counter)}"
        if self.ignore_goals:  # a hung navigator: the goal is listed, never run nor answered
            hung = Goal(gid, self.state.epoch(), x, y, 0.0)
            nav.goals.append(hung)
            return hung
        if _goal_problem(frame, x, y, q) is not None or not self._on_map(x, y):
            return None
        goal = Goal(gid, self.state.epoch(), x, y, 0.0)
        goal.yaw = rb.yaw_from_quaternion({"x": q[0], "y": q[1], "z": q[2], "w": q[3]})
        goal.owner, goal.started = owner, self.state.t
        for g in nav.goals:
            if not g.terminal:
                nav.finish(g, GoalStatus.ABORTED, "preempted by a newer goal")
        nav.goals.append(goal)
        self.state.teleop = None
        nav.pending = goal
        return goal

    def nav2_cancel(self, owner: ActionSink) -> None:
        """A cancel request for the goal ``owner`` sent: CANCELING, then CANCELED at the
        navigator's next cycle (~20 ms after the cancel on a real stack)."""
        nav = self.navigator
        for g in nav.goals:
            if g.owner is owner and not g.terminal:
                nav.cancel_one(g, "")

    def _on_cmd_vel(self, msg: Mapping[str, Any]) -> str | None:
        """A teleop command drives the base only while move_base has no goal.

        move_base does not subscribe to ``/cmd_vel`` (shared/notes/rosbridge.md): a goal is not
        preempted by teleop, and while it runs the controller's own ``/cmd_vel`` (every cycle)
        overrides a teleop command, so the command is dropped. Nav2's controller_server does
        the same to a ROS 2 robot's teleop.
        """
        nav = self.navigator
        vx, vy, wz = rb.twist_from_msg(msg)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise RosbridgeError("cmd_vel holds a non-finite velocity")
        if nav.active is not None or nav.pending is not None or self.state.docking_drives:
            return None  # the docking server's controller drives the base as move_base's does
        self.state.teleop = (vx, vy, wz)
        self.state.teleop_t = self.state.clock.now()
        return None

    def _on_initialpose(self, msg: Mapping[str, Any]) -> str | None:
        m = _obj(msg, "initialpose")
        frame = _header_frame(m)
        x, y, yaw = rb.pose_from_msg(_obj(_obj(m.get("pose"), "pose").get("pose"), "pose.pose"))
        if frame not in _MAP_FRAMES:
            raise RosbridgeError(f"initialpose must be in the map frame, not {frame!r}")
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise RosbridgeError("initialpose holds a non-finite value")
        self.relocalise(x, y, yaw)
        return None

    def _on_action_goal(self, msg: Mapping[str, Any]) -> str | None:
        m = _obj(msg, "goal")
        gid, gstamp = rb.goal_id_from_msg(_obj(m.get("goal_id"), "goal_id"))
        target = _obj(_obj(m.get("goal"), "goal").get("target_pose"), "goal.target_pose")
        return self._new_goal(gid, gstamp, target)

    def _on_simple_goal(self, msg: Mapping[str, Any]) -> str | None:
        # move_base's goalCB wraps the PoseStamped in an action goal with an empty goal id,
        # so the action server gives it an id and stamps it now.
        return self._new_goal("", 0.0, _obj(msg, "goal"))

    def _new_goal(self, gid: str, gstamp: float, target: Mapping[str, Any]) -> str | None:
        """A goal reaching move_base's action server (rules in the module's docstring)."""
        nav = self.navigator
        frame = _header_frame(target)
        pose = _obj(target.get("pose"), "pose")
        x, y, _ = rb.point_from_msg(_obj(pose.get("position"), "position"))
        q = rb.quaternion_from_msg(_obj(pose.get("orientation"), "orientation"))
        if self.ignore_goals:
            return None
        now = self.state.epoch()
        if not gid:
            gid = f"/move_base-{next(self._goal_counter)}-{now:.9f}"
        if any(g.id == gid for g in nav.goals):
            return f"goal {gid} is a duplicate; ignored"
        # StatusTracker: a zero stamp becomes the robot's now, so such a goal is the newest.
        goal = Goal(gid, gstamp if gstamp != 0.0 else now, x, y, 0.0)
        nav.goals.append(goal)
        if gstamp != 0.0 and gstamp <= self._last_cancel:  # ActionServer
            nav.finish(goal, GoalStatus.RECALLED, LAST_CANCEL_CANCELED)
            return None
        if goal.stamp < self._sas_stamp:  # SimpleActionServer: older than the goal it has
            nav.finish(goal, GoalStatus.RECALLED, SAS_CANCELED)
            return None
        self._sas_stamp = goal.stamp
        reason = _goal_problem(frame, x, y, q)
        if reason is not None:
            nav.finish(goal, GoalStatus.REJECTED, reason)
            return None
        goal.yaw = rb.yaw_from_quaternion({"x": q[0], "y": q[1], "z": q[2], "w": q[3]})
        # The newer goal preempts the current one (SimpleActionServer.accept_new_goal) and
        # bumps one still pending (internal_goal_callback).
        for g in nav.goals:
            if g is not goal and not g.terminal:
                nav.cancel_one(g, SAS_CANCELED, at_once=True)
        self.state.teleop = None
        nav.pending = goal
        nav.publish_status()
        return None

    def _on_cancel(self, msg: Mapping[str, Any]) -> str | None:
        """ActionServer ``internal_cancel_callback``: all, by id, or up to a stamp."""
        nav = self.navigator
        gid, stamp = rb.goal_id_from_msg(_obj(msg, "cancel"))
        everything = not gid and stamp == 0.0
        for g in list(nav.goals):
            if not g.terminal and (
                everything or g.id == gid or (stamp != 0.0 and g.stamp <= stamp)
            ):
                nav.cancel_one(g, "")
        self._last_cancel = max(self._last_cancel, stamp)
        return None


def _obj(v: object, what: str) -> Mapping[str, Any]:
    """A nested message object; a missing one takes ROS defaults (empty), others are errors."""
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise RosbridgeError(f"{what} must be an object, not {type(v).__name__}")
    return v


def _only(msg: Mapping[str, Any], fields: set[str], typ: str) -> None:
    """rosbridge 2.x's populate_instance: a field the type does not have is an error."""
    extra = sorted(set(msg) - fields)
    if extra:
        raise RosbridgeError(f"message type {typ} does not have a field {extra[0]!r}")


def _header_frame(msg: Mapping[str, Any]) -> str:
    frame = _obj(msg.get("header"), "header").get("frame_id", "")
    if not isinstance(frame, str):
        raise RosbridgeError("header.frame_id must be a string")
    return frame


def _goal_problem(
    frame: str, x: float, y: float, q: tuple[float, float, float, float]
) -> str | None:
    """Why move_base would reject this goal, or None."""
    if frame not in _MAP_FRAMES:
        return f"goal frame {frame!r} is not the global frame 'map'"
    if not all(math.isfinite(v) for v in (x, y, *q)):
        return "goal contains a NaN or infinite value"
    norm = math.sqrt(sum(v * v for v in q))
    if abs(norm - 1.0) > 1e-2:
        return f"goal orientation is not a unit quaternion (norm {norm:.4g})"
    if abs(q[0]) > 1e-3 or abs(q[1]) > 1e-3:
        return "goal orientation is not a rotation about z"
    return None
