"""The robot links' side of the core: reports received, queued per robot, handled in order.

A :class:`~serveur.robots.ros1.link.RobotLink` calls its listener on the event loop and must not be
blocked, while what a report means — a goal reached, a link lost — has to be decided under the
robot's lock, against the store. :class:`LinkReports` is that listener. It splits reports in
two:

* the frequent ones that only update live state or screens (pose, battery, laser scan, the
  map) are applied at once, without the lock;
* the ones that change a robot's status (link up/down, goal results, the hand-over timer, the
  periodic pose save) go on the robot's queue; one worker task per robot takes them in arrival
  order under the robot's lock and hands each to the :class:`ReportHandler` (the core), then
  publishes the events that wrote.

It also turns the hub's "someone watches / nobody watches" signals into the links' stream
rates (laser scans only while watched, poses slowed while unwatched), and passes poses to the
screens through a :class:`~serveur.core.pose_rate.PoseGate` (at most 10 a wall second per
robot, none while parked).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
from collections.abc import Mapping
from typing import Any, Protocol

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.events import (
    GoalEnded,
    HandoverDue,
    LinkDown,
    LinkFailed,
    LinkUp,
    PersistPose,
    RobotEvent,
)
from serveur.core.hub import Hub
from serveur.core.places import Places
from serveur.core.pose_rate import Pose, PoseGate
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig, Runtime, pose_dict
from serveur.errors import StoreError
from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss
from serveur.robots.sensing import Cloud
from serveur.scheduler import MIN_BATTERY

__all__ = [
    "HANDOVER_GRACE",
    "ODOMETER_JUMP",
    "ODOMETER_STEP",
    "SAVE_TURN",
    "LinkReports",
    "ReportHandler",
    "worth_saving",
]

log = logging.getLogger(__name__)

#: Seconds a robot restored Offline at start is given to connect before a hand-over, however
#: long it was away before the restart (its link needs a connection and a first status).
HANDOVER_GRACE = 10.0
#: A pose this far (m) from the last one is a relocalisation (AMCL, a calibration), not
#: driving: it does not count in the odometer.
ODOMETER_JUMP = 1.0
#: Pose noise of a parked robot stays within this (m) of where it stopped (AMCL's jitter is
#: centimetres): the odometer counts nothing smaller.
ODOMETER_STEP = 0.1
#: A parked robot turned this far (rad) from its stored heading is stored again.
SAVE_TURN = math.radians(5.0)
#: Wall seconds between tries of a report the store could not write (disk full, I/O error),
#: doubling from the first to the last.
STORE_RETRY = (0.5, 10.0)


class ReportHandler(Protocol):
    """What a queued report becomes: the core's decision, made under the robot's lock."""

    async def on_event(self, rt: Runtime, event: RobotEvent) -> None:
        """Handle one event (:mod:`serveur.core.events`)."""

    def moved(self, name: str, x: float, y: float) -> None:
        """A pose: the zones the robot has left are released (serveur.core.traffic)."""

    def localisation_changed(self, name: str) -> None:
        """The robot became lost, or sure again (``rt.localisation.lost``): publish its
        record; sure again, the dispatcher may give it trips."""

    def battery_changed(self, name: str) -> None:
        """The robot's battery moved by a percent or more since last published, or crossed
        the dispatch threshold: publish its record, and let the dispatcher look again (a
        robot charging at home may be usable for trips now)."""


def _odometer(rt: Runtime, x: float, y: float) -> tuple[float, float]:
    """Count the metres a pose has driven the robot; returns the new anchor.

    A parked robot's AMCL pose wanders by centimetres: counting every step would make it
    drive metres standing at a table. So distance is counted from an anchor, and only once
    the pose is ODOMETER_STEP from it (the anchor then moves there): noise inside that circle
    never counts, and a drive is counted in chords of about that length (short by at most one
    step a leg). A jump over ODOMETER_JUMP is a relocalisation, not driving.
    """
    ax, ay = rt.odometer_at if rt.odometer_at is not None else (x, y)
    step = math.hypot(x - ax, y - ay)
    if step < ODOMETER_STEP:
        return (ax, ay)
    if step < ODOMETER_JUMP:
        rt.odometer += step
    return (x, y)


def worth_saving(
    saved: tuple[float, float, float, float | None] | None,
    now: tuple[float, float, float, float | None],
) -> bool:
    """Whether the store's copy of a robot's pose and battery (``saved``) is worth replacing
    by ``now``: it moved past AMCL's noise (:data:`ODOMETER_STEP`, :data:`SAVE_TURN`) or its
    battery by a percent (what staff see). A parked robot's AMCL pose wanders by centimetres
    and its battery by less than a percent in minutes: writing it again every period cost an
    idle server ten SQLite writes, and their thread hand-overs, every five seconds, for a row
    that says the same thing."""
    if saved is None:
        return True
    x, y, yaw, battery = now
    sx, sy, syaw, sbattery = saved
    turned = abs(math.remainder(yaw - syaw, math.tau))
    if math.hypot(x - sx, y - sy) >= ODOMETER_STEP or turned >= SAVE_TURN:
        return True
    if (battery is None) != (sbattery is None):
        return True
    return battery is not None and sbattery is not None and abs(battery - sbattery) >= 0.01


class LinkReports:
    """Every robot link's listener (:class:`~serveur.robots.ros1.link.LinkListener`)."""

    def __init__(
        self,
        runtimes: Mapping[str, Runtime],
        handler: ReportHandler,
        *,
        hub: Hub,
        clock: Clock,
        config: CoreConfig,
        places: Places,
        publisher: Publisher,
    ) -> None:
        self._rt = runtimes
        self._handler = handler
        self._hub = hub
        self._clock = clock
        self._config = config
        self._places = places
        self._publisher = publisher
        self._closing = False
        self._battery_shown: dict[str, float] = {}  # the level last published, per robot
        # Poses reach the screens at most 10 a wall second per robot, and not when parked.
        self._poses = PoseGate(self._publish_pose)

    # -- the per-robot queue and worker ------------------------------------------------------

    def post(self, robot: str, event: RobotEvent) -> None:
        """Queue an event for the robot's worker (dropped once shutting down)."""
        rt = self._rt.get(robot)
        if rt is not None and not self._closing:
            rt.events.put_nowait(event)

    def start_worker(self, rt: Runtime) -> asyncio.Task[None]:
        """The task that handles the robot's queued reports, for the life of the server."""
        return asyncio.create_task(self._worker(rt), name=f"robot-{rt.name}")

    def stop_queueing(self) -> None:
        """Shutting down: reports arriving from now on are dropped."""
        self._closing = True
        self._poses.close()

    async def stop_worker(self, rt: Runtime) -> None:
        """Cancel the robot's worker and wait for it to end."""
        if rt.worker is not None:
            rt.worker.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await rt.worker

    # -- the hand-over timer: a report the server sends itself -------------------------------

    def arm_handover(self, rt: Runtime) -> None:
        """The robot is Offline with a trip: queue ``handover`` once it is gone too long."""
        if self._config.handover_after is None or rt.handover is not None or self._closing:
            return
        rt.handover = asyncio.create_task(self._handover_timer(rt), name=f"handover-{rt.name}")

    def disarm_handover(self, rt: Runtime) -> None:
        """The robot is back or has no trip left to hand over."""
        timer, rt.handover = rt.handover, None
        if timer is not None and timer is not asyncio.current_task():
            timer.cancel()

    async def _handover_timer(self, rt: Runtime) -> None:
        limit = self._config.handover_after
        assert limit is not None
        away = self._clock.epoch() - (rt.offline_since or self._clock.epoch())
        # What is left of the limit, but never less than a short grace (a robot restored at
        # start needs a moment to connect before its trip can be judged), nor more than the
        # limit (a stored time ahead of this clock: an accelerated run, restarted).
        grace = min(limit, HANDOVER_GRACE)
        await self._clock.sleep(min(limit, max(grace, limit - away)))
        rt.handover = None
        # Through the robot's queue, like a link report: a link-up already queued is handled
        # first, and the hand-over then sees the robot back and does nothing.
        self.post(rt.name, HandoverDue())

    async def _worker(self, rt: Runtime) -> None:
        while True:
            await self._apply(rt, await rt.events.get())

    async def _apply(self, rt: Runtime, event: RobotEvent) -> None:
        """Handle one report; one the store could not write is kept and tried again.

        A goal result is what moves a trip on: dropped because the disk was full, the trip
        would never complete (the robot at the table, the order "assigned" for ever). So a
        :class:`~serveur.errors.StoreError` keeps the report at the head of the robot's queue
        and retries it, with backoff, until the store takes it; the reports behind it wait,
        since their order matters. The handler changes no live state before its write
        succeeds, so a retry decides afresh.
        """
        delay, longest = STORE_RETRY
        failing = False
        while True:
            try:
                async with rt.lock:
                    await self._handler.on_event(rt, event)
                await self._publisher.flush_events()
            except asyncio.CancelledError:
                raise
            except StoreError as exc:
                if not failing:
                    log.error("%s: %s report not stored, retrying: %s", rt.name, event, exc)
                    failing = True
                await self._clock.sleep(delay * self._clock.time_scale)
                delay = min(delay * 2.0, longest)
                continue
            except Exception:
                log.exception("%s: handling %s failed", rt.name, event)
            if failing:
                log.warning("%s: %s report stored after the store recovered", rt.name, event)
            return

    # -- robot_link.LinkListener -------------------------------------------------------------

    def link_up(self, robot: str) -> None:
        self.post(robot, LinkUp())

    def link_down(self, robot: str, reason: str) -> None:
        self.post(robot, LinkDown(reason))

    def link_failed(self, robot: str, reason: str) -> None:
        self.post(robot, LinkFailed(reason))

    def goal_done(self, robot: str, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        self.post(robot, GoalEnded(goal_id, status, text))

    def goal_lost(
        self, robot: str, goal_id: str, reason: str, *, cause: GoalLoss = GoalLoss.NAVIGATION
    ) -> None:
        self.post(robot, GoalEnded(goal_id, rb.GoalStatus.LOST, reason, cause))

    def pose(self, robot: str, x: float, y: float, yaw: float, stamp: float) -> None:
        rt = self._rt.get(robot)
        if rt is None:
            return
        rt.odometer_at = _odometer(rt, x, y)
        rt.pose = (x, y, yaw)
        self._handler.moved(robot, x, y)
        if self._hub.watched(f"pose:{robot}"):
            self._poses.offer(robot, rt.pose, stamp)
        now = self._clock.now()
        if now - rt.pose_saved_at > self._config.pose_persist_period:
            rt.pose_saved_at = now
            saving = (x, y, yaw, rt.battery)
            if worth_saving(rt.pose_saved, saving):
                rt.pose_saved = saving
                self.post(robot, PersistPose())

    def _publish_pose(self, robot: str, pose: Pose, stamp: float) -> None:
        topic = f"pose:{robot}"
        if self._hub.watched(topic):
            self._hub.publish(topic, P.dump(pose_dict(pose, stamp)))

    def localisation(self, robot: str, metres: float, radians: float) -> None:
        rt = self._rt.get(robot)
        if rt is not None and rt.localisation.pose(metres, radians):
            self._handler.localisation_changed(robot)

    def cloud(self, robot: str, cloud: Cloud) -> None:
        """The particle cloud (streamed only while someone shows it): its spread counts in
        the robot's localisation, and the screens get at most :data:`CLOUD_SHOWN` particles,
        at most as often as the laser."""
        rt = self._rt.get(robot)
        if rt is None:
            return
        if rt.localisation.cloud(cloud.spread()):
            self._handler.localisation_changed(robot)
        topic = f"cloud:{robot}"
        if self._hub.watched(topic):
            data = {"stamp": cloud.stamp, "count": len(cloud), "particles": cloud.shown()}
            self._hub.publish(topic, P.dump(data))

    def battery(self, robot: str, fraction: float) -> None:
        rt = self._rt.get(robot)
        if rt is None:
            return
        rt.battery = fraction
        # Against the level last *published*: a robot's battery moves by far less than 1 %
        # between two messages (5 s apart), so comparing with the previous message never
        # published a slow change. Crossing the dispatch threshold counts whatever its size.
        shown = self._battery_shown.get(robot)
        if (
            shown is None
            or abs(shown - fraction) >= 0.01
            or (shown < MIN_BATTERY) != (fraction < MIN_BATTERY)
        ):
            self._battery_shown[robot] = fraction
            self._handler.battery_changed(robot)

    def scan(self, robot: str, msg: Mapping[str, Any]) -> None:
        rt = self._rt.get(robot)
        if rt is None or not self._hub.watched(f"scan:{robot}") or not self._poses.scan_due(robot):
            return
        x, y, yaw = rt.pose or (0.0, 0.0, 0.0)
        data = {
            "stamp": rb.from_ros_time(msg["header"]["stamp"]),
            "x": x,
            "y": y,
            "yaw": yaw,
            "angle_min": msg["angle_min"],
            "angle_increment": msg["angle_increment"],
            "range_max": msg["range_max"],
            "ranges": msg["ranges"],
        }
        self._hub.publish(f"scan:{robot}", P.dump(data))

    def map(self, robot: str, msg: Mapping[str, Any]) -> None:
        self._places.adopt_map(robot, msg)

    # -- hub watch signals -------------------------------------------------------------------

    def on_watch(self, topic: str, on: bool) -> None:
        """Scans stream only while watched; poses slow to 1 Hz while unwatched and parked."""
        if topic.startswith("scan:"):
            rt = self._rt.get(topic[5:])
            if rt is not None and rt.link is not None:
                asyncio.get_running_loop().create_task(rt.link.want_scan(on))
        elif topic.startswith("cloud:"):
            rt = self._rt.get(topic[6:])
            if rt is not None and not on and rt.localisation.cloud(None):
                self._handler.localisation_changed(rt.name)
            if rt is not None and rt.link is not None:
                asyncio.get_running_loop().create_task(rt.link.want_cloud(on))
        elif topic.startswith("pose:"):
            if not on:
                self._poses.forget(topic[5:])
            rt = self._rt.get(topic[5:])
            if rt is not None and rt.link is not None:
                asyncio.get_running_loop().create_task(rt.link.want_pose(on))
