"""The server core: robots' live state, what each instruction does, and what robot reports do.

This is the application layer between the websocket endpoint (:mod:`serveur.server`, which
only parses and replies) and the store, the robot links and the dispatcher. Rules it relies
on live in pure modules: the status machine (:mod:`serveur.status`), trip planning
(:mod:`serveur.scheduler`) and message validation (:mod:`serveur.protocol`).

Concurrency: everything that touches one robot — a client instruction, a link report, the
dispatcher giving it a trip — runs under that robot's lock, so "check the status, then act"
can never interleave (two staff pressing Continue and Cancel together get one success and one
``not_allowed_in_status``). Link reports are queued per robot and handled in arrival order.

Robot dropouts: at first the trip stays with its robot — the dishes are physically on its
tray. The robot is Offline while the link is down; when it returns, it resumes the status it
had and re-sends the goal of the current stop (or arrives at once if it is already there).
A robot Offline for longer than ``CoreConfig.handover_after`` has its trip handed over: the
task goes back to the queue (its orders stay on it) and the next free robot takes it; the
away robot, when it returns, goes home instead of continuing a trip that is no longer its own.

Server restarts are the same case: every robot starts Offline and resumes on link-up (one
that was already Offline before the restart keeps counting its hand-over limit from when it
was last seen, with a short grace to reconnect). Before
that, :meth:`Core.start` reconciles what a crash may have left half-done between two
transactions (a trip taken but the robot not yet Delivering, the last stop served but the
trip not closed, a trip handed over but the robot still meant to deliver it).

Shutdown (:meth:`Core.close`) stops every robot's move so none drives off unattended; the
stored status is kept, so a restarted server sends the robot on with its trip.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import replace
from typing import Any

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.alerts import RobotFact, Thresholds
from serveur.core.creation import Creation
from serveur.core.events import (
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
from serveur.core.hub import Hub
from serveur.core.leases import LeaseBook
from serveur.core.link_reports import HANDOVER_GRACE, LinkReports
from serveur.core.moves import RobotMoves
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig, Destination, Runtime, pose_dict
from serveur.core.service import Service
from serveur.core.site import SiteActions
from serveur.core.traffic import Traffic
from serveur.core.trips import Trips
from serveur.domain import (
    DishAction,
    MenuItem,
    OrderStatus,
    Robot,
    TaskStatus,
    WaypointKind,
    WaypointRecord,
)
from serveur.errors import (
    Conflict,
    InvalidField,
    LinkError,
    NotFound,
    ServeurError,
)
from serveur.robots.factory import make_driver
from serveur.robots.names import RosNames
from serveur.scheduler import Candidate, Dispatcher
from serveur.status import Action, Event, RobotState, RobotStatus, apply, check_allowed
from serveur.store.base import Store

__all__ = ["HANDOVER_GRACE", "Core", "CoreConfig", "Destination"]

log = logging.getLogger(__name__)

S = RobotStatus


class Core(RobotMoves, SiteActions, Traffic):
    """Owns robots' runtime state and carries out every instruction.

    Collaborators it owns: :class:`~serveur.core.places.Places` (waypoints, map, path distances),
    :class:`~serveur.core.publisher.Publisher` (topics and the events feed),
    :class:`~serveur.core.link_reports.LinkReports` (every robot link's listener, feeding each
    robot's event queue to :meth:`on_event`, and the hand-over timers),
    :class:`~serveur.core.trips.Trips` (each step of a trip in the store) and
    :class:`~serveur.core.creation.Creation` (orders, trips and waypoints for ``create``). The core
    keeps what ties them together: each robot's status, changed under its lock.
    """

    def __init__(
        self,
        store: Store,
        clock: Clock,
        *,
        config: CoreConfig | None = None,
        nav_map: Any = None,
        map_path: str | None = None,
        plan_in_child: bool = True,
        robot_ssl: ssl.SSLContext | None = None,
    ) -> None:
        self.store = store
        self.clock = clock
        self.config = config or CoreConfig()
        #: How robot links verify ``wss://`` robots (see serveur.security.tls.client_context); None:
        #: the system trust store.
        self.robot_ssl = robot_ssl
        self.hub = Hub(on_watch=self._on_watch)
        self.dispatcher = Dispatcher(self)
        self._rt: dict[str, Runtime] = {}
        self._halted = False  # halt_robots ran: shutting down, robots stopped
        self._robots: dict[str, Robot] = {}
        self.leases = LeaseBook()
        self.zone_records = {}
        self.languages = list(self.config.languages)
        self.language = self.config.language
        self.places = Places(
            self.hub,
            robot_radius=self.config.robot_radius,
            nav_map=nav_map,
            map_path=map_path,
            plan_in_child=plan_in_child,
        )
        self.publisher = Publisher(self.hub, store)
        cfg = self.config
        self.service = Service(
            store,
            clock,
            places=self.places,
            publisher=self.publisher,
            kick=self.dispatcher.kick,
            limits=Thresholds(
                offline_after=cfg.alert_offline_after,
                low_battery=cfg.alert_low_battery,
                battery_ok=cfg.alert_low_battery + 0.05,
                wait_at_table=cfg.alert_wait_at_table,
                dish_at_pass=cfg.alert_dish_at_pass,
                zone_wait=cfg.alert_zone_wait,
            ),
        )
        self.reports = LinkReports(
            self._rt,
            self,
            hub=self.hub,
            clock=clock,
            config=self.config,
            places=self.places,
            publisher=self.publisher,
        )
        self.trips = Trips(
            store,
            clock,
            self.config,
            robots=self._robots,
            places=self.places,
            publisher=self.publisher,
            origin=self._origin,
        )
        self.creation = Creation(
            store,
            clock,
            self.config,
            places=self.places,
            publisher=self.publisher,
            origin=self._origin,
            kick=self.dispatcher.kick,
            reachable=self.service.check_reachable,
        )

    # -- lifecycle ---------------------------------------------------------------------------

    async def start(self) -> None:
        await self.publisher.skip_stored_events()
        await self.load_settings()
        await self.load_zones()
        # Path distances between all waypoints are planned before any robot is driven.
        await self.places.load(await self.store.list_waypoints())
        for robot in await self.store.list_robots():
            # Every robot starts Offline and resumes what it was doing once its link is up.
            resume = robot.resume if robot.status is S.OFFLINE else robot.status
            # A robot already Offline before the restart has been away since its last state
            # change: its hand-over limit counts from then, not from this start.
            away_since = robot.status_since if robot.status is S.OFFLINE else None
            robot, resume = await self.trips.reconcile(robot, resume)
            self._add_runtime(robot)
            self._rt[robot.name].offline_since = away_since
            st = RobotState(S.OFFLINE, robot.mode, resume)
            self._rt[robot.name].state = st
            await self._save_state(robot.name, st, event="robot.restored")
        self.dispatcher.start()
        await self.service.start(self)
        for rt in self._rt.values():
            self._start_link(rt)

    async def halt_robots(self, budget: float = 0.4) -> None:
        """Stop every robot now, before anything else of a shutdown (within ``budget`` wall s).

        Dispatch stops, reports are no longer queued, and each link cancels its goals and
        sends a zero twist, all robots at once; from then on the links refuse to move a robot.
        Closing client connections (which may wait seconds for a stalled tablet) comes after,
        so a robot never drives on while the server says goodbye to its screens.
        """
        if self._halted:
            return
        self._halted = True
        self.reports.stop_queueing()
        links = [rt.link for rt in self._rt.values() if rt.link is not None]
        halts = [asyncio.create_task(link.halt(), name=f"halt-{link.name}") for link in links]
        stopping = asyncio.create_task(self.dispatcher.stop())
        await self.service.stop()
        if halts:
            _, late = await asyncio.wait(halts, timeout=budget)
            for task in late:
                task.cancel()
                log.warning("%s: stop not confirmed sent within %.1fs", task.get_name(), budget)
        await stopping

    async def close(self) -> None:
        """Stop serving robots: no more dispatch, every robot's move cancelled, poses saved.

        Robots are stopped where they are rather than left driving with nobody watching
        (a goal whose result no server will read, "Food collected" that nobody can press).
        Their stored status is left as it was, so a restarted server resumes each trip.
        """
        await self.halt_robots()
        self.places.close()
        for rt in self._rt.values():
            self.reports.disarm_handover(rt)
            await self.reports.stop_worker(rt)
        for rt in self._rt.values():
            if rt.link is not None:
                await rt.link.close()
        for rt in self._rt.values():
            with contextlib.suppress(ServeurError):
                await self._save_pose(rt)

    async def _save_pose(self, rt: Runtime) -> None:
        """Store the robot's last pose and battery (for the map after a restart)."""
        if rt.pose is not None:
            await self.store.save_robot_pose(
                rt.name,
                x=rt.pose[0],
                y=rt.pose[1],
                yaw=rt.pose[2],
                battery=rt.battery,
                now=self.clock.epoch(),
            )

    def _add_runtime(self, robot: Robot) -> Runtime:
        rt = Runtime(robot.name, RobotState(robot.status, robot.mode, robot.resume))
        if robot.x is not None and robot.y is not None and robot.yaw is not None:
            rt.pose = (robot.x, robot.y, robot.yaw)
        rt.battery = robot.battery
        rt.idle_since = self.clock.now()
        self._rt[robot.name] = rt
        self._robots[robot.name] = robot
        rt.worker = self.reports.start_worker(rt)
        return rt

    def _start_link(self, rt: Runtime) -> None:
        robot = self._robots[rt.name]
        rt.link = make_driver(
            rt.name,
            robot.url,
            self.reports,
            self.clock,
            heartbeat=self.config.heartbeat,
            ack_timeout=self.config.ack_timeout,
            ack_retries=self.config.ack_retries,
            want_map=self.places.map is None,
            ssl=self.robot_ssl,
            pose_watched=self.hub.watched(f"pose:{rt.name}"),
            moving_pose_ms=self.config.moving_pose_ms,
            status_ms=self.config.status_ms,
            battery_ms=self.config.battery_ms,
            names=RosNames.from_options(robot.link),
        )
        rt.link.start()
        rt.link_started = self.clock.epoch()

    def _kick(self) -> None:
        self.dispatcher.kick()

    def _post(self, robot: str, event: RobotEvent) -> None:
        self.reports.post(robot, event)

    async def _stop_robot_runtime(self, rt: Runtime) -> None:
        """A removed robot: its link closed (the robot stopped), its worker ended, forgotten."""
        self.reports.disarm_handover(rt)
        await self.reports.stop_worker(rt)
        if rt.link is not None:
            await rt.link.close()
        self._rt.pop(rt.name, None)
        self.lease_forget(rt.name)
        self._robots.pop(rt.name, None)

    def _on_watch(self, topic: str, on: bool) -> None:
        self.reports.on_watch(topic, on)

    # -- distances ---------------------------------------------------------------------------

    def distance(self, a: str, b: str) -> float:
        """Path distance between two waypoints; straight line if not planned or no path."""
        return self.places.distance(a, b)

    def _origin(self) -> str:
        return self.places.origin(r.home for r in self._robots.values())

    # -- publishing -------------------------------------------------------------------------

    def _robot_view(self, name: str) -> Robot:
        rt = self._rt[name]
        upd: dict[str, Any] = {
            "battery": rt.battery,
            "link_error": rt.link_error,
            "waiting_for": rt.waiting_for,
        }
        if rt.pose is not None:
            upd.update(x=rt.pose[0], y=rt.pose[1], yaw=rt.pose[2])
        return self._robots[name].model_copy(update=upd)

    def publish_robot(self, name: str) -> None:
        """Publish the robot's record as screens see it (live pose and battery)."""
        self.publisher.pub("robots", self._robot_view(name))

    def battery_changed(self, name: str) -> None:
        """Screens see the new level; the dispatcher looks again if the robot is waiting at
        home. A robot below the dispatch threshold (``scheduler.choose_robot``) charges there
        and must be given the queued trips once it is above it: nothing else may happen (the
        last dishes of a service are queued, every robot was low), so without this kick the
        trips waited for ever beside a usable robot."""
        self.publish_robot(name)
        if self._rt[name].state.status is S.AWAITING:
            self.dispatcher.kick()

    def task_robot(self, task_id: int) -> str | None:
        """The robot doing (or that did) task ``task_id``, if this server has seen it."""
        robot = self.publisher.task_robot(task_id)
        if robot is None:
            robot = next((n for n, r in self._robots.items() if r.current_task == task_id), None)
        return robot

    async def _save_state(
        self,
        name: str,
        st: RobotState,
        *,
        event: str = "robot.status",
        error: str | None = None,
        keep_error: bool = False,
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        rt = self._rt[name]
        last_error = self._robots[name].last_error if keep_error else error
        # The live state follows the store: a write that failed (disk full) changes nothing,
        # so the report that asked for it can be retried from the same state.
        robot = await self.store.save_robot_state(
            name,
            status=st.status,
            mode=st.mode,
            resume=st.resume,
            last_error=last_error,
            now=self.clock.epoch(),
            event=event,
            data={**(data or {}), "odometer": round(rt.odometer, 2)},
        )
        rt.state = st
        self._robots[name] = robot
        self.lease_status(rt, st.status)
        self.publisher.pub("robots", self._robot_view(name))
        if st.status is not S.OFFLINE:
            rt.offline_since = None
        elif rt.offline_since is None:
            rt.offline_since = self.clock.epoch()
        if st.status is S.OFFLINE and robot.current_task is not None:
            self.reports.arm_handover(rt)
        else:
            self.reports.disarm_handover(rt)
        if st.status is S.AWAITING:
            rt.idle_since = self.clock.now()
            self.dispatcher.kick()
        return robot

    # -- hand-over of the trip of a robot gone too long ---------------------------------------

    async def _hand_over(self, rt: Runtime) -> None:
        """Give the trip of a robot Offline past ``handover_after`` back to the dispatcher.

        The task is requeued whole (its orders stay ``assigned`` to it, stops not served go
        back to ``pending``) and the next free robot takes it. The away robot keeps no trip:
        on its return it goes home (a robot that was Stopped or in Error stays so, for staff
        to look at, and ``continue`` sends it home).
        """
        task_id = self._robots[rt.name].current_task
        if rt.state.status is not S.OFFLINE or task_id is None:
            return
        limit = self.config.handover_after
        reason = f"offline for over {limit:g} s: trip {task_id} handed to another robot"
        log.warning("%s: %s", rt.name, reason)
        await self.trips.hand_back(rt.name, task_id, reason)
        resume = rt.state.resume
        if resume is S.LOADING:
            resume = None  # back automatic, at the pass, without the trip
        elif resume in (S.DELIVERING, S.DELIVERED):
            resume = S.TRANSIT
        await self._save_state(
            rt.name,
            replace(rt.state, resume=resume),
            event="robot.handover",
            error=reason,
            data={"task": task_id},
        )
        self.dispatcher.kick()

    async def _event(self, rt: Runtime, ev: Event, *, error: str | None = None) -> Robot:
        new = apply(rt.state, ev)
        log.info("%s: %s --%s--> %s", rt.name, rt.state.status.value, ev.value, new.status.value)
        return await self._save_state(rt.name, new, error=error, data={"event": ev.value})

    async def flush_events(self) -> None:
        """Push the events recorded since the last flush to ``events`` subscribers."""
        await self.publisher.flush_events()

    def robot_statuses(self) -> list[tuple[str, RobotStatus]]:
        return [(n, rt.state.status) for n, rt in sorted(self._rt.items())]

    # -- snapshots --------------------------------------------------------------------------

    async def snapshot(self, topic: str) -> Any:
        if topic == "robots":
            return [self._robot_view(n) for n in sorted(self._rt)]
        if topic == "orders":
            # Every dish not finished: the kitchen's (ordered, cooking), the pass's (pending,
            # returned) and those on a trip (assigned).
            live = [
                OrderStatus.ORDERED,
                OrderStatus.COOKING,
                OrderStatus.PENDING,
                OrderStatus.ASSIGNED,
                OrderStatus.RETURNED,
            ]
            return await self.store.list_orders(status=live)
        if topic == "tasks":
            return await self.store.list_tasks(status=[TaskStatus.QUEUED, TaskStatus.ACTIVE])
        if topic == "waypoints":
            return list(self.places.waypoints.values())
        if topic == "events":
            return await self.publisher.events_snapshot()
        if topic == "map":
            return self.places.map_snapshot()
        if topic == "alerts":
            return self.service.alerts.active()
        if topic == "menu":
            return await self.store.list_menu()
        if topic == "blocks":
            return list(self.service.blocks.values())
        if topic == "settings":
            return self.settings()
        if topic == "zones":
            return list(self.zone_records.values())
        if topic == "leases":
            return self.lease_rows()
        kind, _, robot = topic.partition(":")
        rt = self._runtime(robot)
        if kind == "pose":
            return pose_dict(rt.pose, self.clock.epoch()) if rt.pose else None
        return None  # scan: the next frame arrives as an update

    # -- instructions -----------------------------------------------------------------------

    def _runtime(self, name: str) -> Runtime:
        rt = self._rt.get(name)
        if rt is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return rt

    async def handle(
        self, msg: P.ClientMessage, *, actor: str | None = None, table: str | None = None
    ) -> dict[str, Any]:
        """Carry out one instruction; the reply payload, or a ServeurError.

        ``actor`` (``user:ana``) is recorded with the steps a person takes; ``table`` is set
        for a table screen: its ``next`` may only act on a robot serving that table.
        """
        try:
            return await self._handle(msg, actor, table)
        finally:
            await self.flush_events()

    async def _handle(
        self, msg: P.ClientMessage, actor: str | None, table: str | None
    ) -> dict[str, Any]:
        if self._halted:
            raise LinkError("the server is shutting down: robots are stopped")
        verb = msg.clientmsg
        if verb == "create":
            return await self._create(msg, actor)
        if verb == "order":
            return await self._order(msg)
        if isinstance(msg, P.DishMsg):
            order = await self.service.dish(
                msg.order,
                DishAction(msg.action),
                seen=None if msg.status is None else OrderStatus(msg.status),
                by=actor,
                quantity=msg.quantity,
                note=msg.note,
                table=msg.table,
            )
            return {"order": order}
        if isinstance(msg, P.AckMsg):
            return {"alert": await self.service.ack(msg.alert, actor or "unknown")}
        if isinstance(msg, P.ClearMsg):
            return await self.service.clear(msg.table, actor)
        if verb == "site":
            return await self.site(msg, actor)
        if isinstance(msg, P.ReleaseMsg):
            return await self.release(msg, actor)
        robot = P.robot_of(msg)
        action = P.action_of(msg)
        if robot is None or action is None:
            raise InvalidField(f"{verb!r} needs a robot")
        rt = self._runtime(robot)
        async with rt.lock:
            if table is not None:
                await self._check_at_table(rt, table)
            if isinstance(msg, P.TargetMsg):
                await self._check_target(rt, msg)
            check_allowed(rt.state.status, action)
            await self._act(rt, action, msg, actor)
            return {"robot": self._robot_view(rt.name)}

    async def _act(self, rt: Runtime, action: Action, msg: Any, actor: str | None = None) -> None:
        link = rt.link
        assert link is not None
        if action is Action.AUTO:
            home = self._robots[rt.name].home
            if home is None:
                raise Conflict(f"robot {rt.name} has no home waypoint; set one first")
            await self._event(rt, Event.AUTO)
            await self._go_home_if_away(rt)
        elif action is Action.MANUAL:
            if self._robots[rt.name].current_task is not None:
                await self.trips.abandon(rt.name, "manual control taken")
            with contextlib.suppress(LinkError):
                await link.cancel_goal()
            rt.dest = None
            await self._event(rt, Event.MANUAL)
        elif action is Action.TELEOP:
            if rt.dest is not None or rt.goal_id is not None:
                # move_base does not listen to /cmd_vel: its goal would keep driving the
                # robot while staff steer, so the goal goes first.
                await link.cancel_goal()
                rt.dest = None
                rt.goal_id = None
            await link.teleop(msg.vx, msg.vy, msg.wz)
        elif action is Action.INITIALPOSE:
            await link.initial_pose(msg.x, msg.y, msg.yaw)
        elif action in (Action.GOAL, Action.GOTO):
            if action is Action.GOTO:
                wp = self.places.waypoint(msg.waypoint)
                dest = Destination("manual", wp.name, wp.x, wp.y, wp.yaw)
            else:
                self._check_reachable(msg.x, msg.y)
                dest = Destination("manual", "", msg.x, msg.y, msg.yaw)
            await self._drive(rt, dest)
        elif action is Action.READY:
            if rt.state.status is S.MANUAL:
                with contextlib.suppress(LinkError):
                    await link.cancel_goal()
                    await link.teleop(0.0, 0.0, 0.0)
            rt.dest = None
            await self._event(rt, Event.RELEASE)
        elif action is Action.NEXT:
            await self._next(rt)
        elif action is Action.GO:
            task = await self.trips.current(rt.name)
            await self._event(rt, Event.GO)
            await self._drive(rt, self._stop_dest(task))
        elif action is Action.SKIP:
            await self._skip(rt, "skipped by staff", actor)
        elif action is Action.STOP:
            await link.cancel_goal()
            rt.goal_id = None
            await self._event(rt, Event.STOP)
        elif action is Action.CONTINUE:
            if rt.state.resume is None:
                # What to resume is lost when a Stopped/Error robot's link drops (the status
                # column holds one "resume"); the trip tells: dishes aboard -> back to the table.
                has_trip = self._robots[rt.name].current_task is not None
                rt.state = replace(rt.state, resume=S.DELIVERING if has_trip else S.TRANSIT)
            await self._event(rt, Event.CONTINUE)
            await self._resume_move(rt)
        elif action is Action.CANCEL:
            if self._robots[rt.name].current_task is not None:
                await self.trips.abandon(rt.name, "cancelled by staff")
            loading = rt.state.status is S.LOADING
            await self._event(rt, Event.CANCEL)
            if not loading:  # a robot still at the pass stays there
                await self._drive(rt, self._home_dest(rt))

    async def _create(self, msg: Any, actor: str | None = None) -> dict[str, Any]:
        kind = msg.type
        if kind == "order":
            order = await self.creation.order(
                msg.dish,
                msg.table,
                msg.key,
                quantity=msg.quantity,
                note=msg.note,
                status=OrderStatus(msg.status),
            )
            return {"order": order}
        if kind == "zone":
            return await self.create_zone(msg, actor)
        if kind == "dish":
            item = MenuItem(
                dish=msg.name,
                category=msg.category,
                price_cents=msg.price_cents,
                available=msg.available,
                position=msg.position,
            )
            return {"dish": await self.service.put_dish(item, actor)}
        if kind == "task":
            return {"tasks": await self.creation.tasks(list(msg.orders), msg.key)}
        if kind == "waypoint":
            if getattr(msg, "robot", None):
                rt = self._runtime(msg.robot)
                async with rt.lock:
                    check_allowed(rt.state.status, Action.SAVE_WAYPOINT)
                    if rt.pose is None:
                        raise Conflict(f"robot {rt.name} has not reported a pose yet")
                    x, y, yaw = rt.pose
            else:
                x, y, yaw = msg.x, msg.y, msg.yaw
            wp = WaypointRecord(name=msg.name, x=x, y=y, yaw=yaw, kind=WaypointKind(msg.kind))
            return {"waypoint": await self.creation.waypoint(wp, replace=msg.replace)}
        if kind == "robot":
            return await self.register_robot(msg)
        raise InvalidField(f"cannot create {kind!r}")

    async def _order(self, msg: Any) -> dict[str, Any]:
        if getattr(msg, "table", None):
            self.places.waypoint(msg.table)
            return {"orders": await self.store.cart(msg.table)}
        rt = self._runtime(msg.robot)
        return {"orders": await self.trips.stop_orders(rt.name)}

    # -- dispatcher (scheduler.Fleet) -------------------------------------------------------

    async def queued_tasks(self) -> list[tuple[int, int]]:
        return [(t.id, len(t.stops)) for t in await self.store.list_tasks(status=TaskStatus.QUEUED)]

    def free_robots(self) -> list[Candidate]:
        return [
            Candidate(
                rt.name,
                rt.idle_since,
                rt.battery,
                self._robots[rt.name].trays or self.config.capacity,
            )
            for rt in self._rt.values()
            if rt.state.status is S.AWAITING
            and rt.link is not None
            and rt.link.up
            and self._robots[rt.name].current_task is None
            # Locked robots are listed too: start_trip waits for the lock and re-checks, so a
            # robot freed inside a locked section is not missed by the kick it caused.
        ]

    async def start_trip(self, task_id: int, robot: str) -> bool:
        rt = self._rt[robot]
        async with rt.lock:
            if rt.state.status is not S.AWAITING:
                return False
            blocked = await self.trips.drop_blocked(task_id, self.service.blocks)
            if blocked is None:
                return False
            task = await self.trips.take(task_id, robot)
            if task is None:
                return False
            if self.config.auto_depart:
                await self._event(rt, Event.DISPATCH)
                await self._drive(rt, self._stop_dest(task))
            else:
                await self._event(rt, Event.ASSIGN)
        await self.flush_events()
        return True

    # -- the service watch (core.service.ServiceHost) ---------------------------------------

    def robot_facts(self) -> list[RobotFact]:
        facts = []
        for name, rt in sorted(self._rt.items()):
            robot = self._robots[name]
            dest = rt.dest
            since = robot.status_since
            if rt.state.status is S.OFFLINE:
                # "Not connected" counts from when this server started trying: the start's
                # path planning (15 s of a demo's scaled clock) and a robot registered long ago
                # raised, and at once cleared, an offline alert per robot at every start.
                tried = rt.link_started if rt.link_started is not None else self.clock.epoch()
                since = max(since, tried)
            facts.append(
                RobotFact(
                    name=name,
                    status=rt.state.status,
                    mode=rt.state.mode,
                    since=since,
                    battery=rt.battery,
                    table=dest.name if dest is not None and dest.kind == "table" else None,
                    error=robot.last_error,
                    waiting_for=tuple(rt.waiting_for or ()),
                    waiting_since=rt.waiting_since,
                    blockers=tuple(self.leases.blockers(name)) if rt.waiting_for else (),
                )
            )
        return facts

    def table_timeouts(self) -> None:
        """Post ``table_timeout`` to each robot at a table past the site's limit (once per
        arrival: the arrival's time identifies it, so a robot that moved on is left alone)."""
        limit = self.config.table_timeout
        if limit is None:
            return
        now = self.clock.epoch()
        for name, rt in self._rt.items():
            robot = self._robots[name]
            since = robot.status_since
            if (
                rt.state.status is S.DELIVERED
                and robot.current_task is not None
                and now - since >= limit
                and rt.timed_out != since
            ):
                rt.timed_out = since
                self.reports.post(name, TableTimeout(robot.current_task, since))

    # -- robot events, queued per robot (link_reports.ReportHandler) ---------------------------

    async def on_event(self, rt: Runtime, event: RobotEvent) -> None:
        """One queued robot event, under the robot's lock: dispatched on its type."""
        await _ON_EVENT[type(event)](self, rt, event)

    async def _on_up(self, rt: Runtime, _: LinkUp) -> None:
        rt.link_error = None
        await self._event(rt, Event.LINK_UP)
        if rt.state.status is S.AWAITING:
            await self._go_home_if_away(rt)
        else:
            await self._resume_move(rt)

    async def _on_down(self, rt: Runtime, ev: LinkDown) -> None:
        rt.goal_id = None
        if rt.state.status is not S.OFFLINE:
            await self._save_state(
                rt.name,
                apply(rt.state, Event.LINK_DOWN),
                error=f"link lost: {ev.reason}",
                data={"event": Event.LINK_DOWN.value},
            )

    async def _on_failed(self, rt: Runtime, ev: LinkFailed) -> None:
        # The link cannot connect (a wrong address, a robot switched off): shown to staff
        # with the robot, once per distinct reason.
        rt.link_error = ev.reason
        self.publish_robot(rt.name)

    async def _on_goal_ended(self, rt: Runtime, ev: GoalEnded) -> None:
        await self._on_goal(rt, ev.goal_id, ev.status, ev.text)

    async def _on_lease(self, rt: Runtime, _: LeaseGranted) -> None:
        await self._lease_granted(rt)

    async def _on_handover(self, rt: Runtime, _: HandoverDue) -> None:
        await self._hand_over(rt)

    async def _on_persist(self, rt: Runtime, _: PersistPose) -> None:
        await self._save_pose(rt)

    async def _on_table_timeout(self, rt: Runtime, ev: TableTimeout) -> None:
        await self._table_timeout(rt, ev.task_id, ev.since)


#: Robot event type -> what the core does with it.
_ON_EVENT: dict[type, Callable[[Core, Runtime, Any], Awaitable[None]]] = {
    LinkUp: Core._on_up,
    LinkDown: Core._on_down,
    LinkFailed: Core._on_failed,
    GoalEnded: Core._on_goal_ended,
    LeaseGranted: Core._on_lease,
    HandoverDue: Core._on_handover,
    PersistPose: Core._on_persist,
    TableTimeout: Core._on_table_timeout,
}
