"""One robot's controller: its live state, its link, its events and its moves through a trip.

Each robot has one :class:`RobotController` (as Home Assistant has one coordinator per
device). It owns the robot's :class:`~serveur.core.runtime.Runtime` (status, pose, goal,
destination) and reacts to two things, both under the robot's lock:

* **events** (:mod:`serveur.core.events`: link up or down, a goal's end, a lease granted, the
  hand-over timer, a table's timeout), queued by :class:`~serveur.core.link_reports.LinkReports`
  and dispatched on their type through :data:`_ON_EVENT`;
* **actions** staff ask for (:mod:`serveur.core.actions`), once the status machine allowed
  them.

The collaborators it works with (store, trips, service, zones, screens) come in a
:class:`~serveur.core.crew.Crew`; it knows nothing of the other robots nor of the core.

Robot dropouts: at first the trip stays with its robot — the dishes are physically on its
tray. The robot is Offline while the link is down; when it returns, it resumes the status it
had and re-sends the goal of the current stop (or arrives at once if it is already there). A
robot Offline for longer than ``CoreConfig.handover_after`` has its trip handed over: the task
goes back to the queue (its orders stay on it) and the next free robot takes it; the away
robot, when it returns, goes home instead of continuing a trip that is no longer its own.
"""

from __future__ import annotations

import contextlib
import logging
import math
import time
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import replace
from typing import Any
from urllib.parse import urlsplit

from serveur import protocol as P
from serveur.core.camera import CameraRelay, CameraSource
from serveur.core.crew import Crew
from serveur.core.events import (
    Charged,
    ChargeDue,
    CruiseResume,
    GoalEnded,
    HandoverDue,
    LeaseGranted,
    LinkDown,
    LinkFailed,
    LinkUp,
    PersistPose,
    RobotEvent,
    TableTimeout,
)
from serveur.core.runtime import Destination, Runtime
from serveur.domain import Robot, StopPurpose, Task, TaskKind
from serveur.errors import Conflict, Forbidden, LinkError, Stale, StoreError
from serveur.robots import rosbridge as rb
from serveur.robots.camera import RosbridgeCamera
from serveur.robots.driver import GoalLoss
from serveur.robots.factory import FAKE_SCHEME, make_driver
from serveur.robots.mjpeg import MjpegCamera
from serveur.robots.names import RosNames
from serveur.status import Event, RobotState, RobotStatus, apply

__all__ = ["RobotController"]

log = logging.getLogger("serveur.core.engine")

S = RobotStatus


class RobotController:
    """One robot: its state, its link, what its events and its trip's steps do."""

    def __init__(self, robot: Robot, crew: Crew) -> None:
        self.crew = crew
        self.name = robot.name
        rt = Runtime(robot.name, RobotState(robot.status, robot.mode, robot.resume))
        if robot.x is not None and robot.y is not None and robot.yaw is not None:
            rt.pose = (robot.x, robot.y, robot.yaw)
        rt.battery = robot.battery
        rt.idle_since = crew.clock.now()
        self.rt = rt
        crew.records[robot.name] = robot
        rt.worker = crew.reports.start_worker(rt)
        #: The robot's camera (made at the first watch) and the options it was made from.
        self._camera: CameraRelay | None = None
        self._camera_from: tuple[str, str, str, int] | None = None

    @property
    def record(self) -> Robot:
        """The robot as stored (status fields as of the last write)."""
        return self.crew.records[self.name]

    @record.setter
    def record(self, robot: Robot) -> None:
        self.crew.records[self.name] = robot

    # -- the record as screens see it -------------------------------------------------------

    def view(self) -> Robot:
        """The stored record with the live pose, battery, link error and zones it waits for."""
        rt = self.rt
        upd: dict[str, Any] = {
            "battery": rt.battery,
            "link_error": rt.link_error,
            "waiting_for": rt.waiting_for,
            "lost": rt.localisation.lost,
            # Going to charge, or stopped (or failed) on the way there.
            "to_dock": rt.to_dock
            and (rt.state.status is S.TRANSIT or rt.state.resume is S.TRANSIT),
        }
        if rt.pose is not None:
            upd.update(x=rt.pose[0], y=rt.pose[1], yaw=rt.pose[2])
        return self.record.model_copy(update=upd)

    def publish(self) -> None:
        """Publish the robot's record as screens see it (live pose and battery)."""
        self.crew.publisher.pub("robots", self.view())

    # -- status changes ---------------------------------------------------------------------

    async def save_state(
        self,
        st: RobotState,
        *,
        event: str = "robot.status",
        error: str | None = None,
        keep_error: bool = False,
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        """Store the robot's new state, then apply it live and publish it.

        The live state follows the store: a write that failed (disk full) changes nothing, so
        the event that asked for it can be retried from the same state.
        """
        crew, rt = self.crew, self.rt
        last_error = self.record.last_error if keep_error else error
        robot = await crew.store.robots.save_robot_state(
            self.name,
            status=st.status,
            mode=st.mode,
            resume=st.resume,
            last_error=last_error,
            now=crew.clock.epoch(),
            event=event,
            data={**(data or {}), "odometer": round(rt.odometer, 2)},
        )
        rt.state = st
        self.record = robot
        crew.traffic.lease_status(rt, st.status)
        self.publish()
        if st.status is not S.OFFLINE:
            rt.offline_since = None
        elif rt.offline_since is None:
            rt.offline_since = crew.clock.epoch()
        if st.status is S.OFFLINE and robot.current_task is not None:
            crew.reports.arm_handover(rt)
        else:
            crew.reports.disarm_handover(rt)
        if st.status is S.AWAITING:
            rt.idle_since = crew.clock.now()
            crew.kick()
        return robot

    async def event(self, ev: Event, *, error: str | None = None) -> Robot:
        """Apply one status-machine event, store and publish the result."""
        old, new = self.rt.state, apply(self.rt.state, ev)
        log.info("%s: %s --%s--> %s", self.name, old.status.value, ev.value, new.status.value)
        return await self.save_state(new, error=error, data={"event": ev.value})

    async def save_pose(self) -> None:
        """Store the robot's last pose and battery (for the map after a restart)."""
        rt = self.rt
        if rt.pose is not None:
            await self.crew.store.robots.save_robot_pose(
                self.name,
                x=rt.pose[0],
                y=rt.pose[1],
                yaw=rt.pose[2],
                battery=rt.battery,
                now=self.crew.clock.epoch(),
            )

    # -- the link ---------------------------------------------------------------------------

    def start_link(self) -> None:
        """Connect to the robot (again), with the stored address and options."""
        crew, rt, robot = self.crew, self.rt, self.record
        cfg = crew.config
        rt.link = make_driver(
            self.name,
            robot.url,
            crew.reports,
            crew.clock,
            heartbeat=cfg.heartbeat,
            ack_timeout=cfg.ack_timeout,
            ack_retries=cfg.ack_retries,
            want_map=crew.places.map is None,
            ssl=crew.robot_ssl,
            pose_watched=crew.hub.watched(f"pose:{self.name}"),
            moving_pose_ms=cfg.moving_pose_ms,
            status_ms=cfg.status_ms,
            battery_ms=cfg.battery_ms,
            names=RosNames.from_options(robot.link),
        )
        rt.link.start()
        rt.link_started = crew.clock.epoch()

    async def camera(self) -> CameraRelay | None:
        """The robot's camera relay, None when its options name no camera (or it is a fake
        robot). Made at the first watch; an edited address or camera topic makes a new one,
        and whoever watched the old one is told it ended."""
        robot = self.record
        names = RosNames.from_options(robot.link)
        fake = urlsplit(robot.url).scheme.lower() == FAKE_SCHEME
        if not (names.camera or names.camera_url) or fake:
            await self._close_camera()
            return None
        made_from = (robot.url, names.camera, names.camera_url, names.ros)
        if self._camera is None or self._camera_from != made_from:
            await self._close_camera()
            source: CameraSource
            if names.camera_url:  # web_video_server's MJPEG, when the robot names one
                source = MjpegCamera(names.camera_url, ssl=self.crew.robot_ssl)
            else:
                source = RosbridgeCamera(
                    robot.url, names.camera, ros=names.ros, ssl=self.crew.robot_ssl
                )
            # Wall time, whatever the clock's scale: a picture's age is what the person
            # driving sees (half a second old on the tablet), as the Wi-Fi allowances are.
            self._camera = CameraRelay(self.name, source, time.time)
            self._camera_from = made_from
        return self._camera

    async def _close_camera(self) -> None:
        cam, self._camera, self._camera_from = self._camera, None, None
        if cam is not None:
            await cam.close()

    async def stop(self) -> None:
        """The robot is removed or the server stops: its events end, its link and camera are
        closed (the robot stopped)."""
        await self._close_camera()
        self.crew.reports.disarm_handover(self.rt)
        await self.crew.reports.stop_worker(self.rt)
        if self.rt.link is not None:
            await self.rt.link.close()

    # -- events -----------------------------------------------------------------------------

    async def on_event(self, event: RobotEvent) -> None:
        """One queued event, under the robot's lock: dispatched on its type."""
        await _ON_EVENT[type(event)](self, event)

    async def _on_up(self, _: LinkUp) -> None:
        self.rt.link_error = None
        await self.event(Event.LINK_UP)
        if self.rt.state.status is S.AWAITING:
            await self.go_home_if_away()
        else:
            await self.resume_move()

    async def _on_down(self, ev: LinkDown) -> None:
        self.rt.goal_id = None
        if self.rt.state.status is not S.OFFLINE:
            await self.save_state(
                apply(self.rt.state, Event.LINK_DOWN),
                error=f"link lost: {ev.reason}",
                data={"event": Event.LINK_DOWN.value},
            )

    async def _on_failed(self, ev: LinkFailed) -> None:
        # The link cannot connect (a wrong address, a robot switched off): shown to staff
        # with the robot, once per distinct reason.
        self.rt.link_error = ev.reason
        self.publish()

    async def _on_goal(self, ev: GoalEnded) -> None:
        rt = self.rt
        if ev.goal_id != rt.goal_id:
            return  # a goal we already replaced or cancelled
        rt.goal_id = None
        try:
            await self._goal_ended(ev.status, ev.text, ev.loss)
        except StoreError:
            if rt.goal_id is None:
                rt.goal_id = ev.goal_id  # not applied: the retry must still recognise the goal
            raise

    async def _on_lease(self, _: LeaseGranted) -> None:
        await self.crew.traffic.lease_granted(self)

    async def _on_persist(self, _: PersistPose) -> None:
        await self.save_pose()

    async def _on_handover(self, _: HandoverDue) -> None:
        """Give the trip of a robot Offline past ``handover_after`` back to the dispatcher.

        The task is requeued whole (its orders stay ``assigned`` to it, stops not served go
        back to ``pending``) and the next free robot takes it. The away robot keeps no trip:
        on its return it goes home (a robot that was Stopped or in Error stays so, for staff
        to look at, and ``continue`` sends it home).
        """
        rt, crew = self.rt, self.crew
        task_id = self.record.current_task
        if rt.state.status is not S.OFFLINE or task_id is None:
            return
        limit = crew.config.handover_after
        reason = f"offline for over {limit:g} s: trip {task_id} handed to another robot"
        log.warning("%s: %s", self.name, reason)
        await crew.trips.hand_back(self.name, task_id, reason)
        resume = rt.state.resume
        if resume is S.LOADING:
            resume = None  # back automatic, at the pass, without the trip
        elif resume in (S.DELIVERING, S.DELIVERED):
            resume = S.TRANSIT
        await self.save_state(
            replace(rt.state, resume=resume),
            event="robot.handover",
            error=reason,
            data={"task": task_id},
        )
        crew.kick()

    async def _on_table_timeout(self, ev: TableTimeout) -> None:
        robot = self.record
        if (
            self.rt.state.status is not S.DELIVERED
            or robot.current_task != ev.task_id
            or robot.status_since != ev.since
        ):
            return  # food collected (or skipped) meanwhile
        if self.rt.at_stop in (StopPurpose.COLLECT, StopPurpose.VISIT):
            # Used dishes collected (what was put on), or a cruise's pause over: on it goes.
            await self.serve(timed_out=True)
            await self.crew.publisher.flush_events()
            return
        limit = self.crew.config.table_timeout or 0.0
        log.warning("%s: nobody collected the food in %g s, going on", self.name, limit)
        await self.skip(f"nobody collected the food in {limit:g} s", None)
        await self.crew.publisher.flush_events()

    async def _on_charge_due(self, _: ChargeDue) -> None:
        rt = self.rt
        if rt.state.status is not S.AWAITING or self.record.dock is None:
            return  # given a trip, or taken by staff, meanwhile
        log.info("%s: battery %.0f%%, going to charge", self.name, (rt.battery or 0) * 100)
        await self.charge()
        await self.crew.publisher.flush_events()

    async def _on_charged(self, _: Charged) -> None:
        if self.rt.state.status is not S.CHARGING:
            return
        log.info("%s: charged to %.0f%%, back to work", self.name, (self.rt.battery or 0) * 100)
        await self.work()
        await self.crew.publisher.flush_events()

    async def _on_cruise_resume(self, ev: CruiseResume) -> None:
        robot = self.record
        if (
            self.rt.state.status is not S.STOPPED
            or robot.current_task != ev.task_id
            or robot.status_since != ev.since
        ):
            return  # staff sent it on, or elsewhere, meanwhile
        await self.event(Event.CONTINUE)
        await self.resume_move()
        await self.crew.publisher.flush_events()

    # -- checks before an instruction -------------------------------------------------------

    async def check_at_table(self, table: str) -> None:
        """A table screen acts only on the robot standing at its own table."""
        here = None
        if self.rt.state.status is S.DELIVERED and self.record.current_task is not None:
            task = await self.crew.trips.current(self.name)
            if task.current_stop < len(task.stops):
                here = task.stops[task.current_stop].table
        if here != table:
            raise Forbidden(f"{self.name} is not at table {table}", robot=self.name, table=table)

    async def check_target(self, msg: P.TargetMsg) -> None:
        """Refuse (``stale``) a command on a trip or stop the robot has moved on from."""
        given, task, stop = msg.expects()
        current = self.record.current_task
        at: int | None = None
        if current is not None and stop is not None:
            at = (await self.crew.trips.current(self.name)).current_stop
        if (given and task != current) or (stop is not None and stop != at):
            status = self.rt.state.status.value
            raise Stale(
                f"{self.name} has moved on: you saw {_trip_words(task, stop)}, it is on"
                f" {_trip_words(current, at)} ({status})",
                robot=self.name,
                task=current,
                stop=at,
                status=status,
            )

    # -- a trip's steps ---------------------------------------------------------------------

    async def serve(self, *, timed_out: bool = False) -> None:
        """Food collected at the current table: on to the next table, or home."""
        await self._go_on(await self.crew.trips.serve_stop(self.name, timed_out=timed_out))

    async def skip(self, reason: str, actor: str | None) -> None:
        """Leave the current table unserved: dishes returned, on to the next table or home."""
        rt = self.rt
        if self.record.current_task is None:
            raise Conflict(f"robot {self.name} has no trip: there is no table to skip")
        if rt.state.status is not S.DELIVERED and rt.link is not None:
            with contextlib.suppress(LinkError):
                await rt.link.cancel_goal()
        rt.goal_id = None
        await self._go_on(await self.crew.trips.skip_stop(self.name, reason, actor))

    async def _go_on(self, task: Task) -> None:
        self.rt.at_stop, self.rt.special = None, False
        self.rt.trip_kind = task.kind if task.current_stop < len(task.stops) else None
        if task.current_stop < len(task.stops):
            await self.event(Event.NEXT_TABLE)
            await self.drive(self.stop_dest(task))
            return
        # Its trip is over: on its way back it may take the plates of a table that called.
        nxt = await self.crew.chain(self.name) if task.kind is TaskKind.DELIVERY else None
        if nxt is not None:
            self.rt.trip_kind = nxt.kind
            await self.event(Event.NEXT_TABLE)
            await self.drive(self.stop_dest(nxt))
        else:
            await self.event(Event.NEXT_HOME)
            await self.drive(self.home_dest())

    def stop_dest(self, task: Task) -> Destination:
        stop = task.stops[task.current_stop]
        wp = self.crew.places.waypoint(stop.table)
        at_table = stop.purpose in (StopPurpose.DELIVER, StopPurpose.COLLECT)
        return Destination("table" if at_table else "place", wp.name, wp.x, wp.y, wp.yaw)

    def dock_dest(self) -> Destination:
        dock = self.record.dock
        if dock is None:
            raise Conflict(
                f"robot {self.name} has no dock: set its charger's place first",
                robot=self.name,
                reason="no_dock",
            )
        wp = self.crew.places.waypoint(dock)
        return Destination("dock", wp.name, wp.x, wp.y, wp.yaw)

    def transit_dest(self) -> Destination:
        """Where a robot in Transit is going: its dock when sent to charge, else home."""
        return self.dock_dest() if self.rt.to_dock else self.home_dest()

    # -- charging and cruising --------------------------------------------------------------

    async def charge(self) -> None:
        """Off to the dock (from Awaiting); Charging once there."""
        dest = self.dock_dest()
        self.rt.to_dock = True
        await self.event(Event.CHARGE)
        await self.drive(dest)

    async def work(self) -> None:
        """Off the dock, home, back into service."""
        rt = self.rt
        rt.to_dock = False
        rt.charge_watch.left()
        rt.not_charging = False
        await self.event(Event.UNDOCK)
        if rt.link is not None:
            try:
                await rt.link.undock()
            except LinkError as exc:
                log.warning("%s: undock not sent: %s", self.name, exc)
        await self.drive(self.home_dest())

    async def recall(self, reason: str) -> None:
        """A cruise ends (dishes wait and no robot is free): home, into service."""
        rt = self.rt
        if rt.link is not None:
            with contextlib.suppress(LinkError):
                await rt.link.cancel_goal()
        rt.goal_id = None
        await self.crew.trips.abandon(self.name, reason)
        rt.at_stop, rt.trip_kind = None, None
        await self.event(Event.RECALL)
        await self.drive(self.home_dest())

    def home_dest(self) -> Destination:
        home = self.record.home
        if home is None:
            raise Conflict(f"robot {self.name} has no home waypoint")
        wp = self.crew.places.waypoint(home)
        return Destination("home", wp.name, wp.x, wp.y, wp.yaw)

    def _near(self, dest: Destination) -> bool:
        pose = self.rt.pose
        if pose is None:
            return False
        return math.hypot(pose[0] - dest.x, pose[1] - dest.y) <= self.crew.config.arrive_tolerance

    # -- moves ------------------------------------------------------------------------------

    async def drive(self, dest: Destination) -> None:
        """Send the robot to ``dest`` once it holds the zones on the way (at once without
        zones); until then it stays where it is (serveur.core.traffic)."""
        rt = self.rt
        rt.dest = dest
        rt.goal_id = None
        rt.resume_dest = None
        rt.to_dock = dest.kind == "dock"
        if await self.crew.traffic.lease_leg(self, dest):
            await self.send_goal(dest)

    async def send_goal(self, dest: Destination) -> None:
        rt = self.rt
        assert rt.link is not None
        try:
            if dest.kind == "dock":
                rt.goal_id = await rt.link.dock(dest.x, dest.y, dest.yaw, dest.name)
            else:
                rt.goal_id = await rt.link.send_goal(dest.x, dest.y, dest.yaw)
        except LinkError as exc:
            rt.goal_id = None  # re-sent when the link is back (resume)
            log.warning("%s: goal to %s not sent: %s", self.name, dest.name, exc)

    async def go_home_if_away(self) -> None:
        dest = self.home_dest()
        if self.rt.state.status is S.AWAITING and not self._near(dest):
            await self.event(Event.GO_HOME)
            await self.drive(dest)

    async def resume_move(self) -> None:
        """Re-send the goal for the current move (after continue, or when the link returns)."""
        status = self.rt.state.status
        if status is S.DELIVERING:
            dest = self.stop_dest(await self.crew.trips.current(self.name))
            if self._near(dest):
                await self._arrived()
            else:
                await self.drive(dest)
        elif status is S.TRANSIT:
            dest = self.transit_dest()
            if self._near(dest):
                self.rt.dest = dest
                await self._arrived()
            else:
                await self.drive(dest)

    async def _arrived(self) -> None:
        rt = self.rt
        if rt.state.status is S.DELIVERING:
            task, special = await self.crew.trips.arrive(self.name)
            stop = task.stops[task.current_stop]
            rt.trip_kind, rt.at_stop, rt.special = task.kind, stop.purpose, special
            if stop.purpose is StopPurpose.COLLECT:
                await self.crew.calls.robot_at(task.id, stop.table, self.name)
        elif rt.state.status is S.TRANSIT and rt.to_dock:
            rt.to_dock = False
            rt.charge_watch.docked(self.crew.clock.epoch(), rt.battery)
            await self.event(Event.DOCKED)
            return
        await self.event(Event.ARRIVED)

    async def _goal_ended(
        self, status: rb.GoalStatus, text: str, loss: GoalLoss | None = None
    ) -> None:
        rt, traffic = self.rt, self.crew.traffic
        if loss is GoalLoss.LINK:
            # The link failed under the goal: nothing is known of the way or the table. The
            # robot goes Offline, and its move is sent again when the link is back (or now,
            # if it is still up).
            log.warning("%s: goal lost with the link: %s", self.name, text)
            if rt.link is not None and rt.link.up and rt.dest is not None:
                await self.drive(rt.dest)
            return
        traffic.leg_ended(rt)
        dest = rt.dest
        # Back outside a zone, at its waiting point: the leg it waited for is asked again.
        succeeded = status is rb.GoalStatus.SUCCEEDED
        if dest is not None and dest.kind == "wait" and await traffic.waited(self, succeeded):
            return
        st = rt.state.status
        if status is rb.GoalStatus.SUCCEEDED and dest is not None:
            if rt.pose is not None:
                off = math.hypot(rt.pose[0] - dest.x, rt.pose[1] - dest.y)
                if off > self.crew.config.far_tolerance:
                    reason = f"robot reports arriving {off:.2f} m from {dest.name or 'its goal'}"
                    await self._failed(reason)
                    return
            if st in (S.DELIVERING, S.TRANSIT):
                await self._arrived()
            elif st is S.MANUAL:
                await self.save_state(rt.state, error=None, event="robot.goal_reached")
            return
        # The driver's own words name its stack ("move_base ABORTED: ...", "Nav2
        # navigate_to_pose ABORTED: ...").
        if status is rb.GoalStatus.LOST:
            reason = f"goal lost: {text}" if text else "goal lost"
        else:
            reason = text or f"goal {status.name}"
        # A goal the robot never took says its navigation is not working, not the table's way.
        await self._failed(reason, block=loss is not GoalLoss.NOT_ACCEPTED)

    async def _failed(self, reason: str, *, block: bool = True) -> None:
        rt, dest = self.rt, self.rt.dest
        if block and rt.state.status is S.DELIVERING and dest is not None and dest.kind == "table":
            # No second robot is sent where this one could not go: the table is blocked
            # until staff clear it (its dishes wait at the pass, with the reason).
            await self.crew.service.block(dest.name, f"{self.name}: {reason}", self.name)
        if rt.state.status in (S.DELIVERING, S.TRANSIT):
            await self.event(Event.NAV_FAILED, error=reason)
        else:
            await self.save_state(rt.state, error=reason, event="robot.goal_failed")


#: Robot event type -> what the controller does with it.
_ON_EVENT: dict[type, Callable[[RobotController, Any], Awaitable[None]]] = {
    LinkUp: RobotController._on_up,
    LinkDown: RobotController._on_down,
    LinkFailed: RobotController._on_failed,
    GoalEnded: RobotController._on_goal,
    LeaseGranted: RobotController._on_lease,
    HandoverDue: RobotController._on_handover,
    PersistPose: RobotController._on_persist,
    TableTimeout: RobotController._on_table_timeout,
    ChargeDue: RobotController._on_charge_due,
    Charged: RobotController._on_charged,
    CruiseResume: RobotController._on_cruise_resume,
}


def _trip_words(task: int | None, stop: int | None) -> str:
    """``trip 12 stop 0`` or ``no trip``: what a ``stale`` message says was seen and is now."""
    if task is None:
        return "no trip"
    return f"trip {task}" + (f" stop {stop}" if stop is not None else "")
