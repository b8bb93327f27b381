"""A fleet of simulated waiter robots, each speaking rosbridge v2 like a real ROS1 robot.

Why a simulator that imitates the wire instead of a fake robot-link object: the server's robot
link, roslibpy and roslibjs must not be able to tell it from a robot running move_base, AMCL and
rosbridge_server, so every quirk those clients depend on is reproduced here (latched ``/map``,
``/move_base/status`` published even when idle, ``null`` for NaN, ``service_response`` always
carrying ``values``, binary frames only for ``cbor`` subscribers...). Tests and load runs then
exercise the same code paths as a restaurant.

Structure:

* :class:`SimRobot` — one robot's ROS graph: kinematics (:mod:`serveur.kinematics`), move_base's
  actionlib state machine, AMCL-like pose, odometry, laser, battery, and what it publishes.
* ``_Endpoint`` / ``_Client`` — one websocket server per robot (many clients each), with
  per-client, per-topic bounded queues so that a slow client only loses its own old messages
  and never blocks the robot or grows memory.
* :class:`Simulation` — the robots of a fleet, one physics loop stepping all of them at a fixed
  20 Hz of *simulated* time (so results do not depend on ``time_scale``), and the fault hooks.

All time goes through a :class:`~serveur.clock.Clock`: motion, publish rates, ``throttle_rate``,
the stale ``cmd_vel`` timeout and ROS stamps (``clock.epoch()``).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import logging
import math
import random
import signal
import socket
import ssl as ssl_module
import sys
import threading
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Final, TextIO, cast

import cbor2
import numpy as np
import numpy.typing as npt
from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from serveur import rosbridge as rb
from serveur.clock import Clock, ScaledClock
from serveur.errors import RosbridgeError, ServeurError
from serveur.kinematics import (
    KINDS,
    Kind,
    Limits,
    MotionModel,
    OdometryModel,
    PathFollower,
    wrap_angle,
)
from serveur.navigation import (
    OccupancyMap,
    Planner,
    Waypoint,
    demo_map_path,
    load_demo,
    load_map,
    load_waypoints,
    raycast,
)
from serveur.rosbridge import GoalStatus

__all__ = [
    "SimRobot",
    "Simulation",
    "add_sim_arguments",
    "run_sim",
    "run_sim_from_args",
    "start_simulation",
]

log = logging.getLogger("serveur.robot_sim")

#: Physics step in simulated seconds (20 Hz); publish periods are whole numbers of ticks.
TICK: Final = 0.05
_ODOM_TICKS: Final = 1  # 20 Hz
_AMCL_TICKS: Final = 2  # 10 Hz
_FEEDBACK_TICKS: Final = 2  # 10 Hz while a goal is active
_SCAN_TICKS: Final = 4  # 5 Hz
_STATUS_TICKS: Final = 4  # 5 Hz (actionlib's default status_frequency)
_BATTERY_TICKS: Final = 20  # 1 Hz
#: Most physics steps taken in one loop pass when the loop fell behind; beyond, sim time slips.
_MAX_CATCH_UP: Final = 20

CMD_VEL_TIMEOUT: Final = 0.5  # s sim: a teleop command older than this is stale, the robot stops
TERMINAL_KEEP: Final = 5.0  # s sim a finished goal stays in the status list (actionlib's default)
BLOCKED_ABORT_AFTER: Final = 1.0  # s sim a blocked robot waits before aborting its goal
STUCK_ABORT_AFTER: Final = 3.0  # s sim pushing against an obstacle before aborting

SCAN_RAYS: Final = 360
SCAN_RANGE_MIN: Final = 0.12
SCAN_RANGE_MAX: Final = 8.0
SCAN_NOISE: Final = 0.01  # m, sigma
AMCL_NOISE_XY: Final = 0.01  # m, sigma
AMCL_NOISE_YAW: Final = 0.005  # rad, sigma

MAX_FRAME: Final = 1 << 20  # bytes: larger incoming frames close the connection with 1009
DEFAULT_QUEUE: Final = 10  # per-topic buffer of a subscription without queue_length
MAX_QUEUE: Final = 100  # cap on a client's queue_length (memory bound)
CONTROL_QUEUE: Final = 256  # replies (status, service_response) kept for a client that lags
SEND_BUFFER: Final = 64 * 1024  # SO_SNDBUF of client sockets (the kernel doubles it)
MAX_FRAGMENTED: Final = 8  # messages being reassembled from fragments at once, per client
MAX_CALLS: Final = 64  # service calls in progress at once, per client
MAX_SUB_IDS: Final = 64  # subscribe ids merged into one subscription

#: Topics the robot subscribes to (clients may publish here; anything else is refused).
ROBOT_SUBSCRIBES: Final = frozenset(
    {"/move_base/goal", "/move_base_simple/goal", "/move_base/cancel", "/cmd_vel", "/initialpose"}
)
_MAP_FRAMES: Final = frozenset({"map", "/map", ""})
_LEVELS: Final = {"none": 0, "error": 1, "warning": 2, "info": 3}

_seq = itertools.count()  # global order of queued frames, so a client gets them in publish order


# ---------------------------------------------------------------------------------------------
# Outgoing frames and subscriptions
# ---------------------------------------------------------------------------------------------


class _Frame:
    """One published op, encoded at most once per format whatever the number of subscribers."""

    __slots__ = ("_cbor", "_text", "op")

    def __init__(self, op: Mapping[str, Any]) -> None:
        self.op = op
        self._text: bytes | None = None
        self._cbor: bytes | None = None

    def text(self) -> bytes:
        if self._text is None:
            self._text = rb.encode(self.op).encode()
        return self._text

    def cbor(self) -> bytes:
        if self._cbor is None:
            self._cbor = rb.encode_cbor(self.op)
        return self._cbor


@dataclass(slots=True)
class _SubParams:
    throttle: float  # s sim
    queue_length: int
    cbor: bool


class _Sub:
    """A client's subscription to one topic (all its subscribe ids merged, as rosbridge does)."""

    __slots__ = (
        "cbor",
        "client",
        "last_offer",
        "last_sent",
        "params",
        "qlen",
        "queue",
        "throttle",
        "topic",
    )

    def __init__(self, client: _Client, topic: str) -> None:
        self.client = client
        self.topic = topic
        self.params: dict[str | int | None, _SubParams] = {}
        self.throttle = 0.0
        self.qlen = 0
        self.cbor = False
        self.queue: deque[tuple[int, _Frame]] = deque(maxlen=DEFAULT_QUEUE)
        self.last_offer = -math.inf
        self.last_sent = -math.inf

    def recompute(self) -> None:
        """Lowest throttle_rate, highest queue_length, compression of the latest subscribe."""
        ps = list(self.params.values())
        self.throttle = min(p.throttle for p in ps)
        self.qlen = max(p.queue_length for p in ps)
        self.cbor = ps[-1].cbor
        maxlen = self.qlen if self.qlen > 0 else DEFAULT_QUEUE
        if self.queue.maxlen != maxlen:
            self.queue = deque(self.queue, maxlen=maxlen)

    def wants(self, t: float) -> bool:
        """Whether a message published at sim time ``t`` is not throttled away at once.

        Without a queue, rosbridge's throttle drops what comes too soon after the last message;
        with a queue, messages wait in it (newest kept) and leave one per throttle period.
        """
        return self.throttle <= 0.0 or self.qlen > 0 or t - self.last_offer >= self.throttle - 1e-6

    def push(self, frame: _Frame, t: float) -> None:
        self.last_offer = t
        self.queue.append((next(_seq), frame))  # a full deque drops its oldest entry
        self.client.wake.set()


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

    @property
    def terminal(self) -> bool:
        return self.status in rb.TERMINAL_STATUSES


# ---------------------------------------------------------------------------------------------
# The robot
# ---------------------------------------------------------------------------------------------


class SimRobot:
    """One simulated robot: its body, its move_base, its sensors, and what it publishes.

    Public read-only state: ``name``, ``pose`` (true pose), ``kinematics``, ``battery``
    (0..1), ``home``, ``velocity``. Fault hooks: :meth:`block_path`, :meth:`ignore_goals`.
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
        map_frame: _Frame | None = None,
        plan_lock: threading.Lock | None = None,
    ) -> None:
        self.name = name
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
        self._subs: dict[str, list[_Sub]] = {}
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
        # teleop
        self._teleop: tuple[float, float, float] | None = None
        self._teleop_t = -math.inf
        # faults
        self._block_path = False
        self._ignore_goals = False
        # laser
        self._scan_rel = -math.pi + (2.0 * math.pi / SCAN_RAYS) * np.arange(SCAN_RAYS)
        self._scan_cache: tuple[tuple[float, float, float], npt.NDArray[np.float64]] | None = None

    # -- public state ----------------------------------------------------------------------

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
        """What ``/move_base/status`` lists now: (goal id, status, text)."""
        return [(g.id, g.status, g.text) for g in self._goals]

    def block_path(self, on: bool) -> None:
        """Fault hook: while on, the active goal (or the next one) ABORTs as if the aisle were
        blocked — the robot stops and gives up after ``BLOCKED_ABORT_AFTER`` s of sim time."""
        self._block_path = bool(on)
        if not on:
            self._blocked_since = None

    def ignore_goals(self, on: bool) -> None:
        """Fault hook: while on, goals are never acknowledged — status keeps publishing without
        them, no result ever comes (a hung move_base)."""
        self._ignore_goals = bool(on)

    def teleport(self, x: float, y: float, yaw: float) -> None:
        """Put the robot somewhere else (like /initialpose, for tests)."""
        self._relocalise(x, y, yaw)

    # -- subscriptions -----------------------------------------------------------------------

    def _add_sub(self, sub: _Sub) -> None:
        self._subs.setdefault(sub.topic, []).append(sub)

    def _remove_sub(self, sub: _Sub) -> None:
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
            stamp = self._clock.epoch()
        frame = _Frame(rb.op_publish(topic, build(self._next_seq(topic), stamp)))
        for s in wanting:
            s.push(frame, t)

    def _relay(self, topic: str, msg: Mapping[str, Any]) -> None:
        """A client's publish on a robot topic also reaches that topic's subscribers (ROS does)."""
        if topic in self._subs:
            frame = _Frame(rb.op_publish(topic, msg))
            t = self._clock.now()
            for s in list(self._subs[topic]):
                if s.wants(t):
                    s.push(frame, t)

    def _offer_latched(self, sub: _Sub) -> None:
        if sub.topic == "/map" and self._map_frame is not None:
            sub.push(self._map_frame, self._t)

    # -- incoming messages (raise RosbridgeError on shapes the ROS type cannot hold) ----------

    def handle_publish(self, topic: str, msg: Mapping[str, Any]) -> str | None:
        """Apply a client's message on a topic the robot subscribes; returns a warning or None."""
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

    def _on_cmd_vel(self, msg: Mapping[str, Any]) -> str | None:
        vx, vy, wz = rb.twist_from_msg(msg)
        if not all(math.isfinite(v) for v in (vx, vy, wz)):
            raise RosbridgeError("cmd_vel holds a non-finite velocity")
        self._cancel_goals(GoalStatus.PREEMPTED, "preempted by teleoperation (cmd_vel)")
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
        target = _obj(msg, "goal")
        stamp = rb.from_ros_time(_obj(target.get("header"), "header").get("stamp") or {})
        return self._new_goal("", stamp, target)

    def _new_goal(self, gid: str, gstamp: float, target: Mapping[str, Any]) -> str | None:
        frame = _header_frame(target)
        pose = _obj(target.get("pose"), "pose")
        x, y, _ = rb.point_from_msg(_obj(pose.get("position"), "position"))
        q = rb.quaternion_from_msg(_obj(pose.get("orientation"), "orientation"))
        if self._ignore_goals:
            return None
        if not gid:
            t = self._clock.epoch()
            gid = f"/move_base-{next(self._goal_counter)}-{t:.9f}"
        if any(g.id == gid for g in self._goals):
            return f"goal {gid} is a duplicate; ignored"
        goal = _Goal(gid, gstamp or self._clock.epoch(), x, y, 0.0)
        reason = _goal_problem(frame, x, y, q)
        if reason is not None:
            self._goals.append(goal)
            self._finish(goal, GoalStatus.REJECTED, reason)
            return None
        goal.yaw = rb.yaw_from_quaternion({"x": q[0], "y": q[1], "z": q[2], "w": q[3]})
        # A newer goal preempts the current one (SimpleActionServer semantics).
        self._cancel_goals(GoalStatus.PREEMPTED, "preempted by a newer goal")
        self._teleop = None
        self._goals.append(goal)
        self._pending = goal
        self._publish_status()
        return None

    def _on_cancel(self, msg: Mapping[str, Any]) -> str | None:
        gid, stamp = rb.goal_id_from_msg(_obj(msg, "cancel"))
        if not gid and stamp == 0.0:
            self._cancel_goals(GoalStatus.PREEMPTED, "canceled")
            return None
        for g in list(self._goals):
            if not g.terminal and (g.id == gid or (stamp != 0.0 and g.stamp <= stamp)):
                self._cancel_one(g, "canceled")
        return None

    # -- move_base ---------------------------------------------------------------------------

    def _cancel_goals(self, status: GoalStatus, text: str) -> None:
        for g in list(self._goals):
            if not g.terminal:
                self._cancel_one(g, text, status)

    def _cancel_one(self, g: _Goal, text: str, status: GoalStatus = GoalStatus.PREEMPTED) -> None:
        # actionlib: a goal never started is RECALLED, a started one PREEMPTED.
        self._finish(g, GoalStatus.RECALLED if g.status == GoalStatus.PENDING else status, text)

    def _finish(self, g: _Goal, status: GoalStatus, text: str) -> None:
        g.status, g.text, g.ended = status, text, self._t
        if g is self._active:
            self._active = None
            self._follower = None
            self._blocked_since = None
        if g is self._pending:
            self._pending = None
        if g is self._plan_goal:
            self._plan_fut = self._plan_goal = None
        stamp = self._clock.epoch()
        self._publish(
            "/move_base/result",
            lambda seq, _s: rb.move_base_result(
                g.id, status, text, stamp=stamp, seq=seq, goal_stamp=g.stamp
            ),
        )
        self._publish_status()

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
        fut.add_done_callback(_consume_exception)
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
            self._finish(g, GoalStatus.ABORTED, f"no path to the goal: {why}")
            return
        path = fut.result()
        x, y, _ = self.pose
        self._follower = PathFollower(path, g.yaw, self.kinematics, self.limits)
        self._stuck_for = 0.0
        length = sum(
            math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise([(x, y), *path])
        )
        self._goal_deadline = self._t + 30.0 + 3.0 * length / self.limits.max_speed
        if g is self._pending:
            self._pending = None
            self._active = g
            g.status = GoalStatus.ACTIVE
            g.text = "This goal has been accepted by the simple action server"
            self._publish_status()

    def _relocalise(self, x: float, y: float, yaw: float) -> None:
        self._motion.teleport(x, y, yaw)
        self._scan_cache = None
        g = self._active or self._pending
        if g is not None:  # move_base replans from the new pose
            self._follower = None
            self._request_plan(g)

    def _command(self, now: float) -> tuple[float, float, float]:
        if self._teleop is not None:
            if now - self._teleop_t > CMD_VEL_TIMEOUT:
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
                    g, GoalStatus.ABORTED, "path blocked: no valid plan (aisle obstructed)"
                )
            return 0.0, 0.0, 0.0
        if self._t > self._goal_deadline:
            self._finish(g, GoalStatus.ABORTED, "the robot did not reach the goal in time")
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
        return cmd

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
                    self._active, GoalStatus.ABORTED, "the robot is stuck against an obstacle"
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
            if self._subs:
                self._publish_due(k)

    def _publish_due(self, k: int) -> None:
        stamp = self._tick_stamp()
        if k % _ODOM_TICKS == 0:
            self._publish("/odom", self._build_odom, stamp)
        if k % _AMCL_TICKS == 0:
            self._publish("/amcl_pose", self._build_amcl, stamp)
        if k % _FEEDBACK_TICKS == 0 and self._active is not None:
            self._publish("/move_base/feedback", self._build_feedback, stamp)
        if k % _SCAN_TICKS == 0:
            self._publish("/scan", self._build_scan, stamp)
        if k % _STATUS_TICKS == 0:
            self._publish("/move_base/status", self._build_status, stamp)
        if k % _BATTERY_TICKS == 0:
            self._publish("/battery_state", self._build_battery, stamp)

    def _tick_stamp(self) -> float:
        """ROS stamp (Unix time of the clock) of the last physics step."""
        clock = self._clock
        return clock.epoch() - clock.now() + self._t

    def _publish_status(self) -> None:
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
        ranges = cache[1] + self._np_rng.normal(0.0, SCAN_NOISE, SCAN_RAYS)
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
        )


_AMCL_COVARIANCE: Final = [0.0] * 36
_AMCL_COVARIANCE[0] = _AMCL_COVARIANCE[7] = AMCL_NOISE_XY**2
_AMCL_COVARIANCE[35] = AMCL_NOISE_YAW**2


def _consume_exception(fut: asyncio.Future[Any]) -> None:
    """Mark a dropped future's exception as seen (a plan for a goal that was since cancelled)."""
    if not fut.cancelled():
        fut.exception()


def _obj(v: object, what: str) -> Mapping[str, Any]:
    """A nested message object; a missing one takes ROS defaults (empty), others are errors."""
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise RosbridgeError(f"{what} must be an object, not {type(v).__name__}")
    return v


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


# ---------------------------------------------------------------------------------------------
# One client connection
# ---------------------------------------------------------------------------------------------


def _op_id(msg: Mapping[str, Any]) -> str | int | None:
    v = msg.get("id")
    return v if isinstance(v, str | int) and not isinstance(v, bool) else None


def _req_str(msg: Mapping[str, Any], key: str) -> str:
    v = msg.get(key)
    if not isinstance(v, str) or not v:
        raise RosbridgeError(f"'{key}' must be a non-empty string")
    return v


def _opt_int(msg: Mapping[str, Any], key: str) -> int:
    v = msg.get(key, 0)
    if v is None:
        return 0
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
        raise RosbridgeError(f"'{key}' must be a non-negative number")
    return int(v)


class _Client:
    """One websocket client of a robot: its subscriptions, its send queues, its op handlers."""

    def __init__(self, endpoint: _Endpoint, ws: ServerConnection) -> None:
        self.endpoint = endpoint
        self.robot = endpoint.robot
        self.clock = endpoint.robot._clock
        self.ws = ws
        self.subs: dict[str, _Sub] = {}
        self.advertised: set[str] = set()
        self.control: deque[tuple[int, _Frame]] = deque(maxlen=CONTROL_QUEUE)
        self.wake = asyncio.Event()
        self.level = _LEVELS["error"]
        self.fragments: dict[str | int, dict[int, str]] = {}
        self.calls: dict[str, asyncio.Future[tuple[Any, bool]]] = {}  # calls we forwarded to it
        self.tasks: set[asyncio.Task[None]] = set()

    # -- sending -----------------------------------------------------------------------------

    def reply(self, op: Mapping[str, Any]) -> None:
        self.control.append((next(_seq), _Frame(op)))
        self.wake.set()

    def status(self, level: str, text: str, id: str | int | None) -> None:
        if _LEVELS[level] <= self.level:
            self.reply(rb.op_status(level, text, id))

    def _pop_next(self, now: float) -> tuple[bytes, bool] | float | None:
        """The next frame to send (bytes, binary); else when a throttled one is due; else None."""
        best: deque[tuple[int, _Frame]] | None = None
        best_sub: _Sub | None = None
        best_seq = 0
        due: float | None = None
        if self.control:
            best, best_seq = self.control, self.control[0][0]
        for sub in self.subs.values():
            q = sub.queue
            if not q:
                continue
            if sub.throttle > 0.0 and sub.qlen > 0:
                ready = sub.last_sent + sub.throttle
                if now < ready - 1e-6:
                    due = ready if due is None else min(due, ready)
                    continue
            if best is None or q[0][0] < best_seq:
                best, best_sub, best_seq = q, sub, q[0][0]
        if best is None:
            return due
        _, frame = best.popleft()
        if best_sub is None:
            return frame.text(), False
        best_sub.last_sent = now
        return (frame.cbor(), True) if best_sub.cbor else (frame.text(), False)

    async def writer(self) -> None:
        """Send queued frames in order; only this task waits on the socket, never the robot."""
        ws, clock, wake = self.ws, self.clock, self.wake
        while True:
            nxt = self._pop_next(clock.now())
            if isinstance(nxt, tuple):
                data, binary = nxt
                await ws.send(data, text=not binary)
                continue
            wake.clear()
            if nxt is None:
                await wake.wait()
                continue
            waiter = asyncio.ensure_future(wake.wait())
            sleeper = asyncio.ensure_future(clock.sleep(nxt - clock.now()))
            try:
                await asyncio.wait({waiter, sleeper}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                waiter.cancel()
                sleeper.cancel()

    # -- receiving ---------------------------------------------------------------------------

    def handle_frame(self, frame: str | bytes, depth: int = 0) -> None:
        """Decode and run one frame; every problem becomes a status reply, never an exception."""
        msg: dict[str, Any] | None = None
        try:
            if isinstance(frame, bytes) and frame[:1] not in (b"{", b" ", b"\n", b"\r", b"\t"):
                msg = self._decode_cbor(frame)
            else:
                msg = rb.decode(frame)
            self.handle_op(msg, depth)
        except ServeurError as exc:
            oid = _op_id(msg) if msg is not None else exc.details.get("id")
            self.status("error", exc.message, oid)
        except Exception as exc:  # a bug must not take the robot or the connection down
            log.exception("%s: error handling a frame", self.robot.name)
            self.status("error", f"internal error: {type(exc).__name__}: {exc}", _op_id(msg or {}))

    @staticmethod
    def _decode_cbor(frame: bytes) -> dict[str, Any]:
        try:
            obj = cbor2.loads(frame)
        except Exception as exc:
            raise RosbridgeError(f"binary frame is not CBOR: {exc}") from exc
        if not isinstance(obj, dict) or not isinstance(obj.get("op"), str):
            raise RosbridgeError("frame is not an object with a string 'op'")
        return cast(dict[str, Any], obj)

    def handle_op(self, msg: dict[str, Any], depth: int = 0) -> None:
        op = msg["op"]
        oid = _op_id(msg)
        if op == "publish":
            self._publish(msg, oid)
        elif op == "subscribe":
            self._subscribe(msg, oid)
        elif op == "unsubscribe":
            self._unsubscribe(msg, oid)
        elif op == "advertise":
            self._advertise(msg)
        elif op == "unadvertise":
            topic = _req_str(msg, "topic")
            if topic not in self.advertised:
                self.status("warning", f"{topic} is not advertised by this client", oid)
            self.advertised.discard(topic)
        elif op == "call_service":
            service = _req_str(msg, "service")
            if len(self.tasks) >= MAX_CALLS:
                why = f"more than {MAX_CALLS} service calls in progress"
                self.reply(rb.op_service_response(service, oid, why, result=False))
                raise RosbridgeError(why)
            task = asyncio.ensure_future(self._call_service(msg, oid))
            self.tasks.add(task)
            task.add_done_callback(self.tasks.discard)
        elif op == "service_response":
            self._service_response(msg, oid)
        elif op == "advertise_service":
            self._advertise_service(msg)
        elif op == "unadvertise_service":
            service = _req_str(msg, "service")
            if self.endpoint.services.get(service) is self:
                del self.endpoint.services[service]
        elif op == "fragment":
            self._fragment(msg, depth)
        elif op == "set_level":
            level = msg.get("level")
            if level not in _LEVELS:
                raise RosbridgeError(f"level must be one of {sorted(_LEVELS)}")
            self.level = _LEVELS[level]
        else:
            raise RosbridgeError(f"unknown op {op!r}")

    def _publish(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = _req_str(msg, "topic")
        if "msg" not in msg:
            raise RosbridgeError("publish needs a 'msg'")
        body = msg["msg"]
        if not isinstance(body, Mapping):
            raise RosbridgeError("'msg' must be an object")
        if topic not in ROBOT_SUBSCRIBES:
            if topic in rb.TOPIC_TYPES:
                raise RosbridgeError(
                    f"{topic} is published by the robot; it does not subscribe to it"
                )
            raise RosbridgeError(f"unknown topic {topic}: the robot does not subscribe to it")
        warning = self.robot.handle_publish(topic, body)
        if warning:
            self.status("warning", warning, oid)

    def _subscribe(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = _req_str(msg, "topic")
        known = rb.TOPIC_TYPES.get(topic)
        if known is None:
            raise RosbridgeError(f"unknown topic {topic}")
        typ = msg.get("type")
        if typ not in (None, "") and (not isinstance(typ, str) or rb.normalize_type(typ) != known):
            raise RosbridgeError(f"{topic} is of type {known}, not {typ!r}")
        throttle = _opt_int(msg, "throttle_rate") / 1000.0
        qlen = min(_opt_int(msg, "queue_length"), MAX_QUEUE)
        _opt_int(msg, "fragment_size")
        compression = msg.get("compression") or "none"
        if compression not in ("none", "cbor", "png", "cbor-raw"):
            raise RosbridgeError(f"unknown compression {compression!r}")
        if compression in ("png", "cbor-raw"):
            self.status(
                "warning", f"compression {compression!r} is not supported; sending JSON", oid
            )
        sub = self.subs.get(topic)
        new = sub is None
        if sub is None:
            sub = self.subs[topic] = _Sub(self, topic)
        if oid not in sub.params and len(sub.params) >= MAX_SUB_IDS:
            raise RosbridgeError(f"more than {MAX_SUB_IDS} subscriptions to {topic}")
        sub.params.pop(oid, None)  # re-subscribing with an id makes it the latest
        sub.params[oid] = _SubParams(throttle, qlen, compression == "cbor")
        sub.recompute()
        if new:
            self.robot._add_sub(sub)
        self.robot._offer_latched(sub)

    def _unsubscribe(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = _req_str(msg, "topic")
        sub = self.subs.get(topic)
        if sub is None:
            self.status("warning", f"not subscribed to {topic}", oid)
            return
        if oid is not None and oid in sub.params and len(sub.params) > 1:
            del sub.params[oid]
            sub.recompute()
            return
        if oid is not None and oid not in sub.params:
            self.status("warning", f"no subscription {oid!r} on {topic}", oid)
            return
        self._drop_sub(sub)

    def _drop_sub(self, sub: _Sub) -> None:
        self.subs.pop(sub.topic, None)
        self.robot._remove_sub(sub)

    def _advertise(self, msg: Mapping[str, Any]) -> None:
        topic = _req_str(msg, "topic")
        typ = _req_str(msg, "type")
        known = rb.TOPIC_TYPES.get(topic)
        if known is None or topic not in ROBOT_SUBSCRIBES:
            raise RosbridgeError(f"cannot advertise {topic}: the robot does not subscribe to it")
        if rb.normalize_type(typ) != known:
            raise RosbridgeError(f"{topic} is of type {known}, not {typ!r}")
        self.advertised.add(topic)

    # -- services ----------------------------------------------------------------------------

    async def _call_service(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        service = cast(str, msg["service"])
        args = msg.get("args")
        try:
            if args is not None and not isinstance(args, Mapping | list):
                raise RosbridgeError("'args' must be an object or a list")
            builtin = _ROSAPI.get(service)
            if builtin is not None:
                values, ok = builtin(self, args), True
            elif service in self.endpoint.services:
                values, ok = await self._forward_call(service, args, msg.get("timeout"))
            else:
                raise RosbridgeError(f"service {service} does not exist")
        except ServeurError as exc:
            self.reply(rb.op_service_response(service, oid, exc.message, result=False))
            self.status("error", exc.message, oid)
            return
        self.reply(rb.op_service_response(service, oid, values, result=ok))

    async def _forward_call(self, service: str, args: Any, limit_s: object) -> tuple[Any, bool]:
        provider = self.endpoint.services[service]
        fid = f"service_request:{service}:{next(_seq)}"
        fut: asyncio.Future[tuple[Any, bool]] = asyncio.get_running_loop().create_future()
        fut.add_done_callback(_consume_exception)  # the caller may be gone when it fails
        provider.calls[fid] = fut
        provider.reply({"op": "call_service", "service": service, "args": args or {}, "id": fid})
        limit = float(limit_s) if isinstance(limit_s, int | float) and limit_s > 0 else 10.0
        try:
            return await asyncio.wait_for(fut, self.clock.wall(limit))
        except TimeoutError as exc:
            raise RosbridgeError(f"service {service} did not answer within {limit} s") from exc
        finally:
            provider.calls.pop(fid, None)

    def _service_response(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        fut = self.calls.get(oid) if isinstance(oid, str) else None
        if fut is None:
            raise RosbridgeError("service_response for no call this server made")
        result = msg.get("result", True)
        if not fut.done():
            fut.set_result((msg.get("values"), result is not False))

    def _advertise_service(self, msg: Mapping[str, Any]) -> None:
        service = _req_str(msg, "service")
        _req_str(msg, "type")
        if service in _ROSAPI:
            raise RosbridgeError(f"{service} is provided by rosapi")
        self.endpoint.services[service] = self

    def _fragment(self, msg: Mapping[str, Any], depth: int) -> None:
        fid = msg.get("id")
        data, num, total = msg.get("data"), msg.get("num"), msg.get("total")
        if not isinstance(fid, str | int) or isinstance(fid, bool):
            raise RosbridgeError("a fragment needs an 'id'")
        if not isinstance(data, str) or not isinstance(num, int) or not isinstance(total, int):
            raise RosbridgeError("a fragment needs 'data' (string), 'num' and 'total' (integers)")
        if not 0 <= num < total or total > MAX_FRAME:
            raise RosbridgeError("fragment 'num' must be in [0, total)")
        parts = self.fragments.get(fid)
        if parts is None:
            if len(self.fragments) >= MAX_FRAGMENTED:  # forget the oldest incomplete message
                self.fragments.pop(next(iter(self.fragments)))
            parts = self.fragments[fid] = {}
        parts[num] = data
        if sum(len(p) for p in parts.values()) > MAX_FRAME:
            del self.fragments[fid]
            raise RosbridgeError("fragmented message is larger than the frame limit")
        if len(parts) == total:
            del self.fragments[fid]
            if depth >= 2:
                raise RosbridgeError("fragments nested too deeply")
            self.handle_frame("".join(parts[i] for i in range(total)), depth + 1)

    def close(self) -> None:
        for sub in list(self.subs.values()):
            self._drop_sub(sub)
        for name, provider in list(self.endpoint.services.items()):
            if provider is self:
                del self.endpoint.services[name]
        for fut in self.calls.values():
            if not fut.done():
                fut.set_exception(RosbridgeError("the service provider disconnected"))
        for task in list(self.tasks):
            task.cancel()


def _rosapi_topics(client: _Client, args: Any) -> dict[str, Any]:
    topics = sorted(rb.TOPIC_TYPES)
    return {"topics": topics, "types": [rb.TOPIC_TYPES[t] for t in topics]}


def _rosapi_get_time(client: _Client, args: Any) -> dict[str, Any]:
    return {"time": rb.ros_time(client.clock.epoch())}


def _rosapi_topic_type(client: _Client, args: Any) -> dict[str, Any]:
    topic = args.get("topic") if isinstance(args, Mapping) else (args[0] if args else None)
    return {"type": rb.TOPIC_TYPES.get(topic, "") if isinstance(topic, str) else ""}


def _rosapi_services(client: _Client, args: Any) -> dict[str, Any]:
    return {"services": sorted([*_ROSAPI, *client.endpoint.services])}


_ROSAPI: Final[dict[str, Callable[[_Client, Any], dict[str, Any]]]] = {
    "/rosapi/topics": _rosapi_topics,
    "/rosapi/get_time": _rosapi_get_time,
    "/rosapi/topic_type": _rosapi_topic_type,
    "/rosapi/services": _rosapi_services,
}


# ---------------------------------------------------------------------------------------------
# One robot's websocket endpoint
# ---------------------------------------------------------------------------------------------


class _Endpoint:
    """The rosbridge websocket server of one robot; can be stopped and restarted on its port.

    With ``ssl`` it speaks only TLS (``wss://``), as a robot whose rosbridge_server was started
    with ``ssl:=true`` does, so the server's certificate checks are exercised for real.
    """

    def __init__(
        self, robot: SimRobot, host: str, port: int, ssl: ssl_module.SSLContext | None = None
    ) -> None:
        self.robot = robot
        self.host = host
        self.port = port
        self.ssl = ssl
        self.server: Server | None = None
        self.clients: set[_Client] = set()
        self.services: dict[str, _Client] = {}

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        scheme = "wss" if self.ssl is not None else "ws"
        return f"{scheme}://{host}:{self.port}"

    async def start(self) -> None:
        if self.server is not None:
            return
        self.server = await serve(
            self._handler,
            self.host,
            self.port,
            compression=None,  # rosbridge_server does not deflate; it would cost CPU per client
            max_size=MAX_FRAME,
            close_timeout=2.0,
            reuse_address=True,
            ssl=self.ssl,
        )
        if self.port == 0:
            self.port = int(self.server.sockets[0].getsockname()[1])

    async def stop(self, close_timeout: float = 2.0) -> None:
        """Stop listening and close every connection with 1001 (Going Away).

        websockets' own ``Server.close`` waits for each close handshake while flushing what is
        queued, and a client that stopped reading never lets that flush end; so each client
        gets ``close_timeout`` wall seconds, then its TCP connection is aborted.
        """
        server, self.server = self.server, None
        if server is None:
            return
        server.close(close_connections=False)

        async def close_one(ws: ServerConnection) -> None:
            try:
                await asyncio.wait_for(ws.close(1001, "endpoint stopped"), close_timeout)
            except TimeoutError:
                ws.transport.abort()

        await asyncio.gather(*(close_one(c.ws) for c in list(self.clients)))
        await server.wait_closed()

    async def _handler(self, ws: ServerConnection) -> None:
        sock = ws.transport.get_extra_info("socket")
        if sock is not None:
            # A small kernel send buffer: a client that stops reading then backs up into our
            # bounded per-topic queues (which drop the oldest) within a few frames, instead of
            # into megabytes of stale scans in the kernel (loopback autotunes up to 4 MiB).
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
        client = _Client(self, ws)
        self.clients.add(client)
        writer = asyncio.ensure_future(client.writer())
        try:
            async for frame in ws:
                client.handle_frame(frame)
        except ConnectionClosed:
            pass
        finally:
            client.close()
            self.clients.discard(client)
            writer.cancel()
            with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
                await writer


# ---------------------------------------------------------------------------------------------
# The fleet
# ---------------------------------------------------------------------------------------------


class Simulation:
    """N robots, their endpoints and the physics loop. Use ``async with`` or start()/close()."""

    def __init__(
        self,
        robots: Sequence[SimRobot],
        endpoints: Sequence[_Endpoint],
        clock: Clock,
        *,
        spread: bool = False,
    ) -> None:
        self.robots: list[SimRobot] = list(robots)
        self._endpoints = list(endpoints)
        self.clock = clock
        #: Step robot i i/N of the AMCL period after robot 0 (see :meth:`phases`).
        self.spread = spread
        self._loop_task: asyncio.Task[None] | None = None

    def phases(self) -> list[tuple[int, float]]:
        """Per robot: (ticks its publishing lags robot 0's by, sim seconds its steps lag by).

        Lock-step (the default), every robot is stepped in the same pass and robots only
        alternate ticks (``SimRobot._ticks`` starts at the robot's index), so half the fleet's
        AMCL poses leave together. Real robots are independent machines whose 10 Hz timers are
        not phase-locked; with ``spread`` robot i's publishing is shifted by i/N of the AMCL
        period (whole ticks, then a fraction of a tick by which its physics steps run later),
        so N robots' poses arrive evenly spread. Physics and publish rates are unchanged.
        """
        n = len(self.robots)
        if not self.spread:
            return [(0, 0.0)] * n
        out = []
        for i in range(n):
            ticks, rest = divmod(i * _AMCL_TICKS, n)
            out.append((ticks, rest * TICK / n))
        return out

    @property
    def urls(self) -> list[str]:
        """ws://host:port (wss:// with TLS) of each robot, in robot order."""
        return [e.url for e in self._endpoints]

    async def start(self) -> None:
        """Open every endpoint and start the physics loop (idempotent)."""
        try:
            for e in self._endpoints:
                await e.start()
        except OSError:
            await self.close()
            raise
        if self._loop_task is None:
            self._loop_task = asyncio.ensure_future(self._run())

    async def close(self) -> None:
        """Stop the physics loop and close every endpoint (clients see close code 1001)."""
        task, self._loop_task = self._loop_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await asyncio.gather(*(e.stop() for e in self._endpoints))

    async def stop_endpoint(self, i: int) -> None:
        """Fault hook: close robot i's websocket server and its connections; the robot keeps
        its pose and goes on simulating (a rosbridge_server crash or a Wi-Fi drop)."""
        await self._endpoints[i].stop()

    async def start_endpoint(self, i: int) -> None:
        """Reopen robot i's websocket server on the same port."""
        await self._endpoints[i].start()

    async def warm_plans(self, goals: Sequence[tuple[float, float]]) -> int:
        """Plan once to each goal now (in a worker thread); how many were reachable.

        A robot's first goal at a spot waits for that spot's distance field (40-80 ms of CPU
        on a restaurant map, which an accelerated replay turns into seconds of a robot
        standing still); after this every plan to these goals is a cached pointer walk.
        """
        robot = self.robots[0]
        start = robot.home[0], robot.home[1]

        def work() -> int:
            done = 0
            for goal in goals:
                with contextlib.suppress(ServeurError):
                    robot._plan_blocking(start, goal)
                    done += 1
            return done

        return await asyncio.get_running_loop().run_in_executor(None, work)

    async def __aenter__(self) -> Simulation:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def _run(self) -> None:
        """Step every robot at TICK of sim time; publish what falls due."""
        clock = self.clock
        t = clock.now()
        groups: dict[float, list[SimRobot]] = {}
        for r, (ticks, offset) in zip(self.robots, self.phases(), strict=True):
            r._t = t + offset  # stamps stay the sim time of the robot's own steps
            if self.spread:
                r._ticks = -ticks
            groups.setdefault(offset, []).append(r)
        passes = sorted(groups.items())
        while True:
            t += TICK
            delay = t - clock.now()
            if delay > 0:
                await clock.sleep(delay)
            steps = 1
            behind = clock.now() - t
            if behind >= TICK:  # overloaded: catch up with several steps in this pass
                steps += min(int(behind / TICK), _MAX_CATCH_UP - 1)
                t += (steps - 1) * TICK
                slip = clock.now() - t
                if slip > TICK * _MAX_CATCH_UP:  # hopelessly behind: let sim time slip
                    t += slip
                    for r in self.robots:
                        r._t += slip
            for offset, group in passes:
                if offset > 0.0 and (lag := t + offset - clock.now()) > 0:
                    await clock.sleep(lag)
                for r in group:
                    try:
                        r._advance(steps)
                    except Exception:  # one robot's bug must not stop the fleet
                        log.exception("%s: simulation step failed", r.name)


def _waypoints_beside(map_path: Path) -> dict[str, Waypoint]:
    if map_path.resolve() == demo_map_path().resolve():
        return load_demo()[1]
    stem = map_path.with_suffix("")
    for cand in (
        stem.with_name(stem.name + "_waypoints.json"),
        stem.with_name(stem.name + ".waypoints.json"),
        stem.with_suffix(".json"),
        map_path.with_name("waypoints.json"),
    ):
        if cand.is_file():
            return load_waypoints(cand)
    found = sorted(map_path.parent.glob("*waypoints*.json"))
    return load_waypoints(found[0]) if len(found) == 1 else {}


def _start_poses(
    n: int, grid: OccupancyMap, planner: Planner, waypoints: Mapping[str, Waypoint]
) -> list[tuple[float, float, float]]:
    """home1..homeN where they exist; the rest on distinct free spots (deterministic order)."""
    poses: list[tuple[float, float, float]] = []
    for i in range(n):
        wp = waypoints.get(f"home{i + 1}")
        if wp is not None:
            poses.append((wp.x, wp.y, wp.yaw))
    if len(poses) == n:
        return poses
    spacing = 0.5  # robots are 0.4 m wide
    ref = poses[0][:2] if poses else grid.cell_to_world(grid.height // 2, grid.width // 2)
    xs = np.arange(
        grid.origin[0] + spacing / 2, grid.origin[0] + grid.width * grid.resolution, spacing
    )
    ys = np.arange(
        grid.origin[1] + spacing / 2, grid.origin[1] + grid.height * grid.resolution, spacing
    )
    spots = [
        (float(x), float(y))
        for y in ys
        for x in xs
        if planner.is_traversable(float(x), float(y))
        and all(math.hypot(x - p[0], y - p[1]) >= spacing for p in poses)
    ]
    spots.sort(key=lambda s: (round(math.hypot(s[0] - ref[0], s[1] - ref[1]), 6), s))
    if len(spots) < n - len(poses):
        raise ServeurError(f"the map has room for {len(poses) + len(spots)} robots, not {n}")
    poses.extend((x, y, 0.0) for x, y in spots[: n - len(poses)])
    return poses


async def start_simulation(
    n: int,
    *,
    port: int = 9090,
    host: str = "127.0.0.1",
    map_path: str | Path | None = None,
    kinematics: str = "omni",
    time_scale: float = 1.0,
    seed: int = 0,
    clock: Clock | None = None,
    names: Sequence[str] | None = None,
    ssl: ssl_module.SSLContext | None = None,
    spread: bool = False,
) -> Simulation:
    """Start ``n`` robots listening on ports ``port``..``port+n-1`` (0: free ports).

    Robot i is named ``names[i]`` or ``r{i+1}``, starts at waypoint ``home{i+1}`` and uses random
    seed ``seed + i``. ``clock`` overrides ``time_scale`` (tests pass a shared ScaledClock).
    ``ssl`` (a server context, see serveur.tls.server_context) serves every robot over TLS.
    ``spread`` spreads the robots' publish phases over the AMCL period (:meth:`Simulation.phases`).
    """
    if n < 1:
        raise ValueError("at least one robot")
    if kinematics not in KINDS:
        raise ValueError(f"kinematics must be one of {KINDS}, not {kinematics!r}")
    if names is not None and len(names) < n:
        raise ValueError("fewer names than robots")
    clock = clock or ScaledClock(time_scale)
    if map_path is None:
        grid, waypoints = load_demo()
    else:
        grid = load_map(map_path)
        waypoints = _waypoints_beside(Path(map_path))
    # One distance field per goal, cached: robots drive to the same waypoints again and again,
    # so the cache holds every waypoint (the 30-table bench room has 37; with the default 32
    # the LRU thrashed and most goals cost a 40-80 ms field, i.e. a robot standing still for
    # seconds of simulated time at a replay's time scales). Capped by bytes in the Planner.
    planner = Planner(grid, robot_radius=0.2, cache_size=max(32, len(waypoints) + 16))
    plan_lock = threading.Lock()
    homes = _start_poses(n, grid, planner, waypoints)
    map_frame = _Frame(rb.op_publish("/map", rb.occupancy_grid(grid, stamp=clock.epoch(), seq=0)))
    robots: list[SimRobot] = []
    endpoints: list[_Endpoint] = []
    for i in range(n):
        robot = SimRobot(
            names[i] if names is not None else f"r{i + 1}",
            index=i,
            grid=grid,
            planner=planner,
            home=homes[i],
            kinematics=kinematics,
            clock=clock,
            seed=seed + i,
            map_frame=map_frame,
            plan_lock=plan_lock,
        )
        robots.append(robot)
        endpoints.append(_Endpoint(robot, host, port + i if port else 0, ssl))
    sim = Simulation(robots, endpoints, clock, spread=spread)
    await sim.start()
    return sim


# ---------------------------------------------------------------------------------------------
# Command line (`serveur sim`)
# ---------------------------------------------------------------------------------------------


def add_sim_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``serveur sim``."""
    parser.add_argument("--robots", type=int, default=1, help="number of robots (default 1)")
    parser.add_argument(
        "--port", type=int, default=9090, help="port of the first robot; robot i uses port+i"
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)"
    )
    parser.add_argument(
        "--map", default=None, help="map_server YAML (default: the demo restaurant)"
    )
    parser.add_argument(
        "--kinematics", choices=KINDS, default="omni", help="omni (default) or diff"
    )
    parser.add_argument("--time-scale", type=float, default=1.0, help="sim seconds per wall second")
    parser.add_argument("--seed", type=int, default=0, help="random seed (robot i uses seed+i)")
    parser.add_argument(
        "--names", default=None, help="comma-separated robot names (default r1, r2...)"
    )
    parser.add_argument(
        "--certfile", default=None, help="PEM certificate (chain): serve wss:// (needs --keyfile)"
    )
    parser.add_argument("--keyfile", default=None, help="PEM private key of --certfile")
    parser.add_argument(
        "--spread-phases",
        action="store_true",
        help="publish robot i's poses i/N of the AMCL period after robot 0's, as independent "
        "robots do (default: the robots are stepped in lock-step)",
    )


async def run_sim(
    n: int,
    *,
    port: int = 9090,
    host: str = "127.0.0.1",
    map_path: str | Path | None = None,
    kinematics: str = "omni",
    time_scale: float = 1.0,
    seed: int = 0,
    names: Sequence[str] | None = None,
    stop: asyncio.Event | None = None,
    out: TextIO | None = None,
    ssl: ssl_module.SSLContext | None = None,
    spread: bool = False,
) -> int:
    """Run a simulation until ``stop`` is set or SIGINT/SIGTERM; print the URLs first.

    Returns a process exit code: 0 after a clean stop, 1 when it could not start.
    """
    out = out or sys.stdout
    stop = stop or asyncio.Event()
    loop = asyncio.get_running_loop()
    installed: list[signal.Signals] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        try:
            sim = await start_simulation(
                n,
                port=port,
                host=host,
                map_path=map_path,
                kinematics=kinematics,
                time_scale=time_scale,
                seed=seed,
                names=names,
                ssl=ssl,
                spread=spread,
            )
        except (OSError, ServeurError, ValueError) as exc:
            print(f"serveur sim: cannot start: {exc}", file=sys.stderr, flush=True)
            return 1
        try:
            for url in sim.urls:
                print(url, file=out)
            out.flush()
            await stop.wait()
        finally:
            await sim.close()
        return 0
    finally:
        for sig in installed:
            loop.remove_signal_handler(sig)


async def run_sim_from_args(ns: argparse.Namespace) -> int:
    """``serveur sim`` entry point: the options of :func:`add_sim_arguments` -> :func:`run_sim`."""
    names = [s.strip() for s in ns.names.split(",")] if getattr(ns, "names", None) else None
    ctx = None
    certfile, keyfile = getattr(ns, "certfile", None), getattr(ns, "keyfile", None)
    if certfile or keyfile:
        from serveur.tls import server_context

        if not (certfile and keyfile):
            print("serveur sim: --certfile and --keyfile go together", file=sys.stderr)
            return 2
        try:
            ctx = server_context(certfile, keyfile)
        except ServeurError as exc:
            print(f"serveur sim: cannot start: {exc}", file=sys.stderr, flush=True)
            return 1
    return await run_sim(
        ns.robots,
        port=ns.port,
        host=ns.host,
        map_path=ns.map,
        kinematics=ns.kinematics,
        time_scale=ns.time_scale,
        seed=ns.seed,
        names=names,
        ssl=ctx,
        spread=getattr(ns, "spread_phases", False),
    )
