"""The server core: the fleet of robot controllers, and what each client instruction does.

This is the application layer between the websocket endpoint (:mod:`serveur.server`, which
only parses and replies) and the store, the robots and the dispatcher. Rules it relies on live
in pure modules: the status machine (:mod:`serveur.status`), trip planning
(:mod:`serveur.scheduler`), zone leases (:mod:`serveur.core.leases`) and message validation
(:mod:`serveur.protocol`). Each robot is a :class:`~serveur.core.robot.RobotController`; the
owner's site changes are :class:`~serveur.core.site.Site`'s, zones :class:`Traffic`'s, dishes
and alerts :class:`~serveur.core.service.Service`'s. The core builds them, hands each its
collaborators, and routes every instruction to
:class:`~serveur.core.instructions.Instructions` (one table from message type to handler).

Concurrency: everything that touches one robot — a client instruction, a robot event, the
dispatcher giving it a trip — runs under that robot's lock, so "check the status, then act"
can never interleave (two staff pressing Continue and Cancel together get one success and one
``not_allowed_in_status``). Robot events are queued per robot and handled in arrival order.

Server restarts: every robot starts Offline and resumes on link-up (one that was already
Offline before the restart keeps counting its hand-over limit from when it was last seen,
with a short grace to reconnect). Before that, :meth:`Core.start` reconciles what a crash may
have left half-done between two transactions (a trip taken but the robot not yet Delivering,
the last stop served but the trip not closed, a trip handed over but the robot still meant to
deliver it).

Shutdown (:meth:`Core.close`) stops every robot's move so none drives off unattended; the
stored status is kept, so a restarted server sends the robot on with its trip.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.alerts import RobotFact, Thresholds, TillFacts
from serveur.core.call_desk import CallDesk
from serveur.core.creation import Creation
from serveur.core.crew import Crew
from serveur.core.events import Charged, ChargeDue, CruiseResume, RobotEvent, TableTimeout
from serveur.core.hub import Hub
from serveur.core.instructions import Instructions
from serveur.core.leases import LeaseBook
from serveur.core.link_reports import HANDOVER_GRACE, LinkReports
from serveur.core.modes import charge_due, charged, stop_wait
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.robot import RobotController
from serveur.core.runtime import CoreConfig, Destination, Runtime, pose_dict
from serveur.core.service import Service
from serveur.core.site import Site
from serveur.core.site_map import stored_backdrop, stored_map
from serveur.core.ticket_desk import TicketDesk
from serveur.core.traffic import Traffic
from serveur.core.trips import Trips
from serveur.domain import (
    Call,
    OrderStatus,
    Robot,
    StopPurpose,
    Task,
    TaskKind,
    TaskStatus,
    ZoneRecord,
)
from serveur.errors import LinkError, NotFound, ServeurError
from serveur.scheduler import (
    Candidate,
    Dispatcher,
    QueuedTrip,
    bussing_seconds,
    may_bus,
    usable,
)
from serveur.status import Event, RobotState, RobotStatus
from serveur.store.base import Store

__all__ = ["HANDOVER_GRACE", "Core", "CoreConfig", "Destination"]

log = logging.getLogger(__name__)

S = RobotStatus


class Core:
    """The fleet's robots and every instruction; the collaborators that carry them out.

    It owns :class:`~serveur.core.places.Places` (waypoints, map, path distances),
    :class:`~serveur.core.publisher.Publisher` (topics and the events feed),
    :class:`~serveur.core.link_reports.LinkReports` (every robot link's listener, feeding each
    robot's event queue to its controller, and the hand-over timers),
    :class:`~serveur.core.trips.Trips` (each step of a trip in the store),
    :class:`~serveur.core.creation.Creation` (orders, trips and waypoints for ``create``),
    :class:`~serveur.core.service.Service` (dishes, menu, blocked tables, alerts),
    :class:`~serveur.core.traffic.Traffic` (zones and leases), :class:`~serveur.core.site.Site`
    (the owner's changes) and one :class:`~serveur.core.robot.RobotController` per robot.
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
        self.config = cfg = config or CoreConfig()
        self.hub = Hub(on_watch=self._on_watch)
        self.dispatcher = Dispatcher(self)
        self._ctl: dict[str, RobotController] = {}
        #: Each robot's live state (the controllers'), by name: what the links' listener and
        #: the tests look up.
        self._rt: dict[str, Runtime] = {}
        #: Each robot's stored record, shared by the controllers and the trips.
        self._robots: dict[str, Robot] = {}
        self._halted = False  # halt_robots ran: shutting down, robots stopped
        self.places = Places(
            self.hub,
            robot_radius=cfg.robot_radius,
            nav_map=nav_map,
            map_path=map_path,
            plan_in_child=plan_in_child,
        )
        self.publisher = Publisher(self.hub, store)
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
            config=cfg,
            places=self.places,
            publisher=self.publisher,
        )
        self.traffic = Traffic(
            store, clock, cfg, places=self.places, publisher=self.publisher, post=self.reports.post
        )
        self.trips = Trips(
            store,
            clock,
            cfg,
            robots=self._robots,
            places=self.places,
            publisher=self.publisher,
            origin=self._origin,
        )
        self.creation = Creation(
            store,
            clock,
            cfg,
            places=self.places,
            publisher=self.publisher,
            origin=self._origin,
            kick=self.dispatcher.kick,
            reachable=self.service.check_reachable,
        )
        self.calls = CallDesk(
            store,
            clock,
            cfg,
            places=self.places,
            publisher=self.publisher,
            kick=self.dispatcher.kick,
        )
        self.tickets = TicketDesk(store, clock, places=self.places, publisher=self.publisher)
        self.crew = Crew(
            store=store,
            clock=clock,
            config=cfg,
            hub=self.hub,
            places=self.places,
            publisher=self.publisher,
            service=self.service,
            trips=self.trips,
            traffic=self.traffic,
            reports=self.reports,
            calls=self.calls,
            records=self._robots,
            kick=self.dispatcher.kick,
            chain=self.chain_bussing,
            robot_ssl=robot_ssl,
        )
        self.site = Site(
            store,
            clock,
            cfg,
            fleet=self,
            records=self._robots,
            places=self.places,
            publisher=self.publisher,
            service=self.service,
            traffic=self.traffic,
            kick=self.dispatcher.kick,
            calls_moved=self.calls.reload,
        )
        self.instructions = Instructions(
            store,
            fleet=self,
            places=self.places,
            trips=self.trips,
            creation=self.creation,
            service=self.service,
            traffic=self.traffic,
            site=self.site,
            calls=self.calls,
            tickets=self.tickets,
        )

    # -- what others read of the collaborators ----------------------------------------------

    @property
    def leases(self) -> LeaseBook:
        return self.traffic.leases

    @property
    def zone_records(self) -> dict[str, ZoneRecord]:
        return self.traffic.zone_records

    @property
    def languages(self) -> list[str]:
        return self.site.languages

    @property
    def language(self) -> str:
        return self.site.language

    def settings(self) -> dict[str, Any]:
        return self.site.settings()

    def leg_zones(self, rt: Runtime, dest: Destination) -> list[str]:
        return self.traffic.leg_zones(rt, dest)

    def write_site(self, folder: Path) -> tuple[Path, float | None, int]:
        return self.site.write_site(folder)

    # -- the fleet (site.Fleet) -------------------------------------------------------------

    def controller(self, name: str) -> RobotController:
        ctl = self._ctl.get(name)
        if ctl is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return ctl

    def has_robot(self, name: str) -> bool:
        return name in self._ctl

    def _add(self, robot: Robot) -> RobotController:
        ctl = RobotController(robot, self.crew)
        self._ctl[robot.name] = ctl
        self._rt[robot.name] = ctl.rt
        return ctl

    def add_robot(self, robot: Robot) -> RobotController:
        ctl = self._add(robot)
        ctl.start_link()
        return ctl

    async def remove_robot(self, ctl: RobotController) -> None:
        await ctl.stop()
        self._ctl.pop(ctl.name, None)
        self._rt.pop(ctl.name, None)
        self.traffic.lease_forget(ctl.name)
        self._robots.pop(ctl.name, None)

    # -- lifecycle ---------------------------------------------------------------------------

    async def start(self) -> None:
        await self.publisher.skip_stored_events()
        await self.site.load_settings()
        await self.traffic.load_zones()
        self.places.backdrop = await stored_backdrop(self.store)
        # Path distances between all waypoints are planned before any robot is driven.
        await self.places.load(
            await self.store.waypoints.list_waypoints(), stored=await stored_map(self.store)
        )
        for robot in await self.store.robots.list_robots():
            # Every robot starts Offline and resumes what it was doing once its link is up.
            resume = robot.resume if robot.status is S.OFFLINE else robot.status
            # A robot already Offline before the restart has been away since its last state
            # change: its hand-over limit counts from then, not from this start.
            away_since = robot.status_since if robot.status is S.OFFLINE else None
            robot, resume = await self.trips.reconcile(robot, resume)
            ctl = self._add(robot)
            ctl.rt.offline_since = away_since
            st = RobotState(S.OFFLINE, robot.mode, resume)
            ctl.rt.state = st
            await ctl.save_state(st, event="robot.restored")
        await self.calls.start()
        await self.tickets.start()
        self.dispatcher.start()
        await self.service.start(self)
        for ctl in self._ctl.values():
            ctl.start_link()

    async def halt_robots(self, budget: float = 0.4) -> None:
        """Stop every robot now, before anything else of a shutdown (within ``budget`` wall s).

        Dispatch stops, events are no longer queued, and each link cancels its goals and
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
        for ctl in self._ctl.values():
            await ctl.stop()
        for ctl in self._ctl.values():
            with contextlib.suppress(ServeurError):
                await ctl.save_pose()

    # -- the links' listener's questions (link_reports.ReportHandler) ------------------------

    async def on_event(self, rt: Runtime, event: RobotEvent) -> None:
        """One queued robot event, under the robot's lock: its controller's."""
        await self._ctl[rt.name].on_event(event)

    def moved(self, name: str, x: float, y: float) -> None:
        self.traffic.moved(name, x, y)

    def localisation_changed(self, name: str) -> None:
        """Lost or sure again: said once each way in the log (as Home Assistant says a
        device's availability), the record republished (the console's "Not sure where it
        is"), and, sure again, the dispatcher looks for trips for it. The alert follows from
        the service watch's next look (robot_facts)."""
        ctl = self._ctl[name]
        loc = ctl.rt.localisation
        if loc.lost:
            log.warning(
                "%s: not sure where it is (spread %.2f m, %.2f rad): no trips until it is",
                name,
                loc.spread,
                loc.radians,
            )
        else:
            log.info("%s: sure where it is again (spread %.2f m)", name, loc.spread)
            self.dispatcher.kick()
        ctl.publish()

    def battery_changed(self, name: str) -> None:
        """Screens see the new level; the dispatcher looks again if the robot is waiting at
        home. A robot below the dispatch threshold (``scheduler.choose_robot``) charges there
        and must be given the queued trips once it is above it: nothing else may happen (the
        last dishes of a service are queued, every robot was low), so without this kick the
        trips waited for ever beside a usable robot."""
        ctl = self._ctl[name]
        ctl.publish()
        if ctl.rt.state.status is S.AWAITING:
            self.dispatcher.kick()

    def _on_watch(self, topic: str, on: bool) -> None:
        self.reports.on_watch(topic, on)

    # -- distances ---------------------------------------------------------------------------

    def distance(self, a: str, b: str) -> float:
        """Path distance between two waypoints; straight line if not planned or no path."""
        return self.places.distance(a, b)

    def _origin(self) -> str:
        return self.places.origin(r.home for r in self._robots.values())

    # -- what screens are told --------------------------------------------------------------

    def task_robot(self, task_id: int) -> str | None:
        """The robot doing (or that did) task ``task_id``, if this server has seen it."""
        robot = self.publisher.task_robot(task_id)
        if robot is None:
            robot = next((n for n, r in self._robots.items() if r.current_task == task_id), None)
        return robot

    async def flush_events(self) -> None:
        """Push the events recorded since the last flush to ``events`` subscribers."""
        await self.publisher.flush_events()

    def robot_statuses(self) -> list[tuple[str, RobotStatus]]:
        return [(n, rt.state.status) for n, rt in sorted(self._rt.items())]

    async def snapshot(self, topic: str) -> Any:
        """A topic's current records, as a ``data`` reply gives them."""
        table = _SNAPSHOTS.get(topic)
        if table is not None:
            return await table(self)
        kind, _, robot = topic.partition(":")
        rt = self.controller(robot).rt
        if kind == "pose":
            return pose_dict(rt.pose, self.clock.epoch()) if rt.pose else None
        return None  # scan, cloud: the next frame arrives as an update

    async def _live_orders(self) -> Any:
        # Every dish not finished: the kitchen's (ordered, cooking), the pass's (pending,
        # returned) and those on a trip (assigned).
        live = [
            OrderStatus.ORDERED,
            OrderStatus.COOKING,
            OrderStatus.PENDING,
            OrderStatus.ASSIGNED,
            OrderStatus.RETURNED,
        ]
        return await self.store.orders.list_orders(status=live)

    async def _live_tasks(self) -> Any:
        return await self.store.tasks.list_tasks(status=[TaskStatus.QUEUED, TaskStatus.ACTIVE])

    # -- instructions -----------------------------------------------------------------------

    async def handle(
        self, msg: P.ClientMessage, *, actor: str | None = None, table: str | None = None
    ) -> dict[str, Any]:
        """Carry out one instruction; the reply payload, or a ServeurError.

        ``actor`` (``user:ana``) is recorded with the steps a person takes; ``table`` is set
        for a table screen: its ``next`` may only act on a robot serving that table.
        """
        try:
            if self._halted:
                raise LinkError("the server is shutting down: robots are stopped")
            return await self.instructions.handle(msg, actor, table)
        finally:
            await self.flush_events()

    # -- dispatcher (scheduler.Fleet) -------------------------------------------------------

    async def queued_tasks(self) -> list[QueuedTrip]:
        out = []
        for t in await self.store.tasks.list_tasks(status=TaskStatus.QUEUED):
            if t.kind is TaskKind.DELIVERY:
                out.append(QueuedTrip(t.id, len(t.stops)))
            elif t.kind is TaskKind.BUSSING:
                tables = [s.table for s in t.stops if s.purpose is StopPurpose.COLLECT]
                last = t.stops[-1].table
                wait = self.config.bussing_wait
                secs = bussing_seconds(self._origin(), tables, last, self.distance, wait=wait)
                out.append(QueuedTrip(t.id, len(t.stops), bussing=True, seconds=secs))
            # A cruise is never queued for just anyone: it is started for its robot.
        return out

    async def chain_bussing(self, robot: str) -> Task | None:
        """A robot's delivery just ended (its lock held): on its way back it takes the oldest
        queued bussing trip if no delivery is queued and :func:`may_bus` allows it, counting
        itself among the free robots. The trip taken, or None."""
        queued = await self.queued_tasks()
        if not queued or any(not q.bussing for q in queued):
            return None
        q = next(q for q in queued if q.bussing)
        free = len([c for c in self.free_robots() if usable(c)]) + 1
        waiting = await self.tables_waiting()
        if not may_bus(free, q.seconds, tables_waiting=waiting, max_delay=self.bussing_max_delay()):
            return None
        task = await self.trips.take(q.task_id, robot)
        if task is not None:
            log.info("%s: on its way back, takes the plates of %s", robot, task.stops[0].table)
        return task

    async def tables_waiting(self) -> int:
        waiting = [OrderStatus.ORDERED, OrderStatus.COOKING, OrderStatus.PENDING]
        return len({o.table for o in await self.store.orders.list_orders(status=waiting)})

    def bussing_max_delay(self) -> float:
        return self.config.bussing_max_delay

    def cruising(self) -> list[str]:
        return [
            name
            for name, ctl in sorted(self._ctl.items())
            if ctl.rt.trip_kind is TaskKind.CRUISE
            and ctl.rt.state.status in (S.DELIVERING, S.DELIVERED)
        ]

    async def recall(self, robot: str) -> bool:
        ctl = self._ctl[robot]
        async with ctl.rt.lock:
            if ctl.rt.trip_kind is not TaskKind.CRUISE or ctl.rt.state.status not in (
                S.DELIVERING,
                S.DELIVERED,
            ):
                return False
            log.info("%s: cruise ended, dishes are waiting", robot)
            await ctl.recall("called back to deliveries")
        await self.flush_events()
        return True

    def free_robots(self) -> list[Candidate]:
        return [
            Candidate(
                ctl.name,
                ctl.rt.idle_since,
                ctl.rt.battery,
                ctl.record.trays or self.config.capacity,
                lost=ctl.rt.localisation.lost,
            )
            for ctl in self._ctl.values()
            if ctl.rt.state.status is S.AWAITING
            and ctl.rt.link is not None
            and ctl.rt.link.up
            and ctl.record.current_task is None
            # Locked robots are listed too: start_trip waits for the lock and re-checks, so a
            # robot freed inside a locked section is not missed by the kick it caused.
        ]

    async def start_trip(self, task_id: int, robot: str) -> bool:
        ctl = self._ctl[robot]
        async with ctl.rt.lock:
            if ctl.rt.state.status is not S.AWAITING or ctl.rt.localisation.lost:
                return False
            blocked = await self.trips.drop_blocked(task_id, self.service.blocks)
            if blocked is None:
                return False
            task = await self.trips.take(task_id, robot)
            if task is None:
                return False
            ctl.rt.trip_kind = task.kind
            if self.config.auto_depart or task.kind is not TaskKind.DELIVERY:
                # Nothing to load at the pass: a bussing robot leaves from where it is.
                await ctl.event(Event.DISPATCH)
                await ctl.drive(ctl.stop_dest(task))
            else:
                await ctl.event(Event.ASSIGN)
        await self.flush_events()
        return True

    # -- the service watch (core.service.ServiceHost) ---------------------------------------

    def robot_facts(self) -> list[RobotFact]:
        facts = []
        for name, ctl in sorted(self._ctl.items()):
            rt, robot = ctl.rt, ctl.record
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
                    lost=rt.localisation.lost,
                    not_charging=rt.not_charging and rt.state.status is S.CHARGING,
                    waits_for_people=rt.at_stop not in (StopPurpose.COLLECT, StopPurpose.VISIT),
                )
            )
        return facts

    async def escalate_calls(self) -> list[Call]:
        await self.calls.escalate_due()
        return self.calls.escalated()

    def till_facts(self) -> TillFacts:
        return self.tickets.facts()

    def timers(self) -> None:
        """Post each robot what its waiting has come to (once per arrival or stop: its
        ``status_since`` identifies it, so a robot that moved on is left alone): a stop's wait
        over (serveur.core.modes.stop_wait), a touched cruising robot's pause over, a free
        robot low enough to charge, a charging one charged."""
        cfg, now = self.config, self.clock.epoch()
        for name, ctl in self._ctl.items():
            rt, robot = ctl.rt, ctl.record
            since, status = robot.status_since, rt.state.status
            if status is S.DELIVERED and robot.current_task is not None:
                limit = stop_wait(
                    rt.at_stop or StopPurpose.DELIVER,
                    special=rt.special,
                    table_timeout=cfg.table_timeout,
                    bussing_wait=cfg.bussing_wait,
                    cruise_pause=cfg.cruise_pause,
                )
                if limit is not None and now - since >= limit and rt.posted_for != since:
                    rt.posted_for = since
                    self.reports.post(name, TableTimeout(robot.current_task, since))
            elif (
                status is S.STOPPED
                and rt.trip_kind is TaskKind.CRUISE
                and robot.current_task is not None
                and now - since >= cfg.cruise_resume
                and rt.posted_for != since
            ):
                rt.posted_for = since
                self.reports.post(name, CruiseResume(robot.current_task, since))
            elif rt.link is not None and rt.link.up and rt.posted_for != since:
                if (
                    charge_due(
                        status, rt.battery, has_dock=robot.dock is not None, below=cfg.charge_below
                    )
                    and not rt.localisation.lost
                ):
                    rt.posted_for = since
                    self.reports.post(name, ChargeDue())
                elif charged(status, rt.battery, until=cfg.charge_until):
                    rt.posted_for = since
                    self.reports.post(name, Charged())
            if status is S.CHARGING:
                rt.not_charging = rt.charge_watch.not_charging(now, rt.battery)


async def _robots(core: Core) -> Any:
    return [core._ctl[n].view() for n in sorted(core._ctl)]


async def _waypoints(core: Core) -> Any:
    return list(core.places.waypoints.values())


async def _events(core: Core) -> Any:
    return await core.publisher.events_snapshot()


async def _map(core: Core) -> Any:
    return core.places.map_snapshot()


async def _alerts(core: Core) -> Any:
    return core.service.alerts.active()


async def _menu(core: Core) -> Any:
    return await core.store.service.list_menu()


async def _blocks(core: Core) -> Any:
    return list(core.service.blocks.values())


async def _settings(core: Core) -> Any:
    return core.settings()


async def _zones(core: Core) -> Any:
    return list(core.zone_records.values())


async def _leases(core: Core) -> Any:
    return core.traffic.lease_rows()


async def _calls(core: Core) -> Any:
    return core.calls.snapshot()


async def _tickets(core: Core) -> Any:
    return await core.tickets.snapshot()


async def _till(core: Core) -> Any:
    return core.tickets.state()


#: Topic -> its snapshot (``pose:<robot>`` and ``scan:<robot>`` are per robot).
_SNAPSHOTS: dict[str, Callable[[Core], Awaitable[Any]]] = {
    "robots": _robots,
    "orders": Core._live_orders,
    "tasks": Core._live_tasks,
    "waypoints": _waypoints,
    "events": _events,
    "map": _map,
    "alerts": _alerts,
    "menu": _menu,
    "blocks": _blocks,
    "settings": _settings,
    "zones": _zones,
    "leases": _leases,
    "calls": _calls,
    "tickets": _tickets,
    "till": _till,
}
