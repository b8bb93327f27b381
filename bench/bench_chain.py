"""The chain's shipper on the Pi budget: what sending a site's events to the centre costs.

Issue 34 numbers every event a site records in the site's outbox (migration 013, in the
event's own transaction: :func:`serveur.store.rows.add_event`) and ships the outbox to the
chain's broker over MQTT QoS 1 (:class:`serveur.chain.shipper.Shipper`), from which the centre
(:class:`serveur.hq.consumer.Consumer`) stores it. Everything runs on this host, on loopback:

* a real Mosquitto behind TLS with the production ACL and a password per user
  (tests/chain/broker.py's ``ChainBroker``, the chain's tests' broker);
* **the site**: a child process of its own (this file with ``--child``) that opens a SQLite
  store (:class:`~serveur.store.sqlite.store.SQLiteStore`, a fresh file each time) and
  records events with ``store.events.add_event`` (the real write path, the outbox number
  included), with or without a ``Shipper`` as ``serveur run --chain`` starts it (``poll``
  1 s, ``spacing`` 0.25 s, ``heartbeat`` 30 s). The child is confined to ``--quota`` of one
  core (25 % by default: a cgroup v1 ``cpu`` quota, bench/bench_camera.py's ``limit``,
  weighted as the deployed ``Nice=-5``, as bench/bench_pi.py and bench/bench_till.py do);
* **the centre**: a ``Consumer`` and an ``HqStore`` on a SQLite file in this process (not
  confined: the centre is a server elsewhere), its ``take`` timed.

Three parts:

1. **Numbering** (site alone, no shipper): ``--pairs`` pairs of events, 50 pairs a second,
   each pair one ``store.events.add_event`` (INSERT, outbox head +1, its number read, outbox
   row INSERT, the event read back) and one event written as before migration 013 (the same
   transaction without the three outbox statements), alternating which goes first. Per event:
   the site process's CPU (``time.process_time``: the loop and aiosqlite's thread) and the
   wall time of the call; medians and p99.

2. **A busy service** (``--rate`` events a second, Poisson, ``--seed``, for ``--duration`` s,
   after ``--idle`` s with no event): the same child twice, the shipper **off** then **on**.
   The site's CPU (``getrusage``, every thread) over the idle window and over the busy one,
   ``add_event`` p50 / p99, the quota's throttling; with the shipper on, each event's
   **latency to the centre**: from ``add_event`` returning at the site (its commit) to the
   centre's ``take`` returning with that number stored (its commit), both on this host's wall
   clock. A third run wakes the shipper after each event, as ``serveur run`` does (its
   publisher's flush of new events calls ``Shipper.wake()``); the second, poll only, shows
   what a shipper that only looks every ``poll`` would cost and take.

3. **Catch-up after a day offline**: a site database holding ``--backlog`` events never sent
   (written with ``rows.add_event``, numbered as the site numbers them, 1,000 to a
   transaction, their times spread over 12 hours), the broker and the centre up; the site
   starts its shipper at t0. Measured: the time until the centre has stored them all, events
   a second, the site's CPU meanwhile (/proc, under the quota), the broker's and the centre's,
   and how late a 10 ms sleep wakes on the site's loop (what a request arriving during the
   catch-up would wait; the probe's own wake-ups count in the site's CPU).

The rate: a replayed dinner (``serveur replay``'s service in virtual time: 2 h of
``generate_orders`` at 600 dishes an hour, the rate bench_pi.py calls a busy service, on the
demo's 16 tables, 5 robots, calls on) recorded 6,745 events for 1,166 dishes, 5.8 a dish; its
busiest hour 3,394 events (0.9 a second), its busiest minute 97 (1.6 a second). 20 events a
second is 12x that minute: a deliberately heavy service (``--rate 1.7`` is the replayed one).
The backlog: 50,000 events are 8,600 dishes at 5.8 a dish, 14 hours at 600 dishes an hour: a
long day of a large restaurant (bench_backup.py's year of a busy restaurant is ~3,000 a day).

Run: ``flock /tmp/bench.lock python3 bench/bench_chain.py`` (about 5 minutes with the
defaults; ``--duration 20 --backlog 10000`` for a quick look; ``--json
FILE`` writes everything). Loopback only; every wait is bounded; the children run in process
groups of their own and are killed, and the quota groups removed, however the bench ends;
the broker is stopped with it.
"""

from __future__ import annotations

import argparse
import asyncio
import atexit
import bisect
import collections
import contextlib
import json
import math
import os
import random
import resource
import signal
import sqlite3
import statistics
import sys
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.chain.broker
sys.path.insert(1, str(Path(__file__).resolve().parent))  # bench_camera, bench_pi

from serveur.chain.address import ChainAddress
from serveur.domain import EventRecord
from serveur.store import rows
from serveur.store.checks import to_json
from serveur.store.sql import Tx, one
from serveur.store.sqlite.store import SQLiteStore

WAIT = 30.0  # seconds anything that should happen at once may take before the bench gives up
#: One site per part (the centre keeps each site's stream: a second part's numbers from 1 would
#: be duplicates of the first's).
SITE_BUSY, SITE_WAKE, SITE_DAY = "bistro", "cafe", "brasserie"
USERS = {"hq": "bench-hq-pw", SITE_BUSY: "bistro-pw", SITE_WAKE: "cafe-pw", SITE_DAY: "day-pw"}
SELF = Path(__file__).resolve()
PAIRS_PER_S = 50.0  # pace of part 1: well under the quota, so each call is timed alone

# -- the events a service records (shaped as a replayed service's) --------------------------

#: (kind, share) of a replayed dinner's events (serveur replay, 2 h at 600 dishes/h, 16 tables,
#: 5 robots, calls on: 6,745 events for 1,166 dishes); the rarer kinds are folded into these.
MIX: tuple[tuple[str, float], ...] = (
    ("robot.status", 0.27),
    ("order.ready", 0.175),
    ("order.created", 0.175),
    ("stop.arrived", 0.06),
    ("stop.done", 0.06),
    ("task.dishes_added", 0.055),
    ("task.created", 0.05),
    ("task.started", 0.05),
    ("task.finished", 0.05),
    ("call.opened", 0.015),
    ("call.answered", 0.015),
    ("alert.raised", 0.01),
    ("alert.cleared", 0.01),
    ("call.escalated", 0.005),
)
DISHES = ["Nasi Lemak", "Teh Tarik", "Laksa", "Satay", "Char Kway Teow", "Crème brûlée"]
STATUSES = ["Ready", "Loading", "Delivering", "Returning", "Charging"]

Event = tuple[str, str | None, int | None, int | None, dict[str, Any]]


def service_event(rng: random.Random, i: int) -> Event:
    """One event as the server records it: (kind, robot, task_id, order_id, data), the data
    shaped and sized as the replayed service's (68 bytes of JSON on average there)."""
    kind = rng.choices([k for k, _ in MIX], [w for _, w in MIX])[0]
    robot = f"r{rng.randint(1, 5)}"
    table = f"T{rng.randint(1, 16)}"
    task, order = 1 + i // 6, 1 + i // 6
    if kind == "robot.status":
        return (
            kind,
            robot,
            None,
            None,
            {
                "event": "status",
                "mode": "auto",
                "odometer": round(rng.uniform(0, 900), 1),
                "status": rng.choice(STATUSES),
            },
        )
    if kind == "order.created":
        return (
            kind,
            None,
            None,
            order,
            {
                "dish": rng.choice(DISHES),
                "key": f"pos-{i}",
                "quantity": 1,
                "status": "ordered",
                "table": table,
            },
        )
    if kind == "order.ready":
        return kind, None, None, order, {"by": "token:1", "from": "ordered", "to": "pending"}
    if kind.startswith("stop."):
        return kind, robot, task, None, {"seq": rng.randint(0, 3), "table": table}
    if kind.startswith("task."):
        return kind, robot, task, None, {"stops": [{"orders": [order], "table": table}]}
    if kind.startswith("call."):
        return (
            kind,
            None,
            None,
            None,
            {"call": i, "kind": "plates", "source": "robot", "table": table},
        )
    return (
        kind,
        None,
        None,
        None,
        {
            "alert": i,
            "kind": "waiting_at_table",
            "message": f"{robot} waiting at {table}",
            "subject": robot,
        },
    )


async def plain_add_event(store: SQLiteStore, ev: Event, now: float) -> EventRecord:
    """``store.events.add_event`` as it was before migration 013: the same checks, the same
    transaction, the events row and its read-back, without the outbox's three statements."""
    kind, robot, task_id, order_id, data = ev
    store.db.dialect.check_name(kind, "kind")
    to_json(dict(data))

    async def work(tx: Tx) -> EventRecord:
        event_id = await tx.insert(
            "INSERT INTO events (ts, kind, robot, task_id, order_id, data)"
            " VALUES (?, ?, ?, ?, ?, ?)",
            (now, kind, robot, task_id, order_id, to_json(dict(data))),
        )
        row = await one(tx, f"{rows.EVENT} WHERE id = ?", (event_id,))
        assert row is not None
        return rows.event_record(row)

    return await store.db.transact(work, "write")


async def add_event(store: SQLiteStore, ev: Event, now: float) -> EventRecord:
    kind, robot, task_id, order_id, data = ev
    return await store.events.add_event(
        kind, robot=robot, task_id=task_id, order_id=order_id, data=data, now=now
    )


def pct(values: Sequence[float], q: float) -> float:
    s = sorted(values)
    return s[max(0, math.ceil(q / 100 * len(s)) - 1)] if s else math.nan


def cpu_now() -> float:
    """This process's CPU seconds so far, every thread (aiosqlite's included)."""
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime


# -- the site (a child process, under the quota) ---------------------------------------------


async def _line() -> str:
    return (await asyncio.to_thread(sys.stdin.readline)).strip()


def _say(**what: Any) -> None:
    print(json.dumps(what), flush=True)


async def child_numbering(cfg: dict[str, Any]) -> dict[str, Any]:
    rng = random.Random(cfg["seed"])
    async with SQLiteStore(cfg["db"]) as store:
        # Warm both paths (the statements' first preparation, the file's first pages).
        for i in range(20):
            await add_event(store, service_event(rng, i), time.time())
            await plain_add_event(store, service_event(rng, i), time.time())
        _say(ready=True)
        await _line()
        out: dict[str, list[float]] = {"numbered_cpu": [], "numbered_wall": []}
        out |= {"plain_cpu": [], "plain_wall": []}
        next_at = time.monotonic()
        for i in range(cfg["pairs"]):
            order = ("numbered", "plain") if i % 2 == 0 else ("plain", "numbered")
            for which in order:
                ev = service_event(rng, i)
                fn = add_event if which == "numbered" else plain_add_event
                c0, t0 = time.process_time(), time.perf_counter()
                await fn(store, ev, time.time())
                t1, c1 = time.perf_counter(), time.process_time()
                out[f"{which}_cpu"].append(c1 - c0)
                out[f"{which}_wall"].append(t1 - t0)
            next_at += 1.0 / PAIRS_PER_S
            await asyncio.sleep(max(0.0, next_at - time.monotonic()))
        return out


async def child_service(cfg: dict[str, Any]) -> dict[str, Any]:
    from serveur.chain.shipper import Shipper
    from serveur.clock import ScaledClock

    rng = random.Random(cfg["seed"])
    arrivals = random.Random(cfg["seed"] + 1)
    async with SQLiteStore(cfg["db"]) as store:
        shipper = None
        if cfg.get("url"):
            address = ChainAddress.parse(cfg["url"], ca=cfg["ca"])
            shipper = Shipper(store, address, ScaledClock(1.0), heartbeat=30)
            shipper.start()
            await asyncio.wait_for(shipper.connected.wait(), WAIT)
        try:
            # The site's first events (its robots reporting in) before the measure.
            for i in range(10):
                await add_event(store, service_event(rng, i), time.time())
            await asyncio.sleep(2.0)
            _say(ready=True)
            await _line()
            c0, t0 = cpu_now(), time.monotonic()
            await asyncio.sleep(cfg["idle"])
            idle = (cpu_now() - c0) / (time.monotonic() - t0)
            committed: list[tuple[int, float]] = []  # (event id, wall time at commit)
            took: list[float] = []
            c0, t0 = cpu_now(), time.monotonic()
            next_at, end, i = t0, t0 + cfg["duration"], 0
            while True:
                next_at += arrivals.expovariate(cfg["rate"])
                if next_at >= end:
                    break
                await asyncio.sleep(max(0.0, next_at - time.monotonic()))
                a = time.perf_counter()
                rec = await add_event(store, service_event(rng, 10 + i), time.time())
                b = time.perf_counter()
                if shipper is not None and cfg.get("wake"):
                    shipper.wake()
                committed.append((rec.id, time.time()))
                took.append(b - a)
                i += 1
            await asyncio.sleep(max(0.0, end - time.monotonic()))
            window = time.monotonic() - t0
            busy = (cpu_now() - c0) / window
            if shipper is not None:
                # Until the centre says it has it all (the retained "confirmed"), bounded.
                deadline = time.monotonic() + WAIT
                while time.monotonic() < deadline:
                    state = await store.outbox.state()
                    if state.confirmed >= state.head:
                        break
                    await asyncio.sleep(0.1)
            return {
                "idle_cpu": idle,
                "busy_cpu": busy,
                "window_s": window,
                "events": len(committed),
                "committed": committed,
                "add_event_s": took,
                "published_batches": shipper.published if shipper else 0,
            }
        finally:
            if shipper is not None:
                await shipper.close()


async def child_catchup(cfg: dict[str, Any]) -> dict[str, Any]:
    from serveur.chain.shipper import Shipper
    from serveur.clock import ScaledClock

    async with SQLiteStore(cfg["db"]) as store:
        state = await store.outbox.state()
        address = ChainAddress.parse(cfg["url"], ca=cfg["ca"])
        shipper = Shipper(store, address, ScaledClock(1.0), heartbeat=30)
        _say(ready=True, head=state.head, unsent=state.unsent)
        await _line()
        late: list[float] = []
        probe = asyncio.create_task(_late(late))
        c0 = cpu_now()
        shipper.start()
        try:
            await _line()  # the bench says when the centre has it all
            return {
                "cpu_s": cpu_now() - c0,
                "published_batches": shipper.published,
                "loop_late_s": late,
            }
        finally:
            probe.cancel()
            await shipper.close()


async def _late(out: list[float]) -> None:
    """How late a 10 ms sleep wakes on the site's loop: what a request arriving then would
    wait for the shipper's turn (and the quota) before the server could read it."""
    while True:
        t0 = time.monotonic()
        await asyncio.sleep(0.01)
        out.append(time.monotonic() - t0 - 0.01)


async def child_main(cfg: dict[str, Any]) -> None:
    fn = {"numbering": child_numbering, "service": child_service, "catchup": child_catchup}
    result = await fn[cfg["mode"]](cfg)
    _say(result=result)


# -- the bench (this process: the broker's owner, the centre) --------------------------------

_GROUPS: set[int] = set()  # children's process groups: killed at exit whatever happens
_CGROUPS: set[int] = set()  # children put under a quota: their groups removed at exit


def _unlimit(pid: int) -> None:
    from bench_camera import CGROUP, unlimit

    group = CGROUP / f"serveur-bench-{os.getpid()}-{pid}"
    for _ in range(40):
        unlimit(pid)
        if not group.exists():
            break
        time.sleep(0.05)
    _CGROUPS.discard(pid)


def _cleanup() -> None:
    for pgid in list(_GROUPS):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(pgid, signal.SIGKILL)
        _GROUPS.discard(pgid)
    for pid in list(_CGROUPS):
        _unlimit(pid)


atexit.register(_cleanup)


class Site:
    """One child process: spawned, confined, told to go, its result read."""

    def __init__(self, cfg: dict[str, Any], quota: float, shares: int, log: Path) -> None:
        self.cfg, self.quota, self.shares, self.log = cfg, quota, shares, log
        self.proc: asyncio.subprocess.Process | None = None
        self.quota_applied = "not started"
        self.hello: dict[str, Any] = {}

    async def start(self) -> None:
        from bench_camera import limit
        from bench_pi import _weigh

        with self.log.open("ab") as err:
            self.proc = await asyncio.create_subprocess_exec(
                sys.executable,
                str(SELF),
                "--child",
                json.dumps(self.cfg),
                stdin=asyncio.subprocess.PIPE,
                stdout=asyncio.subprocess.PIPE,
                stderr=err,
                start_new_session=True,
            )
        _GROUPS.add(self.proc.pid)
        _CGROUPS.add(self.proc.pid)
        self.quota_applied = limit(self.proc.pid, self.quota)
        if self.quota_applied.endswith("of a core"):
            _weigh(self.proc.pid, self.shares)
        self.hello = await self._read()
        if not self.hello.get("ready"):
            raise RuntimeError(f"site child: {self.hello}")

    async def _read(self) -> dict[str, Any]:
        assert self.proc is not None and self.proc.stdout is not None
        line = await asyncio.wait_for(self.proc.stdout.readline(), 4 * WAIT)
        if not line:
            raise RuntimeError(f"the site child ended:\n{self.tail()}")
        return dict(json.loads(line))

    def say(self, what: str = "go") -> None:
        assert self.proc is not None and self.proc.stdin is not None
        self.proc.stdin.write(what.encode() + b"\n")

    async def result(self, within: float) -> dict[str, Any]:
        got = await asyncio.wait_for(self._read(), within)
        return dict(got["result"])

    def cpu_stat(self) -> dict[str, int]:
        from bench_pi import _cpu_stat

        assert self.proc is not None
        return _cpu_stat(self.proc.pid)

    def cpu_seconds(self) -> float:
        from bench_camera import cpu_seconds

        assert self.proc is not None
        return cpu_seconds(self.proc.pid)

    def tail(self, n: int = 20) -> str:
        if not self.log.exists():
            return ""
        return "\n".join(self.log.read_text(errors="replace").splitlines()[-n:])

    async def stop(self) -> None:
        proc = self.proc
        if proc is None:
            return
        if proc.returncode is None:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(proc.wait(), 10)
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(proc.pid, signal.SIGKILL)
        _GROUPS.discard(proc.pid)
        if proc.returncode is None:
            await asyncio.wait_for(proc.wait(), 5)
        _unlimit(proc.pid)


def _throttled(before: dict[str, int], after: dict[str, int]) -> dict[str, float]:
    d = {k: after.get(k, 0) - before.get(k, 0) for k in after}
    periods = max(1, d.get("nr_periods", 0))
    return {
        "periods": d.get("nr_periods", 0),
        "throttled_pct": round(100 * d.get("nr_throttled", 0) / periods, 1),
        "throttled_s": round(d.get("throttled_time", 0) / 1e9, 2),
    }


def _hq_class() -> type:
    from serveur.hq.store import HqStore

    class TimedHq(HqStore):
        """The centre's store, each ``take`` timed: (wall time at commit, stored) per site."""

        def __init__(self, db: Any) -> None:
            super().__init__(db)
            self.stored: dict[str, list[tuple[float, int]]] = collections.defaultdict(list)
            self.took: list[float] = []
            self.changed = asyncio.Event()

        async def take(
            self, site: str, first: int, events: Sequence[EventRecord], now: float
        ) -> int:
            t0 = time.perf_counter()
            stored = await super().take(site, first, events, now)
            self.took.append(time.perf_counter() - t0)
            self.stored[site].append((time.time(), stored))
            self.changed.set()
            return stored

        def of(self, site: str) -> int:
            found = self.stored.get(site)
            return found[-1][1] if found else 0

        async def until(self, site: str, n: int, within: float) -> float | None:
            """Wall time the site's ``stored`` reached ``n`` (None: not ``within`` seconds)."""
            deadline = time.monotonic() + within
            while self.of(site) < n:
                left = deadline - time.monotonic()
                if left <= 0:
                    return None
                self.changed.clear()
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self.changed.wait(), left)
            return next(t for t, s in self.stored[site] if s >= n)

    return TimedHq


def _ms(values: Sequence[float], q: float) -> float:
    return round(1e3 * pct(values, q), 1)


async def part_numbering(ns: argparse.Namespace, tmp: Path) -> dict[str, Any]:
    cfg = {"mode": "numbering", "db": str(tmp / "numbering.db"), "pairs": ns.pairs, "seed": 1}
    site = Site(cfg, ns.quota, ns.shares, tmp / "numbering.log")
    try:
        await site.start()
        s0 = site.cpu_stat()
        site.say()
        r = await site.result(ns.pairs / PAIRS_PER_S + 4 * WAIT)
        th = _throttled(s0, site.cpu_stat())
    finally:
        await site.stop()
    out: dict[str, Any] = {"quota_applied": site.quota_applied, "pairs": ns.pairs, **th}
    for which in ("numbered", "plain"):
        cpu, wall = r[f"{which}_cpu"], r[f"{which}_wall"]
        out[which] = {
            "cpu_us_p50": round(1e6 * statistics.median(cpu)),
            "cpu_us_mean": round(1e6 * statistics.fmean(cpu)),
            "wall_ms_p50": _ms(wall, 50),
            "wall_ms_p99": _ms(wall, 99),
        }
    return out


async def part_service(
    ns: argparse.Namespace, tmp: Path, hq: Any, broker: Any, name: str
) -> dict[str, Any]:
    ship, wake = name != "off", name == "on, woken"
    site_name = SITE_WAKE if wake else SITE_BUSY
    db = tmp / f"service-{name.replace(', ', '-')}.db"
    cfg: dict[str, Any] = {
        "mode": "service",
        "db": str(db),
        "idle": ns.idle,
        "duration": ns.duration,
        "rate": ns.rate,
        "seed": ns.seed,
    }
    if ship:
        cfg |= {"url": broker.url(site_name), "ca": str(broker.ca), "wake": wake}
    site = Site(cfg, ns.quota, ns.shares, db.with_suffix(".log"))
    try:
        await site.start()
        s0 = site.cpu_stat()
        site.say()
        r = await site.result(ns.idle + ns.duration + 6 * WAIT)
        th = _throttled(s0, site.cpu_stat())
    finally:
        await site.stop()
    out: dict[str, Any] = {
        "shipper": name,
        "quota_applied": site.quota_applied,
        "events": r["events"],
        "window_s": round(r["window_s"], 1),
        "idle_cpu_pct": round(100 * r["idle_cpu"], 2),
        "busy_cpu_pct": round(100 * r["busy_cpu"], 2),
        "add_event_ms_p50": _ms(r["add_event_s"], 50),
        "add_event_ms_p99": _ms(r["add_event_s"], 99),
        "published_batches": r["published_batches"],
        **th,
    }
    if ship:
        seq_of = _seqs(db)
        timeline = hq.stored[site_name]
        times, stored = [t for t, _ in timeline], [s for _, s in timeline]
        lat, missing = [], 0
        for event_id, at in r["committed"]:
            i = bisect.bisect_left(stored, seq_of[event_id])
            if i == len(stored):
                missing += 1
            else:
                lat.append(times[i] - at)
        out["to_hq_ms"] = {
            "n": len(lat),
            "missing": missing,
            "p50": _ms(lat, 50),
            "p95": _ms(lat, 95),
            "p99": _ms(lat, 99),
            "max": _ms(lat, 100),
        }
    return out


def _seqs(db: Path) -> dict[int, int]:
    """event id -> outbox number, from the site's database (read-only, after the child)."""
    with contextlib.closing(sqlite3.connect(f"file:{db}?mode=ro", uri=True)) as c:
        return dict(c.execute("SELECT event_id, seq FROM outbox"))


async def fill(db: Path, n: int, seed: int) -> None:
    """A day's events never sent: ``n`` numbered as the site numbers them, 1,000 a
    transaction (a day records them one by one; the outbox ends up the same)."""
    rng = random.Random(seed)
    t0 = time.time() - 86400.0
    async with SQLiteStore(db) as store:
        for start in range(0, n, 1000):
            evs = [service_event(rng, i) for i in range(start, min(n, start + 1000))]

            async def work(tx: Tx, evs: list[Event] = evs, start: int = start) -> None:
                for j, (kind, robot, task_id, order_id, data) in enumerate(evs):
                    at = t0 + 12 * 3600.0 * (start + j) / n
                    await rows.add_event(
                        tx, kind, at, robot=robot, task_id=task_id, order_id=order_id, data=data
                    )

            await store.db.transact(work, "write")


async def part_catchup(ns: argparse.Namespace, tmp: Path, hq: Any, broker: Any) -> dict[str, Any]:
    from bench_camera import cpu_seconds

    db = tmp / "day.db"
    t = time.monotonic()
    await fill(db, ns.backlog, ns.seed)
    filled_s = time.monotonic() - t
    cfg = {"mode": "catchup", "db": str(db), "url": broker.url(SITE_DAY), "ca": str(broker.ca)}
    site = Site(cfg, ns.quota, ns.shares, tmp / "catchup.log")
    assert broker.proc is not None
    try:
        await site.start()
        head = int(site.hello["head"])
        s0, site0 = site.cpu_stat(), site.cpu_seconds()
        broker0, hq0, took0 = cpu_seconds(broker.proc.pid), time.process_time(), len(hq.took)
        t0w, t0 = time.time(), time.monotonic()
        site.say()
        done_at = await hq.until(SITE_DAY, head, ns.backlog / 200.0 + 4 * WAIT)
        t1 = time.monotonic()
        site1, s1 = site.cpu_seconds(), site.cpu_stat()
        broker1, hq1 = cpu_seconds(broker.proc.pid), time.process_time()
        site.say("stop")
        r = await site.result(2 * WAIT)
        th = _throttled(s0, s1)
    finally:
        await site.stop()
    if done_at is None:
        raise RuntimeError(f"the centre stored {hq.of(SITE_DAY)} of {head} in time")
    took = done_at - t0w
    first_at, first_n = hq.stored[SITE_DAY][0]
    first = first_at - t0w
    steady = (head - first_n) / (done_at - first_at) if done_at > first_at else math.nan
    late = r["loop_late_s"]
    return {
        "quota_applied": site.quota_applied,
        "events": head,
        "fill_s": round(filled_s, 1),
        "first_stored_s": round(first, 2),
        "all_stored_s": round(took, 2),
        "events_per_s": round(head / took),
        "steady_events_per_s": round(steady),
        "loop_late_ms": {"p50": _ms(late, 50), "p99": _ms(late, 99), "max": _ms(late, 100)},
        "site_cpu_pct": round(100 * (site1 - site0) / (t1 - t0), 1),
        "site_cpu_s": round(r["cpu_s"], 2),
        "site_cpu_ms_per_1000": round(1e6 * r["cpu_s"] / head, 1),
        "broker_cpu_pct": round(100 * (broker1 - broker0) / (t1 - t0), 1),
        "hq_cpu_pct": round(100 * (hq1 - hq0) / (t1 - t0), 1),
        "hq_take_ms_p50": _ms(hq.took[took0:], 50),
        "batches": r["published_batches"],
        **th,
    }


def table(res: dict[str, Any], ns: argparse.Namespace) -> str:
    n, off, c = res["numbering"], res["off"], res["catchup"]
    runs = [res[k] for k in ("off", "on", "on, woken") if k in res]
    q = 100 * ns.quota
    lines = [
        f"1. Numbering: {n['pairs']} events each way, site under {n['quota_applied']}",
        "",
        "| add_event | site CPU / event p50 (mean) | wall p50 | wall p99 |",
        "|---|---:|---:|---:|",
    ]
    for label, key in (
        ("with the outbox number (now)", "numbered"),
        ("without (before 013)", "plain"),
    ):
        x = n[key]
        lines.append(
            f"| {label} | {x['cpu_us_p50']} µs ({x['cpu_us_mean']} µs) | {x['wall_ms_p50']} ms"
            f" | {x['wall_ms_p99']} ms |"
        )
    lines += [
        "",
        f"2. A busy service: {ns.rate:g} events/s (Poisson) for {ns.duration:g} s after"
        f" {ns.idle:g} s idle, site under {off['quota_applied']}",
        "",
        "| shipper | events | site CPU idle | site CPU busy | add_event p50 / p99 | throttled"
        " periods, time | to hq p50 / p95 / p99 / max |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for r in runs:
        h = r.get("to_hq_ms")
        to_hq = f"{h['p50']} / {h['p95']} / {h['p99']} / {h['max']} ms" if h else "-"
        lines.append(
            f"| {r['shipper']} | {r['events']} | {r['idle_cpu_pct']} % | {r['busy_cpu_pct']} %"
            f" | {r['add_event_ms_p50']} / {r['add_event_ms_p99']} ms | {r['throttled_pct']} %,"
            f" {r['throttled_s']} s | {to_hq} |"
        )
    lines.append("")
    for r in runs[1:]:
        d_idle = r["idle_cpu_pct"] - off["idle_cpu_pct"]
        d_busy = r["busy_cpu_pct"] - off["busy_cpu_pct"]
        lines.append(
            f"the shipper ({r['shipper']}): idle {d_idle:+.2f} % of a core, busy"
            f" {d_busy:+.2f} % of a core ({100 * d_busy / q:+.1f} % of the {q:g} % quota),"
            f" {r['published_batches']} batches"
        )
    late = c["loop_late_ms"]
    lines += [
        "",
        f"3. Catch-up: {c['events']:,} events unsent, site under {c['quota_applied']}",
        "",
        "| events | first stored | all stored | events/s (after the first batch) | site CPU"
        " | site CPU / 1,000 events | throttled periods, time | site loop late p50 / p99 / max"
        " | broker CPU | hq CPU (this process) |",
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
        f"| {c['events']:,} | {c['first_stored_s']} s | {c['all_stored_s']} s"
        f" | {c['events_per_s']:,} ({c['steady_events_per_s']:,}) | {c['site_cpu_pct']} %"
        f" | {c['site_cpu_ms_per_1000']} ms | {c['throttled_pct']} %, {c['throttled_s']} s"
        f" | {late['p50']} / {late['p99']} / {late['max']} ms | {c['broker_cpu_pct']} %"
        f" | {c['hq_cpu_pct']} % |",
    ]
    return "\n".join(lines)


async def main(ns: argparse.Namespace) -> int:
    from serveur.hq.consumer import Consumer
    from serveur.hq.store import open_hq_db
    from tests.chain.broker import ChainBroker, need_mosquitto

    task = asyncio.current_task()
    assert task is not None
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, task.cancel)
    try:
        need_mosquitto()
    except BaseException as exc:  # pytest's Skipped is no Exception
        print(f"bench_chain: {exc}", file=sys.stderr)
        return 2
    load0, started = os.getloadavg(), time.monotonic()
    res: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="serveur-bench-chain-") as d:
        tmp = Path(d)
        res["numbering"] = await part_numbering(ns, tmp)
        print(json.dumps(res["numbering"]), file=sys.stderr, flush=True)
        with ChainBroker(tmp / "broker", USERS) as broker:
            hq = _hq_class()(open_hq_db(str(tmp / "hq.db")))
            await hq.db.open()
            address = ChainAddress.parse(broker.url("hq"), ca=str(broker.ca))
            consumer = Consumer(hq, address, time.time)
            await consumer.start()
            try:
                await asyncio.wait_for(consumer.connected.wait(), WAIT)
                for name in ("off", "on", "on, woken"):
                    r = await part_service(ns, tmp, hq, broker, name)
                    res[r["shipper"]] = r
                    print(json.dumps(r), file=sys.stderr, flush=True)
                res["catchup"] = await part_catchup(ns, tmp, hq, broker)
                print(json.dumps(res["catchup"]), file=sys.stderr, flush=True)
                res["hq_refused"] = consumer.refused
            finally:
                await consumer.close()
                await hq.db.close()
    load1 = os.getloadavg()
    res["load"] = [load0, load1]
    res["wall_s"] = round(time.monotonic() - started, 1)
    print(table(res, ns))
    print(
        f"\nload average before {load0[0]:.2f}, after {load1[0]:.2f}; {res['wall_s']} s in all;"
        f" the centre refused {res['hq_refused']} payloads"
    )
    if ns.json:
        Path(ns.json).write_text(json.dumps(res, indent=1))  # noqa: ASYNC240 - at the end
    bad = res["hq_refused"] or any(
        r["to_hq_ms"]["missing"] for k, r in res.items() if k in ("on", "on, woken")
    )
    return 1 if bad else 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quota", type=float, default=0.25, help="the site's share of a core")
    ap.add_argument("--rate", type=float, default=20.0, help="events a second in the service")
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of busy service")
    ap.add_argument("--idle", type=float, default=15.0, help="seconds idle before it")
    ap.add_argument("--pairs", type=int, default=500, help="events each way in part 1")
    ap.add_argument("--backlog", type=int, default=50000, help="events unsent in part 3")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--shares", type=int, default=3121, help="the site's cpu.shares (3121: Nice=-5)"
    )
    ap.add_argument("--json")
    ap.add_argument("--child", help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.child:
        asyncio.run(child_main(json.loads(args.child)))
        sys.exit(0)
    try:
        code = asyncio.run(main(args))
    except (asyncio.CancelledError, KeyboardInterrupt):
        print("stopped by a signal: everything it started is stopped", file=sys.stderr)
        code = 130
    finally:
        _cleanup()
    sys.exit(code)
