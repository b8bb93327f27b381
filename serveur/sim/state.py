"""What every part of a simulated robot shares: its settings, its clock, its body, its time.

:class:`~serveur.sim.robot.SimRobot` owns one :class:`RobotState` and hands it to each of its
parts (:mod:`~serveur.sim.outbox`, :mod:`~serveur.sim.sensors`,
:mod:`~serveur.sim.navigator`, :mod:`~serveur.sim.inbox`, :mod:`~serveur.sim.floor`); a part
keeps what only it uses on itself. The state holds what two parts or more read or write — the
robot's name, dialect and namespace, its clock, map and planner, its body (true motion,
odometry, battery, the chargers it can charge on), the sim time of its last physics step, a
teleop command, whether the docking server drives the base, the two ROS 2 faults every part
obeys, the other robots sharing its floor — and the few reads all of them
use (topic names under the namespace, the robot's ROS time, its true pose). :class:`Goal` is
one move_base or Nav2 goal as the navigator tracks it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Final

from serveur.clock import Clock
from serveur.maps.navigation import OccupancyMap, Planner
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim.kinematics import MotionModel, OdometryModel
from serveur.sim.topics import ActionSink

__all__ = ["TICK", "Goal", "RobotState"]

#: Physics step in simulated seconds (20 Hz); publish periods are whole numbers of ticks.
TICK: Final = 0.05


@dataclass(slots=True)
class Goal:
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


class RobotState:
    """The state of one simulated robot its parts share, and the reads they all use."""

    def __init__(
        self,
        name: str,
        *,
        namespace: str,
        clock_offset: float,
        ros: int,
        clock: Clock,
        grid: OccupancyMap,
        planner: Planner,
        motion: MotionModel,
        odom: OdometryModel,
    ) -> None:
        self.name = name
        #: Every topic of the robot lives under this ROS namespace ("" for none, "/r1").
        self.namespace = namespace
        self.clock_offset = clock_offset
        #: The dialect: 1 (rosbridge 0.11, move_base, amcl) or 2 (rosbridge 2.x, Nav2).
        self.ros = ros
        self.clock = clock
        self.map = grid
        self.planner = planner
        #: Footprint radius (m): the planner's robot radius, a disc.
        self.radius = planner.robot_radius
        self.motion = motion
        self.odom = odom
        self.battery = 1.0
        self.charging = False
        #: The chargers' poses (x, y, yaw: the pose a robot stands in on its contacts): the
        #: robot's own dock, and in a fleet every robot's (``Simulation``).
        self.chargers: tuple[tuple[float, float, float], ...] = ()
        #: The docking server switched the charger's current off (undocking).
        self.charge_off = False
        #: The docking server drives the base (onto or off a dock): teleop and move_base wait.
        self.docking_drives = False
        self.t = clock.now()  # sim time of the last physics step
        #: A client's ``/cmd_vel`` driving the base (no goal), and when it came (wall-scaled).
        self.teleop: tuple[float, float, float] | None = None
        self.teleop_t = -math.inf
        self.ros_side_dead = False  # ROS 2: rosbridge's ROS side shut (SIGTERM/SIGINT)
        self.node_dead = False  # ROS 2: the robot's node died behind a live rosbridge
        #: Other robots solid for this one (``SimRobot.share_floor``): none by default.
        self.others: tuple[RobotState, ...] = ()

    @property
    def relaying(self) -> bool:
        """What the robot's nodes publish reaches the bridge's clients."""
        return not (self.ros_side_dead or self.node_dead)

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

    # -- time and pose -----------------------------------------------------------------------

    def epoch(self) -> float:
        """The robot's ROS time now: the fleet clock's Unix time plus ``clock_offset``."""
        return self.clock.epoch() + self.clock_offset

    def tick_stamp(self) -> float:
        """ROS stamp (the robot's Unix time, :meth:`epoch`) of the last physics step."""
        clock = self.clock
        return clock.epoch() - clock.now() + self.t + self.clock_offset

    @property
    def pose(self) -> tuple[float, float, float]:
        """True pose (x, y, yaw) in the map frame."""
        m = self.motion
        return m.x, m.y, m.yaw

    @property
    def velocity(self) -> tuple[float, float, float]:
        """True body velocity (vx, vy, wz)."""
        m = self.motion
        return m.vx, m.vy, m.wz
