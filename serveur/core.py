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
import hashlib
import json
import logging
import math
import ssl
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field, replace
from typing import Any

from serveur import protocol as P
from serveur import rosbridge as rb
from serveur.clock import Clock
from serveur.distances import Distances, MapData, PlanRequest, plan_async
from serveur.domain import (
    Order,
    OrderStatus,
    Robot,
    StopStatus,
    Task,
    TaskStatus,
    WaypointKind,
    WaypointRecord,
)
from serveur.errors import Conflict, InvalidField, LinkError, NotFound, ServeurError
from serveur.hub import Hub
from serveur.memory import trim_heap
from serveur.robot_link import RobotLink
from serveur.scheduler import Candidate, Dispatcher, cart_order_trips, order_stops, plan_trips
from serveur.status import Action, Event, RobotMode, RobotState, RobotStatus, apply, check_allowed
from serveur.store import Store

__all__ = ["HANDOVER_GRACE", "Core", "CoreConfig", "Destination"]

#: Seconds a robot restored Offline at start is given to connect before a hand-over, however
#: long it was away before the restart (its link needs a connection and a first status).
HANDOVER_GRACE = 10.0

log = logging.getLogger(__name__)

S = RobotStatus
_RESUMABLE = {S.DELIVERING, S.DELIVERED, S.STOPPED, S.TRANSIT, S.ERROR}


@dataclass
class CoreConfig:
    """Tunables; times are simulated seconds."""

    capacity: int = 4
    heartbeat: float = 1.0
    ack_timeout: float = 2.0
    ack_retries: int = 2
    arrive_tolerance: float = 0.35  # a robot this close to its goal is "there" (reconciliation)
    far_tolerance: float = 0.6  # SUCCEEDED this far from the goal is an error, not an arrival
    pose_persist_period: float = 5.0
    #: rosbridge throttles (ms) of a moving robot's unwatched pose, move_base status and the
    #: battery; 0 for real robots, raised by accelerated replays (serveur.replay).
    moving_pose_ms: int = 0
    status_ms: int = 0
    battery_ms: int = 0
    robot_radius: float = 0.2
    #: A robot Offline this long (simulated seconds) with a trip has the trip handed to another
    #: robot; ``None`` never hands over. Two minutes: long enough for a Wi-Fi dead spot or a
    #: rosbridge restart (seconds) to resume in place, short enough that food is still warm
    #: when the kitchen re-plates it for another robot.
    handover_after: float | None = 120.0
    #: "serveur": trips by area, stops in shortest-route order (scheduler.plan_trips);
    #: "baseline": the design report's behaviour, stops in the order of the cart (replay A/B).
    policy: str = "serveur"


@dataclass(frozen=True, slots=True)
class Destination:
    kind: str  # "table" | "home" | "manual"
    name: str
    x: float
    y: float
    yaw: float


@dataclass
class _Runtime:
    name: str
    state: RobotState
    link: RobotLink | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    events: asyncio.Queue[tuple[str, tuple[Any, ...]]] = field(default_factory=asyncio.Queue)
    worker: asyncio.Task[None] | None = None
    dest: Destination | None = None
    goal_id: str | None = None
    idle_since: float = 0.0
    pose: tuple[float, float, float] | None = None
    battery: float | None = None
    pose_saved_at: float = -1e9
    handover: asyncio.Task[None] | None = None  # the hand-over timer while Offline with a trip
    offline_since: float | None = None  # epoch (clock) the robot was last seen, while Offline


def _fingerprint(payload: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()


class Core:
    """Owns robots' runtime state and carries out every instruction."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        *,
        config: CoreConfig | None = None,
        nav_map: Any = None,
        map_path: str | None = None,
        plan_in_child: bool | None = None,
        robot_ssl: ssl.SSLContext | None = None,
    ) -> None:
        self.store = store
        self.clock = clock
        self.config = config or CoreConfig()
        #: How robot links verify ``wss://`` robots (see serveur.tls.client_context); None:
        #: the system trust store.
        self.robot_ssl = robot_ssl
        self.hub = Hub(on_watch=self._on_watch)
        self.dispatcher = Dispatcher(self)
        self._rt: dict[str, _Runtime] = {}
        self._robots: dict[str, Robot] = {}
        self._task_robots: dict[int, str] = {}  # task id -> robot, for screens' views
        self._waypoints: dict[str, WaypointRecord] = {}
        # The map: a MapData (or an in-process OccupancyMap, converted), or a file the planner
        # reads; path distances are planned off the event loop (serveur.distances), in a child
        # process unless this process already holds numpy (then a thread is cheaper).
        self._map: MapData | None = (
            nav_map
            if nav_map is None or isinstance(nav_map, MapData)
            else MapData.from_occupancy(nav_map)
        )
        self._map_path = map_path
        self._map_json: str | None = None
        self._plan_in_child = "numpy" not in sys.modules if plan_in_child is None else plan_in_child
        self._distances = Distances()
        self._planning: set[asyncio.Task[None]] = set()
        self._closing = False
        self._last_event: int = 0
        self._events_lock = asyncio.Lock()

    # -- lifecycle ---------------------------------------------------------------------------

    async def start(self) -> None:
        while batch := await self.store.list_events(since_id=self._last_event, limit=1000):
            self._last_event = batch[-1].id
        for wp in await self.store.list_waypoints():
            self._waypoints[wp.name] = wp
        self._distances.set_spots(_spot(w) for w in self._waypoints.values())
        if self._map is not None:
            self._set_map(self._map)
        if self._map is not None or self._map_path is not None:
            # Path distances between all waypoints, planned once before any robot is driven
            # (a bad map file stops the start here, with its MapError).
            await self._plan(None)
        for robot in await self.store.list_robots():
            # Every robot starts Offline and resumes what it was doing once its link is up.
            resume = robot.resume if robot.status is S.OFFLINE else robot.status
            # A robot already Offline before the restart has been away since its last state
            # change: its hand-over limit counts from then, not from this start.
            away_since = robot.status_since if robot.status is S.OFFLINE else None
            robot, resume = await self._reconcile(robot, resume)
            self._add_runtime(robot)
            self._rt[robot.name].offline_since = away_since
            st = RobotState(S.OFFLINE, robot.mode, resume)
            self._rt[robot.name].state = st
            await self._save_state(robot.name, st, event="robot.restored")
        self.dispatcher.start()
        for rt in self._rt.values():
            self._start_link(rt)

    async def _reconcile(
        self, robot: Robot, resume: RobotStatus | None
    ) -> tuple[Robot, RobotStatus | None]:
        """The status to resume after a restart, made consistent with the robot's trip.

        Each step of a trip is its own transaction, and the robot's status another one, so a
        crash (SIGKILL, power cut) can fall between them. The trip in the store is the truth;
        the status to resume is derived from it:

        * a trip whose stops are all done but which is still active (crash after the last
          "food collected"): finish it, the robot goes home;
        * a trip taken but the robot not yet Delivering (crash right after dispatch), or
          Delivered although the current stop is not reached (crash after "food collected"
          at a middle stop): the robot delivers to the current stop;
        * Delivering or Delivered without a trip (crash after a hand-over or a cancel): the
          robot goes home.

        Where the robot really is decides the rest on link-up (:meth:`_resume_move`: already
        at the goal counts as arrived, otherwise the goal is sent again).
        """
        if resume not in _RESUMABLE:
            resume = None
        task_id = robot.current_task
        if task_id is not None:
            task = await self.store.get_task(task_id)
            if task.status is not TaskStatus.ACTIVE:  # the store frees robots in the same tx
                log.error("%s holds trip %d, which is %s", robot.name, task_id, task.status)
            elif task.current_stop >= len(task.stops):
                log.warning("%s: closing trip %d, served before the restart", robot.name, task_id)
                await self.store.finish_task(task_id, now=self.clock.epoch())
                robot = await self.store.get_robot(robot.name)
            else:
                reached = task.stops[task.current_stop].status is StopStatus.ARRIVED
                on_trip = (S.DELIVERING, S.DELIVERED, S.STOPPED, S.ERROR)
                if resume not in on_trip or (resume is S.DELIVERED and not reached):
                    resume = S.DELIVERING
        if robot.current_task is None and resume in (S.DELIVERING, S.DELIVERED):
            resume = S.TRANSIT if robot.mode is RobotMode.AUTO else None
        return robot, resume

    async def close(self) -> None:
        """Stop serving robots: no more dispatch, every robot's move cancelled, poses saved.

        Robots are stopped where they are rather than left driving with nobody watching
        (a goal whose result no server will read, "Food collected" that nobody can press).
        Their stored status is left as it was, so a restarted server resumes each trip.
        """
        self._closing = True
        for job in list(self._planning):
            job.cancel()
        await self.dispatcher.stop()
        for rt in self._rt.values():
            self._disarm_handover(rt)
            if rt.worker is not None:
                rt.worker.cancel()
                with contextlib.suppress(asyncio.CancelledError):
                    await rt.worker
        # Workers, dispatcher and clients are gone: nothing can send a new goal after this.
        for rt in self._rt.values():
            if rt.link is not None and rt.link.up:
                try:
                    await asyncio.wait_for(rt.link.cancel_goal(), self.clock.wall(2.0) + 1.0)
                except (LinkError, TimeoutError) as exc:
                    log.warning("%s: could not stop the robot on shutdown: %s", rt.name, exc)
        for rt in self._rt.values():
            if rt.link is not None:
                await rt.link.close()
        for rt in self._rt.values():
            if rt.pose is not None:
                with contextlib.suppress(ServeurError):
                    await self.store.save_robot_pose(
                        rt.name,
                        x=rt.pose[0],
                        y=rt.pose[1],
                        yaw=rt.pose[2],
                        battery=rt.battery,
                        now=self.clock.epoch(),
                    )

    def _add_runtime(self, robot: Robot) -> _Runtime:
        rt = _Runtime(robot.name, RobotState(robot.status, robot.mode, robot.resume))
        if robot.x is not None and robot.y is not None and robot.yaw is not None:
            rt.pose = (robot.x, robot.y, robot.yaw)
        rt.battery = robot.battery
        rt.idle_since = self.clock.now()
        self._rt[robot.name] = rt
        self._robots[robot.name] = robot
        rt.worker = asyncio.create_task(self._worker(rt), name=f"robot-{robot.name}")
        return rt

    def _start_link(self, rt: _Runtime) -> None:
        robot = self._robots[rt.name]
        rt.link = RobotLink(
            rt.name,
            robot.url,
            self,
            self.clock,
            heartbeat=self.config.heartbeat,
            ack_timeout=self.config.ack_timeout,
            ack_retries=self.config.ack_retries,
            want_map=self._map is None,
            ssl=self.robot_ssl,
            pose_watched=self.hub.watched(f"pose:{rt.name}"),
            moving_pose_ms=self.config.moving_pose_ms,
            status_ms=self.config.status_ms,
            battery_ms=self.config.battery_ms,
        )
        rt.link.start()

    # -- map and distances ------------------------------------------------------------------

    def _set_map(self, m: MapData) -> None:
        self._map = m
        self._map_json = P.dump(m.snapshot())
        self.hub.publish("map", self._map_json)

    async def _plan(self, sources: list[str] | None) -> None:
        """Plan the distances of every pair (``sources`` None) or of pairs touching ``sources``."""
        req = PlanRequest(
            spots=[_spot(w) for w in self._waypoints.values()],
            robot_radius=self.config.robot_radius,
            map=self._map,
            map_path=self._map_path if self._map is None else None,
            sources=sources,
        )
        started = time.monotonic()
        result = await plan_async(req, in_child=self._plan_in_child)
        log.info(
            "planned %d path distances in %.1f s (%s)",
            len(result.pairs),
            time.monotonic() - started,
            "child process" if self._plan_in_child else "worker thread",
        )
        if not self._plan_in_child:
            trim_heap()  # the worker thread's freed distance fields (serveur.memory)
        if self._map is None:
            self._set_map(result.map)
        self._distances.merge(req, result)

    def _plan_later(self, sources: list[str] | None) -> None:
        """Plan in the background; until then the scheduler uses straight lines."""

        async def run() -> None:
            try:
                await self._plan(sources)
            except ServeurError as exc:
                log.warning("path distances not planned (straight lines used): %s", exc)

        job = asyncio.get_running_loop().create_task(run())
        self._planning.add(job)
        job.add_done_callback(self._planning.discard)

    def distance(self, a: str, b: str) -> float:
        """Path distance between two waypoints; straight line if not planned or no path."""
        if a == b:
            return 0.0
        planned = self._distances.planned(a, b)
        if planned is not None:
            return planned
        wa, wb = self._waypoints.get(a), self._waypoints.get(b)
        if wa is None or wb is None:
            return 1e6
        return math.hypot(wa.x - wb.x, wa.y - wb.y)

    def _origin(self) -> str:
        for kind in (WaypointKind.PASS, WaypointKind.HOME):
            for wp in self._waypoints.values():
                if wp.kind is kind:
                    return wp.name
        for r in self._robots.values():
            if r.home:
                return r.home
        return next(iter(self._waypoints), "")

    # -- publishing -------------------------------------------------------------------------

    def _robot_view(self, name: str) -> Robot:
        rt = self._rt[name]
        upd: dict[str, Any] = {"battery": rt.battery}
        if rt.pose is not None:
            upd.update(x=rt.pose[0], y=rt.pose[1], yaw=rt.pose[2])
        return self._robots[name].model_copy(update=upd)

    def _pub(self, topic: str, record: Any) -> None:
        if self.hub.watched(topic):
            self.hub.publish(topic, P.dump(record), record)

    def _pub_task(self, task: Task) -> None:
        if task.robot is not None:
            self._task_robots[task.id] = task.robot
            while len(self._task_robots) > 10_000:  # a night has hundreds; bound it anyway
                del self._task_robots[next(iter(self._task_robots))]
        self._pub("tasks", task)

    def task_robot(self, task_id: int) -> str | None:
        """The robot doing (or that did) task ``task_id``, if this server has seen it."""
        robot = self._task_robots.get(task_id)
        if robot is None:
            robot = next((n for n, r in self._robots.items() if r.current_task == task_id), None)
        return robot

    async def _pub_orders(self, ids: Sequence[int]) -> None:
        if self.hub.watched("orders"):
            for oid in ids:
                self._pub("orders", await self.store.get_order(oid))

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
        rt.state = st
        last_error = self._robots[name].last_error if keep_error else error
        robot = await self.store.save_robot_state(
            name,
            status=st.status,
            mode=st.mode,
            resume=st.resume,
            last_error=last_error,
            now=self.clock.epoch(),
            event=event,
            data=data,
        )
        self._robots[name] = robot
        self._pub("robots", self._robot_view(name))
        if st.status is not S.OFFLINE:
            rt.offline_since = None
        elif rt.offline_since is None:
            rt.offline_since = self.clock.epoch()
        if st.status is S.OFFLINE and robot.current_task is not None:
            self._arm_handover(rt)
        else:
            self._disarm_handover(rt)
        if st.status is S.AWAITING:
            rt.idle_since = self.clock.now()
            self.dispatcher.kick()
        return robot

    # -- hand-over of the trip of a robot gone too long ---------------------------------------

    def _arm_handover(self, rt: _Runtime) -> None:
        if self.config.handover_after is None or rt.handover is not None or self._closing:
            return
        rt.handover = asyncio.create_task(self._handover_timer(rt), name=f"handover-{rt.name}")

    def _disarm_handover(self, rt: _Runtime) -> None:
        timer, rt.handover = rt.handover, None
        if timer is not None and timer is not asyncio.current_task():
            timer.cancel()

    async def _handover_timer(self, rt: _Runtime) -> None:
        limit = self.config.handover_after
        assert limit is not None
        away = self.clock.epoch() - (rt.offline_since or self.clock.epoch())
        # What is left of the limit, but never less than a short grace (a robot restored at
        # start needs a moment to connect before its trip can be judged), nor more than the
        # limit (a stored time ahead of this clock: an accelerated run, restarted).
        grace = min(limit, HANDOVER_GRACE)
        await self.clock.sleep(min(limit, max(grace, limit - away)))
        rt.handover = None
        # Through the robot's queue, like a link report: a link-up already queued is handled
        # first, and the hand-over then sees the robot back and does nothing.
        self._post(rt.name, "handover")

    async def _hand_over(self, rt: _Runtime) -> None:
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
        now = self.clock.epoch()
        try:
            task = await self.store.requeue_task(task_id, now=now, reason=reason)
        except Conflict:
            # Every stop was served before the link dropped: the trip is over, not handed on.
            task = await self.store.finish_task(task_id, now=now)
        self._robots[rt.name] = await self.store.get_robot(rt.name)
        self._pub_task(task)
        await self._pub_orders([o for s in task.stops for o in s.orders])
        resume = rt.state.resume
        if resume in (S.DELIVERING, S.DELIVERED):
            resume = S.TRANSIT
        await self._save_state(
            rt.name,
            replace(rt.state, resume=resume),
            event="robot.handover",
            error=reason,
            data={"task": task_id},
        )
        self.dispatcher.kick()

    async def _event(self, rt: _Runtime, ev: Event, *, error: str | None = None) -> Robot:
        new = apply(rt.state, ev)
        log.info("%s: %s --%s--> %s", rt.name, rt.state.status.value, ev.value, new.status.value)
        return await self._save_state(rt.name, new, error=error, data={"event": ev.value})

    async def flush_events(self) -> None:
        """Push the events recorded since the last flush to ``events`` subscribers.

        The store writes an event row in the same transaction as every state change; reading
        them back here (by id, so nothing is missed or repeated) keeps that one source of truth.
        """
        async with self._events_lock:
            while batch := await self.store.list_events(since_id=self._last_event, limit=500):
                self._last_event = batch[-1].id
                if self.hub.watched("events"):
                    for ev in batch:
                        self.hub.publish("events", P.dump(ev))

    def robot_statuses(self) -> list[tuple[str, RobotStatus]]:
        return [(n, rt.state.status) for n, rt in sorted(self._rt.items())]

    # -- snapshots --------------------------------------------------------------------------

    async def snapshot(self, topic: str) -> Any:
        if topic == "robots":
            return [self._robot_view(n) for n in sorted(self._rt)]
        if topic == "orders":
            return await self.store.list_orders(status=[OrderStatus.PENDING, OrderStatus.ASSIGNED])
        if topic == "tasks":
            return await self.store.list_tasks(status=[TaskStatus.QUEUED, TaskStatus.ACTIVE])
        if topic == "waypoints":
            return list(self._waypoints.values())
        if topic == "events":
            await self.flush_events()
            return await self.store.list_events(since_id=max(0, self._last_event - 100))
        if topic == "map":
            return json.loads(self._map_json) if self._map_json else None
        kind, _, robot = topic.partition(":")
        rt = self._runtime(robot)
        if kind == "pose":
            return _pose_dict(rt.pose, self.clock.epoch()) if rt.pose else None
        return None  # scan: the next frame arrives as an update

    # -- instructions -----------------------------------------------------------------------

    def _runtime(self, name: str) -> _Runtime:
        rt = self._rt.get(name)
        if rt is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return rt

    def _waypoint(self, name: str) -> WaypointRecord:
        wp = self._waypoints.get(name)
        if wp is None:
            raise NotFound(f"no waypoint named {name!r}", waypoint=name)
        return wp

    async def handle(self, msg: P.ClientMessage) -> dict[str, Any]:
        """Carry out one instruction; the reply payload, or a ServeurError."""
        try:
            return await self._handle(msg)
        finally:
            await self.flush_events()

    async def _handle(self, msg: P.ClientMessage) -> dict[str, Any]:
        verb = msg.clientmsg
        if verb == "create":
            return await self._create(msg)
        if verb == "order":
            return await self._order(msg)
        robot = P.robot_of(msg)
        action = P.action_of(msg)
        if robot is None or action is None:
            raise InvalidField(f"{verb!r} needs a robot")
        rt = self._runtime(robot)
        async with rt.lock:
            check_allowed(rt.state.status, action)
            await self._act(rt, action, msg)
            return {"robot": self._robot_view(rt.name)}

    async def _act(self, rt: _Runtime, action: Action, msg: Any) -> None:
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
                await self._abandon_task(rt, "manual control taken")
            with contextlib.suppress(LinkError):
                await link.cancel_goal()
            rt.dest = None
            await self._event(rt, Event.MANUAL)
        elif action is Action.TELEOP:
            await link.teleop(msg.vx, msg.vy, msg.wz)
        elif action is Action.INITIALPOSE:
            await link.initial_pose(msg.x, msg.y, msg.yaw)
        elif action in (Action.GOAL, Action.GOTO):
            if action is Action.GOTO:
                wp = self._waypoint(msg.waypoint)
                dest = Destination("manual", wp.name, wp.x, wp.y, wp.yaw)
            else:
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
                await self._abandon_task(rt, "cancelled by staff")
            await self._event(rt, Event.CANCEL)
            await self._drive(rt, self._home_dest(rt))

    async def _abandon_task(self, rt: _Runtime, reason: str) -> None:
        task_id = self._robots[rt.name].current_task
        if task_id is None:
            return
        aboard = [o.id for o in await self.store.list_orders(task_id=task_id)]
        task = await self.store.cancel_task(task_id, now=self.clock.epoch(), reason=reason)
        self._robots[rt.name] = await self.store.get_robot(rt.name)
        self._pub_task(task)
        await self._pub_orders(aboard)

    async def _next(self, rt: _Runtime) -> None:
        task = await self._current_task(rt)
        stop = task.stops[task.current_stop]
        task = await self.store.complete_stop(task.id, stop.seq, now=self.clock.epoch())
        self._pub_task(task)
        await self._pub_orders(stop.orders)
        if task.current_stop < len(task.stops):
            await self._event(rt, Event.NEXT_TABLE)
            await self._drive(rt, self._stop_dest(task))
        else:
            task = await self.store.finish_task(task.id, now=self.clock.epoch())
            self._robots[rt.name] = await self.store.get_robot(rt.name)
            self._pub_task(task)
            await self._event(rt, Event.NEXT_HOME)
            await self._drive(rt, self._home_dest(rt))

    async def _current_task(self, rt: _Runtime) -> Task:
        task_id = self._robots[rt.name].current_task
        if task_id is None:
            raise Conflict(f"robot {rt.name} has no trip")
        return await self.store.get_task(task_id)

    def _stop_dest(self, task: Task) -> Destination:
        wp = self._waypoint(task.stops[task.current_stop].table)
        return Destination("table", wp.name, wp.x, wp.y, wp.yaw)

    def _home_dest(self, rt: _Runtime) -> Destination:
        home = self._robots[rt.name].home
        if home is None:
            raise Conflict(f"robot {rt.name} has no home waypoint")
        wp = self._waypoint(home)
        return Destination("home", wp.name, wp.x, wp.y, wp.yaw)

    def _near(self, rt: _Runtime, dest: Destination) -> bool:
        if rt.pose is None:
            return False
        return math.hypot(rt.pose[0] - dest.x, rt.pose[1] - dest.y) <= self.config.arrive_tolerance

    async def _drive(self, rt: _Runtime, dest: Destination) -> None:
        rt.dest = dest
        assert rt.link is not None
        try:
            rt.goal_id = await rt.link.send_goal(dest.x, dest.y, dest.yaw)
        except LinkError as exc:
            rt.goal_id = None  # re-sent when the link is back (resume)
            log.warning("%s: goal to %s not sent: %s", rt.name, dest.name, exc)

    async def _go_home_if_away(self, rt: _Runtime) -> None:
        dest = self._home_dest(rt)
        if rt.state.status is S.AWAITING and not self._near(rt, dest):
            await self._event(rt, Event.GO_HOME)
            await self._drive(rt, dest)

    async def _resume_move(self, rt: _Runtime) -> None:
        """Re-send the goal for the current move (after continue, or when the link returns)."""
        status = rt.state.status
        if status is S.DELIVERING:
            task = await self._current_task(rt)
            dest = self._stop_dest(task)
            if self._near(rt, dest):
                await self._arrived(rt)
            else:
                await self._drive(rt, dest)
        elif status is S.TRANSIT:
            dest = self._home_dest(rt)
            if self._near(rt, dest):
                rt.dest = dest
                await self._event(rt, Event.ARRIVED)
            else:
                await self._drive(rt, dest)

    async def _arrived(self, rt: _Runtime) -> None:
        if rt.state.status is S.DELIVERING:
            task = await self._current_task(rt)
            task = await self.store.arrive_stop(
                task.id, task.stops[task.current_stop].seq, now=self.clock.epoch()
            )
            self._pub_task(task)
        await self._event(rt, Event.ARRIVED)

    async def _create(self, msg: Any) -> dict[str, Any]:
        now = self.clock.epoch()
        kind = msg.type
        if kind == "order":
            self._waypoint(msg.table)
            order = await self.store.add_order(
                msg.dish, msg.table, ready_at=now, key=msg.key, now=now
            )
            self._pub("orders", order)
            return {"order": order}
        if kind == "task":
            return {"tasks": await self._create_task(list(msg.orders), msg.key)}
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
            wp = await self.store.put_waypoint(wp, replace=msg.replace, now=now)
            self._waypoints[wp.name] = wp
            self._distances.set_spots([_spot(wp)])
            if self._map is not None:
                self._plan_later([wp.name])
            self._pub("waypoints", wp)
            return {"waypoint": wp}
        if kind == "robot":
            if msg.home is not None:
                self._waypoint(msg.home)
            robot = await self.store.add_robot(
                msg.name, msg.url, home=msg.home, kinematics=msg.kinematics, now=now
            )
            if robot.name not in self._rt:
                self._add_runtime(robot)
                self._start_link(self._rt[robot.name])
            self._pub("robots", self._robot_view(robot.name))
            return {"robot": self._robot_view(robot.name)}
        raise InvalidField(f"cannot create {kind!r}")

    async def _create_task(self, order_ids: list[int], key: str | None) -> list[Task]:
        fp = _fingerprint({"orders": sorted(order_ids)})
        orders: list[Order] = [await self.store.get_order(i) for i in order_ids]
        pending = [o for o in orders if o.status is OrderStatus.PENDING]
        if key is None and len(pending) != len(orders):
            bad = sorted(o.id for o in orders if o.status is not OrderStatus.PENDING)
            raise Conflict(f"orders not pending: {bad}", orders=bad)
        if self.config.policy == "baseline":
            trips = cart_order_trips(pending or orders, self.config.capacity)
        else:
            trips = plan_trips(
                pending or orders, self._origin(), self.distance, self.config.capacity
            )
        tasks = await self.store.create_tasks(
            trips, key=key, fingerprint=fp, now=self.clock.epoch()
        )
        for t in tasks:
            self._pub_task(t)
        await self._pub_orders(order_ids)
        self.dispatcher.kick()
        return tasks

    async def _order(self, msg: Any) -> dict[str, Any]:
        if getattr(msg, "table", None):
            self._waypoint(msg.table)
            return {"orders": await self.store.cart(msg.table)}
        rt = self._runtime(msg.robot)
        task_id = self._robots[rt.name].current_task
        if task_id is None:
            return {"orders": []}
        task = await self.store.get_task(task_id)
        if task.current_stop >= len(task.stops):
            return {"orders": []}
        ids = set(task.stops[task.current_stop].orders)
        return {"orders": [o for o in await self.store.list_orders(task_id=task_id) if o.id in ids]}

    # -- dispatcher (scheduler.Fleet) -------------------------------------------------------

    async def queued_task_ids(self) -> list[int]:
        return [t.id for t in await self.store.list_tasks(status=TaskStatus.QUEUED)]

    def free_robots(self) -> list[Candidate]:
        return [
            Candidate(rt.name, rt.idle_since, rt.battery)
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
            home = self._robots[robot].home or self._origin()
            task = await self.store.get_task(task_id)
            order = [s.table for s in task.stops]
            if self.config.policy == "baseline":
                stop_order = order  # the cart's order, as the design report's robot does
            else:
                stop_order = order_stops(home, order, self.distance, end=home)
            try:
                task = await self.store.start_task(
                    task_id, robot, stop_order=stop_order, now=self.clock.epoch()
                )
            except Conflict:
                return False
            self._robots[robot] = await self.store.get_robot(robot)
            self._pub_task(task)
            await self._pub_orders([o for s in task.stops for o in s.orders])
            await self._event(rt, Event.DISPATCH)
            await self._drive(rt, self._stop_dest(task))
        await self.flush_events()
        return True

    # -- link reports (robot_link.LinkListener) ---------------------------------------------

    def _post(self, robot: str, kind: str, *args: Any) -> None:
        rt = self._rt.get(robot)
        if rt is not None and not self._closing:
            rt.events.put_nowait((kind, args))

    def link_up(self, robot: str) -> None:
        self._post(robot, "up")

    def link_down(self, robot: str, reason: str) -> None:
        self._post(robot, "down", reason)

    def goal_done(self, robot: str, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        self._post(robot, "goal", goal_id, status, text)

    def goal_lost(self, robot: str, goal_id: str, reason: str) -> None:
        self._post(robot, "goal", goal_id, rb.GoalStatus.LOST, reason)

    def pose(self, robot: str, x: float, y: float, yaw: float, stamp: float) -> None:
        rt = self._rt.get(robot)
        if rt is None:
            return
        rt.pose = (x, y, yaw)
        topic = f"pose:{robot}"
        if self.hub.watched(topic):
            self.hub.publish(topic, P.dump(_pose_dict(rt.pose, stamp)))
        if self.clock.now() - rt.pose_saved_at > self.config.pose_persist_period:
            rt.pose_saved_at = self.clock.now()
            self._post(robot, "persist_pose")

    def battery(self, robot: str, fraction: float) -> None:
        rt = self._rt.get(robot)
        if rt is None:
            return
        old, rt.battery = rt.battery, fraction
        if old is None or abs(old - fraction) >= 0.01:
            self._pub("robots", self._robot_view(robot))

    def scan(self, robot: str, msg: Mapping[str, Any]) -> None:
        rt = self._rt.get(robot)
        if rt is None or not self.hub.watched(f"scan:{robot}"):
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
        self.hub.publish(f"scan:{robot}", P.dump(data))

    def map(self, robot: str, msg: Mapping[str, Any]) -> None:
        if self._map is not None:
            return
        try:
            self._set_map(MapData.from_grid_msg(msg))
            log.info("adopted the map published by %s", robot)
            self._plan_later(None)
        except ServeurError as exc:
            log.warning("%s: unusable /map: %s", robot, exc)

    def _on_watch(self, topic: str, on: bool) -> None:
        # Scans stream only while watched; poses slow to 1 Hz while unwatched and parked.
        if topic.startswith("scan:"):
            rt = self._rt.get(topic[5:])
            if rt is not None and rt.link is not None:
                asyncio.get_running_loop().create_task(rt.link.want_scan(on))
        elif topic.startswith("pose:"):
            rt = self._rt.get(topic[5:])
            if rt is not None and rt.link is not None:
                asyncio.get_running_loop().create_task(rt.link.want_pose(on))

    async def _worker(self, rt: _Runtime) -> None:
        while True:
            kind, args = await rt.events.get()
            try:
                async with rt.lock:
                    await self._on_report(rt, kind, args)
                await self.flush_events()
            except asyncio.CancelledError:
                raise
            except Exception:
                log.exception("%s: handling %s failed", rt.name, kind)

    async def _on_report(self, rt: _Runtime, kind: str, args: tuple[Any, ...]) -> None:
        if kind == "up":
            await self._event(rt, Event.LINK_UP)
            if rt.state.status is S.AWAITING:
                await self._go_home_if_away(rt)
            else:
                await self._resume_move(rt)
        elif kind == "down":
            rt.goal_id = None
            if rt.state.status is not S.OFFLINE:
                await self._save_state(
                    rt.name, apply(rt.state, Event.LINK_DOWN), error=f"link lost: {args[0]}"
                )
        elif kind == "goal":
            await self._on_goal(rt, *args)
        elif kind == "handover":
            await self._hand_over(rt)
        elif kind == "persist_pose" and rt.pose is not None:
            await self.store.save_robot_pose(
                rt.name,
                x=rt.pose[0],
                y=rt.pose[1],
                yaw=rt.pose[2],
                battery=rt.battery,
                now=self.clock.epoch(),
            )

    async def _on_goal(self, rt: _Runtime, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        if goal_id != rt.goal_id:
            return  # a goal we already replaced or cancelled
        rt.goal_id = None
        dest = rt.dest
        st = rt.state.status
        if status is rb.GoalStatus.SUCCEEDED and dest is not None:
            if rt.pose is not None:
                off = math.hypot(rt.pose[0] - dest.x, rt.pose[1] - dest.y)
                if off > self.config.far_tolerance:
                    reason = f"robot reports arriving {off:.2f} m from {dest.name or 'its goal'}"
                    await self._failed(rt, reason)
                    return
            if st in (S.DELIVERING, S.TRANSIT):
                await self._arrived(rt)
            elif st is S.MANUAL:
                await self._save_state(rt.name, rt.state, error=None, event="robot.goal_reached")
            return
        what = {rb.GoalStatus.LOST: "goal lost"}.get(status, f"move_base {status.name}")
        await self._failed(rt, f"{what}: {text}" if text else what)

    async def _failed(self, rt: _Runtime, reason: str) -> None:
        if rt.state.status in (S.DELIVERING, S.TRANSIT):
            await self._event(rt, Event.NAV_FAILED, error=reason)
        else:
            await self._save_state(rt.name, rt.state, error=reason, event="robot.goal_failed")


def _pose_dict(pose: tuple[float, float, float], stamp: float) -> dict[str, float]:
    return {"x": pose[0], "y": pose[1], "yaw": pose[2], "stamp": stamp}


def _spot(w: WaypointRecord) -> tuple[str, float, float]:
    return (w.name, w.x, w.y)
