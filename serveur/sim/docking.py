"""A simulated ROS 2 robot's docking server: opennav_docking's ``dock_robot`` and ``undock_robot``.

Split from :mod:`serveur.sim.robot`: what a robot made with ``docking`` does with the
DockRobot and UndockRobot goals rosbridge 2.x hands it (:mod:`serveur.sim.bridge`; the wire
forms in :mod:`serveur.sim.ros2`), and where the robot's chargers are (:func:`on_charger`, which
the robot's battery reads too). Modelled on Nav2's docking server as its sources say
(ros-navigation/navigation2 ``nav2_docking/opennav_docking/src/docking_server.cpp``, the
``SimpleChargingDock`` plugin and the parameters' defaults in open-navigation/opennav_docking's
README), one step per physics tick like the navigator:

* **Dock.** ``use_dock_id`` true asks the server's dock database, which this robot has none
  of: DOCK_NOT_IN_DB (901). A dock pose outside ``map`` cannot be transformed: UNKNOWN (999).
  A robot already on that charger and charging succeeds at once. Otherwise feedback
  NAV_TO_STAGING_POSE (1) once, and the robot is sent by Nav2 (a navigate goal of the server's
  own, answered to nobody) to the staging pose :data:`STAGING_OFFSET` in front of the dock,
  facing it — unless ``navigate_to_staging_pose`` is false or the robot is within
  :data:`PRESTAGING_TOLERANCE` of it; that goal failing, or taking longer than
  ``max_staging_time``, is FAILED_TO_STAGE (903). Then INITIAL_PERCEPTION (2) once: a charger
  within :data:`DETECT_DISTANCE` of the requested pose and :data:`DETECT_RANGE` of the robot is
  seen (the dock's true pose refines the requested one, as a detector does); none within
  :data:`INITIAL_PERCEPTION_TIMEOUT` is FAILED_TO_DETECT_DOCK (904, "Failed initial dock
  detection"). Then CONTROLLING (3) every tick while the server drives the base onto the
  contacts at :data:`APPROACH_SPEED` (more than :data:`DOCK_APPROACH_TIMEOUT`:
  FAILED_TO_CONTROL, 905), then WAIT_FOR_CHARGE (4) every tick until the robot charges (more
  than :data:`WAIT_CHARGE_TIMEOUT`: FAILED_TO_CHARGE, 906). Success: status 4 and ``success``
  true; a failure: status 6 ABORTED, ``success`` false and the code (and, but on Humble,
  ``error_msg``, the exception's text: Nav2's current DockRobot has the field; that Jazzy's
  has it too is assumed, not checked).
* **Undock.** A robot on no charger: ABORTED with ``success`` false and no error code (the
  server's "Robot is not in the dock, no need to undock" returns without a verdict, and Nav2's
  SimpleActionServer aborts the goal). Otherwise the charger's current is switched off and the
  server backs the robot :data:`STAGING_OFFSET` straight off the dock, to within
  :data:`UNDOCK_LINEAR_TOLERANCE` / :data:`UNDOCK_ANGULAR_TOLERANCE`: success; more than
  ``max_undocking_time``: FAILED_TO_CONTROL. UndockRobot has no feedback.
* **Cancel** (``cancel_action_goal``): at the server's next cycle the goal ends CANCELED (5)
  with ``success`` false, its staging goal cancelled and the robot stopped, as a navigate
  goal's cancel ends at the navigator's next cycle. A new dock goal while one runs takes its
  place (the running one ends ABORTED, Nav2's SimpleActionServer preempting); an undock while
  a dock runs (or the reverse) waits for it: the server runs one at a time (its mutex).
* A navigate goal taken while the server drives the base ends the dock or undock
  FAILED_TO_CONTROL (the sim keeps one controller on the base); teleop is ignored meanwhile.
* The robot's node dying (``SimRobot.kill_node``) ends every docking goal unanswered; with
  the bridge's ROS side stopped the server works on but its results never reach the client.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Final

from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.kinematics import Kind, wrap_angle
from serveur.sim.navigator import Navigator
from serveur.sim.state import Goal, RobotState
from serveur.sim.topics import ActionSink

__all__ = [
    "APPROACH_SPEED",
    "CHARGE_DISTANCE",
    "CHARGE_YAW",
    "DETECT_DISTANCE",
    "DETECT_RANGE",
    "DOCK_APPROACH_TIMEOUT",
    "INITIAL_PERCEPTION_TIMEOUT",
    "PRESTAGING_TOLERANCE",
    "STAGING_OFFSET",
    "UNDOCK_ANGULAR_TOLERANCE",
    "UNDOCK_LINEAR_TOLERANCE",
    "WAIT_CHARGE_TIMEOUT",
    "DockingServer",
    "on_charger",
    "staging_pose",
]

#: A charger's contacts touch the robot's within this distance (m) and heading (rad) of the
#: charger's pose: a few centimetres (SimpleChargingDock's ``docking_threshold``, 0.05 m) and
#: square enough for the contacts to meet.
CHARGE_DISTANCE: Final = 0.05
CHARGE_YAW: Final = 0.1
#: SimpleChargingDock's ``staging_x_offset`` (the staging pose 0.7 m in front of the dock,
#: facing it) and the docking server's ``dock_prestaging_tolerance`` (m, with the heading's
#: radians in the same norm: opennav's ``utils::l2Norm``).
STAGING_OFFSET: Final = 0.7
PRESTAGING_TOLERANCE: Final = 0.5
#: The docking server's timeouts (s): ``initial_perception_timeout``, ``dock_approach_timeout``,
#: ``wait_charge_timeout``.
INITIAL_PERCEPTION_TIMEOUT: Final = 5.0
DOCK_APPROACH_TIMEOUT: Final = 30.0
WAIT_CHARGE_TIMEOUT: Final = 5.0
#: ``undock_linear_tolerance`` (m) and ``undock_angular_tolerance`` (rad).
UNDOCK_LINEAR_TOLERANCE: Final = 0.05
UNDOCK_ANGULAR_TOLERANCE: Final = 0.05
#: The docking controller's ``v_linear_max`` (m/s) and ``v_angular_max`` (rad/s).
APPROACH_SPEED: Final = 0.25
APPROACH_TURN: Final = 0.75
#: The dock seen: a charger this close (m, rad) to the requested dock pose, this close (m) to
#: the robot (a dock detector's range from the staging pose).
DETECT_DISTANCE: Final = 0.3
DETECT_YAW: Final = 0.35
DETECT_RANGE: Final = 2.0
#: On the contacts: the approach drives until this close (m, rad) to the dock's pose.
_DOCKED_DISTANCE: Final = 0.02
_DOCKED_YAW: Final = 0.05
#: The approach's gains (1/s): a proportional controller, capped at the speeds above.
_GAIN: Final = 1.0
_TURN_GAIN: Final = 2.0
_LATERAL_GAIN: Final = 2.0

# DockRobot feedback states (nav2_msgs/action/DockRobot.action).
_NAV_TO_STAGING_POSE: Final = 1
_INITIAL_PERCEPTION: Final = 2
_CONTROLLING: Final = 3
_WAIT_FOR_CHARGE: Final = 4

Pose = tuple[float, float, float]


def staging_pose(x: float, y: float, yaw: float) -> Pose:
    """The staging pose of a dock at (x, y, yaw): :data:`STAGING_OFFSET` in front of it (the
    robot's back to the room, its contacts toward the dock), facing the same way."""
    return (
        x - STAGING_OFFSET * math.cos(yaw),
        y - STAGING_OFFSET * math.sin(yaw),
        yaw,
    )


def on_charger(state: RobotState) -> Pose | None:
    """The charger whose contacts the robot's touch now (its true pose within
    :data:`CHARGE_DISTANCE` and :data:`CHARGE_YAW`), or None."""
    x, y, yaw = state.pose
    for c in state.chargers:
        if math.hypot(x - c[0], y - c[1]) <= CHARGE_DISTANCE and (
            abs(wrap_angle(yaw - c[2])) <= CHARGE_YAW
        ):
            return c
    return None


def _l2(a: Pose, b: Pose) -> float:
    """opennav_docking's ``utils::l2Norm``: x, y and the heading's radians in one norm."""
    return math.sqrt((a[0] - b[0]) ** 2 + (a[1] - b[1]) ** 2 + wrap_angle(a[2] - b[2]) ** 2)


def _clamp(v: float, limit: float) -> float:
    return max(-limit, min(limit, v))


@dataclass(slots=True)
class _Job:
    """One DockRobot or UndockRobot goal the server took."""

    kind: str  # "dock" | "undock"
    owner: ActionSink | None
    started: float  # sim time it arrived
    #: The dock's requested pose (dock), or None (undock).
    pose: Pose | None = None
    goal: ros2.DockGoal | None = None
    #: max_staging_time (dock) or max_undocking_time (undock), seconds.
    max_time: float = 30.0
    phase: str = "start"
    since: float = 0.0  # sim time the phase began
    #: Where the server drives the base: the dock's true pose, or (undock) the staging pose.
    target: Pose | None = None
    staging: Goal | None = None  # the server's own navigate goal to the staging pose
    cancel: bool = False


class DockingServer:
    """The robot's docking server (see the module's docstring). ``navigate`` sends the robot
    to a pose through its navigator as a goal of the server's own, the Goal or None when the
    navigator refuses it."""

    def __init__(
        self,
        state: RobotState,
        navigator: Navigator,
        *,
        navigate: Callable[[float, float, float, str], Goal | None],
        kinematics: Kind,
        release: str,
    ) -> None:
        self.state = state
        self.navigator = navigator
        self._navigate = navigate
        self.kinematics = kinematics
        self.release = release
        #: The goal being worked on, and those waiting for the server (one at a time).
        self.active: _Job | None = None
        self.waiting: list[_Job] = []
        self._staging_ids = itertools.count(1)

    # -- goals and cancels (from the bridge) -------------------------------------------------

    def dock(self, owner: ActionSink | None, goal: ros2.DockGoal) -> None:
        """A DockRobot goal the server took."""
        yaw = 2.0 * math.atan2(goal.q[2], goal.q[3])
        job = _Job(
            "dock",
            owner,
            self.state.t,
            pose=(goal.x, goal.y, wrap_angle(yaw)),
            goal=goal,
            max_time=goal.max_staging_time,
        )
        self._take(job)

    def undock(self, owner: ActionSink | None, max_undocking_time: float) -> None:
        """An UndockRobot goal the server took."""
        self._take(_Job("undock", owner, self.state.t, max_time=max_undocking_time))

    def _take(self, job: _Job) -> None:
        active = self.active
        if active is None:
            self.active = job
        elif active.kind == job.kind:
            # Nav2's SimpleActionServer: a new goal of the same action preempts the running one.
            self._fail(active, 0, "preempted by a newer goal", then=job)
        else:
            self.waiting.append(job)  # the server's mutex: it waits for the running goal

    def cancel(self, owner: ActionSink) -> None:
        """A cancel request for the goal ``owner`` sent: it ends at the server's next cycle."""
        for job in (self.active, *self.waiting):
            if job is not None and job.owner is owner:
                job.cancel = True

    def kill(self) -> None:
        """The robot's node died: every goal ends unanswered (its handler waits for ever)."""
        self._let_go(self.active)
        self.active = None
        self.waiting.clear()

    # -- the server's cycle ------------------------------------------------------------------

    def step(self) -> None:
        """One cycle (each physics tick): phases, timeouts, feedback, results."""
        for waiting in [j for j in self.waiting if j.cancel]:
            self._end(waiting, ros2.CANCELED, self._values(waiting, False, 0, ""))
        job = self.active
        if job is None:
            return
        if job.cancel:
            self._end(job, ros2.CANCELED, self._values(job, False, 0, ""))
            return
        t = self.state.t
        if job.phase == "start":
            job.since = t
            if job.kind == "dock":
                self._begin_dock(job)
            else:
                self._begin_undock(job)
        elif job.phase == "stage":
            self._stage(job, t)
        elif job.phase == "perceive":
            self._perceive(job, t)
        elif job.phase == "approach":
            self._approach(job, t)
        elif job.phase == "charge":
            self._feedback(job, _WAIT_FOR_CHARGE)
            if self.state.charging:
                self._end(job, ros2.SUCCEEDED, self._values(job, True, 0, ""))
            elif t - job.since > WAIT_CHARGE_TIMEOUT:
                self._fail(job, ros2.FAILED_TO_CHARGE, "Timed out waiting for charge to start")
        elif job.phase == "leave":
            self._leave(job, t)

    def _begin_dock(self, job: _Job) -> None:
        goal, pose, st = job.goal, job.pose, self.state
        assert goal is not None and pose is not None
        if goal.use_dock_id:
            self._fail(job, ros2.DOCK_NOT_IN_DB, "Dock ID requested is not in database!")
            return
        if goal.frame.lstrip("/") != "map":
            self._fail(
                job,
                ros2.DOCK_UNKNOWN,
                f"Transform error: frame {goal.frame!r} does not exist",
            )
            return
        seen = self._charger_near(pose, st.pose)
        if seen is not None and on_charger(st) == seen and st.charging:
            self._end(job, ros2.SUCCEEDED, self._values(job, True, 0, ""))  # already docked
            return
        self._feedback(job, _NAV_TO_STAGING_POSE)
        staging = staging_pose(*pose)
        if not goal.navigate_to_staging_pose or _l2(st.pose, staging) < PRESTAGING_TOLERANCE:
            self._to_perception(job)
            return
        nav_goal = self._navigate(*staging, f"docking-staging-{next(self._staging_ids)}")
        if nav_goal is None:
            self._fail(job, ros2.FAILED_TO_STAGE, "Failed to send goal to the staging pose")
            return
        job.staging, job.phase = nav_goal, "stage"

    def _stage(self, job: _Job, t: float) -> None:
        g = job.staging
        assert g is not None
        if g.status == GoalStatus.SUCCEEDED:
            self._to_perception(job)
        elif g.terminal:
            self._fail(job, ros2.FAILED_TO_STAGE, "Failed to navigate to staging pose")
        elif t - job.since > job.max_time:
            self._fail(job, ros2.FAILED_TO_STAGE, "Navigation to staging pose timed out")

    def _to_perception(self, job: _Job) -> None:
        self._feedback(job, _INITIAL_PERCEPTION)
        job.phase, job.since = "perceive", self.state.t
        self._perceive(job, self.state.t)

    def _perceive(self, job: _Job, t: float) -> None:
        assert job.pose is not None
        seen = self._charger_near(job.pose, self.state.pose)
        if seen is not None:
            job.target, job.phase, job.since = seen, "approach", t
            self.state.docking_drives = True
        elif t - job.since > INITIAL_PERCEPTION_TIMEOUT:
            self._fail(job, ros2.FAILED_TO_DETECT_DOCK, "Failed initial dock detection")

    def _approach(self, job: _Job, t: float) -> None:
        self._feedback(job, _CONTROLLING)
        target = job.target
        assert target is not None
        if self._base_taken():
            self._fail(job, ros2.FAILED_TO_CONTROL, "Another goal took the base while docking")
            return
        x, y, yaw = self.state.pose
        if math.hypot(target[0] - x, target[1] - y) <= _DOCKED_DISTANCE and (
            abs(wrap_angle(target[2] - yaw)) <= _DOCKED_YAW
        ):
            self.state.docking_drives = False  # on the contacts: the robot stops there
            job.phase, job.since = "charge", t
        elif t - job.since > DOCK_APPROACH_TIMEOUT:
            self._fail(
                job,
                ros2.FAILED_TO_CONTROL,
                "Timed out approaching dock; dock nor charging (if applicable) detected",
            )

    def _begin_undock(self, job: _Job) -> None:
        st = self.state
        if on_charger(st) is None and not st.charging:
            # "Robot is not in the dock, no need to undock": no verdict, the goal is aborted.
            self._end(job, ros2.ABORTED, self._values(job, False, 0, ""))
            return
        st.charge_off = True  # disableCharging(): the contacts part without current
        st.charging = False
        job.target, job.phase = staging_pose(*st.pose), "leave"
        st.docking_drives = True

    def _leave(self, job: _Job, t: float) -> None:
        target = job.target
        assert target is not None
        if self._base_taken():
            self._fail(job, ros2.FAILED_TO_CONTROL, "Another goal took the base while undocking")
            return
        x, y, yaw = self.state.pose
        if math.hypot(target[0] - x, target[1] - y) < UNDOCK_LINEAR_TOLERANCE and (
            abs(wrap_angle(target[2] - yaw)) < UNDOCK_ANGULAR_TOLERANCE
        ):
            self._end(job, ros2.SUCCEEDED, self._values(job, True, 0, ""))
        elif t - job.since > job.max_time:
            self._fail(job, ros2.FAILED_TO_CONTROL, "Undocking timed out")

    # -- the base ----------------------------------------------------------------------------

    def command(self) -> tuple[float, float, float]:
        """The body velocity the server commands while it drives the base (onto the dock's
        pose, or straight back to the staging pose), capped at the docking controller's
        speeds; a differential base steers its lateral error out while going forward."""
        job = self.active
        target = job.target if job is not None else None
        if target is None:
            return 0.0, 0.0, 0.0
        x, y, yaw = self.state.pose
        dx, dy = target[0] - x, target[1] - y
        c, s = math.cos(yaw), math.sin(yaw)
        ex, ey = c * dx + s * dy, -s * dx + c * dy
        e_yaw = wrap_angle(target[2] - yaw)
        vx = _clamp(_GAIN * ex, APPROACH_SPEED)
        if self.kinematics == "omni":
            return vx, _clamp(_GAIN * ey, APPROACH_SPEED), _clamp(_TURN_GAIN * e_yaw, APPROACH_TURN)
        lateral = _LATERAL_GAIN * ey if vx > 0.0 else 0.0
        return vx, 0.0, _clamp(_TURN_GAIN * e_yaw + lateral, APPROACH_TURN)

    def _base_taken(self) -> bool:
        """A navigate goal (a client's) took the navigator while the server drives."""
        nav = self.navigator
        return nav.active is not None or nav.pending is not None

    def _charger_near(self, pose: Pose, robot: Pose) -> Pose | None:
        """The charger the dock detector sees for a dock requested at ``pose``, if any."""
        for c in self.state.chargers:
            if (
                math.hypot(c[0] - pose[0], c[1] - pose[1]) <= DETECT_DISTANCE
                and abs(wrap_angle(c[2] - pose[2])) <= DETECT_YAW
                and math.hypot(c[0] - robot[0], c[1] - robot[1]) <= DETECT_RANGE
            ):
                return c
        return None

    # -- ends --------------------------------------------------------------------------------

    def _feedback(self, job: _Job, state: int) -> None:
        owner = job.owner
        if owner is not None and owner.feedback and self.state.relaying:
            owner.send_feedback(ros2.dock_feedback(state, self.state.t - job.started))

    def _values(self, job: _Job, success: bool, code: int, text: str) -> dict[str, Any]:
        if job.kind == "dock":
            return ros2.dock_result(self.release, success, code, text)
        return ros2.undock_result(success, code)

    def _fail(self, job: _Job, code: int, text: str, *, then: _Job | None = None) -> None:
        self._end(job, ros2.ABORTED, self._values(job, False, code, text), then=then)

    def _end(
        self, job: _Job, status: int, values: dict[str, Any], *, then: _Job | None = None
    ) -> None:
        """End ``job``: its result to its client (not if the bridge's ROS side is gone); the
        next goal (``then``, or the first waiting) is the server's."""
        if job is self.active:
            self._let_go(job)
            self.active = (
                then if then is not None else (self.waiting.pop(0) if self.waiting else None)
            )
        elif job in self.waiting:
            self.waiting.remove(job)
        owner = job.owner
        if owner is not None:
            owner.end(status, values, send=not self.state.ros_side_dead)

    def _let_go(self, job: _Job | None) -> None:
        """The server stops working on ``job``: its staging goal cancelled, the base and the
        charger's current back to the robot."""
        st = self.state
        st.docking_drives = False
        st.charge_off = False
        if job is not None and job.staging is not None and not job.staging.terminal:
            self.navigator.cancel_one(job.staging, "")
