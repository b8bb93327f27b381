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
  robot on without them.

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
from serveur.replay.guests import Guests
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
from serveur.replay.orders import LogOrder
from serveur.replay.staff import Staff
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


# -- one service -------------------------------------------------------------------------------


class _Service:
    """One replayed service: the kitchen, the staff and the guests around one running App.

    The players act through one :class:`~serveur.replay.client.Console`; the service feeds
    it the server's updates, tells the staff and guests what happened to the robots, counts
    each robot's time away from the pass, and ends when the guests have every dish or a
    player failed.
    """

    def __init__(
        self, orders: Sequence[LogOrder], opts: ReplayOptions, policy: str, clock: Any
    ) -> None:
        self.log = list(orders)
        self.opts = opts
        self.policy = policy
        self.clock = clock
        # Timeouts are sized for wall-clock jitter times the scale; virtual time has none.
        self._scale = opts.time_scale or 1.0
        self.console = Console(clock)
        self.finished = asyncio.Event()
        self.staff = Staff(self.console, self.log, opts, policy, self.finished, self._spawn)
        self.guests = Guests(
            self.console,
            opts.seed,
            self.staff.line_of,
            len(self.log),
            self.finished,
            absences(self.log, opts.seed, opts.away),
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
        elif topic == "orders":
            self.staff.on_order(data)
        elif topic == "robots":
            self._on_robot(data)
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
                    self._spawn(
                        self.guests.collect(
                            name, task["id"], stop["seq"], stop["table"], stop["orders"]
                        )
                    )
        elif status == "Error":
            self.nav_errors += 1
            self._spawn(self.staff.rescue(name))

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
            workdir / f"{self.policy}.db",
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
            snap = await client.call("data", topics=["robots", "tasks", "orders"])
            for r in snap["data"]["robots"]:
                self._on_robot(r)
            names = [s.name for s in specs]
            for name in names:
                await console.until(partial(console.status_is, name, "Ready"), f"{name} Ready")
                await client.call("control", robot=name, action="auto")
            await console.until(
                lambda: all(console.robots[n]["status"] == "Awaiting" for n in names), "auto"
            )
            console.t0 = float(self.clock.now())
            epoch0 = float(self.clock.epoch())
            watch.start()
            bg.append(asyncio.create_task(self._sample(sim, result.paths)))
            if opts.progress:
                bg.append(asyncio.create_task(self._progress(self.policy)))
            self._spawn(self.staff.run())
            limit = (self.log[-1].ready_at if self.log else 0.0) + opts.overtime
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
        for t in await store.tasks.list_tasks():
            stops = t.stops
            robot_of[t.id] = t.robot
            result.trips.append(
                {
                    "id": t.id,
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
        for name in sorted(robots):
            pts = result.paths.get(name, [])
            dist = sum(math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in itertools.pairwise(pts))
            busy = self.busy.get(name, 0.0)
            spans = list(self.spans.get(name, []))
            if name in self.busy_since:
                busy += self.now() - self.busy_since[name]
                spans.append((self.busy_since[name], self.now()))
            trips = sum(1 for t in result.trips if t["robot"] == name and t["status"] == "done")
            result.robots.append(
                {
                    "name": name,
                    "distance": dist,
                    "busy": busy,
                    "trips": trips,
                    "loading": ev.loading.get(name, 0.0),
                    "busy_spans": [[round(a, 1), round(b, 1)] for a, b in spans],
                }
            )


async def replay_policy(
    orders: Sequence[LogOrder], opts: ReplayOptions, policy: str, workdir: Path
) -> PolicyResult:
    """Replay ``orders`` once with ``policy`` (a fresh server, database and fleet)."""
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
    return await _Service(_numbered(orders), opts, policy, clock).run(workdir)


def _numbered(orders: Sequence[LogOrder]) -> list[LogOrder]:
    """Generated orders (line 0) get the line they would have in their CSV (header = 1), so
    their idempotency keys are unique and their guests dwell as after a round trip to disk."""
    if all(o.line for o in orders):
        return list(orders)
    return [o if o.line else replace(o, line=i + 2) for i, o in enumerate(orders)]


async def replay(
    orders: Sequence[LogOrder], opts: ReplayOptions, policies: Sequence[str]
) -> dict[str, PolicyResult]:
    """Each policy in turn on the same log (one after the other: they must not share CPU)."""
    out: dict[str, PolicyResult] = {}
    with tempfile.TemporaryDirectory(prefix="serveur-replay-") as tmp:
        for p in policies:
            out[p] = await replay_policy(orders, opts, p, Path(tmp))
    return out


# -- command line ------------------------------------------------------------------------------


def run_replay(
    orders: Sequence[LogOrder], opts: ReplayOptions, policies: Sequence[str]
) -> dict[str, PolicyResult]:
    """Each policy in turn, each on a fresh event loop of the kind ``opts`` needs.

    Virtual time unless ``time_scale`` is set. A fresh loop per policy starts each service at
    loop time 0, so a policy's report does not depend on which ran before it (float rounding
    of a larger clock would move its stamps in the last digits).
    """
    factory = VirtualTimeLoop if opts.time_scale is None else None
    out: dict[str, PolicyResult] = {}
    with tempfile.TemporaryDirectory(prefix="serveur-replay-") as tmp:
        for p in policies:
            with asyncio.Runner(loop_factory=factory) as runner:
                out[p] = runner.run(replay_policy(orders, opts, p, Path(tmp)))
    return out
