"""A dinner service during which the server is SIGKILLed again and again.

Used by ``tests/store/test_crash.py`` (bounded, for CI) and ``bench/crash.py`` (longer,
configurable).

Three actors share one event loop, the server runs in its own process:

* the **robots**: ``start_simulation`` in this process, time-scaled, never restarted — as in
  a restaurant, the robots keep driving while the server is down;
* the **staff**: a tablet that (re)connects whenever the server is up, sends the kitchen's
  carts one after another (orders and carts carry idempotency keys, so a request whose
  reply was lost is simply sent again), presses "food collected" at every table and
  "continue" on a robot in Error;
* the **killer**: at seeded kill points it SIGKILLs the server, checks the database, restarts
  the server on the same file and port, and checks it again.

A kill point is "after the next *n* updates the server pushes (the state changes it commits),
or after *t* wall seconds if sooner", *n* and *t* drawn from the seed; n = 0 kills the server
while it is still starting its robot links. Tying kills to updates lands them right after
commits, in the middle of multi-step work (a trip taken but not yet driven, a stop served but
the trip not yet moved on), which is where a crash can do damage.

Checks (tests/invariants.py): after each kill, every order in exactly one consistent state,
no delivery repeated or undone; after each restart, in addition, each robot's status agrees
with its trip. At the end: every order delivered exactly once, robots at home where the
simulator says they physically are, ``PRAGMA integrity_check`` ok, and a clean SIGTERM exit.
"""

from __future__ import annotations

import asyncio
import contextlib
import math
import random
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import websockets

from serveur.clock import ScaledClock
from serveur.maps.mapio import demo_map_path
from serveur.maps.navigation import load_demo
from serveur.robot_sim import Simulation, start_simulation
from tests import invariants
from tests.conftest import Client
from tests.subprocess_server import ServerProcess, close_quietly, staff_client

TABLES = ["T1", "T2", "T3", "T5", "T6", "T7", "T9", "T10", "T11", "T4", "T8", "T12"]


class ServerGone(Exception):
    """The connection to the server closed (it was killed): reconnect when it is back."""


@dataclass
class CrashConfig:
    seed: int = 1
    kills: int = 20
    robots: int = 2
    carts: int = 8
    cart_size: int = 3
    time_scale: float = 10.0
    max_updates: int = 12  # a kill point waits for 0..max_updates pushed updates...
    max_wait: float = 1.2  # ...or this many wall seconds (drawn in [0.1, max_wait])
    finish_timeout: float = 60.0  # wall seconds for the service to end after the last kill


@dataclass
class CrashReport:
    kills: int = 0
    checks: int = 0
    orders: int = 0
    delivered: int = 0
    wall: float = 0.0
    integrity: str = ""
    kill_points: list[str] = field(default_factory=list)
    delivered_at_kill: list[int] = field(default_factory=list)


async def call(c: Client, verb: str, **fields: Any) -> dict[str, Any]:
    """``c.call`` that fails fast with ServerGone when the server dies mid-request."""
    req = asyncio.ensure_future(c.call(verb, **fields))
    try:
        done, _ = await asyncio.wait({req, c._reader}, return_when=asyncio.FIRST_COMPLETED)
    except BaseException:
        req.cancel()
        raise
    if req in done and not req.cancelled() and req.exception() is None:
        return req.result()
    req.cancel()
    with contextlib.suppress(BaseException):
        await req
    raise ServerGone


async def wait_frames(c: Client, n: int, timeout: float | None = None) -> None:
    """Until ``c`` has received more than ``n`` frames; ServerGone if the connection ends."""
    wait = asyncio.ensure_future(c.until(lambda: len(c.frames) > n, timeout or 3600.0))
    try:
        done, _ = await asyncio.wait({wait, c._reader}, return_when=asyncio.FIRST_COMPLETED)
    finally:
        wait.cancel()
        with contextlib.suppress(BaseException):
            await wait
    if wait not in done:
        raise ServerGone


class Staff:
    """The kitchen and the waiters: carts in order, food collected, failures continued."""

    def __init__(self, cfg: CrashConfig, server: ServerProcess, up: asyncio.Event) -> None:
        self.cfg = cfg
        self.server = server
        self.up = up
        self.robots = [f"r{i + 1}" for i in range(cfg.robots)]
        n = cfg.carts * cfg.cart_size
        self.dishes = [(f"dish{k}", TABLES[k % len(TABLES)]) for k in range(n)]
        self.order_ids: dict[int, int] = {}  # dish index -> order id
        self.carts_sent = 0
        self.done = asyncio.Event()

    async def run(self) -> None:
        while True:
            await self.up.wait()
            try:
                c = await staff_client(self.server)
            except (OSError, websockets.exceptions.WebSocketException):
                self.up.clear()  # killed between "up" and our connect: wait for the restart
                continue
            try:
                if await self.session(c):
                    return
            except ServerGone:
                pass
            finally:
                await c.close()

    async def session(self, c: Client) -> bool:
        reply = await call(c, "data", topics=["robots", "orders", "tasks"])
        if reply["servermsg"] != "ok":
            return False
        while True:
            seen = len(c.frames)
            for name in self.robots:
                status = c.robot(name).get("status")
                verb = {"Ready": "control", "Delivered": "next", "Error": "continue"}.get(
                    status or ""
                )
                if verb == "control":
                    await call(c, verb, robot=name, action="auto")
                elif verb is not None:
                    await call(c, verb, robot=name)
            queued = [t for t in c.records.get("tasks", {}).values() if t["status"] == "queued"]
            if not queued and self.carts_sent < self.cfg.carts:
                await self.send_cart(c, self.carts_sent)
                self.carts_sent += 1
                continue
            if self.finished(c):
                self.done.set()
                return True
            await wait_frames(c, seen)

    async def send_cart(self, c: Client, j: int) -> None:
        size = self.cfg.cart_size
        for k in range(j * size, (j + 1) * size):
            dish, table = self.dishes[k]
            rep = await call(c, "create", type="order", dish=dish, table=table, key=f"o{k}")
            assert rep["servermsg"] == "ok", rep
            self.order_ids[k] = rep["order"]["id"]
        ids = [self.order_ids[k] for k in range(j * size, (j + 1) * size)]
        rep = await call(c, "create", type="task", orders=ids, key=f"cart{j}")
        assert rep["servermsg"] == "ok", rep
        for t in rep["tasks"]:
            c._apply("tasks", t)

    def finished(self, c: Client) -> bool:
        """Every cart sent, no order live (the snapshot lists every pending and assigned one),
        every robot home and waiting."""
        if self.carts_sent < self.cfg.carts:
            return False
        orders = c.records.get("orders", {})
        live = [
            i
            for i in self.order_ids.values()
            if orders.get(i, {}).get("status") not in (None, "delivered")
        ]
        return not live and all(c.robot(n).get("status") == "Awaiting" for n in self.robots)


async def kill_point(server: ServerProcess, rng: random.Random, cfg: CrashConfig) -> str:
    """Wait for the seeded kill point; describe it."""
    n = rng.randint(0, cfg.max_updates)
    limit = rng.uniform(0.1, cfg.max_wait)
    if n == 0:
        return "at start-up"
    try:
        obs = await staff_client(server)
    except (OSError, websockets.exceptions.WebSocketException):
        return "at start-up (no connection yet)"
    try:
        await call(obs, "data", topics=["robots", "orders", "tasks"])
        mark = len(obs.frames)
        with contextlib.suppress(AssertionError, ServerGone):
            await wait_frames(obs, mark + n - 1, timeout=limit)
        return f"after {len(obs.frames) - mark} updates"
    except ServerGone:
        return "server gone"
    finally:
        await obs.close()


async def run_crash(workdir: Path, cfg: CrashConfig, log: Any = None) -> CrashReport:
    """Run the service with ``cfg.kills`` SIGKILLs; raise AssertionError on any violation."""
    t0 = time.monotonic()
    rng = random.Random(cfg.seed)
    report = CrashReport()
    clock = ScaledClock(cfg.time_scale)
    sim: Simulation = await start_simulation(
        cfg.robots, port=0, map_path=demo_map_path(), clock=clock, seed=cfg.seed
    )
    robots = {r.name: url for r, url in zip(sim.robots, sim.urls, strict=True)}
    server = ServerProcess(workdir / "serveur.db", robots, time_scale=cfg.time_scale)
    up = asyncio.Event()
    staff = Staff(cfg, server, up)
    staff_task: asyncio.Task[None] | None = None
    try:
        await server.start()
        up.set()
        staff_task = asyncio.create_task(staff.run())
        delivered: set[int] = set()
        for i in range(cfg.kills):
            where = await kill_point(server, rng, cfg)
            up.clear()
            await server.kill()
            report.kills += 1
            snap = invariants.read(server.db)
            invariants.check_deliveries(snap, delivered)
            delivered = snap.delivered()
            report.kill_points.append(where)
            report.delivered_at_kill.append(len(delivered))
            await server.start()
            snap = invariants.read(server.db)
            invariants.check_deliveries(snap, delivered)
            check_restarted_robots(snap)
            report.checks += 2
            if log is not None:
                log(f"kill {i + 1}: {where}; {len(delivered)} orders delivered so far")
            up.set()
            if staff_task.done():
                staff_task.result()  # a staff assertion failed: report it now
        try:
            await asyncio.wait_for(asyncio.shield(staff_task), cfg.finish_timeout)
        except TimeoutError:
            raise AssertionError(
                "the service did not finish:\n" + "\n".join(list(server.output)[-30:])
            ) from None
        # Robots are home, where they physically are (the simulator's true pose).
        _, waypoints = load_demo()
        for i, r in enumerate(sim.robots):
            home = waypoints[f"home{i + 1}"]
            assert math.hypot(r.pose[0] - home.x, r.pose[1] - home.y) < 0.5, (r.name, r.pose)
        assert await server.terminate() == 0
        snap = invariants.read(server.db)
        invariants.check_deliveries(snap, delivered)
        invariants.check_robots(snap)
        report.orders = len(snap.orders)
        report.delivered = len(snap.delivered())
        assert report.orders == len(staff.dishes)  # resends created nothing twice
        assert report.delivered == report.orders  # none lost
        assert all(snap.deliveries[i] == 1 for i in snap.orders)  # none delivered twice
        report.integrity = invariants.integrity(server.db)
        assert report.integrity == "ok", report.integrity
    finally:
        if staff_task is not None:
            staff_task.cancel()
            with contextlib.suppress(BaseException):
                await staff_task
        await close_quietly(server.close, sim.close)
    report.wall = time.monotonic() - t0
    return report


def check_restarted_robots(snap: invariants.Snapshot) -> None:
    """Robot statuses right after a restart: reconciled, except a dispatch that a robot
    whose link is already back may have started (its trip taken, its status not yet
    Delivering: two transactions)."""
    for name, r in snap.robots.items():
        if r["status"] == "Awaiting" and r["current_task"] is not None:
            r = dict(r, status="Delivering")
        invariants.check_robots(
            invariants.Snapshot(snap.orders, snap.tasks, snap.stops, {name: r}, snap.deliveries)
        )
