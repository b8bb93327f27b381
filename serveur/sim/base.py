"""What every part of a simulated robot shares: its state, its names, its clock and pose.

Split from :mod:`serveur.sim.robot` so the robot's parts (:mod:`~serveur.sim.sensors`,
:mod:`~serveur.sim.navigator`, :mod:`~serveur.sim.inbox`, :mod:`~serveur.sim.floor`), each a
class :class:`~serveur.sim.robot.SimRobot` inherits, see one declaration of the state they
share: :class:`RobotBase` declares every attribute (``SimRobot.__init__`` sets them) and the
few reads all of them use (topic names under the namespace, the robot's ROS time, its true
pose); :class:`Goal` is one move_base or Nav2 goal as the navigator tracks it.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import itertools
import math
import random
import threading
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from serveur.clock import Clock
from serveur.maps.navigation import OccupancyMap, Planner
from serveur.robots import rosbridge as rb
from serveur.robots.rosbridge import GoalStatus
from serveur.sim.kinematics import Kind, Limits, MotionModel, OdometryModel, PathFollower
from serveur.sim.topics import ActionSink, Frame, Sub

__all__ = ["TICK", "Goal", "RobotBase"]

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


class RobotBase:
    """The state of one simulated robot (set by ``SimRobot.__init__``) and its basic reads."""

    name: str
    namespace: str
    clock_offset: float
    amcl: str
    ros: int
    release: str
    twist_stamped: bool
    humble_queue: bool
    rosbridge_fix: bool
    topic_types: dict[str, str]
    subscribes: frozenset[str]
    _amcl_min: tuple[float, float]
    index: int
    kinematics: Kind
    home: tuple[float, float, float]
    limits: Limits
    _map: OccupancyMap
    _planner: Planner
    _clock: Clock
    _rng: random.Random
    _np_rng: np.random.Generator
    _motion: MotionModel
    _odom: OdometryModel
    _battery: float
    _charging: bool
    _map_frame: Frame | None
    _subs: dict[str, list[Sub]]
    _seqs: dict[str, int]
    _t: float
    _ticks: int
    # move_base
    _goals: list[Goal]
    _pending: Goal | None
    _plan_fut: asyncio.Future[list[tuple[float, float]]] | None
    _plan_goal: Goal | None
    _plan_lock: threading.Lock
    _active: Goal | None
    _follower: PathFollower | None
    _goal_deadline: float
    _blocked_since: float | None
    _stuck_for: float
    _goal_counter: itertools.count[int]
    _sas_stamp: float
    _last_cancel: float
    # AMCL in "real" mode
    _amcl_frame: Frame | None
    _amcl_at: tuple[float, float, float] | None
    _amcl_force: bool
    # teleop
    _teleop: tuple[float, float, float] | None
    _teleop_t: float
    # faults
    _block_path: bool
    _ignore_goals: bool
    _drop_results: int
    _ros_side_dead: bool  # ROS 2: rosbridge's ROS side shut (SIGTERM/SIGINT), socket open
    _node_dead: bool  # ROS 2: the robot's node died behind a live rosbridge and rosapi
    # laser
    _scan_rel: npt.NDArray[np.floating[Any]]
    _scan_cache: tuple[tuple[float, float, float], npt.NDArray[np.float64]] | None
    # other robots (share_floor)
    radius: float
    _others: tuple[RobotBase, ...]
    _patience: float
    _wait_since: float | None
    _wait_at: tuple[float, float]
    _replanned: float
    _detour: (
        tuple[float, tuple[float, float], concurrent.futures.Future[list[tuple[float, float]]]]
        | None
    )
    _robots_scan: (
        tuple[tuple[float, float, float], tuple[tuple[float, float], ...], npt.NDArray[np.float64]]
        | None
    )

    @property
    def ros_side_dead(self) -> bool:
        """ROS 2 fault: rosbridge's ROS side stopped (see ``SimRobot.stop_bridge_ros_side``)."""
        return self._ros_side_dead

    @property
    def node_dead(self) -> bool:
        """ROS 2 fault: the robot's node is dead behind a live bridge (``SimRobot.kill_node``)."""
        return self._node_dead

    @property
    def _relaying(self) -> bool:
        """What the robot's nodes publish reaches the bridge's clients."""
        return not (self._ros_side_dead or self._node_dead)

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

    def _tick_stamp(self) -> float:
        """ROS stamp (the robot's Unix time, :meth:`epoch`) of the last physics step."""
        clock = self._clock
        return clock.epoch() - clock.now() + self._t + self.clock_offset
