"""A fake robot driver: the :class:`~serveur.robots.driver.RobotDriver` interface with no robot,
no socket and no ROS behind it, on an injected :class:`~serveur.clock.Clock`.

Why it exists (Equinor ISAR's mock robot is the model): the simulator imitates a robot's wire so
the real drivers can be tested as a restaurant runs them, but a test of the *core* (trips,
traffic, alerts, the screens) does not need rosbridge frames, a websocket per robot and a
physics loop at 20 Hz: it needs a robot that connects, drives, arrives and fails on demand, in
time a test controls. This driver is that robot. It runs in the server's process, moves only
when its clock says time passed (``clock.sleep``: a :class:`~serveur.clock.FakeClock` moved by
hand, or a scaled or virtual clock), and lets a test script the faults real robots have.
:mod:`serveur.robots.factory` gives it to a robot whose URL is ``fake://NAME`` (tests, demos and
replays without sockets), and ``tests/robots/test_conformance.py`` holds it to the same
assertions as the ROS1 and ROS 2 drivers, so it cannot drift from what they report.

What it does, as the core sees a real robot through a real driver:

* **Link.** A moment after :meth:`FakeDriver.start` the link comes up: a pose, the battery,
  then ``link_up``, in that order, and only once the robot knows where it is (a fake made
  without a pose stays down until :meth:`FakeDriver.localise`), as the real drivers wait for
  AMCL's first pose. Commands raise :class:`~serveur.errors.LinkError` while the link is down.
* **Goals.** The robot drives in a straight line at ``speed`` m/s of clock time, turning to the
  goal's heading at ``turn_rate`` rad/s (no map, no obstacles: a fake plans nothing), reports
  its pose every ``tick`` while it moves and ``goal_done`` SUCCEEDED "Goal reached." when it
  stands on the goal. A new goal replaces the one under way, which is never reported (the real
  drivers ignore the result of a goal they replaced); :meth:`FakeDriver.cancel_goal` stops the
  robot where it is and the goal is never reported either.
* **Teleop** is a velocity in the robot's frame, held until the next one; the joystick's dead
  man's switch (:class:`~serveur.robots.deadman.DeadManSwitch`, the real drivers' own) stops the
  robot when no twist follows. While a goal runs the robot ignores it, as move_base and Nav2 do
  (their controller drives the base; the core cancels the goal before steering by hand).
* **Docking**: a fake has no docking server: :meth:`FakeDriver.dock` is a goal to the dock's
  pose (SUCCEEDED "Goal reached." there), :meth:`FakeDriver.undock` does nothing.
* :meth:`FakeDriver.halt` forgets the goal, stops the robot and refuses every later command.
* A goal that ends while the link is down is not reported (its result went to a connection
  that is gone, as with Nav2): the core re-sends the move when the link is back.

Faults a test scripts: :meth:`~FakeDriver.refuse_next_goal` (never acknowledged: ``goal_lost``
NOT_ACCEPTED after ``ack_timeout``), :meth:`~FakeDriver.lose_goal` (``goal_lost`` now, for the
:class:`~serveur.robots.driver.GoalLoss` a test says), :meth:`~FakeDriver.abort_goal` (a
navigation failure: ``goal_done`` ABORTED with a text), :meth:`~FakeDriver.block_path` (the
robot stops and its goal aborts after :data:`BLOCKED_ABORT_AFTER`, like the simulator's hook),
:meth:`~FakeDriver.drop_link` and :meth:`~FakeDriver.restore_link` (the network gone and back:
``link_down`` once, ``link_up`` once). ``true_pose``, ``velocity`` and ``received`` show what
the robot did and was told, as a test reads a simulated robot.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
from collections.abc import Coroutine
from dataclasses import dataclass
from typing import Any, Final

from serveur.clock import Clock
from serveur.errors import LinkError
from serveur.robots import rosbridge as rb
from serveur.robots.deadman import DeadManSwitch
from serveur.robots.driver import GoalLoss, LinkListener, connect_failed

__all__ = [
    "BLOCKED_ABORT_AFTER",
    "INITIAL_SPREAD",
    "SPEED",
    "SURE_SPREAD",
    "TICK",
    "FakeDriver",
]

log = logging.getLogger(__name__)

#: The localisation spread (m, rad) of a converged filter, and AMCL's after an initial pose.
SURE_SPREAD: Final = (0.02, 0.01)
INITIAL_SPREAD: Final = (0.5, 0.26)
#: Clock seconds between two motion steps (and pose reports) of a moving robot: the simulator's
#: physics rate, 20 Hz.
TICK = 0.05
#: Metres per clock second a fake drives a goal at: a waiter robot's cruising speed.
SPEED = 0.5
#: Radians per clock second it turns at.
TURN_RATE = 1.5
#: Clock seconds a blocked robot waits before its goal aborts (the simulator's value).
BLOCKED_ABORT_AFTER = 1.0
#: Clock seconds from start(), restore_link() or localise() to the link being up: a real link
#: needs a connection and a first status; a fake comes up soon, but never inside the call.
CONNECT_DELAY = 0.1
#: Clock seconds a dropped connection (drop()) takes to come back, as a real link's first backoff.
RECONNECT_DELAY = 0.2
#: Clock seconds between two laser scans while someone watches them (the real drivers' 5 Hz).
SCAN_PERIOD = 0.2
#: Wall seconds without a joystick twist before the robot is stopped (the real drivers' value).
TELEOP_TIMEOUT = 0.5
#: What a fake's laser sees: nothing within range, in every direction.
_SCAN_RAYS = 90
_SCAN_RANGE = 8.0
_ARRIVED = 1e-6  # metres / radians: the robot stands on its goal


def _wrap(angle: float) -> float:
    """An angle in (-pi, pi]."""
    out = math.remainder(angle, math.tau)
    return math.pi if out <= -math.pi else out


@dataclass(slots=True)
class _Goal:
    handle: str
    x: float
    y: float
    yaw: float
    sent_at: float
    #: Why the robot never acknowledges it (refuse_next_goal), None for a goal it drives.
    refused: str | None = None
    #: Clock time the robot found its way blocked, None while it is free to drive.
    blocked_since: float | None = None


class FakeDriver:
    """One fake robot and its link (:class:`~serveur.robots.driver.RobotDriver`, no socket).

    ``pose`` is where the robot starts (None: it does not know, and the link stays down until
    :meth:`localise`); ``reachable`` False starts it with the network gone (:meth:`drop_link`).
    ``ack_timeout`` is how long a refused goal takes to be reported lost; ``heartbeat`` is
    what :meth:`heartbeat_timeout` says (a fake has no heartbeat: its link fails only when a
    test says so).
    """

    kind = "fake"

    def __init__(
        self,
        name: str,
        url: str,
        listener: LinkListener,
        clock: Clock,
        *,
        pose: tuple[float, float, float] | None = (0.0, 0.0, 0.0),
        battery: float = 1.0,
        speed: float = SPEED,
        turn_rate: float = TURN_RATE,
        tick: float = TICK,
        ack_timeout: float = 2.0,
        heartbeat: float = 1.0,
        teleop_timeout: float = TELEOP_TIMEOUT,
        reachable: bool = True,
    ) -> None:
        if not (speed > 0 and turn_rate > 0 and tick > 0):
            raise ValueError("speed, turn_rate and tick must be > 0")
        self.name = name
        self.url = url
        self._listener = listener
        self._clock = clock
        self._speed = speed
        self._turn_rate = turn_rate
        self._tick = tick
        self._ack_timeout = ack_timeout
        self._heartbeat = heartbeat
        self._deadman = DeadManSwitch(name, clock, teleop_timeout, self._deadman_stop)
        #: Where the robot really is (None: it does not know), whatever the link reported.
        self.true_pose = pose
        self._battery = min(1.0, max(0.0, battery))
        #: The robot's velocity now, in its own frame (vx, vy, wz), as it moved the last tick.
        self.velocity: tuple[float, float, float] = (0.0, 0.0, 0.0)
        #: Every command the robot was told, in order: ("goal", x, y, yaw), ("cancel",),
        #: ("teleop", vx, vy, wz), ("initial_pose", x, y, yaw), ("halt",), ("dock", x, y,
        #: yaw, dock_id), ("undock",).
        self.received: list[tuple[Any, ...]] = []
        self._twist = (0.0, 0.0, 0.0)  # the joystick's last velocity, held by the base
        self._goal: _Goal | None = None
        self._refusals: list[str] = []
        self._blocked = False
        self._network = reachable
        self._up = False
        self._started = False
        self._halted = False
        self._closed = False
        self._seq = itertools.count(1)
        self._scan_seq = itertools.count()
        self._connecting: asyncio.Task[None] | None = None
        self._motion: asyncio.Task[None] | None = None
        self._scanning: asyncio.Task[None] | None = None
        #: Someone watches the pose live / the laser scan (want_pose, want_scan).
        self.pose_watched = False
        self.scan_wanted = False
        self.cloud_wanted = False
        #: The spread (m, rad) reported with each pose: a converged filter's, until
        #: :meth:`lose_localisation`.
        self.spread: tuple[float, float] = SURE_SPREAD
        self.pose: tuple[float, float, float] | None = None
        self.battery: float | None = None
        self.last_failure = ""
        self.connects = 0

    # -- the driver interface: lifecycle -----------------------------------------------------

    @property
    def up(self) -> bool:
        return self._up

    @property
    def goal_id(self) -> str | None:
        return self._goal.handle if self._goal else None

    def start(self) -> None:
        if self._started or self._closed:
            return
        self._started = True
        self._connect_soon(CONNECT_DELAY)

    async def close(self) -> None:
        """Stop every task of the driver; the link goes down as a real one does at shutdown."""
        self._closed = True
        self._deadman.release()
        tasks = [t for t in (self._connecting, self._motion, self._scanning) if t is not None]
        self._connecting = self._motion = self._scanning = None
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError):
                await task
        self._set_down("server shutting down")

    async def drop(self) -> None:
        """The connection closes as if the network failed; it comes back by itself."""
        if self._up:
            self._set_down("connection closed")
            self._connect_soon(RECONNECT_DELAY)

    def heartbeat_timeout(self) -> float:
        return self._heartbeat

    # -- the driver interface: commands ------------------------------------------------------

    def _check(self) -> None:
        if self._halted:
            raise LinkError(f"robot {self.name} is stopped: the server is shutting down")
        if not self._up:
            raise LinkError(f"robot {self.name} is not connected")

    async def halt(self) -> None:
        """Stop the robot for good: its goal forgotten, no velocity, every later command refused."""
        self._halted = True
        self._goal = None
        self._twist = (0.0, 0.0, 0.0)
        self._deadman.release()
        self.received.append(("halt",))

    async def send_goal(self, x: float, y: float, yaw: float) -> str:
        self._check()
        self.received.append(("goal", x, y, yaw))
        return self._new_goal(x, y, yaw)

    def _new_goal(self, x: float, y: float, yaw: float) -> str:
        handle = f"fake-{self.name}-{next(self._seq)}"
        refused = self._refusals.pop(0) if self._refusals else None
        self._goal = _Goal(handle, x, y, _wrap(yaw), self._clock.now(), refused)
        self._move()
        return handle

    async def dock(self, x: float, y: float, yaw: float, dock_id: str) -> str:
        """No docking server: a goal to the dock's pose (the faults of goals apply)."""
        self._check()
        self.received.append(("dock", x, y, yaw, dock_id))
        return self._new_goal(x, y, yaw)

    async def undock(self) -> None:
        """Nothing to do: the next goal drives the robot off its dock."""
        self.received.append(("undock",))

    async def cancel_goal(self) -> None:
        self._check()
        self._goal = None
        self.received.append(("cancel",))

    async def teleop(self, vx: float, vy: float, wz: float) -> None:
        self._check()
        self._deadman.twist((vx, vy, wz) != (0.0, 0.0, 0.0))
        self._twist = (vx, vy, wz)
        self.received.append(("teleop", vx, vy, wz))
        self._move()

    async def _deadman_stop(self) -> None:
        self._twist = (0.0, 0.0, 0.0)
        self.received.append(("teleop", 0.0, 0.0, 0.0))

    async def initial_pose(self, x: float, y: float, yaw: float) -> None:
        """The robot is where it is told, and sure of it again (as AMCL is after an initial
        pose: its spread is the initial covariance's, 0.5 m and 0.26 rad)."""
        self._check()
        self.received.append(("initial_pose", x, y, yaw))
        self.true_pose = (x, y, _wrap(yaw))
        self.spread = INITIAL_SPREAD
        self._report_pose()

    async def want_pose(self, on: bool) -> None:
        """Noted only: a fake reports every tick while it moves, watched or not."""
        self.pose_watched = on

    async def want_scan(self, on: bool) -> None:
        """Scans (an empty room) every :data:`SCAN_PERIOD` while someone looks at them."""
        self.scan_wanted = on
        self._scan_if_wanted()

    async def want_cloud(self, on: bool) -> None:
        """Noted only: a fake has no particle filter."""
        self.cloud_wanted = on

    # -- test controls: what the robot does -------------------------------------------------

    def localise(self, x: float, y: float, yaw: float) -> None:
        """The robot finds itself there (or is carried there): its pose is reported, and a
        link waiting for a first pose comes up."""
        self.true_pose = (x, y, _wrap(yaw))
        if self._up:
            self._report_pose()
        else:
            self._connect_soon(CONNECT_DELAY)

    def lose_localisation(self, metres: float = 3.0, radians: float = 1.5) -> None:
        """The robot's localisation spreads out (it no longer knows where it is): the next
        poses say so, until an initial pose. Reported at once while the link is up."""
        self.spread = (metres, radians)
        self._report_pose()

    def set_battery(self, fraction: float) -> None:
        """The battery reads ``fraction`` now (reported at once while the link is up)."""
        self._battery = min(1.0, max(0.0, fraction))
        if self._up:
            self.battery = self._battery
            self._listener.battery(self.name, self._battery)

    def refuse_next_goal(
        self, reason: str = "goal not acknowledged by the robot (fake: refused)"
    ) -> None:
        """The next goal is never acknowledged: the robot stays put, and the goal is reported
        lost (:attr:`~serveur.robots.driver.GoalLoss.NOT_ACCEPTED`) with ``reason``
        ``ack_timeout`` clock seconds after it was sent."""
        self._refusals.append(reason)

    def abort_goal(self, text: str = "the robot could not reach the goal (fake fault)") -> None:
        """The goal under way fails now: the robot stops, ``goal_done`` ABORTED with ``text``."""
        if self._goal is not None:
            self._end_goal(rb.GoalStatus.ABORTED, text)

    def lose_goal(
        self,
        reason: str = "the goal's end never came (fake fault)",
        cause: GoalLoss = GoalLoss.NAVIGATION,
    ) -> None:
        """The goal under way is lost now, for ``cause``: the robot stops (a real driver
        cancels a goal it declares lost) and ``goal_lost`` says ``reason``."""
        if self._goal is not None:
            self._lose_goal(reason, cause)

    def block_path(self, on: bool) -> None:
        """While on, the robot cannot drive: its goal (or the next one) aborts after
        :data:`BLOCKED_ABORT_AFTER` clock seconds of standing blocked."""
        self._blocked = on

    def drop_link(self, reason: str = "network unreachable") -> None:
        """The network to the robot is gone: ``link_down`` with ``reason`` once, then one
        ``link_failed`` as the reconnection attempts fail. The robot drives on unheard."""
        self._network = False
        if self._connecting is not None:
            self._connecting.cancel()
            self._connecting = None
        self._set_down(reason)
        if self._started and not self._closed:
            self._connect_failed(reason)

    def restore_link(self) -> None:
        """The network is back: the link comes up again soon (pose, battery, ``link_up``)."""
        self._network = True
        self._connect_soon(CONNECT_DELAY)

    # -- the link ----------------------------------------------------------------------------

    def _connect_soon(self, delay: float) -> None:
        if not self._started or self._closed or self._up:
            return
        if self._connecting is None or self._connecting.done():
            self._connecting = self._spawn(self._connect(delay), "connect")

    async def _connect(self, delay: float) -> None:
        await self._clock.sleep(delay)
        self._connecting = None
        if self._closed or self._up:
            return
        if not self._network:
            self._connect_failed("network unreachable")
            return
        if self.true_pose is None:
            return  # connected but not localised: not up (localise() tries again)
        self.connects += 1
        self.last_failure = ""
        self._report_pose(connecting=True)
        self.battery = self._battery
        self._listener.battery(self.name, self._battery)
        self._up = True
        log.info("%s: link up (%s, fake)", self.name, self.url)
        self._listener.link_up(self.name)
        self._scan_if_wanted()

    def _connect_failed(self, reason: str) -> None:
        connect_failed(self, self._listener, f"fake: {reason}", log)

    def _set_down(self, reason: str) -> None:
        was_up, self._up = self._up, False
        if was_up:
            log.warning("%s: link down (%s)", self.name, reason)
            self._listener.link_down(self.name, reason)

    def _spawn(self, coro: Coroutine[Any, Any, None], what: str) -> asyncio.Task[None]:
        return asyncio.get_running_loop().create_task(coro, name=f"fake-{what}-{self.name}")

    # -- motion ------------------------------------------------------------------------------

    def _moving(self) -> bool:
        return self._goal is not None or self._twist != (0.0, 0.0, 0.0)

    def _move(self) -> None:
        """Start the motion loop if it is not running (it ends when the robot stands still)."""
        if not self._closed and (self._motion is None or self._motion.done()):
            self._motion = self._spawn(self._drive(), "motion")

    async def _drive(self) -> None:
        last = self._clock.now()
        try:
            while self._moving() and not self._halted:
                await self._clock.sleep(self._tick)
                now = self._clock.now()
                self._step(now, now - last)
                last = now
        finally:
            self.velocity = (0.0, 0.0, 0.0)

    def _step(self, now: float, dt: float) -> None:
        pose = self.true_pose
        if pose is None:
            return
        goal = self._goal
        if goal is None:
            self._steer(pose, dt)
        elif goal.refused is not None:
            self.velocity = (0.0, 0.0, 0.0)
            if now - goal.sent_at >= self._ack_timeout:
                self._lose_goal(goal.refused, GoalLoss.NOT_ACCEPTED)
        elif self._blocked:
            self.velocity = (0.0, 0.0, 0.0)
            if goal.blocked_since is None:
                goal.blocked_since = now
            elif now - goal.blocked_since >= BLOCKED_ABORT_AFTER:
                self._end_goal(
                    rb.GoalStatus.ABORTED, "path blocked: no valid plan (aisle obstructed)"
                )
        else:
            goal.blocked_since = None
            self._toward(pose, goal, dt)

    def _toward(self, pose: tuple[float, float, float], goal: _Goal, dt: float) -> None:
        x, y, yaw = pose
        dx, dy = goal.x - x, goal.y - y
        dist = math.hypot(dx, dy)
        step = min(dist, self._speed * dt)
        turn = _wrap(goal.yaw - yaw)
        rot = max(-self._turn_rate * dt, min(self._turn_rate * dt, turn))
        mx, my = (dx / dist * step, dy / dist * step) if dist > 0 else (0.0, 0.0)
        arrived = dist - step <= _ARRIVED and abs(turn - rot) <= _ARRIVED
        self.true_pose = (
            (goal.x, goal.y, goal.yaw) if arrived else (x + mx, y + my, _wrap(yaw + rot))
        )
        if dt > 0:  # in the robot's frame, as the simulator's velocity is
            c, s = math.cos(yaw), math.sin(yaw)
            self.velocity = ((c * mx + s * my) / dt, (c * my - s * mx) / dt, rot / dt)
        self._report_pose()
        if arrived:
            self._end_goal(rb.GoalStatus.SUCCEEDED, "Goal reached.")

    def _steer(self, pose: tuple[float, float, float], dt: float) -> None:
        vx, vy, wz = self._twist
        x, y, yaw = pose
        c, s = math.cos(yaw), math.sin(yaw)
        self.true_pose = (
            x + (c * vx - s * vy) * dt,
            y + (s * vx + c * vy) * dt,
            _wrap(yaw + wz * dt),
        )
        self.velocity = self._twist
        self._report_pose()

    def _lose_goal(self, reason: str, cause: GoalLoss) -> None:
        goal, self._goal = self._goal, None
        self.velocity = (0.0, 0.0, 0.0)
        if goal is not None and self._up:
            self._listener.goal_lost(self.name, goal.handle, reason, cause=cause)

    def _end_goal(self, status: rb.GoalStatus, text: str) -> None:
        goal, self._goal = self._goal, None
        self.velocity = (0.0, 0.0, 0.0)
        if goal is not None and self._up:
            self._listener.goal_done(self.name, goal.handle, status, text)

    def _report_pose(self, *, connecting: bool = False) -> None:
        """Report where the robot is, if the link is up (or coming up: the first pose goes out
        before ``link_up``, as AMCL's does on a real robot)."""
        pose = self.true_pose
        if pose is None or not (self._up or connecting):
            return
        self.pose = pose
        self._listener.pose(self.name, *pose, self._clock.epoch())
        self._listener.localisation(self.name, *self.spread)

    # -- the laser ---------------------------------------------------------------------------

    def _scan_if_wanted(self) -> None:
        if self.scan_wanted and self._up and (self._scanning is None or self._scanning.done()):
            self._scanning = self._spawn(self._scan(), "scan")

    async def _scan(self) -> None:
        while self.scan_wanted and self._up:
            msg = rb.laser_scan(
                [math.inf] * _SCAN_RAYS,
                stamp=self._clock.epoch(),
                seq=next(self._scan_seq),
                angle_min=-math.pi,
                angle_increment=math.tau / _SCAN_RAYS,
                range_min=0.1,
                range_max=_SCAN_RANGE,
                scan_time=SCAN_PERIOD,
            )
            self._listener.scan(self.name, msg)
            await self._clock.sleep(SCAN_PERIOD)
