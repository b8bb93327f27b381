"""One simulated waiter robot's ROS graph: move_base (or Nav2), AMCL, odometry, laser, battery.

Split from :mod:`serveur.robot_sim` (the fleet, its physics loop and ``serveur sim``) because a
robot is a subject of its own: what a ROS1 robot with move_base and AMCL does with the goals,
cancels, ``cmd_vel`` and initial poses it is sent, and what it publishes, at which rates, with
which quirks (actionlib's status list, terminal goals kept 5 s, a blocked robot aborting its
goal, noisy AMCL poses and laser scans). Its rosbridge side is :mod:`serveur.sim.bridge`.
Everything is stepped by the fleet at :data:`TICK` of simulated time.

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
  (:meth:`serveur.sim.inbox.Inbox.nav2_goal`) or on ``/goal_pose`` (RViz2), and the robot
  answers the goal's sender alone: feedback every physics tick (20 Hz, unthrottled, as the
  navigator's feedback reached clients on a real stack) and one result, SUCCEEDED 4, CANCELED 5
  (a cancel: CANCELING until the navigator's next cycle) or ABORTED 6 (blocked, stuck, too slow,
  no path, or a newer goal: Nav2's navigator aborts the goal it drives when another arrives). A
  goal it cannot take (not in ``map``, NaN, not a rotation about z, off the map) is rejected,
  which rosbridge before its 2026 fix never reports.
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
fleet's ``robots_see_each_other``; on by default): :mod:`serveur.sim.floor`.

**Battery and charger.** Each robot has a dock (``dock``, a pose; by default its home): its
charger. It charges only standing still on a charger's contacts — within
:data:`~serveur.sim.docking.CHARGE_DISTANCE` (5 cm) and :data:`~serveur.sim.docking.CHARGE_YAW`
of the charger's pose, with no goal and no teleop — its own dock, or in a fleet any robot's.
A full charge takes :data:`FULL_CHARGE` (4.5 h: PuduBot's and BellaBot's stated charging
time); a charge lasts :data:`IDLE_DRAIN` standing (12 h, the same robots' stated runtime
between 10 and 24 h) or :data:`DRIVE_RANGE` of driving. ``/battery_state`` says CHARGING (1)
while it charges, FULL (4) when full on the charger, DISCHARGING (2) off it, with the current
that goes with each (sensor_msgs/BatteryState: positive while charging).

A ROS 2 robot made with ``docking`` also runs opennav_docking's docking server
(:mod:`serveur.sim.docking`): ``dock_robot`` drives it through a staging pose onto a charger,
``undock_robot`` backs it off again.

The robot is :class:`SimRobot`, composed of one part per concern: it owns a
:class:`~serveur.sim.state.RobotState` (what the parts share: settings, clock, body, time) and
creates its parts, each given the state and the parts it calls, none inheriting another —
:mod:`~serveur.sim.outbox` (subscriptions and frames), :mod:`~serveur.sim.navigator` (a goal's
life and plan; publishes through the outbox), :mod:`~serveur.sim.sensors` (what is published
when; reads the navigator's goal for feedback and status), :mod:`~serveur.sim.inbox` (what
clients send: goals, cancels, teleop, initial poses; move_base's rules for taking a goal) and
:mod:`~serveur.sim.floor` (other robots; acts on the navigator's path). This module keeps the
robot's construction, its public reads and fault hooks, the control cycle and the physics step,
and re-exports the parts' public constants.
"""

from __future__ import annotations

import math
import random
import threading
from collections.abc import Callable, Sequence
from typing import Any, Final

import numpy as np

from serveur.clock import Clock
from serveur.maps.navigation import OccupancyMap, Planner
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.docking import DockingServer, on_charger
from serveur.sim.floor import ROBOT_GAP, ROBOT_PATIENCE, Floor
from serveur.sim.inbox import Inbox
from serveur.sim.kinematics import Kind, Limits, MotionModel, OdometryModel, wrap_angle
from serveur.sim.navigator import LAST_CANCEL_CANCELED, SAS_ACCEPTED, SAS_CANCELED, Navigator
from serveur.sim.outbox import Outbox
from serveur.sim.sensors import (
    AMCL_MODES,
    AMCL_TICKS,
    AMCL_UPDATE_MIN_A,
    AMCL_UPDATE_MIN_D,
    NAV2_UPDATE_MIN_A,
    NAV2_UPDATE_MIN_D,
    SCAN_RAYS,
    Sensors,
)
from serveur.sim.state import TICK, Goal, RobotState
from serveur.sim.topics import Frame, Sub

__all__ = [
    "AMCL_MODES",
    "AMCL_TICKS",
    "AMCL_UPDATE_MIN_A",
    "AMCL_UPDATE_MIN_D",
    "DRIVE_RANGE",
    "FULL_CHARGE",
    "IDLE_DRAIN",
    "LAST_CANCEL_CANCELED",
    "MAX_CATCH_UP",
    "NAV2_UPDATE_MIN_A",
    "NAV2_UPDATE_MIN_D",
    "ROBOT_GAP",
    "ROBOT_PATIENCE",
    "ROS1_SUBSCRIBES",
    "SAS_ACCEPTED",
    "SAS_CANCELED",
    "SCAN_RAYS",
    "TICK",
    "SimRobot",
]

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
#: Sim seconds from empty to full on a charger: 4.5 h, the charging time PuduBot's and BellaBot's
#: makers state (a waiter robot's battery at its dock's few amperes), in place of the 2 h this
#: simulator used before docks; and a charge's life standing idle (12 h) and in metres driven.
FULL_CHARGE: Final = 4.5 * 3600.0
IDLE_DRAIN: Final = 12.0 * 3600.0
DRIVE_RANGE: Final = 4000.0
#: Topics a ROS1 robot subscribes to (clients may publish there; anything else is refused).
ROS1_SUBSCRIBES: Final = frozenset(
    {"/move_base/goal", "/move_base_simple/goal", "/move_base/cancel", "/cmd_vel", "/initialpose"}
)
#: Topics a ROS 2 robot subscribes to.
ROS2_SUBSCRIBES: Final = frozenset({"/cmd_vel", "/initialpose", "/goal_pose"})


class SimRobot:
    """One simulated robot: its body, its move_base, its sensors, and what it publishes.

    Public read-only state: ``name``, ``pose`` (true pose), ``kinematics``, ``battery``
    (0..1), ``charging``, ``home``, ``dock`` (its charger's pose; ``home`` unless given),
    ``velocity``, ``clock_offset``, ``amcl``, ``ros`` (1 or 2), and for ROS 2 ``release``,
    ``twist_stamped``, ``humble_queue``, ``rosbridge_fix``, ``docking`` (its docking server,
    None without); ``topic_types`` and ``subscribes`` (the robot's graph in its dialect).
    Fault hooks: :meth:`block_path`, :meth:`ignore_goals`, and for ROS 2
    :meth:`drop_results`, :meth:`stop_bridge_ros_side` (healed by
    ``Simulation.restart_rosbridge``) and :meth:`kill_node` / :meth:`restart_node`.

    ``clock_offset`` (seconds) is added to every stamp the robot makes (:meth:`epoch`);
    ``amcl`` is one of :data:`AMCL_MODES` (see the module's docstring).

    Its parts, each given the shared :attr:`state` and the parts it calls: :attr:`outbox`
    (subscriptions, frames), :attr:`navigator` (goals, plans), :attr:`sensors` (what is
    published when), :attr:`inbox` (what clients send; the bridge hands it their messages) and
    :attr:`floor` (other robots).
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
        dock: tuple[float, float, float] | None = None,
        docking: bool = False,
    ) -> None:
        if docking and ros != 2:
            raise ValueError("docking is a ROS 2 docking server's (ros=2)")
        if dock is not None and not all(math.isfinite(v) for v in dock):
            raise ValueError("a dock is a finite pose (x, y, yaw)")
        if amcl not in AMCL_MODES:
            raise ValueError(f"amcl must be one of {AMCL_MODES}, not {amcl!r}")
        if ros not in (1, 2):
            raise ValueError(f"ros must be 1 or 2, not {ros!r}")
        if release not in ros2.RELEASES:
            raise ValueError(f"release must be one of {ros2.RELEASES}, not {release!r}")
        if not math.isfinite(clock_offset):
            raise ValueError("clock_offset must be a finite number of seconds")
        self.amcl = amcl
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
        else:
            self.topic_types = dict(rb.TOPIC_TYPES)
            self.subscribes = ROS1_SUBSCRIBES
        self.index = index
        self.kinematics = kinematics
        self.home = home
        self.limits = limits or Limits()
        rng = random.Random(seed)
        #: What the parts share (see :mod:`serveur.sim.state`).
        self.state = state = RobotState(
            name,
            namespace=namespace.rstrip("/"),
            clock_offset=float(clock_offset),
            ros=ros,
            clock=clock,
            grid=grid,
            planner=planner,
            motion=MotionModel(kinematics, self.limits, *home),
            odom=OdometryModel(rng),
        )
        self._ticks = index  # staggers publishing across robots
        self._block_path = False
        self.outbox = Outbox(state, map_frame)
        self.navigator = Navigator(
            state,
            self.outbox,
            kinematics=kinematics,
            limits=self.limits,
            release=release,
            plan_lock=plan_lock or threading.Lock(),
        )
        self.sensors = Sensors(
            state,
            self.outbox,
            self.navigator,
            amcl=amcl,
            rng=rng,
            np_rng=np.random.default_rng(seed),
        )
        self.inbox = Inbox(
            state, self.outbox, self.navigator, self.sensors, twist_stamped=self.twist_stamped
        )
        self.floor = Floor(state, self.navigator)
        #: The robot's charger: where it docks (its home unless told otherwise).
        self.dock: tuple[float, float, float] = (
            (float(dock[0]), float(dock[1]), float(dock[2])) if dock is not None else home
        )
        state.chargers = (self.dock,)
        self._charger_cache: tuple[tuple[float, float, float], bool] | None = None
        #: ROS 2 with ``docking``: opennav_docking's docking server (None without).
        self.docking: DockingServer | None = (
            DockingServer(
                state,
                self.navigator,
                navigate=self._navigate,
                kinematics=kinematics,
                release=release,
            )
            if docking
            else None
        )

    # -- public state ----------------------------------------------------------------------

    @property
    def name(self) -> str:
        return self.state.name

    @property
    def namespace(self) -> str:
        """Every topic of the robot lives under this ROS namespace ("" for none, "/r1")."""
        return self.state.namespace

    @property
    def clock_offset(self) -> float:
        return self.state.clock_offset

    @property
    def ros(self) -> int:
        """The dialect: 1 (rosbridge 0.11, move_base, amcl) or 2 (rosbridge 2.x, Nav2)."""
        return self.state.ros

    @property
    def pose(self) -> tuple[float, float, float]:
        """True pose (x, y, yaw) in the map frame."""
        return self.state.pose

    @property
    def velocity(self) -> tuple[float, float, float]:
        """True body velocity (vx, vy, wz)."""
        return self.state.velocity

    def epoch(self) -> float:
        """The robot's ROS time now: the fleet clock's Unix time plus ``clock_offset``."""
        return self.state.epoch()

    def wire(self, topic: str) -> str:
        """A topic's name on the wire: under the robot's namespace, if it has one."""
        return self.state.wire(topic)

    def local(self, topic: str) -> str | None:
        """A wire name without the namespace (None: a name outside the robot's namespace)."""
        return self.state.local(topic)

    @property
    def ros_side_dead(self) -> bool:
        """ROS 2 fault: rosbridge's ROS side stopped (see :meth:`stop_bridge_ros_side`)."""
        return self.state.ros_side_dead

    @property
    def node_dead(self) -> bool:
        """ROS 2 fault: the robot's node is dead behind a live bridge (:meth:`kill_node`)."""
        return self.state.node_dead

    @property
    def battery(self) -> float:
        """State of charge, 0..1 (sensor_msgs/BatteryState.percentage)."""
        return self.state.battery

    @battery.setter
    def battery(self, value: float) -> None:
        self.state.battery = min(1.0, max(0.0, float(value)))

    @property
    def charging(self) -> bool:
        """On a charger's contacts, taking current (or full there)."""
        return self.state.charging

    def set_chargers(self, chargers: Sequence[tuple[float, float, float]]) -> None:
        """The chargers the robot can charge on (the fleet's docks); its own is always one."""
        self.state.chargers = (self.dock, *(c for c in chargers if c != self.dock))
        self._charger_cache = None

    @property
    def goal_statuses(self) -> list[tuple[str, GoalStatus, str]]:
        """What ``/move_base/status`` lists now: (goal id, status, text). A ROS 2 robot lists
        its navigator's goals the same way: under the client's goal id (``nav2-N`` without
        one), with actionlib statuses (a cancelled goal PREEMPTED, one aborted by a newer goal
        ABORTED; a goal taken while :meth:`ignore_goals` is on stays PENDING)."""
        return [(g.id, g.status, g.text) for g in self.navigator.goals]

    @property
    def _subs(self) -> dict[str, list[Sub]]:
        """The clients' subscriptions by topic (tests read their throttles)."""
        return self.outbox.subs

    @property
    def _build_amcl(self) -> Callable[[int, float], dict[str, Any]]:
        """What builds ``/amcl_pose``; a test swaps it to make the localisation drift."""
        return self.sensors.amcl_builder

    @_build_amcl.setter
    def _build_amcl(self, build: Callable[[int, float], dict[str, Any]]) -> None:
        self.sensors.amcl_builder = build

    # -- fault hooks and other robots -------------------------------------------------------

    def share_floor(self, others: Sequence[SimRobot], patience: float = ROBOT_PATIENCE) -> None:
        """Make ``others`` solid for this robot (:meth:`serveur.sim.floor.Floor.share`)."""
        self.floor.share([o.state for o in others], patience)

    def block_path(self, on: bool) -> None:
        """Fault hook: while on, the active goal (or the next one) ABORTs as if the aisle were
        blocked — the robot stops and gives up after ``BLOCKED_ABORT_AFTER`` s of sim time."""
        self._block_path = bool(on)
        if not on:
            self.navigator.blocked_since = None

    def ignore_goals(self, on: bool) -> None:
        """Fault hook: while on, goals are never acknowledged — status keeps publishing without
        them, no result ever comes (a hung move_base). A ROS 2 goal then gets no frame at all,
        and with the queue trap its connection stays held."""
        self.inbox.ignore_goals = bool(on)

    def drop_results(self, n: int = 1) -> None:
        """Fault hook (ROS 2): the next ``n`` goals end on the robot but their ``action_result``
        never reaches the client (measured about once in 200 goals on a real Jazzy stack,
        shared/notes/ros2.md; the cause is unknown). The connection is not held by them."""
        self.navigator.drop_results = max(0, int(n))

    def stop_bridge_ros_side(self) -> None:
        """Fault hook (ROS 2): rosbridge got SIGTERM or SIGINT (what ``ros2 launch`` and
        systemd send first). Measured on rosbridge 2.1.0 (shared/notes/ros2.md, "Liveness,
        measured on the same stack"): its ROS side shuts down but its websocket server keeps
        running until killed — connections stay open, every ``call_service`` (rosapi's too)
        is answered ``result: false`` with ``values`` "rcl node's context is invalid", topics
        go quiet, action feedback stops. The robot itself (Nav2) is not touched: a goal under
        way drives on to its end, whose result never comes. A ``send_action_goal`` gets
        ``action_result`` with ``result`` false and the same text (rosbridge's capability
        reports an exception so; inferred, not measured); other ops do nothing. Only a new
        rosbridge heals it: ``Simulation.restart_rosbridge``."""
        self.state.ros_side_dead = True
        self.state.teleop = None

    def bridge_restarted(self) -> None:
        """A new rosbridge process runs (its old connections are gone: the caller closes
        them): the robot's topics reach clients again, AMCL's latched pose first."""
        self.state.ros_side_dead = False
        self.sensors.force_amcl()

    def kill_node(self) -> None:
        """Fault hook (ROS 2): the robot's node dies while rosbridge and rosapi live
        (shared/notes/ros2.md, "Liveness, measured on the same stack"): rosapi still answers
        (``get_time``, ``topics``...), but the robot's topics stop, its navigator is gone —
        the goal under way stops and no frame ever comes for it (its rosbridge handler waits,
        holding a Humble connection), a new goal gets no frame at all (no action server),
        cancels and ``/cmd_vel`` reach nobody — and ``/bt_navigator/get_state`` is never
        answered (rosapi still lists the dead node, so rosbridge waits for it)."""
        self.state.node_dead = True
        self.state.teleop = None
        if self.docking is not None:
            self.docking.kill()
        for g in list(self.navigator.goals):
            if not g.terminal:
                g.owner = None  # its result never reaches the bridge
                self.navigator.finish(g, GoalStatus.ABORTED, "the navigator died")

    def restart_node(self) -> None:
        """The robot's node is back: a fresh navigator (active, no goal), AMCL publishing
        its pose at start."""
        self.state.node_dead = False
        self.sensors.force_amcl()

    def lose_localisation(self, metres: float = 3.0, radians: float = 1.5) -> None:
        """Fault: AMCL loses track of the robot (its spread goes to ``metres``, ``radians``)
        until an initial pose (see :meth:`serveur.sim.sensors.Sensors.lose_localisation`)."""
        self.sensors.lose_localisation(metres, radians)

    def teleport(self, x: float, y: float, yaw: float) -> None:
        """Put the robot somewhere else (like /initialpose, for tests)."""
        self.inbox.relocalise(x, y, yaw)

    def _navigate(self, x: float, y: float, yaw: float, gid: str) -> Goal | None:
        """The docking server's own navigate goal to (x, y, yaw), answered to nobody."""
        q = (0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0))
        return self.inbox.nav2_goal(None, "map", x, y, q, gid)

    # -- move_base's control cycle -----------------------------------------------------------

    def _command(self, now: float) -> tuple[float, float, float]:
        st, nav = self.state, self.navigator
        if nav.active is not None and nav.active.status == GoalStatus.PREEMPTING:
            # move_base's control cycle sees the preempt request: zero velocity, setPreempted()
            nav.finish(nav.active, GoalStatus.PREEMPTED, "")
            return 0.0, 0.0, 0.0
        if st.docking_drives and self.docking is not None:
            return self.docking.command()
        if st.teleop is not None:
            if now - st.teleop_t > CMD_VEL_TIMEOUT * st.clock.time_scale:
                st.teleop = None  # stale: stop, as a velocity watchdog does
                return 0.0, 0.0, 0.0
            return st.teleop
        if nav.plan_fut is not None and nav.plan_fut.done():
            nav.take_plan()
        if nav.pending is not None and nav.plan_fut is None:
            nav.request_plan(nav.pending)
            if nav.plan_fut is not None and nav.plan_fut.done():  # planned at once
                nav.take_plan()
        g, f = nav.active, nav.follower
        if g is None or f is None:
            return 0.0, 0.0, 0.0
        if self._block_path:
            if nav.blocked_since is None:
                nav.blocked_since = st.t
            elif st.t - nav.blocked_since >= BLOCKED_ABORT_AFTER:
                nav.finish(
                    g,
                    GoalStatus.ABORTED,
                    "path blocked: no valid plan (aisle obstructed)",
                    code=ros2.NO_VALID_PATH,
                )
            return 0.0, 0.0, 0.0
        if st.t > nav.goal_deadline:
            nav.finish(
                g, GoalStatus.ABORTED, "the robot did not reach the goal in time", code=ros2.UNKNOWN
            )
            return 0.0, 0.0, 0.0
        m = st.motion
        cmd = f.command(m.x, m.y, m.yaw)
        if f.done and m.speed < 0.01 and abs(m.wz) < 0.02:
            dx, dy = g.x - m.x, g.y - m.y
            if (
                math.hypot(dx, dy) <= f.xy_tolerance
                and abs(wrap_angle(g.yaw - m.yaw)) <= f.yaw_tolerance
            ):
                nav.finish(g, GoalStatus.SUCCEEDED, "Goal reached.")
                return 0.0, 0.0, 0.0
        if st.others:
            return self.floor.mind_robots(g, cmd)
        return cmd

    # -- physics -----------------------------------------------------------------------------

    def _step(self, dt: float) -> None:
        st, nav = self.state, self.navigator
        st.t += dt
        m = st.motion
        if self.docking is not None:
            self.docking.step()
        if (
            st.teleop is None
            and not st.docking_drives
            and nav.active is None
            and nav.pending is None
            and nav.plan_fut is None
            and m.vx == 0.0
            and m.vy == 0.0
            and m.wz == 0.0
        ):
            # Parked (most of a robot's service): no command to compute, nothing to integrate,
            # odometry reads zero; only the battery and the goal list age. Same state as the
            # general path below, at a fraction of its cost (five robots x 20 Hz, replayed at
            # 300x, are 30,000 steps a wall second).
            st.odom.update(0.0, 0.0, 0.0, dt)
            nav.stuck_for = 0.0
            self._battery_tick(dt)
            if nav.goals and nav.goals[0].ended < st.t - TERMINAL_KEEP:
                nav.goals = [g for g in nav.goals if g.ended >= st.t - TERMINAL_KEEP]
            return
        now = st.clock.now()
        cmd = self._command(now)
        if cmd == (0.0, 0.0, 0.0) and m.vx == 0.0 and m.vy == 0.0 and m.wz == 0.0:
            moved_ok = True  # at rest: nothing to integrate
            st.odom.update(0.0, 0.0, 0.0, dt)
        else:
            x0, y0 = m.x, m.y
            moved_ok = m.step(*cmd, dt, st.planner.is_traversable)
            if st.others and self.floor.into_robot(x0, y0, m.x, m.y):
                m.x, m.y = x0, y0  # never into another robot: the base stops short
                m.vx = m.vy = 0.0
            if (
                abs(m.vx) < 1e-4
                and abs(m.vy) < 1e-4
                and abs(m.wz) < 1e-4
                and cmd == (0.0, 0.0, 0.0)
            ):
                m.vx = m.vy = m.wz = 0.0
            st.odom.update(m.vx, m.vy, m.wz, dt)
            self._battery_drain(math.hypot(m.x - x0, m.y - y0))
        if not moved_ok and nav.active is not None:
            nav.stuck_for += dt
            if nav.stuck_for >= STUCK_ABORT_AFTER:
                nav.finish(
                    nav.active,
                    GoalStatus.ABORTED,
                    "the robot is stuck against an obstacle",
                    code=ros2.FAILED_TO_MAKE_PROGRESS,
                )
        elif moved_ok:
            nav.stuck_for = 0.0
        self._battery_tick(dt)
        if nav.goals and nav.goals[0].ended < st.t - TERMINAL_KEEP:
            nav.goals = [g for g in nav.goals if g.ended >= st.t - TERMINAL_KEEP]

    def _battery_drain(self, distance: float) -> None:
        st = self.state
        st.battery = max(0.0, st.battery - distance / DRIVE_RANGE)

    def _battery_tick(self, dt: float) -> None:
        """Charge on a charger's contacts, standing still with nothing to do (the module's
        docstring); else the electronics drain the battery."""
        st = self.state
        m = st.motion
        charging = (
            m.vx == 0.0
            and m.vy == 0.0
            and m.wz == 0.0
            and self.navigator.active is None
            and st.teleop is None
            and not st.charge_off
            and self._on_charger()
        )
        st.charging = charging
        if charging:
            st.battery = min(1.0, st.battery + dt / FULL_CHARGE)
        else:
            st.battery = max(0.0, st.battery - dt / IDLE_DRAIN)

    def _on_charger(self) -> bool:
        """:func:`~serveur.sim.docking.on_charger`, kept while the robot stands still (a
        parked fleet at a replay's time scale asks 20 times a simulated second)."""
        pose = self.state.pose
        cache = self._charger_cache
        if cache is None or cache[0] != pose:
            cache = self._charger_cache = (pose, on_charger(self.state) is not None)
        return cache[1]

    # -- the tick: physics, then what falls due -----------------------------------------------

    def _advance(self, steps: int) -> None:
        """Take ``steps`` physics steps, each followed by what falls due at its tick.

        Publishing per tick (not once per pass) keeps publish rates and stamps tied to sim
        time when the loop has to catch up several ticks at once (high time scales, load).
        """
        st = self.state
        for _ in range(steps):
            self._step(TICK)
            self._ticks = k = self._ticks + 1
            # A latched pose is kept without subscribers; a ROS 2 goal's feedback has none.
            # Nothing reaches clients while the robot's node or the bridge's ROS side is dead.
            if (self.outbox.subs or self.amcl == "real" or st.ros == 2) and st.relaying:
                self.sensors.publish_due(k)
