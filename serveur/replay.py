"""Replay an order log through the real server and simulated robots, in virtual time.

"How many robots do I need, and how long do guests wait?" is answered by running the service:
the real :class:`~serveur.app.App` (store, core, dispatcher, websocket endpoint) and N robots
of :mod:`serveur.robot_sim` speaking rosbridge over real loopback sockets, all in one process
on one event loop whose clock is virtual (:mod:`serveur.vtime`): time stands still while
anything can run and jumps to the next timer when nothing can, so a 4-hour dinner takes as
long as the CPU needs to compute it (about half a minute) and every server timeout means what
it means in a restaurant. With ``time_scale`` set, the loop follows the wall clock instead,
``time_scale`` times faster (:class:`~serveur.clock.ScaledClock`), e.g. to watch a replay in
the staff console. The replay itself is only a client of the websocket protocol:

* **the kitchen** creates each dish (``create order``) at its ``ready_at``;
* **the staff** confirm a cart (``create task``) when robots are free — the ``baseline`` staff
  fill it first-in first-out up to the tray's tables (the design report); the ``serveur`` staff
  follow :func:`serveur.scheduler.suggest_carts` (each table on the trip that collects it
  soonest: a free robot now, or one due back from its trip; tables with the most plates per
  robot-second choose first; a hold for a table's next dish seen on the kitchen display,
  10 s growing to 60 s as tables queue);
* **the guests** press "Food collected" (``next``) a seeded dwell time after the robot stops.

The server runs with ``CoreConfig(policy=...)``: ``baseline`` visits tables in cart order,
``serveur`` plans trips by area and stops by shortest route. Waits (ready -> collected) come
from the server's own records afterwards, so they are what the restaurant's database says.

Determinism. The simulated world is seeded (robots: ``seed + i``; dwell per dish from
``(seed, line)``, independent of which trip the dish rides), staff act on protocol updates,
never on wall-clock polling, and physics steps are fixed 50 ms of simulated time. In virtual
time nothing depends on the host's speed or load either: the same log, seed and options give
the same report, to the last digit. With ``time_scale`` set, scheduling jitter remains: a goal
reaches a robot a few ms of *wall* time after it was sent, which is ``time_scale`` times more
simulated time, and on a busy service such a tick can flip which robot frees first.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import logging
import math
import random
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection, connect

from serveur.orders import LogOrder, OrderLogError, read_orders
from serveur.vtime import LoopClock, VirtualTimeLoop

__all__ = [
    "POLICIES",
    "PolicyResult",
    "ReplayError",
    "ReplayOptions",
    "add_replay_parser",
    "dish_dwell",
    "peak_utilisation",
    "percentile",
    "replay",
    "replay_policy",
    "run_replay",
    "stop_dwell",
]

log = logging.getLogger(__name__)

POLICIES = ("baseline", "serveur")
#: When a virtual-time service opens: 2026-01-01 00:00 UTC.
VIRTUAL_EPOCH = 1_767_225_600.0
_MAX_CART = 50  # dishes in one ``create task`` (protocol limit)
_WAIT = 60.0  # wall seconds any single protocol round trip may take before the replay gives up


class ReplayError(RuntimeError):
    """The replay could not run (server refused an instruction, robots never came up...)."""


@dataclass(frozen=True)
class ReplayOptions:
    """How to replay. Times are simulated seconds unless said otherwise."""

    robots: int = 3
    time_scale: float | None = None  # None: virtual time (deterministic, as fast as the CPU)
    map_path: str | None = None  # ROS map YAML; waypoints from <stem>_waypoints.json beside it
    seed: int = 0
    capacity: int = 4
    kinematics: str = "omni"
    hold: float = 10.0  # serveur staff: wait this long at most for a table's next dish ...
    hold_max: float = 60.0  # ... growing to this as tables queue (scheduler.adaptive_hold)
    rank: str = "best"  # serveur staff: how tables are ranked (scheduler.RANKS)
    lookahead: float = 60.0  # the kitchen display shows dishes this far ahead of ready
    overtime: float = 3600.0  # give up this long after the last dish was ready
    progress: bool = True


def dish_dwell(seed: int, line: int) -> float:
    """Seconds a guest takes to notice the robot and lift this dish (seeded per log line).

    Keyed by the dish, not by the trip, so both policies face the same guests.
    Mostly 6-20 s, a long tail to ~40 s (a guest on the phone).
    """
    rng = random.Random(seed * 1_000_003 + line)
    return round(min(40.0, 6.0 + rng.expovariate(1 / 8.0)), 1)


def stop_dwell(seed: int, lines: Sequence[int]) -> float:
    """A stop's dwell: the slowest guest at the table, plus 2 s per extra plate to lift."""
    if not lines:
        return 0.0
    return max(dish_dwell(seed, n) for n in lines) + 2.0 * (len(lines) - 1)


def peak_utilisation(
    spans: Sequence[Sequence[tuple[float, float]]], window: float = 3600.0, step: float = 60.0
) -> float:
    """The fleet's busiest ``window``: the largest fraction of robot-time spent away on trips.

    ``spans`` holds each robot's (left the pass, back and Awaiting) intervals. Windows start
    every ``step`` seconds; a service shorter than ``window`` is one window over all of it.
    It is how "busy" is measured for the baseline-vs-serveur comparison: near 1.0 the fleet
    is out the whole peak hour and dishes queue on the pass.
    """
    if not spans or not any(spans):
        return 0.0
    end = max(b for robot in spans for _, b in robot)
    window = min(window, end) or 1.0
    best = 0.0
    start = 0.0
    while True:
        lo, hi = start, start + window
        used = sum(max(0.0, min(b, hi) - max(a, lo)) for robot in spans for a, b in robot)
        best = max(best, used / (window * len(spans)))
        if hi >= end:
            return best
        start += step


def percentile(values: Sequence[float], q: float) -> float:
    """Nearest-rank percentile (no interpolation: the value one order actually had)."""
    if not values:
        return math.nan
    s = sorted(values)
    return s[max(0, math.ceil(q / 100.0 * len(s)) - 1)]


@dataclass
class PolicyResult:
    """Everything one replay measured (service times in seconds from opening)."""

    policy: str
    orders: list[dict[str, Any]] = field(default_factory=list)
    trips: list[dict[str, Any]] = field(default_factory=list)
    robots: list[dict[str, Any]] = field(default_factory=list)
    paths: dict[str, list[tuple[float, float]]] = field(default_factory=dict)
    undelivered: int = 0
    nav_errors: int = 0
    recoveries: int = 0
    sim_seconds: float = 0.0
    wall_seconds: float = 0.0

    def waits(self) -> list[float]:
        return [o["wait"] for o in self.orders if o["wait"] is not None]

    def stats(self) -> dict[str, Any]:
        """The figures the summary prints (raw floats; the text rounds them)."""
        waits = self.waits()
        bounds = [o["lower_bound"] for o in self.orders]
        trips = [t for t in self.trips if t["status"] == "done"]
        mean_wait = sum(waits) / len(waits) if waits else math.nan
        mean_lb = sum(bounds) / len(bounds) if bounds else math.nan
        return {
            "orders": len(self.orders),
            "delivered": len(waits),
            "undelivered": self.undelivered,
            "wait_mean": mean_wait,
            "wait_p50": percentile(waits, 50),
            "wait_p95": percentile(waits, 95),
            "wait_max": max(waits) if waits else math.nan,
            "lower_bound_mean": mean_lb,
            "gap_to_lower_bound": mean_wait / mean_lb if mean_lb else math.nan,
            "trips": len(trips),
            "dishes_per_trip": sum(t["dishes"] for t in trips) / len(trips) if trips else 0.0,
            "tables_per_trip": sum(t["tables"] for t in trips) / len(trips) if trips else 0.0,
            "nav_errors": self.nav_errors,
            "recoveries": self.recoveries,
            "peak_utilisation": peak_utilisation(
                [[(a, b) for a, b in r.get("busy_spans", [])] for r in self.robots]
            ),
        }


# -- a small protocol client -------------------------------------------------------------------


class _Client:
    """The replay's one websocket connection: request/reply by id, updates to a callback."""

    def __init__(self, ws: ClientConnection, on_update: Callable[[str, Any], None]) -> None:
        self.ws = ws
        self._ids = itertools.count(1)
        self._pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self._on_update = on_update
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                msg = json.loads(frame)
                if msg["servermsg"] == "update":
                    self._on_update(msg["topic"], msg["data"])
                else:
                    fut = self._pending.pop(msg.get("id"), None)
                    if fut is not None and not fut.done():
                        fut.set_result(msg)

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        rid = next(self._ids)
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self._pending[rid] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": rid, **fields}))
        reply = await asyncio.wait_for(fut, _WAIT)
        if reply["servermsg"] != "ok":
            raise ReplayError(f"{verb} {fields}: {reply.get('code')}: {reply.get('message')}")
        return reply

    async def close(self) -> None:
        await self.ws.close()
        self._reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._reader


# -- one service -------------------------------------------------------------------------------


def _load_world(map_path: str | None) -> tuple[Any, dict[str, Any], Path]:
    from serveur.navigation import demo_map_path, load_demo, load_map, load_waypoints

    if map_path is None:
        grid, wps = load_demo()
        return grid, wps, demo_map_path()
    p = Path(map_path)
    stem = p.with_suffix("")
    for cand in (stem.with_name(stem.name + "_waypoints.json"), p.with_name("waypoints.json")):
        if cand.is_file():
            return load_map(p), load_waypoints(cand), p
    raise ReplayError(f"no waypoints for {p}: expected {stem.name}_waypoints.json beside it")


class _Service:
    """One replayed service: the kitchen, the staff and the guests around one running App."""

    def __init__(
        self, orders: Sequence[LogOrder], opts: ReplayOptions, policy: str, clock: Any
    ) -> None:
        self.log = list(orders)
        self.opts = opts
        self.policy = policy
        self.clock = clock
        # Timeouts are sized for wall-clock jitter times the scale; virtual time has none.
        self._scale = opts.time_scale or 1.0
        self.client: _Client | None = None
        self.distance: Callable[[str, str], float] = lambda a, b: 0.0
        self.t0 = 0.0
        self.line_of: dict[int, int] = {}  # server order id -> log line (dwell key)
        self.pending: dict[int, Any] = {}  # server order id -> scheduler.Dish, not yet carted
        self.created = 0
        self.delivered: set[int] = set()
        self.robots: dict[str, dict[str, Any]] = {}
        self.tasks: dict[int, dict[str, Any]] = {}
        self.busy: dict[str, float] = {}
        self.busy_since: dict[str, float] = {}
        self.spans: dict[str, list[tuple[float, float]]] = {}  # robot -> (left, back) spans
        self.eta: dict[str, float] = {}  # busy robot -> when staff expect it back (service s)
        self.served: set[tuple[int, int]] = set()
        self.nav_errors = 0
        self.recoveries = 0
        self.retries: dict[str, int] = {}
        self.carted: set[int] = set()
        self.wake = asyncio.Event()
        self.changed = asyncio.Event()
        self.finished = asyncio.Event()
        self.jobs: set[asyncio.Task[None]] = set()
        self.failure: BaseException | None = None

    def now(self) -> float:
        return float(self.clock.now()) - self.t0

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
            self.tasks[data["id"]] = data
        elif topic == "orders":
            self._on_order(data)
        elif topic == "robots":
            self._on_robot(data)
        self.changed.set()

    def _on_robot(self, robot: dict[str, Any]) -> None:
        name = robot["name"]
        old = self.robots.get(name, {}).get("status")
        self.robots[name] = robot
        status = robot["status"]
        if status == old:
            return
        self.wake.set()  # a robot freed or taken: the staff look at the pass again
        if self.t0:
            if old == "Awaiting":
                self.busy_since[name] = self.now()
                self._expect(name, robot)
            elif status == "Awaiting" and name in self.busy_since:
                since = self.busy_since.pop(name)
                self.busy[name] = self.busy.get(name, 0.0) + self.now() - since
                self.spans.setdefault(name, []).append((since, self.now()))
        if status == "Awaiting":
            self.eta.pop(name, None)
        if status == "Delivered":
            task = self.tasks.get(robot["current_task"] or -1)
            if task is not None and task["current_stop"] < len(task["stops"]):
                stop = task["stops"][task["current_stop"]]
                key = (task["id"], stop["seq"])
                if key not in self.served:
                    self.served.add(key)
                    self._spawn(self._guests(name, stop["orders"]))
        elif status == "Error":
            self.nav_errors += 1
            self._spawn(self._retry(name))

    def _expect(self, name: str, robot: dict[str, Any]) -> None:
        """When staff expect a robot that just left to be back, from its trip's stops.

        What a waiter sees on the console (the trip's tables and dishes) and a rule of
        thumb per leg and per stop (:class:`serveur.scheduler.TripEstimate`); the serveur
        staff use it to decide whether a table should wait for that robot.
        """
        from serveur.scheduler import TripEstimate

        task = self.tasks.get(robot.get("current_task") or -1)
        home = robot.get("home")
        if task is None or not home:
            return
        stops = [(s["table"], len(s["orders"])) for s in task["stops"]]
        self.eta[name] = self.now() + TripEstimate().trip(home, stops, self.distance)

    def _busy(self, now: float) -> list[float]:
        """Seconds until each robot out on a trip is expected back at the pass.

        Only robots on a normal trip count, and only until they are 15 s late: one stuck,
        in manual control or offline may be gone for minutes, and a table left on the pass
        for it would wait while a free robot idles.
        """
        out = []
        for name, r in self.robots.items():
            eta = self.eta.get(name)
            if eta is None or r["status"] not in ("Delivering", "Delivered", "Transit"):
                continue
            if now - eta <= 15.0:
                out.append(max(1.0, eta - now))
        return out

    def _origin(self) -> str:
        """Where trips start: the free robots' home spots sit at the pass; the first one's."""
        homes = [
            r["home"]
            for _, r in sorted(self.robots.items())
            if r.get("home") and r["status"] == "Awaiting"
        ]
        homes = homes or [r["home"] for _, r in sorted(self.robots.items()) if r.get("home")]
        return str(homes[0]) if homes else "pass"

    def _on_order(self, order: dict[str, Any]) -> None:
        """A dish back to ``pending`` after its trip was cancelled goes on a new cart."""
        from serveur.scheduler import Dish

        oid = order["id"]
        if order["status"] == "pending" and oid in self.carted and oid in self.line_of:
            self.carted.discard(oid)
            line = self.line_of[oid]
            ready = next(o.ready_at for o in self.log if o.line == line)
            self.pending[oid] = Dish(oid, order["table"], ready)

    def _status_is(self, robot: str, status: str) -> bool:
        return bool(self.robots.get(robot, {}).get("status") == status)

    async def _until(self, cond: Callable[[], bool], what: str, wall: float = _WAIT) -> None:
        async def wait() -> None:
            while not cond():
                self.changed.clear()
                await self.changed.wait()

        try:
            await asyncio.wait_for(wait(), wall)
        except TimeoutError:
            raise ReplayError(f"timed out waiting for {what}") from None

    # the actors --------------------------------------------------------------------------

    async def _guests(self, robot: str, order_ids: list[int]) -> None:
        """Guests at the table take their dishes, then press "Food collected"."""
        assert self.client is not None
        await self.clock.sleep(stop_dwell(self.opts.seed, [self.line_of[i] for i in order_ids]))
        for attempt in itertools.count():
            try:
                await self.client.call("next", robot=robot)
                break
            except ReplayError:
                # The robot's link dropped meanwhile (a stalled host at a high time scale):
                # it comes back Delivered at the same table, and the guests press again.
                if attempt >= 5:
                    raise
                await self._until(
                    partial(self._status_is, robot, "Delivered"), f"{robot} back", 4 * _WAIT
                )
        self.delivered.update(order_ids)
        if len(self.delivered) == len(self.log):
            self.finished.set()

    async def _retry(self, robot: str) -> None:
        """Staff walk over to a robot that gave up a move (10 s later) and sort it out.

        With dishes aboard they press Continue, twice at most; a robot that still fails, or
        was only going home, is taken in manual control, backed off whatever it bumped with
        the joystick and put back in automatic mode (it then drives home). Taking manual
        control cancels a trip: its dishes are pending again and go on a new cart.
        """
        with contextlib.suppress(ReplayError):  # the link dropped meanwhile: it resumes itself
            await self._rescue(robot)

    async def _rescue(self, robot: str) -> None:
        c = self.client
        assert c is not None
        await self.clock.sleep(10.0)
        r = self.robots[robot]
        if r["status"] != "Error":
            return
        tries = self.retries.get(robot, 0)
        if r["current_task"] is not None and tries < 2:
            self.retries[robot] = tries + 1
            await c.call("continue", robot=robot)
            return
        self.retries[robot] = 0
        self.recoveries += 1
        await c.call("control", robot=robot, action="manual")
        for _ in range(5):
            await c.call("control", robot=robot, action="teleop", vx=-0.25, vy=0.0, wz=0.0)
            await self.clock.sleep(0.3)
        await c.call("control", robot=robot, action="teleop", vx=0.0, vy=0.0, wz=0.0)
        await c.call("ready", robot=robot)
        await c.call("control", robot=robot, action="auto")

    async def _create_due(self, t: float) -> None:
        """The kitchen: every dish of the log ready by ``t`` appears at the pass, in order."""
        from serveur.scheduler import Dish

        assert self.client is not None
        while self.created < len(self.log) and self.log[self.created].ready_at <= t:
            o = self.log[self.created]
            reply = await self.client.call(
                "create", type="order", dish=o.dish, table=o.table, key=f"log-{o.line}"
            )
            oid = reply["order"]["id"]
            self.line_of[oid] = o.line
            self.pending[oid] = Dish(oid, o.table, o.ready_at)
            self.created += 1

    def _free_robots(self) -> int:
        idle = sum(
            1
            for r in self.robots.values()
            if r["status"] == "Awaiting" and r["current_task"] is None
        )
        return idle - sum(1 for t in self.tasks.values() if t["status"] == "queued")

    def _carts(self, now: float) -> list[list[int]]:
        from serveur.scheduler import Dish, fifo_cart, suggest_carts

        free = self._free_robots()
        if free < 1 or not self.pending:
            return []
        dishes = list(self.pending.values())
        if self.policy == "baseline":
            carts: list[list[int]] = []
            for _ in range(free):
                cart = fifo_cart(dishes, self.opts.capacity)
                if not cart:
                    break
                carts.append(cart)
                dishes = [d for d in dishes if d.id not in set(cart)]
            return carts
        horizon = now + self.opts.lookahead
        coming = [
            Dish(-1 - i, o.table, o.ready_at)
            for i, o in enumerate(self.log[self.created :])
            if o.ready_at <= horizon
        ]
        return suggest_carts(
            dishes,
            free,
            self.distance,
            now=now,
            origin=self._origin(),
            capacity=self.opts.capacity,
            coming=coming,
            hold=self.opts.hold,
            hold_max=self.opts.hold_max,
            busy=self._busy(now),
            rank=self.opts.rank,
        )

    async def _staff(self) -> None:
        """The pass, in simulated-time order: dishes appear, then staff decide on carts.

        One loop does both so that what is on the pass at a decision is a function of the
        decision's simulated time (every dish of the log ready by then), not of how the
        kitchen's and the staff's requests happened to interleave on the event loop. Staff
        look again at each dish's ready time, whenever a robot changes status, and every
        5 s (a held table's hold running out).
        """
        assert self.client is not None
        while not self.finished.is_set():
            nxt = self.log[self.created].ready_at if self.created < len(self.log) else math.inf
            delay = min(nxt - self.now(), 5.0)
            self.wake.clear()
            if delay > 0:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self.wake.wait(), self.clock.wall(delay))
            t = self.now()
            if nxt <= t:
                await self._create_due(t)
                t = max(nxt, self.log[self.created - 1].ready_at)
            for cart in self._carts(t):
                for oid in cart:
                    del self.pending[oid]
                    self.carted.add(oid)
                for i in range(0, len(cart), _MAX_CART):  # the protocol's limit per cart
                    reply = await self.client.call(
                        "create", type="task", orders=cart[i : i + _MAX_CART]
                    )
                    for task in reply["tasks"]:
                        self.tasks.setdefault(task["id"], task)

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
            frac = min(1.0, len(self.delivered) / max(1, len(self.log)))
            bar = "#" * int(frac * 30)
            h, m = divmod(int(t) // 60, 60)
            eh, em = divmod(int(end) // 60, 60)
            busy = sum(1 for r in self.robots.values() if r["status"] != "Awaiting")
            line = (
                f"{label:<9} [{bar:<30}] {len(self.delivered)}/{len(self.log)} delivered"
                f"  service {h:d}:{m:02d}/{eh:d}:{em:02d}  robots busy {busy}/{len(self.robots)}"
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
        from serveur.core import CoreConfig
        from serveur.robot_sim import start_simulation
        from serveur.sessions import SecurityConfig

        opts = self.opts
        nav_map, waypoints, map_path = _load_world(opts.map_path)
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
        )
        # Every waypoint's distance field before the service opens: a robot's first goal at a
        # spot would otherwise wait for it (40-80 ms of CPU, in the middle of the service).
        await sim.warm_plans([(w.x, w.y) for w in waypoints.values()])
        specs = [
            RobotSpec(r.name, url, homes[i].name, opts.kinematics)
            for i, (r, url) in enumerate(zip(sim.robots, sim.urls, strict=True))
        ]
        # Link timeouts are simulated seconds: at high time scales a 20 ms pause of the event
        # loop (or of the whole process, on a shared machine) is many simulated seconds, so
        # they are kept at >= 2 s of wall time. Nothing here fails on purpose, so they only
        # need to never fire spuriously.
        scale = self._scale
        heartbeat = max(1.0, 2.0 * scale)
        # Accelerated, the replay's cost is rosbridge traffic (~16 messages a robot-second,
        # encoded by the simulator, decoded by the links): nobody watches poses (distances
        # come from the simulator's true poses) and status is only a heartbeat and goal acks,
        # so both are throttled (ms of simulated time) — 2 Hz poses leave the server's arrival
        # checks a pose at most 0.35 m old; status keeps 4 beats per heartbeat period — and
        # the battery, which the server only reports when it moves by 1 %, every 30 s.
        fast = scale >= 10.0 or opts.time_scale is None
        cfg = CoreConfig(
            capacity=opts.capacity,
            policy=self.policy,
            heartbeat=heartbeat,
            ack_timeout=max(2.0, 2.0 * scale),
            # Saved poses are for a crash restart, which a replay never does: every 5 min.
            pose_persist_period=300.0 if opts.time_scale is None else max(5.0, 0.5 * scale),
            moving_pose_ms=500 if fast else 0,
            status_ms=int(min(1000.0, 250.0 * heartbeat)) if fast else 0,
            battery_ms=30_000 if fast else 0,  # 1 % of charge takes minutes
        )
        app = App(
            workdir / f"{self.policy}.db",
            port=0,
            clock=self.clock,
            nav_map=nav_map,
            waypoints=waypoints,
            robots=specs,
            config=cfg,
            # The per-connection rate limit counts wall seconds, but the replay's one client
            # speaks for a whole kitchen and staff in accelerated time: at 200x a rush is
            # hundreds of requests a wall second. Scaled, the limit holds in simulated time.
            # In virtual time a whole service's requests come in half a minute of wall time.
            security=SecurityConfig(
                # Nobody revokes the replay's token from another process: look every 5 min.
                sweep_every=300.0,
                rate=50.0 * (max(1.0, scale) if opts.time_scale else 1000.0),
                burst=200.0 * (max(1.0, scale) if opts.time_scale else 1000.0),
            ),
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
            self.distance = core.distance
            token = await app.issue_token("staff", label="replay")
            ws = await connect(
                app.url, max_size=2**24, additional_headers={"Authorization": f"Bearer {token}"}
            )
            self.client = client = _Client(ws, self.on_update)
            snap = await client.call("data", topics=["robots", "tasks", "orders"])
            for r in snap["data"]["robots"]:
                self._on_robot(r)
            names = [s.name for s in specs]
            for name in names:
                await self._until(partial(self._status_is, name, "Ready"), f"{name} Ready")
                await client.call("control", robot=name, action="auto")
            await self._until(
                lambda: all(self.robots[n]["status"] == "Awaiting" for n in names), "auto"
            )
            self.t0 = float(self.clock.now())
            epoch0 = float(self.clock.epoch())
            bg.append(asyncio.create_task(self._sample(sim, result.paths)))
            if opts.progress:
                bg.append(asyncio.create_task(self._progress(self.policy)))
            self._spawn(self._staff())
            limit = (self.log[-1].ready_at if self.log else 0.0) + opts.overtime
            await asyncio.wait_for(self.finished.wait(), self.clock.wall(limit) + _WAIT)
            if self.failure is not None:
                raise ReplayError(f"the replay failed: {self.failure!r}") from self.failure
            with contextlib.suppress(ReplayError):  # robots drive home: their busy time ends
                await self._until(
                    lambda: all(self.robots[n]["status"] == "Awaiting" for n in names),
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
            if self.client is not None:
                await self.client.close()
            await app.close()
            await sim.close()
        result.wall_seconds = time.perf_counter() - wall0
        result.nav_errors = self.nav_errors
        result.recoveries = self.recoveries
        return result

    async def _collect(
        self, app: Any, result: PolicyResult, epoch0: float, waypoints: dict[str, Any]
    ) -> None:
        """Read the service back from the server's database: its stamps are the truth."""
        from serveur.kinematics import Limits

        vmax = Limits().max_speed
        homes = [r["home"] for r in self.robots.values() if r.get("home")]
        store = app.store
        by_line = {o.line: o for o in self.log}
        robot_of: dict[int, str | None] = {}
        for t in await store.list_tasks():
            stops = t.stops
            robot_of[t.id] = t.robot
            result.trips.append(
                {
                    "id": t.id,
                    "robot": t.robot,
                    "status": t.status.value,
                    "tables": len(stops),
                    "dishes": sum(len(s.orders) for s in stops),
                    "stops": [s.table for s in stops],
                    "started": None if t.started_at is None else t.started_at - epoch0,
                    "finished": None if t.finished_at is None else t.finished_at - epoch0,
                }
            )
        lines = {oid: line for oid, line in self.line_of.items()}
        for o in await store.list_orders():
            line = lines.get(o.id)
            if line is None:
                continue
            lo = by_line[line]
            travel = min(self.distance(h, o.table) for h in homes) / vmax if homes else 0.0
            wait = None if o.delivered_at is None else o.delivered_at - o.ready_at
            result.orders.append(
                {
                    "line": line,
                    "table": o.table,
                    "dish": o.dish,
                    "ready_at": lo.ready_at,
                    "created": o.ready_at - epoch0,
                    "collected": None if o.delivered_at is None else o.delivered_at - epoch0,
                    "wait": wait,
                    "lower_bound": travel + dish_dwell(self.opts.seed, line),
                    "robot": robot_of.get(o.task_id or -1),
                    "task": o.task_id,
                }
            )
        result.orders.sort(key=lambda d: d["line"])
        result.undelivered = len(self.log) - sum(1 for o in result.orders if o["wait"] is not None)
        for name in sorted(self.robots):
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
            raise ReplayError("a virtual-time replay runs on serveur.vtime.VirtualTimeLoop")
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


def _cmd_replay(ns: argparse.Namespace) -> int:
    root = logging.getLogger()
    level = root.level
    if not ns.verbose:  # every status change is logged at INFO: too much for a whole service
        root.setLevel(logging.ERROR)
    try:
        return _replay_command(ns)
    finally:
        root.setLevel(level)


def _replay_command(ns: argparse.Namespace) -> int:
    opts = ReplayOptions(
        robots=ns.robots,
        time_scale=ns.time_scale,
        map_path=ns.map,
        seed=ns.seed,
        capacity=ns.capacity,
        kinematics=ns.kinematics,
        hold=ns.hold,
        hold_max=ns.hold_max,
        rank=ns.rank,
        progress=not ns.quiet,
    )
    try:
        _, waypoints, _ = _load_world(ns.map)
        tables = {w.name for w in waypoints.values() if w.kind == "table"}
        orders = read_orders(ns.log, tables=tables)
    except (OrderLogError, ReplayError) as exc:
        print(f"serveur replay: {exc}", file=sys.stderr)
        return 2
    policies = list(POLICIES) if ns.policy == "both" else [ns.policy]
    try:
        results = run_replay(orders, opts, policies)
    except ReplayError as exc:
        print(f"serveur replay: {exc}", file=sys.stderr)
        return 1
    from serveur.replay_report import write_outputs

    text = write_outputs(results, ns.log, opts, Path(ns.out))
    print(text, end="")
    print(f"report, summary and plots in {ns.out}/")
    return 0 if all(r.undelivered == 0 for r in results.values()) else 1


def add_replay_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur replay`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "replay",
        help="replay an order log through the server and simulated robots",
        description="Run the real server and N simulated robots on one accelerated clock, "
        "feed the log's dishes at their times, play staff and guests, and write report.json, "
        "summary.txt and PNG plots to --out. Exit 1 if any dish was left undelivered.",
    )
    p.add_argument("log", help="order log CSV (ready_at,table,dish)")
    p.add_argument("--robots", type=int, default=3, help="simulated robots (default 3)")
    p.add_argument(
        "--time-scale",
        type=float,
        default=None,
        help="follow the wall clock, this many times faster (default: virtual time, as fast "
        "as the CPU allows and deterministic)",
    )
    p.add_argument("--policy", choices=[*POLICIES, "both"], default="serveur")
    p.add_argument("--map", default=None, help="map YAML (waypoints: <stem>_waypoints.json)")
    p.add_argument("--seed", type=int, default=0, help="robots' and guests' seed (default 0)")
    p.add_argument("--capacity", type=int, default=4, help="tables per tray (default 4)")
    p.add_argument("--kinematics", choices=["omni", "diff"], default="omni")
    p.add_argument(
        "--hold",
        type=float,
        default=10.0,
        help="serveur staff: seconds a table may wait for its next dish (default 10)",
    )
    p.add_argument(
        "--hold-max",
        type=float,
        default=60.0,
        help="serveur staff: ... growing to this as tables queue (default 60; = --hold: fixed)",
    )
    p.add_argument(
        "--rank",
        choices=["fifo", "wspt", "best"],
        default="best",
        help="serveur staff: tables first-ready, by plates per robot-second, or the better "
        "(default best)",
    )
    p.add_argument("--out", default="replay-out", help="output directory (default replay-out)")
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(func=_cmd_replay, is_async=False)
