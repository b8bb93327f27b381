"""Replay an order log through the real server and simulated robots, in virtual time.

"How many robots do I need, and how long do guests wait?" is answered by running the service:
the real :class:`~serveur.app.App` (store, core, dispatcher, websocket endpoint) and N robots
of :mod:`serveur.robot_sim` speaking rosbridge over real loopback sockets, all in one process
on one event loop whose clock is virtual (:mod:`serveur.replay.vtime`): time stands still while
anything can run and jumps to the next timer when nothing can, so a 4-hour dinner takes as
long as the CPU needs to compute it (about half a minute) and every server timeout means what
it means in a restaurant. With ``time_scale`` set, the loop follows the wall clock instead,
``time_scale`` times faster (:class:`~serveur.clock.ScaledClock`), e.g. to watch a replay in
the staff console. The replay itself is only a client of the websocket protocol
(:mod:`serveur.replay.client`):

* **the kitchen** creates each dish (``create order``) at its ``ready_at``;
* **the staff** confirm a cart (``create task``) when robots are free — the ``baseline`` staff
  fill it first-in first-out up to the tray's tables (the design report); the ``serveur`` staff
  follow :func:`serveur.scheduler.suggest_carts` (each table on the trip that collects it
  soonest: a free robot now, or one due back from its trip; tables with the most plates per
  robot-second choose first; a hold for a table's next dish seen on the kitchen display,
  10 s growing to 60 s as tables queue) — both in :mod:`serveur.replay.staff`;
* **the staff** also load each trip at the pass: the server runs as a site does
  (``auto_depart`` off), so a robot given a trip waits ``Loading`` until staff press Go after
  a seeded loading time (:func:`~serveur.replay.model.loading_time`), and dishes returned from
  a table that timed out are sent again once their robot is back at the pass;
* **the guests** press "Food collected" (``next``) a seeded dwell time after the robot stops
  (:mod:`serveur.replay.guests`); a few parties are away when their food comes
  (:func:`~serveur.replay.model.absences`), and the server's ``table_timeout`` sends the
  robot on without them;
* with calls on (``ReplayOptions.calls``, ``serveur replay``'s default), **the guests** also
  call once served — the plates cleared, a waiter, the bill
  (:func:`~serveur.replay.orders.guest_calls`, :class:`~serveur.replay.guests.Callers`) — and
  put their plates on the bussing robot a plates call sends; **the floor staff** answer the
  waiter and bill calls and empty bussing robots at the dish return
  (:class:`~serveur.replay.staff.Floor`), a place the replay adds beside the demo room's pass
  as staff would (``create waypoint``). Each policy's service is then replayed once more
  without calls, with deliveries alone, for the dish waits side by side.

The server runs with ``CoreConfig(policy=...)``: ``baseline`` visits tables in cart order,
``serveur`` plans trips by area and stops by shortest route. Waits (ready -> collected) come
from the server's own records afterwards, so they are what the restaurant's database says.

This module runs one service — the server and simulated fleet in the world of
:mod:`serveur.replay.world`, the players above around them — records the fleet's busy time
and paths, and reads the results back (:class:`PolicyResult`, :mod:`serveur.replay.model`);
:mod:`serveur.replay.cli` is the command line and :mod:`serveur.replay.report` the report.
The public names of all of them are importable from here.

Determinism. The simulated world is seeded (robots: ``seed + i``; dwell per dish from
``(seed, line)``, independent of which trip the dish rides; loading per trip from the seed and
the trip's first line; which parties are away from the seed and each party's first line),
staff act on protocol updates,
never on wall-clock polling, and physics steps are fixed 50 ms of simulated time. In virtual
time nothing depends on the host's speed or load either: the same log, seed and options give
the same report, to the last digit. With ``time_scale`` set, scheduling jitter remains: a goal
reaches a robot a few ms of *wall* time after it was sent, which is ``time_scale`` times more
simulated time, and on a busy service such a tick can flip which robot frees first.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import replace
from functools import partial
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from serveur.domain import StopStatus
from serveur.replay.client import WAIT, Console, ProtocolClient, ReplayError
from serveur.replay.guests import Callers, Guests
from serveur.replay.model import (
    POLICIES,
    PolicyResult,
    ReplayOptions,
    absences,
    dish_dwell,
    loading_time,
    peak_utilisation,
    percentile,
    service_events,
    stop_dwell,
)
from serveur.replay.orders import LogOrder, guest_calls
from serveur.replay.staff import Floor, Staff
from serveur.replay.traffic import TrafficWatch, load_zones, zone_waits
from serveur.replay.vtime import LoopClock, VirtualTimeLoop
from serveur.replay.world import load_world, server_config, zones_path

__all__ = [
    "POLICIES",
    "PolicyResult",
    "ReplayError",
    "ReplayOptions",
    "absences",
    "dish_dwell",
    "loading_time",
    "peak_utilisation",
    "percentile",
    "replay",
    "replay_policy",
    "run_replay",
    "service_events",
    "stop_dwell",
]

log = logging.getLogger(__name__)

#: When a virtual-time service opens: 2026-01-01 00:00 UTC.
VIRTUAL_EPOCH = 1_767_225_600.0
#: Where the replay puts a dish return in the demo room (it has none): beside the pass
#: (8.0, 10.8), a metre towards the kitchen's other end, clear of robots parked at home1-3.
DEMO_DISH_RETURN = (9.0, 10.8)
#: Its name, as staff would type it.
DISH_RETURN = "dish return"


# -- one service -------------------------------------------------------------------------------


class _Service:
    """One replayed service: the kitchen, the staff and the guests around one running App.

    The players act through one :class:`~serveur.replay.client.Console`; the service feeds
    it the server's updates, tells the staff and guests what happened to the robots, counts
    each robot's time away from the pass, and ends when the guests have every dish or a
    player failed.
    """

    def __init__(
        self,
        orders: Sequence[LogOrder],
        opts: ReplayOptions,
        policy: str,
        clock: Any,
        label: str | None = None,
    ) -> None:
        self.log = list(orders)
        self.opts = opts
        self.policy = policy
        self.label = label or policy  # its database's and progress bar's name
        self.clock = clock
        # Timeouts are sized for wall-clock jitter times the scale; virtual time has none.
        self._scale = opts.time_scale or 1.0
        self.console = Console(clock)
        self.finished = asyncio.Event()  # the service is over (or a player failed)
        self.dishes_done = asyncio.Event()  # every dish collected
        self.staff = Staff(self.console, self.log, opts, policy, self.finished, self._spawn)
        self.callers: Callers | None = None
        self.floor: Floor | None = None
        if opts.calls:
            calls = guest_calls(
                self.log,
                opts.seed,
                plates=opts.call_plates,
                waiter=opts.call_waiter,
                bill=opts.call_bill,
                eat=opts.eat,
                pay=opts.pay,
            )
            self.callers = Callers(self.console, calls, self.staff.line_of, self._spawn)
            self.floor = Floor(self.console, opts, self._spawn)
        self.guests = Guests(
            self.console,
            opts.seed,
            self.staff.line_of,
            len(self.log),
            self.dishes_done,
            absences(self.log, opts.seed, opts.away),
            served=None if self.callers is None else self.callers.served,
            forget_done=opts.forget_done,
        )
        self.busy: dict[str, float] = {}
        self.busy_since: dict[str, float] = {}
        self.spans: dict[str, list[tuple[float, float]]] = {}  # robot -> (left, back) spans
        self.served: set[tuple[int, int]] = set()
        self.nav_errors = 0
        self.jobs: set[asyncio.Task[None]] = set()
        self.failure: BaseException | None = None
        self.sim: Any = None
        # robot -> (since, x, y, zones) while its record says it waits for zones
        self.waiting: dict[str, tuple[float, float, float, list[str]]] = {}
        self.wait_places: list[dict[str, Any]] = []

    def now(self) -> float:
        return self.console.now()

    def _spawn(self, coro: Any) -> None:
        task = asyncio.create_task(coro)
        self.jobs.add(task)
        task.add_done_callback(self._job_done)

    def _job_done(self, task: asyncio.Task[None]) -> None:
        self.jobs.discard(task)
        if not task.cancelled() and task.exception() is not None and self.failure is None:
            self.failure = task.exception()
            self.finished.set()

    # updates from the server -------------------------------------------------------------

    def on_update(self, topic: str, data: Any) -> None:
        if topic == "tasks":
            self.console.tasks[data["id"]] = data
            bussing = data.get("kind") == "bussing"
            if self.floor is not None and bussing and data["status"] == "cancelled":
                self.floor.trip_cancelled(data["id"])  # nobody comes for those plates
        elif topic == "orders":
            self.staff.on_order(data)
        elif topic == "robots":
            self._on_robot(data)
        elif topic == "calls":
            self.console.calls[data["id"]] = data
            if self.floor is not None:
                self.floor.on_call(data)
        self.console.changed.set()

    def _on_robot(self, robot: dict[str, Any]) -> None:
        name = robot["name"]
        robots = self.console.robots
        old = robots.get(name, {}).get("status")
        robots[name] = robot
        self._waiting_for(name, robot.get("waiting_for"))
        status = robot["status"]
        if status == old:
            return
        self.staff.look_again()
        if self.console.t0:
            if old == "Awaiting":
                self.busy_since[name] = self.now()
                self.staff.robot_left(name, robot)
            elif status == "Awaiting" and name in self.busy_since:
                since = self.busy_since.pop(name)
                self.busy[name] = self.busy.get(name, 0.0) + self.now() - since
                self.spans.setdefault(name, []).append((since, self.now()))
        if status == "Awaiting":
            self.staff.robot_home(name)
        elif status == "Loading":
            self.staff.robot_loading(name, robot)
        if status == "Delivered":
            task = self.console.tasks.get(robot["current_task"] or -1)
            if task is not None and task["current_stop"] < len(task["stops"]):
                stop = task["stops"][task["current_stop"]]
                key = (task["id"], stop["seq"])
                if key not in self.served:
                    self.served.add(key)
                    self._at_stop(name, task, stop)
        elif status == "Error":
            self.nav_errors += 1
            self._spawn(self.staff.rescue(name))

    def _at_stop(self, name: str, task: dict[str, Any], stop: dict[str, Any]) -> None:
        """A robot stopped: guests take their dishes, or put their plates on a bussing
        robot; at the dish return staff empty it."""
        purpose = stop.get("purpose", "deliver")
        if purpose == "deliver":
            job = self.guests.collect(name, task["id"], stop["seq"], stop["table"], stop["orders"])
        elif purpose == "collect" and self.callers is not None:
            party = self.callers.party_of(task["id"], stop["table"])
            job = self.guests.put_plates(name, task["id"], stop["seq"], party)
        elif purpose == "unload" and self.floor is not None:
            tables = sum(1 for s in task["stops"] if s.get("purpose") == "collect")
            job = self.floor.unload(name, task["id"], stop["seq"], tables)
        else:
            return
        self._spawn(job)

    async def _close(self) -> None:
        """The service is over once every dish is collected and, with calls on, every party
        has called, every call is closed and every bussing trip is over."""
        await self.dishes_done.wait()
        callers, c = self.callers, self.console

        def over() -> bool:
            assert callers is not None
            closed = all(
                x.get("answered_at") is not None or x.get("cancelled_at") is not None
                for x in c.calls.values()
            )
            bussing = any(
                t.get("kind") == "bussing" and t["status"] in ("queued", "active")
                for t in c.tasks.values()
            )
            return callers.done() and closed and not bussing

        if callers is not None:
            await c.settled(over)
        self.finished.set()

    async def _dish_return(self, sim: Any, waypoints: dict[str, Any]) -> str:
        """The restaurant's dish return: the map's, or one the replay adds as staff would
        (``create waypoint``, kind ``dish_return``) at ``opts.dish_return`` or, in the demo
        room, beside the pass (:data:`DEMO_DISH_RETURN`)."""
        found = sorted(n for n, w in waypoints.items() if w.kind == "dish_return")
        if found:
            return found[0]
        spot = self.opts.dish_return
        if spot is None:
            if self.opts.map_path is not None:
                raise ReplayError(
                    "the map has no dish return (a waypoint of kind dish_return) for the "
                    "bussing robots: add one, say where (--dish-return X,Y) or --no-calls"
                )
            spot = DEMO_DISH_RETURN
        name = DISH_RETURN
        while name in waypoints:
            name += "'"
        await sim.warm_plans([spot])
        await self.console.call(
            "create", type="waypoint", name=name, x=spot[0], y=spot[1], kind="dish_return"
        )
        return name

    def _waiting_for(self, name: str, zones: list[str] | None) -> None:
        """Where and how long each robot waited for zones, from its record (the plot)."""
        if not self.console.t0 or self.sim is None:
            return
        if zones and name not in self.waiting:
            x, y = next(((r.pose[0], r.pose[1]) for r in self.sim.robots if r.name == name), (0, 0))
            self.waiting[name] = (self.now(), x, y, list(zones))
        elif not zones and name in self.waiting:
            self._waited(name)

    def _waited(self, name: str) -> None:
        since, x, y, zones = self.waiting.pop(name)
        self.wait_places.append(
            {
                "robot": name,
                "t": round(since, 1),
                "s": round(self.now() - since, 1),
                "zones": zones,
                "x": round(x, 2),
                "y": round(y, 2),
            }
        )

    async def _create_zones(self, app: Any, result: PolicyResult) -> None:
        """The zones file's zones, created as the owner would (``create zone``)."""
        path = zones_path(self.opts)
        if path is None:
            return
        try:
            zones = load_zones(path)
        except ValueError as exc:
            raise ReplayError(str(exc)) from None
        token = await app.issue_token("integration", scopes=["site", "read"], label="zones")
        ws = await connect(app.url, additional_headers={"Authorization": f"Bearer {token}"})
        owner = ProtocolClient(ws, lambda _topic, _data: None)
        try:
            for z in zones:
                await owner.call("create", type="zone", replace=True, **z)
        finally:
            await owner.close()
        result.zones = zones

    # recording ---------------------------------------------------------------------------

    async def _sample(self, sim: Any, paths: dict[str, list[tuple[float, float]]]) -> None:
        """Robot positions (true poses from the simulator), for distances and the path plot.

        Every 0.25 s of service, or every 5 ms of wall time at high time scales (up to 1 s of
        service: a robot covers 0.7 m, and paths are straight between corners, so distances
        come out within a percent or two while the sampler stays cheap).
        """
        period = min(1.0, max(0.25, 0.005 * self._scale)) if self.opts.time_scale else 0.5
        while True:
            for r in sim.robots:
                x, y, _ = r.pose
                pts = paths.setdefault(r.name, [])
                if not pts or math.hypot(x - pts[-1][0], y - pts[-1][1]) >= 0.05:
                    pts.append((round(x, 3), round(y, 3)))
            await self.clock.sleep(period)

    async def _progress(self, label: str) -> None:
        """A progress bar on stderr (a line per 10 % when stderr is not a terminal)."""
        end = self.log[-1].ready_at if self.log else 1.0
        tty = sys.stderr.isatty()
        shown = -1
        while True:
            t = max(0.0, self.now())
            delivered = len(self.guests.delivered)
            frac = min(1.0, delivered / max(1, len(self.log)))
            bar = "#" * int(frac * 30)
            h, m = divmod(int(t) // 60, 60)
            eh, em = divmod(int(end) // 60, 60)
            robots = self.console.robots
            busy = sum(1 for r in robots.values() if r["status"] != "Awaiting")
            line = (
                f"{label:<9} [{bar:<30}] {delivered}/{len(self.log)} delivered"
                f"  service {h:d}:{m:02d}/{eh:d}:{em:02d}  robots busy {busy}/{len(robots)}"
            )
            if tty:
                sys.stderr.write("\r" + line + " ")
            elif int(frac * 10) > shown:
                shown = int(frac * 10)
                sys.stderr.write(line + "\n")
            sys.stderr.flush()
            # Half a wall second on a scaled clock; in virtual time a wall pause would stop
            # nothing, so the bar is redrawn every 30 s of service (a few hundred times).
            await (asyncio.sleep(0.5) if self.opts.time_scale else self.clock.sleep(30.0))

    # the whole run -----------------------------------------------------------------------

    async def run(self, workdir: Path) -> PolicyResult:
        from serveur.app import App, RobotSpec
        from serveur.robot_sim import start_simulation

        opts = self.opts
        nav_map, waypoints, map_path = load_world(opts.map_path)
        homes = sorted((w for w in waypoints.values() if w.kind == "home"), key=lambda w: w.name)
        if opts.robots > len(homes):
            raise ReplayError(f"the map has {len(homes)} home spots; --robots {opts.robots}")
        wall0 = time.perf_counter()
        sim = await start_simulation(
            opts.robots,
            port=0,
            map_path=map_path,
            kinematics=opts.kinematics,
            clock=self.clock,
            seed=opts.seed,
            ros=[opts.ros[i % len(opts.ros)] for i in range(opts.robots)],
            robots_see_each_other=opts.robots_see_each_other,
        )
        self.sim = sim
        watch = TrafficWatch(
            sim.robots,
            self.now,
            conflict_distance=opts.conflict_distance,
            deadlock_after=opts.deadlock_after,
        )
        watch.attach()
        # Every waypoint's distance field before the service opens: a robot's first goal at a
        # spot would otherwise wait for it (40-80 ms of CPU, in the middle of the service).
        await sim.warm_plans([(w.x, w.y) for w in waypoints.values()])
        specs = [
            RobotSpec(
                r.name, url, homes[i].name, opts.kinematics, {"ros": "2"} if r.ros == 2 else {}
            )
            for i, (r, url) in enumerate(zip(sim.robots, sim.urls, strict=True))
        ]
        cfg, security = server_config(opts, self.policy)
        app = App(
            workdir / f"{self.label}.db",
            port=0,
            clock=self.clock,
            nav_map=nav_map,
            waypoints=waypoints,
            robots=specs,
            config=cfg,
            security=security,
            # Virtual time: the loop's stalls are invisible to the replay, and a child's wall
            # time would let the virtual clock run on while it plans (no longer deterministic).
            plan_in_child=False,
        )
        result = PolicyResult(self.policy)
        bg: list[asyncio.Task[None]] = []
        try:
            loop = asyncio.get_running_loop()
            if isinstance(loop, VirtualTimeLoop):
                # SQLite runs in aiosqlite's thread: no time may pass while a query runs.
                loop.add_busy(app.store.busy)
            await app.start()
            core = app.core
            assert core is not None
            await self._create_zones(app, result)
            console = self.console
            console.distance = core.distance
            token = await app.issue_token("staff", label="replay")
            ws = await connect(
                app.url, max_size=2**24, additional_headers={"Authorization": f"Bearer {token}"}
            )
            console.client = client = ProtocolClient(ws, self.on_update)
            topics = ["robots", "tasks", "orders"]
            if self.callers is not None:
                topics.append("calls")
            snap = await client.call("data", topics=topics)
            for r in snap["data"]["robots"]:
                self._on_robot(r)
            names = [s.name for s in specs]
            for name in names:
                await console.until(partial(console.status_is, name, "Ready"), f"{name} Ready")
                await client.call("control", robot=name, action="auto")
            await console.until(
                lambda: all(console.robots[n]["status"] == "Awaiting" for n in names), "auto"
            )
            if self.callers is not None:
                result.dish_return = await self._dish_return(sim, waypoints)
            console.t0 = float(self.clock.now())
            epoch0 = float(self.clock.epoch())
            watch.start()
            bg.append(asyncio.create_task(self._sample(sim, result.paths)))
            if opts.progress:
                bg.append(asyncio.create_task(self._progress(self.label)))
            self._spawn(self.staff.run())
            self._spawn(self._close())
            limit = (self.log[-1].ready_at if self.log else 0.0) + opts.overtime
            if self.callers is not None:  # the last party's meal and bill come after its food
                limit += opts.eat[1] + opts.pay[1]
            await asyncio.wait_for(self.finished.wait(), self.clock.wall(limit) + WAIT)
            if self.failure is not None:
                raise ReplayError(f"the replay failed: {self.failure!r}") from self.failure
            with contextlib.suppress(ReplayError):  # robots drive home: their busy time ends
                await console.until(
                    lambda: all(console.robots[n]["status"] == "Awaiting" for n in names),
                    "robots home",
                    self.clock.wall(300.0) + 5.0,
                )
            result.sim_seconds = self.now()
            await self._collect(app, result, epoch0, waypoints)
        except TimeoutError:
            log.warning("%s: service not finished in time", self.policy)
            result.sim_seconds = self.now()
            await self._collect(app, result, self.clock.epoch() - self.now(), waypoints)
        finally:
            if opts.progress and sys.stderr.isatty():
                sys.stderr.write("\n")
            for t in [*bg, *self.jobs]:
                t.cancel()
            for t in [*bg, *self.jobs]:
                with contextlib.suppress(BaseException):
                    await t
            if self.console.client is not None:
                await self.console.client.close()
            await app.close()
            await sim.close()
        result.wall_seconds = time.perf_counter() - wall0
        result.traffic = watch.result()
        for name in sorted(self.waiting):  # still waiting when the service ended
            self._waited(name)
        result.wait_places = self.wait_places
        result.nav_errors = self.nav_errors
        result.recoveries = self.staff.recoveries
        return result

    async def _collect(
        self, app: Any, result: PolicyResult, epoch0: float, waypoints: dict[str, Any]
    ) -> None:
        """Read the service back from the server's database: its stamps are the truth."""
        from serveur.sim.kinematics import Limits

        vmax = Limits().max_speed
        robots = self.console.robots
        homes = [r["home"] for r in robots.values() if r.get("home")]
        store = app.store
        by_line = {o.line: o for o in self.log}
        robot_of: dict[int, str | None] = {}
        tasks = await store.tasks.list_tasks()
        for t in tasks:
            stops = t.stops
            robot_of[t.id] = t.robot
            result.trips.append(
                {
                    "id": t.id,
                    "kind": t.kind.value,
                    "robot": t.robot,
                    "status": t.status.value,
                    "tables": len(stops),
                    # Delivered: a skipped stop lists what it carried back too.
                    "dishes": sum(len(s.orders) for s in stops if s.status is StopStatus.DONE),
                    "stops": [s.table for s in stops],
                    "started": None if t.started_at is None else t.started_at - epoch0,
                    "finished": None if t.finished_at is None else t.finished_at - epoch0,
                }
            )
        events: list[dict[str, Any]] = []
        last = 0
        while batch := await store.events.list_events(since_id=last, limit=1000):
            last = batch[-1].id
            events += [
                {
                    "ts": e.ts - epoch0,
                    "kind": e.kind,
                    "robot": e.robot,
                    "order_id": e.order_id,
                    "data": e.data,
                }
                for e in batch
            ]
        ev = service_events(events, self.now())
        result.zone_waits = zone_waits(events)
        lines = dict(self.staff.line_of)
        for o in await store.orders.list_orders():
            line = lines.get(o.id)
            if line is None:
                continue
            lo = by_line[line]
            travel = min(self.console.distance(h, o.table) for h in homes) / vmax if homes else 0.0
            # From the first time the dish was ready: a dish sent again waited all along.
            first = self.staff.first_ready.get(o.id, o.ready_at or 0.0)
            wait = None if o.delivered_at is None else o.delivered_at - first
            result.orders.append(
                {
                    "line": line,
                    "table": o.table,
                    "dish": o.dish,
                    "ready_at": lo.ready_at,
                    "created": first - epoch0,
                    "collected": None if o.delivered_at is None else o.delivered_at - epoch0,
                    "wait": wait,
                    "lower_bound": travel + dish_dwell(self.opts.seed, line),
                    "robot": robot_of.get(o.task_id or -1),
                    "task": o.task_id,
                    "status": o.status.value,
                    "returned": ev.returned.get(o.id, 0),
                    "resent": ev.resent.get(o.id, 0),
                }
            )
        result.orders.sort(key=lambda d: d["line"])
        result.undelivered = len(self.log) - sum(1 for o in result.orders if o["wait"] is not None)
        result.loading = sum(ev.loading.values())
        result.table_timeouts = ev.timeouts
        result.staff_skips = ev.skips
        result.returned = sum(ev.returned.values())
        result.resent = sum(ev.resent.values())
        result.joined = ev.joined
        staff = self.staff
        result.players = {
            "go_pressed": len(staff.loaded),
            "loading_s": sum(staff.loaded.values()),
            "resent": staff.resent,
            "joined": staff.joined,
            "tables_cleared": staff.cleared,
            "guests_missed": len(self.guests.missed),
            "parties_away": sum(len(a) for a in self.guests.away.values()),
        }
        if self.callers is not None and self.floor is not None:
            await self._collect_calls(store, result, epoch0, tasks)
        for name in sorted(robots):
            pts = result.paths.get(name, [])
            dist = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(pts))
            busy = self.busy.get(name, 0.0)
            spans = list(self.spans.get(name, []))
            if name in self.busy_since:
                busy += self.now() - self.busy_since[name]
                spans.append((self.busy_since[name], self.now()))
            trips = sum(1 for t in result.deliveries() if t["robot"] == name)
            bussing = sum(1 for b in result.bussing if b["robot"] == name and b["status"] == "done")
            result.robots.append(
                {
                    "name": name,
                    "distance": dist,
                    "busy": busy,
                    "trips": trips,
                    "bussing": bussing,
                    "loading": ev.loading.get(name, 0.0),
                    "busy_spans": [[round(a, 1), round(b, 1)] for a, b in spans],
                }
            )

    async def _collect_calls(
        self, store: Any, result: PolicyResult, epoch0: float, tasks: Sequence[Any]
    ) -> None:
        """The guests' calls and the bussing trips, from the server's records."""
        from serveur.domain import StopPurpose, TaskKind

        def at(ts: float | None) -> float | None:
            return None if ts is None else round(ts - epoch0, 3)

        calls = await store.calls.calls_between(0.0, 1e11)  # all of them
        for call in calls:
            end = call.answered_at if call.answered_at is not None else call.cancelled_at
            result.calls.append(
                {
                    "id": call.id,
                    "table": call.table,
                    "kind": call.kind.value,
                    "source": call.source,
                    "presses": call.presses,
                    "opened": at(call.opened_at),
                    "answered": at(call.answered_at),
                    "by": call.answered_by,
                    "after": None if end is None else round(end - call.opened_at, 3),
                    "escalated": at(call.escalated_at),
                    "cancelled": at(call.cancelled_at),
                    "task": call.task_id,
                }
            )
        sent_for = {(c.task_id, c.table): c for c in calls if c.task_id is not None}
        for t in tasks:
            if t.kind is not TaskKind.BUSSING:
                continue
            stops = []
            for st in t.stops:
                if st.purpose is not StopPurpose.COLLECT:
                    continue
                call = sent_for.get((t.id, st.table))
                reach = None
                if call is not None and st.arrived_at is not None:
                    reach = round(st.arrived_at - call.opened_at, 3)
                stops.append(
                    {
                        "table": st.table,
                        "status": st.status.value,
                        "arrived": at(st.arrived_at),
                        "done": at(st.done_at),
                        "call": None if call is None else call.id,
                        "call_to_robot": reach,
                    }
                )
            unload = [st for st in t.stops if st.purpose is StopPurpose.UNLOAD]
            result.bussing.append(
                {
                    "id": t.id,
                    "robot": t.robot,
                    "status": t.status.value,
                    "created": at(t.created_at),
                    "started": at(t.started_at),
                    "finished": at(t.finished_at),
                    "unloaded": at(unload[0].done_at) if unload else None,
                    "stops": stops,
                }
            )
        assert self.callers is not None and self.floor is not None
        result.callers = {
            "calls_made": len(self.callers.made),
            "merged": sum(1 for m in self.callers.made if m["merged"]),
            "answered_by_staff": len(self.floor.answered),
            "answer_s": round(sum(self.floor.answered.values()), 1),
            "plates_done_pressed": self.guests.plates_done,
            "plates_left_to_the_wait": self.guests.plates_left,
            "unloaded": len(self.floor.unloaded),
            "unload_s": round(sum(self.floor.unloaded.values()), 1),
        }


async def replay_policy(
    orders: Sequence[LogOrder],
    opts: ReplayOptions,
    policy: str,
    workdir: Path,
    label: str | None = None,
) -> PolicyResult:
    """Replay ``orders`` once with ``policy`` (a fresh server, database and fleet): the
    database is ``<label>.db`` in ``workdir`` (default: the policy's name)."""
    from serveur.clock import ScaledClock

    if policy not in POLICIES:
        raise ValueError(f"policy must be one of {POLICIES}")
    if not orders:
        raise ReplayError("the order log is empty")
    clock: Any
    if opts.time_scale is None:
        if not isinstance(asyncio.get_running_loop(), VirtualTimeLoop):
            raise ReplayError("a virtual-time replay runs on serveur.replay.vtime.VirtualTimeLoop")
        # A fixed date, too: stamps are epoch floats, and their rounding would otherwise
        # differ with the wall-clock second the replay started at.
        clock = LoopClock(start_epoch=VIRTUAL_EPOCH)
    else:
        clock = ScaledClock(opts.time_scale)
    return await _Service(_numbered(orders), opts, policy, clock, label).run(workdir)


def _numbered(orders: Sequence[LogOrder]) -> list[LogOrder]:
    """Generated orders (line 0) get the line they would have in their CSV (header = 1), so
    their idempotency keys are unique and their guests dwell as after a round trip to disk."""
    if all(o.line for o in orders):
        return list(orders)
    return [o if o.line else replace(o, line=i + 2) for i, o in enumerate(orders)]


#: The label of a policy's run with deliveries alone, beside its run with calls and bussing.
ALONE = "{}-alone"


def _runs(opts: ReplayOptions, policies: Sequence[str]) -> list[tuple[str, str, ReplayOptions]]:
    """(policy, label, options) of each run: with calls on, each policy's service is run
    again without calls and bussing (its dish waits beside: :meth:`PolicyResult.modes`)."""
    out = []
    for p in policies:
        out.append((p, p, opts))
        if opts.calls:
            out.append((p, ALONE.format(p), replace(opts, calls=False)))
    return out


def _gather(results: Sequence[tuple[str, str, PolicyResult]]) -> dict[str, PolicyResult]:
    out: dict[str, PolicyResult] = {}
    for policy, label, r in results:
        if label == policy:
            out[policy] = r
        else:
            out[policy].alone = r
    return out


async def replay(
    orders: Sequence[LogOrder], opts: ReplayOptions, policies: Sequence[str]
) -> dict[str, PolicyResult]:
    """Each policy in turn on the same log (one after the other: they must not share CPU)."""
    done = []
    with tempfile.TemporaryDirectory(prefix="serveur-replay-") as tmp:
        for p, label, o in _runs(opts, policies):
            done.append((p, label, await replay_policy(orders, o, p, Path(tmp), label)))
    return _gather(done)


# -- command line ------------------------------------------------------------------------------


def run_replay(
    orders: Sequence[LogOrder], opts: ReplayOptions, policies: Sequence[str]
) -> dict[str, PolicyResult]:
    """Each policy in turn, each on a fresh event loop of the kind ``opts`` needs.

    Virtual time unless ``time_scale`` is set; with ``calls`` on, each policy's service is
    also run with deliveries alone (its result's ``alone``). A fresh loop per run starts each
    service at loop time 0, so a policy's report does not depend on which ran before it
    (float rounding of a larger clock would move its stamps in the last digits).
    """
    factory = VirtualTimeLoop if opts.time_scale is None else None
    done = []
    with tempfile.TemporaryDirectory(prefix="serveur-replay-") as tmp:
        for p, label, o in _runs(opts, policies):
            with asyncio.Runner(loop_factory=factory) as runner:
                done.append((p, label, runner.run(replay_policy(orders, o, p, Path(tmp), label))))
    return _gather(done)
