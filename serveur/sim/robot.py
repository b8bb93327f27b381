"""One simulated waiter robot's ROS graph: move_base (or Nav2), AMCL, odometry, laser, battery.

Split from :mod:`serveur.robot_sim` (the fleet, its physics loop and ``serveur sim``) because a
robot is a subject of its own: what a ROS1 robot with move_base and AMCL does with the goals,
cancels, ``cmd_vel`` and initial poses it is sent, and what it publishes, at which rates, with
which quirks (actionlib's status list, terminal goals kept 5 s, a blocked robot aborting its
goal, noisy AMCL poses and laser scans). Its rosbridge side is :mod:`serveur.sim.bridge`.
Everything is stepped by the fleet at :data:`TICK` of simulated time.

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

The robot's clock may run ``clock_offset`` seconds from the fleet's (a robot whose NTP is off):
everything it stamps — headers, the stamps of zero-stamped goals, rosapi ``get_time`` — is
``clock.epoch() + clock_offset``.

AMCL runs in one of :data:`AMCL_MODES`: ``"continuous"`` publishes ``/amcl_pose`` at 10 Hz
whatever the robot does; ``"real"`` behaves like the amcl node (shared/notes/rosbridge.md): the
topic is latched (a new subscriber gets the last pose at once), and a pose is published once at
start, once after each ``/initialpose`` and otherwise only after the robot moved more than
:data:`AMCL_UPDATE_MIN_D` or turned more than :data:`AMCL_UPDATE_MIN_A` since the last
published pose (amcl's ``update_min_d``/``update_min_a``): a parked robot publishes nothing.

A robot made with ``ros=2`` is a ROS 2 robot running Nav2 behind rosbridge 2.x
(shared/notes/ros2.md; its wire forms in :mod:`serveur.sim.ros2`, the action ops in
:mod:`serveur.sim.bridge`). The same body, planner and sensors, with these differences:

* No ``/move_base/*`` topics: goals come as ``send_action_goal`` to ``navigate_to_pose``
  (:meth:`SimRobot.nav2_goal`) or on ``/goal_pose`` (RViz2), and the robot answers the goal's
  sender alone: feedback every physics tick (20 Hz, unthrottled, as the navigator's feedback
  reached clients on a real stack) and one result, SUCCEEDED 4, CANCELED 5 (a cancel: CANCELING
  until the navigator's next cycle) or ABORTED 6 (blocked, stuck, too slow, no path, or a newer
  goal: Nav2's navigator aborts the goal it drives when another arrives). A goal it cannot take
  (not in ``map``, NaN, not a rotation about z, off the map) is rejected, which rosbridge
  before its 2026 fix never reports.
* Every message has ROS 2 shapes: ``{sec, nanosec}`` stamps, headers without ``seq``;
  ``/battery_state`` leaves the temperature it does not measure NaN (``null``).
* AMCL's "real" mode uses Nav2 amcl's defaults, 0.25 m / 0.2 rad.
* ``/initialpose`` in a frame other than ``map`` (an empty one too), with a NaN, or off the map
  is ignored with a log line and no error to the client (Nav2 amcl ``initialPoseReceived``).
* ``/cmd_vel`` is ``geometry_msgs/msg/Twist``, or ``TwistStamped`` with ``twist_stamped`` (a
  message of the other type is refused, as rosbridge 2.x cannot fill it in); ignored while a
  goal runs, with the same stale-command watchdog as a ROS1 robot.
* ``release`` picks the result's shape (Humble ``{result: {}}``, Jazzy and Kilted
  ``{error_code, error_msg}`` with Nav2's codes: 208 no valid path, 105 no progress, 9000).

Other robots are not obstacles unless the fleet says so (:meth:`SimRobot.share_floor`, the
fleet's ``robots_see_each_other``; off by default). Then each robot's footprint, a disc of the
planner's robot radius, shows in the others' ``/scan`` (ray-disc intersection) and stops them:
a robot slows down to stop :data:`ROBOT_GAP` short of one in its way and waits, as a local
planner whose costmap holds the other robot does; after :data:`ROBOT_REPLAN_AFTER` s it plans
around the robots standing still (their discs marked on a copy of the map, as a costmap's
obstacle layer marks them) and takes the detour if one exists; after the patience
(:data:`ROBOT_PATIENCE`, 30 s of sim time: move_base aborts after ``controller_patience``, 15 s
by default in move_base.cpp, plus its default recoveries; Nav2's default navigate_to_pose tree
retries 6 times, with a progress checker allowing 10 s per 0.5 m, docs.nav2.org) its goal
ABORTs with "blocked by another robot (NAME) for N s": move_base ABORTED (4), Nav2 status 6
with error code 105 (FAILED_TO_MAKE_PROGRESS). What is not modelled: the recoveries' own motion
(in-place rotations, backing up), other robots' velocities (only where they are now), and any
rule about who gives way, so two robots meeting head-on in an aisle one robot wide deadlock
until both goals abort.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import logging
import math
import random
import threading
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from serveur.clock import Clock
from serveur.errors import RosbridgeError, ServeurError
from serveur.maps.navigation import OccupancyMap, Planner, raycast
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.kinematics import (
    Kind,
    Limits,
    MotionModel,
    OdometryModel,
    PathFollower,
    wrap_angle,
)
from serveur.sim.topics import ActionSink, Frame, Sub, consume_exception

__all__ = [
    "AMCL_MODES",
    "AMCL_TICKS",
    "AMCL_UPDATE_MIN_A",
    "AMCL_UPDATE_MIN_D",
    "LAST_CANCEL_CANCELED",
    "MAX_CATCH_UP",
    "NAV2_UPDATE_MIN_A",
    "NAV2_UPDATE_MIN_D",
    "ROBOT_GAP",
    "ROBOT_PATIENCE",
    "ROS1_SUBSCRIBES",
    "SAS_ACCEPTED",
    "SAS_CANCELED",
    "TICK",
    "SimRobot",
]

log = logging.getLogger("serveur.robot_sim")

#: Physics step in simulated seconds (20 Hz); publish periods are whole numbers of ticks.
TICK: Final = 0.05
_ODOM_TICKS: Final = 1  # 20 Hz
AMCL_TICKS: Final = 2  # 10 Hz
_FEEDBACK_TICKS: Final = 2  # 10 Hz while a goal is active
_SCAN_TICKS: Final = 4  # 5 Hz
_STATUS_TICKS: Final = 4  # 5 Hz (actionlib's default status_frequency)
_BATTERY_TICKS: Final = 20  # 1 Hz
#: Most physics steps taken in one loop pass when the loop fell behind; beyond, sim time slips.
MAX_CATCH_UP: Final = 20

#: A teleop command older than this (wall seconds) is stale and the base stops, as a velocity
#: watchdog does. Wall time, not the robot's: a person's joystick repeats at 5-10 Hz of wall
#: time, so in robot time the timeout must grow with --time-scale or the robot crawls (at 10x,
#: commands 2 s of robot time apart against a 0.5 s watchdog).
CMD_VEL_TIMEOUT: Final = 0.5
TERMINAL_KEEP: Final = 5.0  # s sim a finished goal stays in the status list (actionlib's default)
BLOCKED_ABORT_AFTER: Final = 1.0  # s sim a blocked robot waits before aborting its goal
STUCK_ABORT_AFTER: Final = 3.0  # s sim pushing against an obstacle before aborting
#: Other robots as obstacles (opt-in, :meth:`SimRobot.share_floor`). A robot blocked by another
#: waits this long (s sim) before its goal ABORTs. move_base gives up after controller_patience
#: (15 s by default, move_base.cpp) then its default recoveries (two costmap clearings, two
#: in-place rotations); Nav2's default tree retries 6 times with Wait 5 s among its recoveries
#: and a progress checker allowing 10 s per 0.5 m. Some tens of seconds either way: 30 s.
ROBOT_PATIENCE: Final = 30.0
#: s sim blocked by a robot standing still before planning around it (a costmap marks it and
#: the planner routes around it), then at most every 5 s (move_base's planner_patience).
ROBOT_REPLAN_AFTER: Final = 2.0
ROBOT_REPLAN_EVERY: Final = 5.0
#: m a robot's footprint stops short of another's (a local planner's safety margin).
ROBOT_GAP: Final = 0.05
_ROBOT_STOP: Final = 0.02  # m of room left under which a robot counts as blocked
#: m a blocked robot must get from where it stopped to count as progressing again (Nav2's
#: SimpleProgressChecker ``required_movement_radius`` default).
ROBOT_PROGRESS: Final = 0.5
_ROBOT_STILL: Final = 0.05  # m/s: a robot slower than this is standing still (planned around)
#: s sim between asking for a plan around robots and taking it: the planning runs in a worker
#: thread meanwhile (~40 ms on the demo room), and the robot, standing still, takes the detour
#: exactly this long after it asked whatever the load (a run stays deterministic).
ROBOT_REPLAN_TAKES: Final = 0.5
_DETOURS: concurrent.futures.ThreadPoolExecutor | None = None


def _detour_pool() -> concurrent.futures.ThreadPoolExecutor:
    global _DETOURS
    if _DETOURS is None:
        _DETOURS = concurrent.futures.ThreadPoolExecutor(2, thread_name_prefix="sim-detour")
    return _DETOURS


SCAN_RAYS: Final = 360
SCAN_RANGE_MIN: Final = 0.12
SCAN_RANGE_MAX: Final = 8.0
SCAN_NOISE: Final = 0.01  # m, sigma
AMCL_NOISE_XY: Final = 0.01  # m, sigma
AMCL_NOISE_YAW: Final = 0.005  # rad, sigma
#: ``amcl`` parameter values: 10 Hz poses whatever happens, or the amcl node's behaviour.
AMCL_MODES: Final = ("continuous", "real")
AMCL_UPDATE_MIN_D: Final = 0.2  # m: amcl's update_min_d default
AMCL_UPDATE_MIN_A: Final = math.pi / 6.0  # rad (30 degrees): amcl's update_min_a default
NAV2_UPDATE_MIN_D: Final = 0.25  # m: Nav2 amcl's update_min_d default
NAV2_UPDATE_MIN_A: Final = 0.2  # rad: Nav2 amcl's update_min_a default
#: Topics a ROS1 robot subscribes to (clients may publish there; anything else is refused).
ROS1_SUBSCRIBES: Final = frozenset(
    {"/move_base/goal", "/move_base_simple/goal", "/move_base/cancel", "/cmd_vel", "/initialpose"}
)
#: Topics a ROS 2 robot subscribes to.
ROS2_SUBSCRIBES: Final = frozenset({"/cmd_vel", "/initialpose", "/goal_pose"})

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
_MAP_FRAMES: Final = frozenset({"map", "/map", ""})


# ---------------------------------------------------------------------------------------------
# Goals
# ---------------------------------------------------------------------------------------------


@dataclass(slots=True)
class _Goal:
    id: str
    stamp: float  # the goal's own ROS stamp (cancel-by-time compares it)
    x: float
    y: float
    yaw: float
    status: GoalStatus = GoalStatus.PENDING
    text: str = ""
    ended: float = math.inf  # sim time when it became terminal
    #: ROS 2: the rosbridge goal (its connection) that gets feedback and the result.
    owner: ActionSink | None = None
    started: float = 0.0  # sim time it arrived (navigation_time)

    @property
    def terminal(self) -> bool:
        return self.status in rb.TERMINAL_STATUSES


# ---------------------------------------------------------------------------------------------
# The robot
# ---------------------------------------------------------------------------------------------


class SimRobot:
    """One simulated robot: its body, its move_base, its sensors, and what it publishes.

    Public read-only state: ``name``, ``pose`` (true pose), ``kinematics``, ``battery``
    (0..1), ``home``, ``velocity``, ``clock_offset``, ``amcl``, ``ros`` (1 or 2), and for ROS 2
    ``release``, ``twist_stamped``, ``humble_queue``, ``rosbridge_fix``; ``topic_types`` and
    ``subscribes`` (the robot's graph in its dialect). Fault hooks: :meth:`block_path`,
    :meth:`ignore_goals`, and for ROS 2 :meth:`drop_results`.

    ``clock_offset`` (seconds) is added to every stamp the robot makes (:meth:`epoch`);
    ``amcl`` is one of :data:`AMCL_MODES` (see the module's docstring).
    """

    def __init__(
        self,
        name: str,
        *,
        index: int,
        grid: OccupancyMap,
        planner: Planner,
        home: tuple[float, float, float],
        kinematics: Kind,
        clock: Clock,
        seed: int,
        limits: Limits | None = None,
        map_frame: Frame | None = None,
        plan_lock: threading.Lock | None = None,
        clock_offset: float = 0.0,
        amcl: str = "continuous",
        namespace: str = "",
        ros: int = 1,
        release: str = "jazzy",
        twist_stamped: bool | None = None,
        humble_queue: bool | None = None,
        rosbridge_fix: bool = False,
    ) -> None:
        if amcl not in AMCL_MODES:
            raise ValueError(f"amcl must be one of {AMCL_MODES}, not {amcl!r}")
        if ros not in (1, 2):
            raise ValueError(f"ros must be 1 or 2, not {ros!r}")
        if release not in ros2.RELEASES:
            raise ValueError(f"release must be one of {ros2.RELEASES}, not {release!r}")
        if not math.isfinite(clock_offset):
            raise ValueError("clock_offset must be a finite number of seconds")
        self.name = name
        #: Every topic of the robot lives under this ROS namespace ("" for none, "/r1").
        self.namespace = namespace.rstrip("/")
        self.clock_offset = float(clock_offset)
        self.amcl = amcl
        #: The dialect: 1 (rosbridge 0.11, move_base, amcl) or 2 (rosbridge 2.x, Nav2).
        self.ros = ros
        #: ROS 2 release (:data:`serveur.sim.ros2.RELEASES`): the NavigateToPose result's shape
        #: and the defaults of the two switches below.
        self.release = release
        #: ROS 2: ``/cmd_vel`` is geometry_msgs/msg/TwistStamped (Kilted's default).
        self.twist_stamped = release == "kilted" if twist_stamped is None else bool(twist_stamped)
        #: ROS 2: rosbridge's ``send_action_goals_in_new_thread`` is false (Humble's default):
        #: a goal holds its connection's later ops until it ends (see serveur.sim.bridge).
        self.humble_queue = release == "humble" if humble_queue is None else bool(humble_queue)
        #: ROS 2: rosbridge with the 2026 fix: a rejected goal, or one to an action nobody
        #: serves (after 1 s), gets ``action_result`` with ``result`` false instead of nothing.
        self.rosbridge_fix = bool(rosbridge_fix)
        if ros == 2:
            self.topic_types = ros2.topic_types(self.twist_stamped)
            self.subscribes = ROS2_SUBSCRIBES
            self._amcl_min = (NAV2_UPDATE_MIN_D, NAV2_UPDATE_MIN_A)
        else:
            self.topic_types = dict(rb.TOPIC_TYPES)
            self.subscribes = ROS1_SUBSCRIBES
            self._amcl_min = (AMCL_UPDATE_MIN_D, AMCL_UPDATE_MIN_A)
        self.index = index
        self.kinematics: Kind = kinematics
        self.home = home
        self.limits = limits or Limits()
        self._map = grid
        self._planner = planner
        self._clock = clock
        self._rng = random.Random(seed)
        self._np_rng = np.random.default_rng(seed)
        self._motion = MotionModel(kinematics, self.limits, *home)
        self._odom = OdometryModel(self._rng)
        self._battery = 1.0
        self._charging = False
        self._map_frame = map_frame
        self._subs: dict[str, list[Sub]] = {}
        self._seqs: dict[str, int] = {}
        self._t = clock.now()  # sim time of the last physics step
        self._ticks = index  # staggers publishing across robots
        # move_base
        self._goals: list[_Goal] = []
        self._pending: _Goal | None = None
        self._plan_fut: asyncio.Future[list[tuple[float, float]]] | None = None
        self._plan_goal: _Goal | None = None
        self._plan_lock = plan_lock or threading.Lock()
        self._active: _Goal | None = None
        self._follower: PathFollower | None = None
        self._goal_deadline = math.inf
        self._blocked_since: float | None = None
        self._stuck_for = 0.0
        self._goal_counter = itertools.count(1)
        #: Stamp of the last goal the SimpleActionServer took (its current or next goal).
        self._sas_stamp = 0.0
        #: Latest stamp of a cancel-by-stamp (ActionServer's ``last_cancel``).
        self._last_cancel = 0.0
        # AMCL in "real" mode: the latched pose, the true pose it was taken at, a forced update
        self._amcl_frame: Frame | None = None
        self._amcl_at: tuple[float, float, float] | None = None
        self._amcl_force = True
        # teleop
        self._teleop: tuple[float, float, float] | None = None
        self._teleop_t = -math.inf
        # faults
        self._block_path = False
        self._ignore_goals = False
        self._drop_results = 0
        # laser
        self._scan_rel = -math.pi + (2.0 * math.pi / SCAN_RAYS) * np.arange(SCAN_RAYS)
        self._scan_cache: tuple[tuple[float, float, float], npt.NDArray[np.float64]] | None = None
        # other robots (share_floor): none unless the fleet makes them solid
        #: Footprint radius (m): the planner's robot radius, a disc.
        self.radius = planner.robot_radius
        self._others: tuple[SimRobot, ...] = ()
        self._patience = ROBOT_PATIENCE
        self._wait_since: float | None = None  # sim time a robot in the way stopped this one
        self._wait_at = (0.0, 0.0)  # where it stopped
        self._replanned = -math.inf  # sim time of the last plan around standing robots
        #: A plan around robots under way: (sim time to take it, where it starts, the plan).
        self._detour: (
            tuple[float, tuple[float, float], concurrent.futures.Future[list[tuple[float, float]]]]
            | None
        ) = None
        self._robots_scan: (
            tuple[
                tuple[float, float, float], tuple[tuple[float, float], ...], npt.NDArray[np.float64]
            ]
            | None
        ) = None

    # -- names -------------------------------------------------------------------------------

    def wire(self, topic: str) -> str:
        """A topic's name on the wire: under the robot's namespace, if it has one."""
        return self.namespace + topic

    def local(self, topic: str) -> str | None:
        """A wire name without the namespace (None: a name outside the robot's namespace)."""
        if not self.namespace:
            return topic
        prefix = self.namespace + "/"
        return topic[len(self.namespace) :] if topic.startswith(prefix) else None

    # -- public state ----------------------------------------------------------------------

    def epoch(self) -> float:
        """The robot's ROS time now: the fleet clock's Unix time plus ``clock_offset``."""
        return self._clock.epoch() + self.clock_offset

    @property
    def pose(self) -> tuple[float, float, float]:
        """True pose (x, y, yaw) in the map frame."""
        m = self._motion
        return m.x, m.y, m.yaw

    @property
    def velocity(self) -> tuple[float, float, float]:
        """True body velocity (vx, vy, wz)."""
        m = self._motion
        return m.vx, m.vy, m.wz

    @property
    def battery(self) -> float:
        """State of charge, 0..1 (sensor_msgs/BatteryState.percentage)."""
        return self._battery

    @battery.setter
    def battery(self, value: float) -> None:
        self._battery = min(1.0, max(0.0, float(value)))

    @property
    def goal_statuses(self) -> list[tuple[str, GoalStatus, str]]:
        """What ``/move_base/status`` lists now: (goal id, status, text). A ROS 2 robot lists
        its navigator's goals the same way: under the client's goal id (``nav2-N`` without
        one), with actionlib statuses (a cancelled goal PREEMPTED, one aborted by a newer goal
        ABORTED; a goal taken while :meth:`ignore_goals` is on stays PENDING)."""
        return [(g.id, g.status, g.text) for g in self._goals]

    def block_path(self, on: bool) -> None:
        """Fault hook: while on, the active goal (or the next one) ABORTs as if the aisle were
        blocked — the robot stops and gives up after ``BLOCKED_ABORT_AFTER`` s of sim time."""
        self._block_path = bool(on)
        if not on:
            self._blocked_since = None

    def ignore_goals(self, on: bool) -> None:
        """Fault hook: while on, goals are never acknowledged — status keeps publishing without
        them, no result ever comes (a hung move_base). A ROS 2 goal then gets no frame at all,
        and with the queue trap its connection stays held."""
        self._ignore_goals = bool(on)

    def drop_results(self, n: int = 1) -> None:
        """Fault hook (ROS 2): the next ``n`` goals end on the robot but their ``action_result``
        never reaches the client (measured about once in 200 goals on a real Jazzy stack,
        shared/notes/ros2.md; the cause is unknown). The connection is not held by them."""
        self._drop_results = max(0, int(n))

    def teleport(self, x: float, y: float, yaw: float) -> None:
        """Put the robot somewhere else (like /initialpose, for tests)."""
        self._relocalise(x, y, yaw)

    def share_floor(self, others: Sequence[SimRobot], patience: float = ROBOT_PATIENCE) -> None:
        """Make ``others`` solid for this robot: their footprints (discs of their
        :attr:`radius`) show in its ``/scan`` and it never drives its own into theirs.

        Driving a goal, the robot slows down to stop :data:`ROBOT_GAP` short of a robot in its
        way and waits; after :data:`ROBOT_REPLAN_AFTER` s, if the robots in the way stand still,
        it plans around their footprints (again at most every :data:`ROBOT_REPLAN_EVERY` s)
        and follows the detour if there is one. Blocked ``patience`` s (sim) without getting
        :data:`ROBOT_PROGRESS` m from where it stopped, its goal ABORTs ("blocked by another
        robot"). Any other motion (teleop) into another robot is simply not taken. Nothing
        decides who gives way: two robots meeting head-on in an aisle one robot wide deadlock
        until both goals abort, as two move_base/Nav2 robots without a fleet manager would.
        """
        if not (math.isfinite(patience) and patience > 0):
            raise ValueError("patience must be a positive number of seconds")
        self._others = tuple(o for o in others if o is not self)
        self._patience = float(patience)
        self._wait_since = None

    # -- subscriptions -----------------------------------------------------------------------

    def _add_sub(self, sub: Sub) -> None:
        self._subs.setdefault(sub.topic, []).append(sub)

    def _remove_sub(self, sub: Sub) -> None:
        subs = self._subs.get(sub.topic)
        if subs and sub in subs:
            subs.remove(sub)
            if not subs:
                del self._subs[sub.topic]

    def _next_seq(self, topic: str) -> int:
        s = self._seqs.get(topic, 0)
        self._seqs[topic] = s + 1
        return s

    def _publish(
        self,
        topic: str,
        build: Callable[[int, float], dict[str, Any]],
        stamp: float | None = None,
    ) -> None:
        """Build (only if a subscriber takes it now) and hand one frame to every subscriber.

        ``stamp`` defaults to now; ticks pass their own sim time.
        """
        subs = self._subs.get(topic)
        if not subs:
            return
        t = self._t
        wanting = [s for s in subs if s.wants(t)]
        if not wanting:
            return
        if stamp is None:
            stamp = self.epoch()
        msg = build(self._next_seq(topic), stamp)
        frame = Frame(rb.op_publish(self.wire(topic), ros2.to_ros2(msg) if self.ros == 2 else msg))
        for s in wanting:
            s.push(frame, t)

    def _relay(self, topic: str, msg: Mapping[str, Any]) -> None:
        """A client's publish on a robot topic also reaches that topic's subscribers (ROS does)."""
        if topic in self._subs:
            frame = Frame(rb.op_publish(self.wire(topic), msg))
            t = self._clock.now()
            for s in list(self._subs[topic]):
                if s.wants(t):
                    s.push(frame, t)

    def _offer_latched(self, sub: Sub) -> None:
        """A new subscriber to a latched topic gets its last message at once."""
        if sub.topic == "/map" and self._map_frame is not None:
            sub.push(self._map_frame, self._t)
        elif sub.topic == "/amcl_pose" and self._amcl_frame is not None:
            sub.push(self._amcl_frame, self._t)

    # -- incoming messages (raise RosbridgeError on shapes the ROS type cannot hold) ----------

    def handle_publish(self, topic: str, msg: Mapping[str, Any]) -> str | None:
        """Apply a client's message on a topic the robot subscribes; returns a warning or None."""
        if self.ros == 2:
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
        self._relay(topic, msg)
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
        self._relay(topic, msg)
        return None

    def _on_initialpose2(self, msg: Mapping[str, Any]) -> None:
        """Nav2's amcl ``initialPoseReceived``: a pose whose frame is not ``map`` (a leading
        ``/`` stripped; an empty frame too), or with a NaN, or off the map, is ignored with only
        a log line on the robot: no error reaches the client (shared/notes/ros2.md)."""
        m = _obj(msg, "initialpose")
        frame = _header_frame(m)
        x, y, yaw = rb.pose_from_msg(_obj(_obj(m.get("pose"), "pose").get("pose"), "pose.pose"))
        if frame.lstrip("/") != "map":
            log.warning("%s: amcl ignores an initial pose in frame %r", self.name, frame)
            return
        if not all(math.isfinite(v) for v in (x, y, yaw)) or not self._on_map(x, y):
            log.warning("%s: amcl ignores an initial pose off the map or with NaN", self.name)
            return
        self._relocalise(x, y, yaw)

    def _on_map(self, x: float, y: float) -> bool:
        g = self._map
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
    ) -> bool:
        """A NavigateToPose goal reaching the navigator; False if it is rejected.

        ``gid`` is the id the client gave the goal (rosbridge's op id): :attr:`goal_statuses`
        lists the goal under it, so a test sees which ids a driver sent (else ``nav2-N``).

        A goal the navigator cannot take (not in the map frame, NaN, not a rotation about z,
        off the map) is rejected: rosbridge before its 2026 fix then sends no frame at all
        (shared/notes/ros2.md), so the owner never hears of it. A taken goal aborts (status 6)
        the one the navigator was driving: a new goal to Nav2's navigator is not a cancel.
        """
        gid = gid if gid is not None else f"nav2-{next(self._goal_counter)}"
        if self._ignore_goals:  # a hung navigator: the goal is listed, never run nor answered
            self._goals.append(_Goal(gid, self.epoch(), x, y, 0.0))
            return True
        if _goal_problem(frame, x, y, q) is not None or not self._on_map(x, y):
            return False
        goal = _Goal(gid, self.epoch(), x, y, 0.0)
        goal.yaw = rb.yaw_from_quaternion({"x": q[0], "y": q[1], "z": q[2], "w": q[3]})
        goal.owner, goal.started = owner, self._t
        for g in self._goals:
            if not g.terminal:
                self._finish(g, GoalStatus.ABORTED, "preempted by a newer goal")
        self._goals.append(goal)
        self._teleop = None
        self._pending = goal
        return True

    def nav2_cancel(self, owner: ActionSink) -> None:
        """A cancel request for the goal ``owner`` sent: CANCELING, then CANCELED at the
        navigator's next cycle (~20 ms after the cancel on a real stack)."""
        for g in self._goals:
            if g.owner is owner and not g.terminal:
                self._cancel_one(g, "")

    def _nav2_feedback(self, g: _Goal, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.pose
        f = self._follower
        if f is None:
            left = math.hypot(g.x - x, g.y - y)
        else:
            seg = min(f._seg, len(f.path) - 2)
            if seg < 0:
                left = math.hypot(g.x - x, g.y - y)
            else:
                nx, ny = f.path[seg + 1]
                left = math.hypot(nx - x, ny - y) + f._tail[seg]
        return ros2.nav2_feedback(
            x,
            y,
            yaw,
            stamp=stamp,
            navigation_time=self._t - g.started,
            distance_remaining=left,
            speed=self._motion.speed,
        )

    def _on_cmd_vel(self, msg: Mapping[str, Any]) -> str | None:
        """A teleop command drives the base only while move_base has no goal.

        move_base does not subscribe to ``/cmd_vel`` (shared/notes/rosbridge.md): a goal is not
        preempted by teleop, and while it runs the controller's own ``/cmd_vel`` (every cycle)
        overrides a teleop command, so the command is dropped. Nav2's controller_server does
        the same to a ROS 2 robot's teleop.
        """
        vx, vy, wz = rb.twist_from_msg(msg)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise RosbridgeError("cmd_vel holds a non-finite velocity")
        if self._active is not None or self._pending is not None:
            return None
        self._teleop = (vx, vy, wz)
        self._teleop_t = self._clock.now()
        return None

    def _on_initialpose(self, msg: Mapping[str, Any]) -> str | None:
        m = _obj(msg, "initialpose")
        frame = _header_frame(m)
        x, y, yaw = rb.pose_from_msg(_obj(_obj(m.get("pose"), "pose").get("pose"), "pose.pose"))
        if frame not in _MAP_FRAMES:
            raise RosbridgeError(f"initialpose must be in the map frame, not {frame!r}")
        if not all(math.isfinite(v) for v in (x, y, yaw)):
            raise RosbridgeError("initialpose holds a non-finite value")
        self._relocalise(x, y, yaw)
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
        frame = _header_frame(target)
        pose = _obj(target.get("pose"), "pose")
        x, y, _ = rb.point_from_msg(_obj(pose.get("position"), "position"))
        q = rb.quaternion_from_msg(_obj(pose.get("orientation"), "orientation"))
        if self._ignore_goals:
            return None
        now = self.epoch()
        if not gid:
            gid = f"/move_base-{next(self._goal_counter)}-{now:.9f}"
        if any(g.id == gid for g in self._goals):
            return f"goal {gid} is a duplicate; ignored"
        # StatusTracker: a zero stamp becomes the robot's now, so such a goal is the newest.
        goal = _Goal(gid, gstamp if gstamp != 0.0 else now, x, y, 0.0)
        self._goals.append(goal)
        if gstamp != 0.0 and gstamp <= self._last_cancel:  # ActionServer
            self._finish(goal, GoalStatus.RECALLED, LAST_CANCEL_CANCELED)
            return None
        if goal.stamp < self._sas_stamp:  # SimpleActionServer: older than the goal it has
            self._finish(goal, GoalStatus.RECALLED, SAS_CANCELED)
            return None
        self._sas_stamp = goal.stamp
        reason = _goal_problem(frame, x, y, q)
        if reason is not None:
            self._finish(goal, GoalStatus.REJECTED, reason)
            return None
        goal.yaw = rb.yaw_from_quaternion({"x": q[0], "y": q[1], "z": q[2], "w": q[3]})
        # The newer goal preempts the current one (SimpleActionServer.accept_new_goal) and
        # bumps one still pending (internal_goal_callback).
        for g in self._goals:
            if g is not goal and not g.terminal:
                self._cancel_one(g, SAS_CANCELED, at_once=True)
        self._teleop = None
        self._pending = goal
        self._publish_status()
        return None

    def _on_cancel(self, msg: Mapping[str, Any]) -> str | None:
        """ActionServer ``internal_cancel_callback``: all, by id, or up to a stamp."""
        gid, stamp = rb.goal_id_from_msg(_obj(msg, "cancel"))
        everything = not gid and stamp == 0.0
        for g in list(self._goals):
            if not g.terminal and (
                everything or g.id == gid or (stamp != 0.0 and g.stamp <= stamp)
            ):
                self._cancel_one(g, "")
        self._last_cancel = max(self._last_cancel, stamp)
        return None

    # -- move_base ---------------------------------------------------------------------------

    def _cancel_one(self, g: _Goal, text: str, *, at_once: bool = False) -> None:
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

    def _finish(self, g: _Goal, status: GoalStatus, text: str, *, code: int = 0) -> None:
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

    def _end_nav2(self, g: _Goal, status: GoalStatus, text: str, code: int) -> None:
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
        send = self._drop_results == 0
        if not send:
            self._drop_results -= 1
        owner.end(st, values, send=send)

    def _plan_blocking(
        self, start: tuple[float, float], goal: tuple[float, float]
    ) -> list[tuple[float, float]]:
        with self._plan_lock:  # the shared Planner's cache is not thread-safe
            return self._planner.plan(start, goal)

    def _request_plan(self, g: _Goal) -> None:
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

    def _command(self, now: float) -> tuple[float, float, float]:
        if self._active is not None and self._active.status == GoalStatus.PREEMPTING:
            # move_base's control cycle sees the preempt request: zero velocity, setPreempted()
            self._finish(self._active, GoalStatus.PREEMPTED, "")
            return 0.0, 0.0, 0.0
        if self._teleop is not None:
            if now - self._teleop_t > CMD_VEL_TIMEOUT * self._clock.time_scale:
                self._teleop = None  # stale: stop, as a velocity watchdog does
                return 0.0, 0.0, 0.0
            return self._teleop
        if self._plan_fut is not None and self._plan_fut.done():
            self._take_plan()
        if self._pending is not None and self._plan_fut is None:
            self._request_plan(self._pending)
            if self._plan_fut is not None and self._plan_fut.done():  # planned at once
                self._take_plan()
        g, f = self._active, self._follower
        if g is None or f is None:
            return 0.0, 0.0, 0.0
        if self._block_path:
            if self._blocked_since is None:
                self._blocked_since = self._t
            elif self._t - self._blocked_since >= BLOCKED_ABORT_AFTER:
                self._finish(
                    g,
                    GoalStatus.ABORTED,
                    "path blocked: no valid plan (aisle obstructed)",
                    code=ros2.NO_VALID_PATH,
                )
            return 0.0, 0.0, 0.0
        if self._t > self._goal_deadline:
            self._finish(
                g, GoalStatus.ABORTED, "the robot did not reach the goal in time", code=ros2.UNKNOWN
            )
            return 0.0, 0.0, 0.0
        m = self._motion
        cmd = f.command(m.x, m.y, m.yaw)
        if f.done and m.speed < 0.01 and abs(m.wz) < 0.02:
            dx, dy = g.x - m.x, g.y - m.y
            if (
                math.hypot(dx, dy) <= f.xy_tolerance
                and abs(wrap_angle(g.yaw - m.yaw)) <= f.yaw_tolerance
            ):
                self._finish(g, GoalStatus.SUCCEEDED, "Goal reached.")
                return 0.0, 0.0, 0.0
        if self._others:
            return self._mind_robots(g, cmd)
        return cmd

    # -- other robots (share_floor) ----------------------------------------------------------

    def _gap_ahead(self, dx: float, dy: float) -> tuple[float, SimRobot | None]:
        """How far (m) this robot's footprint can go along the unit vector (dx, dy) before it
        touches another robot's, and which robot that is (inf, None: nothing in the way)."""
        m = self._motion
        best, who = math.inf, None
        for o in self._others:
            om = o._motion
            px, py = om.x - m.x, om.y - m.y
            s = px * dx + py * dy
            if s <= 0.0:
                continue  # beside or behind
            reach = self.radius + o.radius
            h2 = px * px + py * py - s * s
            if h2 >= reach * reach:
                continue  # passes clear of it
            gap = max(0.0, s - math.sqrt(reach * reach - h2))
            if gap < best:
                best, who = gap, o
        return best, who

    def _mind_robots(self, g: _Goal, cmd: tuple[float, float, float]) -> tuple[float, float, float]:
        """The local planner facing other robots: slow down to stop short of one in the way,
        wait, plan around robots standing still, and abort after the patience."""
        m = self._motion
        if self._detour is not None and self._t >= self._detour[0] - 1e-9:
            self._take_detour(g)
            cmd = self._follower.command(m.x, m.y, m.yaw) if self._follower else (0.0, 0.0, 0.0)
        vx, vy, wz = cmd
        speed = math.hypot(vx, vy)
        gap, who = math.inf, None
        if speed > 1e-9:
            c, s = math.cos(m.yaw), math.sin(m.yaw)
            gap, who = self._gap_ahead((vx * c - vy * s) / speed, (vx * s + vy * c) / speed)
        room = gap - ROBOT_GAP
        if room > _ROBOT_STOP:
            if self._wait_since is not None and (
                math.hypot(m.x - self._wait_at[0], m.y - self._wait_at[1]) >= ROBOT_PROGRESS
            ):
                self._wait_since = None  # got away: a new block starts a new wait
            if gap < math.inf:
                lim = self.limits
                v = min(math.sqrt(2.0 * 0.8 * lim.max_accel * room), 2.0 * room)
                if v < speed:
                    k = v / speed
                    return vx * k, vy * k, wz
            return cmd
        t = self._t
        if self._wait_since is None:
            self._wait_since, self._wait_at = t, (m.x, m.y)
            # waiting for a robot is not slowness: the goal's deadline leaves room for it
            self._goal_deadline = max(self._goal_deadline, t + self._patience + 1.0)
        waited = t - self._wait_since
        if waited >= self._patience:
            name = who.name if who is not None else "?"
            self._finish(
                g,
                GoalStatus.ABORTED,
                f"blocked by another robot ({name}) for {waited:.0f} s",
                code=ros2.FAILED_TO_MAKE_PROGRESS,
            )
        elif (
            waited >= ROBOT_REPLAN_AFTER
            and t - self._replanned >= ROBOT_REPLAN_EVERY
            and self._detour is None
        ):
            self._replanned = t
            self._plan_around(g)
        return 0.0, 0.0, 0.0

    def _plan_around(self, g: _Goal) -> None:
        """Ask for a plan to ``g`` with the footprints of the robots standing still marked as
        obstacles (a costmap's obstacle layer); :meth:`_take_detour` follows it if there is
        one, else the robot keeps waiting.

        The map and the robots are copied now and planned on in a worker thread (a fresh
        planner, one distance field: ~40 ms on the demo room), taken :data:`ROBOT_REPLAN_TAKES`
        s of sim time later, so neither the physics loop stalls nor a run's outcome depends on
        the machine's speed (a slow plan is waited for then).
        """
        still = [o for o in self._others if o._motion.speed < _ROBOT_STILL]
        if not still:
            return
        base = self._map
        grid = base.grid.copy()
        res, (ox, oy, _) = base.resolution, base.origin
        rows, cols = np.ogrid[0 : base.height, 0 : base.width]
        for o in still:
            om = o._motion
            cx, cy = (om.x - ox) / res - 0.5, (om.y - oy) / res - 0.5  # in cell-centre units
            r = o.radius / res
            grid[(rows - cy) ** 2 + (cols - cx) ** 2 <= r * r] = 100
        m = self._motion
        start, goal = (m.x, m.y), (g.x, g.y)
        radius, clearance = self._planner.robot_radius, self._planner.clearance

        def work() -> list[tuple[float, float]]:
            planner = Planner(
                OccupancyMap(grid, res, base.origin), radius, clearance=clearance, cache_size=1
            )
            return planner.plan(start, goal)

        fut = _detour_pool().submit(work)
        fut.add_done_callback(lambda f: f.cancelled() or f.exception())
        self._detour = (self._t + ROBOT_REPLAN_TAKES, start, fut)

    def _take_detour(self, g: _Goal) -> None:
        """Follow the plan :meth:`_plan_around` asked for (waiting for it if it is late), unless
        there is none or the robot moved since it asked."""
        due = self._detour
        self._detour = None
        assert due is not None
        _, (x0, y0), fut = due
        m = self._motion
        try:
            path = fut.result()
        except ServeurError as exc:
            log.debug("%s: no way around the robots in the way: %s", self.name, exc)
            return
        except Exception:
            log.exception("%s: planning around the robots in the way failed", self.name)
            return
        if math.hypot(m.x - x0, m.y - y0) > 0.05:
            return  # the way cleared meanwhile and the robot drove on
        self._follower = PathFollower(path, g.yaw, self.kinematics, self.limits)
        length = sum(math.dist(a, b) for a, b in itertools.pairwise(path))
        self._goal_deadline = max(
            self._goal_deadline, self._t + 30.0 + 3.0 * length / self.limits.max_speed
        )

    def _into_robot(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """Whether moving from (x0, y0) to (x1, y1) drives this robot's footprint into another
        robot's (robots already overlapping may still move apart)."""
        for o in self._others:
            om = o._motion
            reach = self.radius + o.radius
            d1 = math.hypot(x1 - om.x, y1 - om.y)
            if d1 < reach and d1 < math.hypot(x0 - om.x, y0 - om.y):
                return True
        return False

    # -- physics -----------------------------------------------------------------------------

    def _step(self, dt: float) -> None:
        self._t += dt
        m = self._motion
        if (
            self._teleop is None
            and self._active is None
            and self._pending is None
            and self._plan_fut is None
            and m.vx == 0.0
            and m.vy == 0.0
            and m.wz == 0.0
        ):
            # Parked (most of a robot's service): no command to compute, nothing to integrate,
            # odometry reads zero; only the battery and the goal list age. Same state as the
            # general path below, at a fraction of its cost (five robots x 20 Hz, replayed at
            # 300x, are 30,000 steps a wall second).
            self._odom.update(0.0, 0.0, 0.0, dt)
            self._stuck_for = 0.0
            self._battery_tick(dt)
            if self._goals and self._goals[0].ended < self._t - TERMINAL_KEEP:
                self._goals = [g for g in self._goals if g.ended >= self._t - TERMINAL_KEEP]
            return
        now = self._clock.now()
        cmd = self._command(now)
        if cmd == (0.0, 0.0, 0.0) and m.vx == 0.0 and m.vy == 0.0 and m.wz == 0.0:
            moved_ok = True  # at rest: nothing to integrate
            self._odom.update(0.0, 0.0, 0.0, dt)
        else:
            x0, y0 = m.x, m.y
            moved_ok = m.step(*cmd, dt, self._planner.is_traversable)
            if self._others and self._into_robot(x0, y0, m.x, m.y):
                m.x, m.y = x0, y0  # never into another robot: the base stops short
                m.vx = m.vy = 0.0
            if (
                abs(m.vx) < 1e-4
                and abs(m.vy) < 1e-4
                and abs(m.wz) < 1e-4
                and cmd == (0.0, 0.0, 0.0)
            ):
                m.vx = m.vy = m.wz = 0.0
            self._odom.update(m.vx, m.vy, m.wz, dt)
            self._battery_drain(math.hypot(m.x - x0, m.y - y0))
        if not moved_ok and self._active is not None:
            self._stuck_for += dt
            if self._stuck_for >= STUCK_ABORT_AFTER:
                self._finish(
                    self._active,
                    GoalStatus.ABORTED,
                    "the robot is stuck against an obstacle",
                    code=ros2.FAILED_TO_MAKE_PROGRESS,
                )
        elif moved_ok:
            self._stuck_for = 0.0
        self._battery_tick(dt)
        if self._goals and self._goals[0].ended < self._t - TERMINAL_KEEP:
            self._goals = [g for g in self._goals if g.ended >= self._t - TERMINAL_KEEP]

    def _battery_drain(self, distance: float) -> None:
        self._battery = max(0.0, self._battery - distance / 4000.0)  # ~4 km of driving a charge

    def _battery_tick(self, dt: float) -> None:
        m = self._motion
        hx, hy, _ = self.home
        at_home = (
            m.vx == 0.0
            and m.vy == 0.0
            and self._active is None
            and self._teleop is None
            and math.hypot(m.x - hx, m.y - hy) < 0.25
        )
        self._charging = at_home
        if at_home:
            self._battery = min(1.0, self._battery + dt / 7200.0)  # full in 2 h
        else:
            self._battery = max(0.0, self._battery - dt / 43200.0)  # 12 h idle

    # -- publishing --------------------------------------------------------------------------

    def _advance(self, steps: int) -> None:
        """Take ``steps`` physics steps, each followed by what falls due at its tick.

        Publishing per tick (not once per pass) keeps publish rates and stamps tied to sim
        time when the loop has to catch up several ticks at once (high time scales, load).
        """
        for _ in range(steps):
            self._step(TICK)
            self._ticks = k = self._ticks + 1
            # A latched pose is kept without subscribers; a ROS 2 goal's feedback has none.
            if self._subs or self.amcl == "real" or self.ros == 2:
                self._publish_due(k)

    def _publish_due(self, k: int) -> None:
        stamp = self._tick_stamp()
        if k % _ODOM_TICKS == 0:
            self._publish("/odom", self._build_odom, stamp)
        if k % AMCL_TICKS == 0:
            if self.amcl == "real":
                self._amcl_update(stamp)
            else:
                self._publish("/amcl_pose", self._build_amcl, stamp)
        if self.ros == 2:
            g = self._active
            if g is not None and g.owner is not None and g.owner.feedback:
                # One action_feedback per navigator feedback, unthrottled (20 Hz here).
                g.owner.send_feedback(self._nav2_feedback(g, stamp))
        elif k % _FEEDBACK_TICKS == 0 and self._active is not None:
            self._publish("/move_base/feedback", self._build_feedback, stamp)
        if k % _SCAN_TICKS == 0:
            self._publish("/scan", self._build_scan, stamp)
        if k % _STATUS_TICKS == 0 and self.ros == 1:
            self._publish("/move_base/status", self._build_status, stamp)
        if k % _BATTERY_TICKS == 0:
            self._publish("/battery_state", self._build_battery, stamp)

    def _amcl_update(self, stamp: float) -> None:
        """AMCL in "real" mode: publish (latched) only when forced or after enough motion.

        amcl_node.cpp updates its filter when the motion since the last update exceeds
        ``update_min_d`` or ``update_min_a`` and publishes after the first update following
        an initial pose; the notes' model of it (shared/notes/rosbridge.md) is what is coded:
        more than 0.2 m (straight-line distance) or 30 degrees since the last published pose;
        for a ROS 2 robot Nav2's amcl defaults, 0.25 m or 0.2 rad (shared/notes/ros2.md).
        """
        x, y, yaw = self.pose
        at = self._amcl_at
        if (
            not self._amcl_force
            and at is not None
            and math.hypot(x - at[0], y - at[1]) <= self._amcl_min[0]
            and abs(wrap_angle(yaw - at[2])) <= self._amcl_min[1]
        ):
            return
        self._amcl_force = False
        self._amcl_at = (x, y, yaw)
        msg = self._build_amcl(self._next_seq("/amcl_pose"), stamp)
        frame = Frame(
            rb.op_publish(self.wire("/amcl_pose"), ros2.to_ros2(msg) if self.ros == 2 else msg)
        )
        self._amcl_frame = frame
        t = self._t
        for s in self._subs.get("/amcl_pose", ()):
            if s.wants(t):
                s.push(frame, t)

    def _tick_stamp(self) -> float:
        """ROS stamp (the robot's Unix time, :meth:`epoch`) of the last physics step."""
        clock = self._clock
        return clock.epoch() - clock.now() + self._t + self.clock_offset

    def _publish_status(self) -> None:
        if self.ros == 1:
            self._publish("/move_base/status", self._build_status)

    def _build_status(self, seq: int, stamp: float) -> dict[str, Any]:
        return rb.goal_status_array(
            [(g.id, g.status, g.text, g.stamp) for g in self._goals], stamp=stamp, seq=seq
        )

    def _build_odom(self, seq: int, stamp: float) -> dict[str, Any]:
        o = self._odom
        return rb.odometry(o.x, o.y, o.yaw, o.vx, o.vy, o.wz, stamp=stamp, seq=seq)

    def _build_amcl(self, seq: int, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.pose
        g = self._rng.gauss
        return rb.pose_with_covariance_stamped(
            x + g(0.0, AMCL_NOISE_XY),
            y + g(0.0, AMCL_NOISE_XY),
            wrap_angle(yaw + g(0.0, AMCL_NOISE_YAW)),
            stamp=stamp,
            seq=seq,
            covariance=_AMCL_COVARIANCE,
        )

    def _build_feedback(self, seq: int, stamp: float) -> dict[str, Any]:
        g = self._active
        assert g is not None
        x, y, yaw = self.pose
        return rb.move_base_feedback(
            g.id, g.status, x, y, yaw, stamp=stamp, seq=seq, goal_stamp=g.stamp
        )

    def _build_scan(self, seq: int, stamp: float) -> dict[str, Any]:
        pose = self.pose
        cache = self._scan_cache
        if cache is None or cache[0] != pose:
            # Ray-cast only when the robot moved: at rest the room looks the same.
            x, y, yaw = pose
            clean = np.asarray(
                raycast(self._map, x, y, self._scan_rel + yaw, SCAN_RANGE_MAX), dtype=np.float64
            )
            self._scan_cache = cache = (pose, clean)
        ranges = cache[1]
        if self._others:
            ranges = np.minimum(ranges, self._robot_ranges(*pose))
        ranges = ranges + self._np_rng.normal(0.0, SCAN_NOISE, SCAN_RAYS)
        ranges[ranges < SCAN_RANGE_MIN] = SCAN_RANGE_MIN
        ranges[ranges > SCAN_RANGE_MAX] = np.inf  # no return within range: +Inf (REP 117)
        return rb.laser_scan(
            ranges,
            stamp=stamp,
            seq=seq,
            angle_min=-math.pi,
            angle_increment=2.0 * math.pi / SCAN_RAYS,
            range_min=SCAN_RANGE_MIN,
            range_max=SCAN_RANGE_MAX,
            scan_time=TICK * _SCAN_TICKS,
            time_increment=TICK * _SCAN_TICKS / SCAN_RAYS,
        )

    def _robot_ranges(self, x: float, y: float, yaw: float) -> npt.NDArray[np.float64]:
        """Range along each scan ray to the nearest other robot's footprint (inf: none).

        Ray-disc intersection from the laser at the robot's centre, every robot in range at
        once; a robot whose disc holds the laser (overlapping robots) is not seen, as a laser
        does not see inside a body. Kept while neither this robot nor any other moved (a
        parked fleet's scans cost one comparison).
        """
        where = tuple((o._motion.x, o._motion.y) for o in self._others)
        cache = self._robots_scan
        if cache is not None and cache[0] == (x, y, yaw) and cache[1] == where:
            return cache[2]
        c = np.asarray(where, dtype=np.float64).reshape(-1, 2) - (x, y)
        r = np.fromiter((o.radius for o in self._others), np.float64, len(self._others))
        d2 = (c * c).sum(axis=1)
        near = (d2 > r * r) & (d2 <= (SCAN_RANGE_MAX + r) ** 2)
        out = np.full(SCAN_RAYS, np.inf)
        if near.any():
            c, d2, r = c[near], d2[near], r[near]
            ang = self._scan_rel + yaw
            b = c[:, :1] * np.cos(ang) + c[:, 1:] * np.sin(ang)  # (robots, rays)
            disc = b * b - (d2 - r * r)[:, None]
            t = np.where((disc >= 0.0) & (b > 0.0), b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
            out = t.min(axis=0)
        self._robots_scan = ((x, y, yaw), where, out)
        return out

    def _build_battery(self, seq: int, stamp: float) -> dict[str, Any]:
        m = self._motion
        pct = self._battery
        if self._charging:
            status, current = (
                (rb.BatteryStatus.FULL, 0.0) if pct >= 1.0 else (rb.BatteryStatus.CHARGING, 5.0)
            )
        else:
            status, current = rb.BatteryStatus.DISCHARGING, -(1.5 + 4.0 * m.speed)
        return rb.battery_state(
            pct,
            stamp=stamp,
            seq=seq,
            voltage=21.0 + 4.2 * pct,
            current=current,
            status=status,
            serial_number=self.name,
            # A ROS 2 driver leaves what it does not measure NaN (null on the wire).
            temperature=math.nan if self.ros == 2 else 30.0,
        )


_AMCL_COVARIANCE: Final = [0.0] * 36
_AMCL_COVARIANCE[0] = _AMCL_COVARIANCE[7] = AMCL_NOISE_XY**2
_AMCL_COVARIANCE[35] = AMCL_NOISE_YAW**2


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
