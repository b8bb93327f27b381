"""Event-loop stalls while waypoints are created in a burst, with simulated robots streaming.

Creating a waypoint plans its path distances to every other waypoint in the background. This
bench measures what that costs the server's event loop and the clients and robots it serves:
N waypoints (default 10) are created in one burst while R simulated robots (default 5) stream
to the server, everything at ``--time-scale`` (default 10, as ``serveur demo`` would run).

Three processes per run, so that the load never shares an interpreter with what it measures:

* **the server** — an in-process :class:`serveur.app.App` (as tests/conftest.py starts one:
  the demo map and waypoints, numpy loaded, so distances are planned in worker threads) plus a
  *stall probe*, a task of the server's own loop that sleeps ``--stall-interval`` (2 ms) again
  and again and records how late it woke: the loop's stalls, measured where they happen;
* **the robots** — ``serveur sim --robots R --time-scale X --port 0`` (a child process);
* **the clients** — this script with ``--client`` (a child process): a probe connection that
  sends the cheapest request of docs/protocol.md (``data`` unsubscribing from ``map``: parsed,
  validated and answered, no database) every ``--period`` (20 ms) on a fixed schedule (open
  loop: a stalled server does not slow the probe down, each request is timed from its own
  send), and a staff connection that watches ``robots`` and sends the burst of ``create``
  ``waypoint`` requests back to back.

The window: ``--baseline`` (5 s) of quiet, the burst, then until every create has replied *and*
the background plans the creates started are done, then ``--tail`` (3 s) more. (Replies come
before the plans end: the window runs to the later of the two, so the plans' stalls are in it.)
Over that window the bench reports the loop's longest and 99th-percentile stall, the probe's
request latency (p50/p99/max), the robot link drops (``link down`` lines of
``serveur.robots.ros1.link``, and robots the clients saw go Offline), the wall time from the
first create sent to the last reply, and when the last plan finished.

Each run is a fresh process (``--runs N`` runs them one after another and prints the medians),
so no cache of an earlier run answers a plan. Everything listens on 127.0.0.1 only, every wait
is bounded and a run stops by itself after ``--max-seconds`` (120 s); the children are stopped
(SIGINT, then killed) when a run ends.

**Targets** (the exit code is 1 when one is not met): the median of the runs' longest stalls
at most ``--max-stall`` (20 ms), no robot link dropped, every probe request answered, every
create answered ok and its plans done.

**The Pi's share of a CPU**: ``--quota 0.25`` confines the server process (its event loop,
the store's thread) to a quarter of one core, a cgroup v1 ``cpu`` group with a
``--quota-period`` of 10 ms (bench/bench_camera.py's helpers use 100 ms; a shorter period
spreads the share as a slower CPU does, instead of letting the server run 25 ms and then
stopping it for 75). The robots, the clients and the plans' child processes stay outside it:
on a Raspberry Pi 4 those children run on another of its four cores. The run reports how often
the group was throttled.

Run: ``python bench/bench_stall.py [--runs 3] [--quota 0.25] [--json out.json]``. Which serveur
is measured is whichever ``import serveur`` finds: put a tree first with
``PYTHONPATH=/path/to/tree`` (the children inherit it); every process prints the ``serveur``
file it imported.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import logging
import math
import os
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection, connect

HOST = "127.0.0.1"
HZ = os.sysconf("SC_CLK_TCK")
_PROBE_FIELDS = {"clientmsg": "data", "topics": ["map"], "unsubscribe": True}
_PLANNED = re.compile(r"^planned \d+ path distances in [\d.]+ s \((?P<how>.+)\)$")


def pct(values: list[float], q: float) -> float:
    """The ``q``-th percentile (nearest rank) of ``values``; NaN if there are none."""
    s = sorted(values)
    return s[max(0, math.ceil(q / 100 * len(s)) - 1)] if s else math.nan


def _emit(event: str, **fields: Any) -> None:
    """One JSON line on stdout: how the children talk to their parent."""
    print(json.dumps({"event": event, **fields}), flush=True)


# -- /proc: load conditions ------------------------------------------------------------------


def _cpu_total() -> tuple[int, int]:
    """(busy, total) jiffies of the whole machine, from /proc/stat."""
    fields = [int(v) for v in Path("/proc/stat").read_text().split("\n", 1)[0].split()[1:]]
    idle = fields[3] + fields[4]  # idle + iowait
    return sum(fields) - idle, sum(fields)


def _proc_cpu(pid: int) -> float:
    """CPU seconds (user + system, every thread) a process has used; NaN once it is gone."""
    try:
        fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    except OSError:
        return math.nan
    return (int(fields[11]) + int(fields[12])) / HZ


def _loadavg() -> list[float]:
    return [float(v) for v in Path("/proc/loadavg").read_text().split()[:3]]


# -- a CPU quota for the server (cgroup v1 cpu) -----------------------------------------------

CGROUP = Path("/sys/fs/cgroup/cpu")


def _quota_group(quota: float, period: float) -> Path:
    """A cgroup v1 ``cpu`` group allowing ``quota`` of a core per ``period`` seconds."""
    group = CGROUP / f"serveur-stall-{os.getpid()}"
    group.mkdir()
    (group / "cpu.cfs_period_us").write_text(str(int(period * 1e6)))
    (group / "cpu.cfs_quota_us").write_text(str(int(quota * period * 1e6)))
    return group


def _throttled(group: Path) -> dict[str, float]:
    """The group's throttling so far: periods, periods throttled, seconds held back."""
    stat = dict(line.split() for line in (group / "cpu.stat").read_text().splitlines())
    return {
        "periods": int(stat["nr_periods"]),
        "throttled": int(stat["nr_throttled"]),
        "throttled_s": int(stat["throttled_time"]) / 1e9,
    }


def _shepherd(group: Path, keep: int, stop: threading.Event, moved: list[int]) -> None:
    """Until ``stop``: move every process but ``keep`` (the server) out of ``group`` to the
    root group: the children the server starts (plans) inherit its group, and on a Pi they
    run on another core. Polls every 5 ms (a child's interpreter takes longer to start)."""
    while not stop.wait(0.005):
        with contextlib.suppress(OSError):
            for pid in (group / "cgroup.procs").read_text().split():
                if int(pid) != keep:
                    with contextlib.suppress(OSError):
                        (CGROUP / "cgroup.procs").write_text(pid)
                        moved.append(int(pid))


# -- the clients' process --------------------------------------------------------------------


class _Conn:
    """One client websocket: replies matched by id with their arrival time; robots' statuses
    (from snapshots and ``robots`` updates) and when one went Offline."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self._ids = itertools.count(1)
        self._pending: dict[int, asyncio.Future[tuple[float, dict[str, Any]]]] = {}
        self.status: dict[str, str] = {}
        self.offline: list[tuple[float, str]] = []
        self._changed = asyncio.Event()
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                now = time.monotonic()
                if '"servermsg":"update"' in frame:
                    if '"topic":"robots"' in frame:
                        self._robot(now, json.loads(frame)["data"])
                    continue
                msg = json.loads(frame)
                data = msg.get("data")
                if isinstance(data, dict):
                    for rec in data.get("robots") or []:
                        self._robot(now, rec)
                fut = self._pending.pop(msg.get("id"), None)
                if fut is not None and not fut.done():
                    fut.set_result((now, msg))

    def _robot(self, now: float, rec: dict[str, Any]) -> None:
        name, status = str(rec["name"]), str(rec["status"])
        if status == "Offline" and self.status.get(name, "Offline") != "Offline":
            self.offline.append((now, name))
        self.status[name] = status
        self._changed.set()

    async def send(self, verb: str, **fields: Any) -> asyncio.Future[tuple[float, dict[str, Any]]]:
        """Send a request; the future it returns gets (arrival time, reply)."""
        rid = next(self._ids)
        fut: asyncio.Future[tuple[float, dict[str, Any]]]
        fut = asyncio.get_running_loop().create_future()
        self._pending[rid] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": rid, **fields}))
        return fut

    async def until(self, cond: Any, limit: float) -> None:
        """Wait (at most ``limit`` s) until ``cond()`` holds on the robots' statuses."""

        async def wait() -> None:
            while not cond():
                self._changed.clear()
                await self._changed.wait()

        await asyncio.wait_for(wait(), limit)


async def _probe(conn: _Conn, period: float, stop: asyncio.Event) -> list[list[Any]]:
    """The cheap request every ``period`` s on a fixed schedule (open loop) until ``stop``.

    Returns ``[sent at, latency s or None, ok]`` per request; None: no reply by 2 s after stop.
    """
    rows: list[list[Any]] = []
    waits: list[asyncio.Task[None]] = []

    async def timed(row: list[Any], fut: asyncio.Future[tuple[float, dict[str, Any]]]) -> None:
        at, msg = await fut
        row[1] = at - row[0]
        row[2] = msg.get("servermsg") == "ok"

    due = time.monotonic()
    while not stop.is_set():
        row: list[Any] = [time.monotonic(), None, False]
        rows.append(row)
        waits.append(asyncio.create_task(timed(row, await conn.send("data", **_PROBE_FIELDS))))
        due += period
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(stop.wait(), max(0.0, due - time.monotonic()))
    _, late = await asyncio.wait(waits, timeout=2.0) if waits else (set(), set())
    for task in late:
        task.cancel()
    return rows


async def _client_main() -> None:
    """The ``--client`` process. Its configuration is the first line on stdin, then it takes
    the commands ``burst`` and ``stop`` (or end of input); it answers in JSON lines."""
    cfg = json.loads(await asyncio.to_thread(sys.stdin.readline))
    auth = {"Authorization": f"Bearer {cfg['token']}"}
    opts: dict[str, Any] = {"compression": None, "max_size": 2**24, "additional_headers": auth}
    async with connect(cfg["url"], **opts) as pws, connect(cfg["url"], **opts) as sws:
        probe, staff = _Conn(pws), _Conn(sws)
        robots: list[str] = cfg["robots"]
        poses = [f"pose:{n}" for n in robots] if cfg["watch_poses"] else []
        reply = await asyncio.wait_for(await staff.send("data", topics=["robots", *poses]), 30)
        if reply[1].get("servermsg") != "ok":
            raise RuntimeError(f"subscribe refused: {reply[1]}")
        await staff.until(
            lambda: (
                set(robots) <= staff.status.keys()
                and all(staff.status[n] != "Offline" for n in robots)
            ),
            cfg["ready_limit"],
        )
        stop = asyncio.Event()
        probing = asyncio.create_task(_probe(probe, cfg["period"], stop))
        _emit("ready", t=time.monotonic())
        while True:
            line = (await asyncio.to_thread(sys.stdin.readline)).strip()
            if line == "burst":
                t0 = time.monotonic()
                futs = [await staff.send("create", type="waypoint", **w) for w in cfg["spots"]]
                done, _ = await asyncio.wait(futs, timeout=cfg["create_limit"])
                replies = [f.result() for f in done]
                errors = [m for _, m in replies if m.get("servermsg") != "ok"]
                _emit(
                    "created",
                    t0=t0,
                    t1=max((at for at, _ in replies), default=None),
                    ok=len(replies) - len(errors),
                    unanswered=len(futs) - len(replies),
                    errors=errors[:3],
                )
            elif line in ("stop", ""):
                stop.set()
                _emit("result", samples=await probing, offline=staff.offline)
                return


# -- the server's process (one run) ----------------------------------------------------------


class _Capture(logging.Handler):
    """Every serveur log record as (monotonic time, logger, level, message)."""

    def __init__(self) -> None:
        super().__init__(logging.INFO)
        self.records: list[tuple[float, str, int, str]] = []

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append((time.monotonic(), record.name, record.levelno, record.getMessage()))


async def _stall_probe(interval: float, out: list[tuple[float, float]]) -> None:
    """In the server's loop: sleep ``interval`` again and again; record (when, how late)."""
    while True:
        t = time.monotonic()
        await asyncio.sleep(interval)
        out.append((t, time.monotonic() - t - interval))


def _pick_spots(n: int, robot_radius: float) -> list[dict[str, Any]]:
    """``n`` new waypoints B1..Bn on free cells of the demo map beside its tables, each where
    a robot fits and at least 0.45 m from every other waypoint."""
    from serveur.maps.navigation import Planner, load_demo

    grid, waypoints = load_demo()
    planner = Planner(grid, robot_radius=robot_radius)
    taken = [(w.x, w.y) for w in waypoints.values()]
    tables = sorted(
        (w for w in waypoints.values() if w.kind == "table"), key=lambda w: int(w.name[1:])
    )
    offsets = [(0.0, -0.6), (0.6, 0.0), (-0.6, 0.0), (0.0, 0.6), (0.5, -0.5), (-0.5, -0.5)]
    out: list[dict[str, Any]] = []
    for dx, dy in offsets:
        for t in tables:
            x, y = round(t.x + dx, 2), round(t.y + dy, 2)
            free = len(out) < n and planner.is_traversable(x, y)
            if free and all(math.hypot(x - a, y - b) >= 0.45 for a, b in taken):
                taken.append((x, y))
                out.append(
                    {"name": f"B{len(out) + 1}", "x": x, "y": y, "yaw": 0.0, "kind": "table"}
                )
    if len(out) < n:
        raise SystemExit(f"only {len(out)} free spots beside the demo tables, not {n}")
    return out


async def _read_event(proc: asyncio.subprocess.Process, event: str, limit: float) -> Any:
    """The next JSON line ``{"event": event, ...}`` from a child (other lines are skipped)."""
    assert proc.stdout is not None
    async with asyncio.timeout(limit):
        while True:
            line = await proc.stdout.readline()
            if not line:
                raise RuntimeError(f"child {proc.pid} exited before {event!r}")
            with contextlib.suppress(ValueError):
                msg = json.loads(line)
                if isinstance(msg, dict) and msg.get("event") == event:
                    return msg


async def _tell(proc: asyncio.subprocess.Process, line: str) -> None:
    assert proc.stdin is not None
    proc.stdin.write(line.encode() + b"\n")
    await proc.stdin.drain()


async def _stop_child(proc: asyncio.subprocess.Process | None, sig: int, limit: float) -> None:
    """Stop one child this run started: ``sig``, then SIGKILL after ``limit`` s."""
    if proc is None or proc.returncode is not None:
        return
    with contextlib.suppress(ProcessLookupError):
        proc.send_signal(sig)
    try:
        await asyncio.wait_for(proc.wait(), limit)
    except TimeoutError:
        with contextlib.suppress(ProcessLookupError):
            proc.kill()
        await proc.wait()


_SIM_BOOT = (
    "import sys, serveur; print(serveur.__file__, flush=True); "
    "from serveur.cli import main; sys.exit(main(sys.argv[1:]))"
)


def _ms(values: list[float], q: float | None = None) -> float:
    """Max (``q`` None) or percentile of seconds, in ms; NaN if empty."""
    if not values:
        return math.nan
    return 1e3 * (max(values) if q is None else pct(values, q))


async def _run_once(opt: dict[str, Any]) -> dict[str, Any]:
    """One run in this (fresh) process: sim child, in-process server, client child."""
    import serveur
    from serveur.app import App, RobotSpec
    from serveur.clock import ScaledClock
    from serveur.core.engine import CoreConfig
    from serveur.maps.navigation import load_demo
    from serveur.security.sessions import SecurityConfig

    print(f"[server process] serveur from {serveur.__file__}", file=sys.stderr, flush=True)
    capture = _Capture()
    slog = logging.getLogger("serveur")
    slog.addHandler(capture)
    slog.setLevel(logging.INFO)
    slog.propagate = False  # captured, not printed
    # "default": as serveur run/demo; "tests": as tests/conftest.py
    tests = opt["core_config"] == "tests"
    cfg = CoreConfig(heartbeat=2.0, ack_timeout=3.0) if tests else CoreConfig()
    spots = _pick_spots(opt["waypoints"], cfg.robot_radius)
    load_before = _loadavg()
    env = dict(os.environ)  # PYTHONPATH and all: the children import the same serveur
    sim: asyncio.subprocess.Process | None = None
    client: asyncio.subprocess.Process | None = None
    app: Any = None
    stalls: list[tuple[float, float]] = []
    stall_task: asyncio.Task[None] | None = None
    with tempfile.TemporaryDirectory(prefix="serveur-stall-") as tmpdir:
        tmp = Path(tmpdir)
        sim_log = (tmp / "sim.log").open("wb")
        try:
            async with asyncio.timeout(opt["max_seconds"]):
                sim = await asyncio.create_subprocess_exec(
                    sys.executable,
                    "-c",
                    _SIM_BOOT,
                    "sim",
                    "--robots",
                    str(opt["robots"]),
                    "--time-scale",
                    str(opt["time_scale"]),
                    "--port",
                    "0",
                    "--host",
                    HOST,
                    stdout=asyncio.subprocess.PIPE,
                    stderr=sim_log,
                    env=env,
                )
                assert sim.stdout is not None
                lines = []
                for _ in range(opt["robots"] + 1):
                    line = await asyncio.wait_for(sim.stdout.readline(), 60)
                    if not line:
                        raise RuntimeError("serveur sim exited: " + _tail(tmp / "sim.log"))
                    lines.append(line.decode().strip())
                sim_file, urls = lines[0], lines[1:]
                print(f"[sim process {sim.pid}] serveur from {sim_file}", file=sys.stderr)
                nav_map, waypoints = load_demo()  # numpy loaded: plans in worker threads
                specs = [RobotSpec(f"r{i + 1}", u, f"home{i + 1}") for i, u in enumerate(urls)]
                app = App(
                    tmp / "bench.db",
                    host=HOST,
                    port=0,
                    clock=ScaledClock(opt["time_scale"]),
                    nav_map=nav_map,
                    waypoints=waypoints,
                    robots=specs,
                    config=cfg,
                    # 50 requests/s per connection is the default cap: the probe sends 50/s
                    security=SecurityConfig(rate=1000.0, burst=1000.0),
                    create_owner=False,
                )
                await app.start()
                token = await app.issue_token("staff", label="bench_stall")
                stall_task = asyncio.create_task(_stall_probe(opt["stall_interval"], stalls))
                client = await asyncio.create_subprocess_exec(
                    sys.executable,
                    __file__,
                    "--client",
                    stdin=asyncio.subprocess.PIPE,
                    stdout=asyncio.subprocess.PIPE,
                    env=env,
                    limit=2**26,
                )
                await _tell(
                    client,
                    json.dumps(
                        {
                            "url": app.url,
                            "token": token,
                            "robots": [s.name for s in specs],
                            "watch_poses": opt["watch_poses"],
                            "spots": spots,
                            "period": opt["period"],
                            "ready_limit": 60.0,
                            "create_limit": 60.0,
                        }
                    ),
                )
                if opt.get("cgroup"):  # the children started: only the server is confined
                    procs = Path(opt["cgroup"], "cgroup.procs")
                    procs.write_text(str(os.getpid()))  # noqa: ASYNC240 - one small write
                t_start = (await _read_event(client, "ready", 90))["t"]
                cpu0 = _cpu_total(), _proc_cpu(os.getpid()), _proc_cpu(sim.pid)
                cpu0c = _proc_cpu(client.pid)
                await asyncio.sleep(max(0.0, t_start + opt["baseline"] - time.monotonic()))
                t_burst = time.monotonic()
                await _tell(client, "burst")
                created = await _read_event(client, "created", 90)
                plans_at, plans_logged = await _wait_plans(app, capture, t_burst, opt)
                t_end = max(created["t1"] or t_burst, plans_at or t_burst) + opt["tail"]
                await asyncio.sleep(max(0.0, t_end - time.monotonic()))
                cpu1 = _cpu_total(), _proc_cpu(os.getpid()), _proc_cpu(sim.pid)
                cpu1c = _proc_cpu(client.pid)
                await _tell(client, "stop")
                result = await _read_event(client, "result", 30)
        finally:
            if stall_task is not None:
                stall_task.cancel()
            await _stop_child(client, signal.SIGTERM, 5)
            if app is not None:
                with contextlib.suppress(Exception):
                    await asyncio.wait_for(app.close(), 20)
            await _stop_child(sim, signal.SIGINT, 10)
            sim_log.close()
    dt = t_end - t_start
    in_window = [(t, late) for t, late in stalls if t_start <= t < t_end]
    window = [late for _, late in in_window]
    base = [late for t, late in in_window if t < t_burst]
    burst = [late for t, late in in_window if t >= t_burst]
    rows = [r for r in result["samples"] if t_start <= r[0] < t_end]
    lat = [r[1] for r in rows if r[1] is not None]
    base_lat = [r[1] for r in rows if r[1] is not None and r[0] < t_burst]
    drops = [
        (t, msg)
        for t, name, _, msg in capture.records
        if name.startswith("serveur.robots.ros1.link") and "link down" in msg
    ]
    hows = sorted(
        {
            m["how"]
            for t, _, _, msg in capture.records
            if t >= t_burst and (m := _PLANNED.match(msg))
        }
    )
    busy = (cpu1[0][0] - cpu0[0][0]) / HZ  # CPU-seconds of the whole machine
    ours = (cpu1[1] - cpu0[1]) + (cpu1[2] - cpu0[2]) + (cpu1c - cpu0c)
    return {
        "serveur": serveur.__file__,
        "sim_serveur": sim_file,
        "planning": hows,
        "window_s": dt,
        "stall_max_ms": _ms(window),
        "stall_p99_ms": _ms(window, 99),
        "stall_samples": len(window),
        "baseline_stall_max_ms": _ms(base),
        "baseline_stall_p99_ms": _ms(base, 99),
        "burst_stall_p99_ms": _ms(burst, 99),
        "req_p50_ms": _ms(lat, 50),
        "req_p99_ms": _ms(lat, 99),
        "req_max_ms": _ms(lat),
        "baseline_req_p99_ms": _ms(base_lat, 99),
        "requests": len(rows),
        "req_unanswered": len(rows) - len(lat),
        "req_errors": sum(1 for r in rows if r[1] is not None and not r[2]),
        "link_drops": sum(1 for t, _ in drops if t_start <= t < t_end),
        "link_drops_before_window": sum(1 for t, _ in drops if t < t_start),  # start-up
        "offline_seen": sum(1 for t, _ in result["offline"] if t_start <= t < t_end),
        "creates_s": None if created["t1"] is None else created["t1"] - created["t0"],
        "creates_ok": created["ok"],
        "creates_unanswered": created["unanswered"],
        "create_errors": created["errors"],
        "plans_s": None if plans_at is None else plans_at - t_burst,
        "plans_logged": plans_logged,
        # serveur's warnings of the whole run (start-up and shutdown too), s from the window
        "warnings": [
            [round(t - t_start, 3), name, msg]
            for t, name, lvl, msg in capture.records
            if lvl >= logging.WARNING
        ][:30],
        "load": {
            "cpus": os.cpu_count(),
            "loadavg_before": load_before,
            "loadavg_after": _loadavg(),
            "machine_busy_pct": 100 * (cpu1[0][0] - cpu0[0][0]) / (cpu1[0][1] - cpu0[0][1]),
            "server_cpu_pct": 100 * (cpu1[1] - cpu0[1]) / dt,
            "sim_cpu_pct": 100 * (cpu1[2] - cpu0[2]) / dt,
            "client_cpu_pct": 100 * (cpu1c - cpu0c) / dt,
            "others_cpu_pct": 100 * (busy - ours) / dt,
        },
    }


async def _wait_plans(
    app: Any, capture: _Capture, since: float, opt: dict[str, Any]
) -> tuple[float | None, int]:
    """When the plans the burst started were done (None: not within ``plan_wait`` s) and how
    many ``planned ...`` lines were logged. Done: the core's background planning jobs are all
    finished and at least one plan was logged, or (if the core has no such set) as many plans
    were logged as waypoints created."""
    deadline = time.monotonic() + opt["plan_wait"]
    while True:
        logged = [t for t, _, _, msg in capture.records if t >= since and _PLANNED.match(msg)]
        jobs = getattr(getattr(app.core, "places", None), "planning", None)
        idle = (not jobs) if isinstance(jobs, set | frozenset | list | dict) else None
        if (idle and logged) or (idle is None and len(logged) >= opt["waypoints"]):
            return (max(logged) if logged else time.monotonic()), len(logged)
        if time.monotonic() > deadline:
            return None, len(logged)
        await asyncio.sleep(0.01)


def _tail(path: Path) -> str:
    with contextlib.suppress(OSError):
        return " | ".join(path.read_text(errors="replace").strip().splitlines()[-3:])
    return ""


# -- the driver: runs, medians, table --------------------------------------------------------

_COLUMNS = [
    ("stall max", "stall_max_ms", "{:.0f} ms"),
    ("stall p99", "stall_p99_ms", "{:.1f} ms"),
    ("req p50", "req_p50_ms", "{:.1f} ms"),
    ("req p99", "req_p99_ms", "{:.0f} ms"),
    ("req max", "req_max_ms", "{:.0f} ms"),
    ("lost", "req_unanswered", "{:.0f}"),
    ("drops", "link_drops", "{:.0f}"),
    ("offline", "offline_seen", "{:.0f}"),
    ("creates", "creates_s", "{:.2f} s"),
    ("plans", "plans_s", "{:.2f} s"),
    ("others", "others_cpu_pct", "{:.0f}%"),
]


def _flat(run: dict[str, Any]) -> dict[str, Any]:
    return {**run, **run["load"]}


def _cell(value: Any, fmt: str) -> str:
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"
    return fmt.format(value)


def _table(runs: list[dict[str, Any]], med: dict[str, Any]) -> str:
    head = ["run", *(c[0] for c in _COLUMNS)]
    body = [
        [str(i + 1), *(_cell(_flat(r)[k], f) for _, k, f in _COLUMNS)] for i, r in enumerate(runs)
    ]
    body.append(["median", *(_cell(med.get(k), f) for _, k, f in _COLUMNS)])
    widths = [max(len(row[i]) for row in [head, *body]) for i in range(len(head))]
    return "\n".join(
        "  ".join(c.rjust(w) for c, w in zip(row, widths, strict=True)) for row in [head, *body]
    )


def _medians(runs: list[dict[str, Any]]) -> dict[str, float]:
    out: dict[str, float] = {}
    for key, value in _flat(runs[0]).items():
        if isinstance(value, int | float) and not isinstance(value, bool):
            vals = [_flat(r)[key] for r in runs]
            vals = [v for v in vals if isinstance(v, int | float) and not math.isnan(v)]
            if vals:
                out[key] = statistics.median(vals)
    return out


def main(ns: argparse.Namespace) -> int:
    opt = {k: v for k, v in vars(ns).items() if k not in ("json", "runs", "one_run", "client")}
    runs: list[dict[str, Any]] = []
    for i in range(ns.runs):
        print(f"run {i + 1}/{ns.runs}", file=sys.stderr, flush=True)
        group = _quota_group(ns.quota, ns.quota_period) if ns.quota else None
        opt["cgroup"] = str(group) if group else None
        # A session of its own, so a run that overruns is killed with every child it started.
        proc = subprocess.Popen(
            [sys.executable, __file__, "--one-run", json.dumps(opt)],
            stdout=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        stop = threading.Event()
        moved: list[int] = []
        if group is not None:
            shepherd = threading.Thread(
                target=_shepherd, args=(group, proc.pid, stop, moved), daemon=True
            )
            shepherd.start()
        try:
            out, _ = proc.communicate(timeout=ns.max_seconds + 60)
        except (subprocess.TimeoutExpired, KeyboardInterrupt):
            with contextlib.suppress(ProcessLookupError):
                os.killpg(proc.pid, signal.SIGKILL)  # this run's process group only
            proc.communicate()
            raise
        finally:
            stop.set()
            throttled = _throttled(group) if group is not None else None
            if group is not None:
                with contextlib.suppress(OSError):
                    group.rmdir()
        run = None
        for line in out.splitlines():
            with contextlib.suppress(ValueError):
                msg = json.loads(line)
                if isinstance(msg, dict) and msg.get("event") == "run":
                    run = msg["result"]
        if proc.returncode != 0 or run is None:
            print(f"run {i + 1} failed (exit {proc.returncode})", file=sys.stderr)
            return 1
        run["quota"] = {
            "share": ns.quota,
            "period_s": ns.quota_period,
            "children_moved_out": len(moved),
            **(throttled or {}),
        }
        runs.append(run)
        print(
            "  " + ", ".join(f"{k} {_cell(_flat(run)[k], f)}" for _, k, f in _COLUMNS),
            file=sys.stderr,
            flush=True,
        )
    med = _medians(runs)
    first = runs[0]
    print(
        f"serveur {first['serveur']} (sim: {first['sim_serveur']}); planning: "
        f"{', '.join(first['planning']) or '?'}; {ns.robots} robots, {ns.waypoints} waypoints, "
        f"time scale {ns.time_scale}, core config {ns.core_config}, {first['load']['cpus']} CPUs"
    )
    if ns.quota:
        q = [r["quota"] for r in runs]
        print(
            f"server under {ns.quota:g} of a core ({ns.quota_period * 1e3:g} ms periods): "
            + "; ".join(
                f"run {i + 1} throttled in {x['throttled']} of {x['periods']} periods, "
                f"{x['throttled_s']:.1f} s held back, {x['children_moved_out']} children "
                "moved out"
                for i, x in enumerate(q)
            )
        )
    print(_table(runs, med))
    verdict = _verdict(runs, med, ns)
    if ns.json:
        Path(ns.json).write_text(
            json.dumps({"options": opt, "runs": runs, "median": med, "verdict": verdict}, indent=1)
            + "\n"
        )
    failed = [name for name, v in verdict.items() if v != "ok"]
    print("targets:", "all met" if not failed else "NOT met: " + "; ".join(failed))
    return 1 if failed else 0


def _verdict(
    runs: list[dict[str, Any]], med: dict[str, Any], ns: argparse.Namespace
) -> dict[str, str]:
    """Each target: "ok" or what was measured instead."""

    def check(ok: bool, got: Any) -> str:
        return "ok" if ok else f"FAILED: {got}"

    drops = sum(r["link_drops"] for r in runs)
    lost = sum(r["req_unanswered"] + r["req_errors"] for r in runs)
    creates = [(r["creates_ok"], r["create_errors"]) for r in runs]
    unplanned = sum(r["plans_s"] is None for r in runs)
    stall = med["stall_max_ms"]
    return {
        f"longest stall <= {ns.max_stall:g} ms (median of runs)": check(
            stall <= ns.max_stall, f"{stall:.1f} ms"
        ),
        "no robot link dropped": check(drops == 0, drops),
        "every probe request answered ok": check(lost == 0, lost),
        f"all {ns.waypoints} creates ok": check(
            all(ok == ns.waypoints for ok, _ in creates), creates
        ),
        "every plan done": check(unplanned == 0, f"{unplanned} runs not"),
    }


def _parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(description=(__doc__ or "").split("\n")[0])
    ap.add_argument("--time-scale", type=float, default=10.0, help="server and robots (10)")
    ap.add_argument("--robots", type=int, default=5, help="simulated robots, 1..6 (5)")
    ap.add_argument("--waypoints", type=int, default=10, help="waypoints created (10)")
    ap.add_argument("--runs", type=int, default=1, help="runs, each a fresh process (1)")
    ap.add_argument("--json", metavar="PATH", help="write every run and the medians here")
    ap.add_argument("--baseline", type=float, default=5.0, help="quiet seconds first (5)")
    ap.add_argument("--tail", type=float, default=3.0, help="seconds after it all (3)")
    ap.add_argument("--period", type=float, default=0.02, help="probe request period (0.02)")
    ap.add_argument(
        "--stall-interval", type=float, default=0.002, help="stall probe's sleep (0.002)"
    )
    ap.add_argument(
        "--plan-wait", type=float, default=60.0, help="at most this long for the plans (60)"
    )
    ap.add_argument("--max-seconds", type=float, default=120.0, help="a run's bound (120)")
    ap.add_argument(
        "--core-config",
        choices=("default", "tests"),
        default="default",
        help="default: CoreConfig() as serveur run/demo (heartbeat 1 s); tests: as "
        "tests/conftest.py (heartbeat 2 s, ack timeout 3 s)",
    )
    ap.add_argument(
        "--watch-poses",
        action="store_true",
        help="the staff client also watches every robot's pose (full-rate AMCL streams)",
    )
    ap.add_argument("--max-stall", type=float, default=20.0, help="target: longest stall, ms (20)")
    ap.add_argument(
        "--quota",
        type=float,
        default=None,
        metavar="SHARE",
        help="confine the server process to this share of one core (e.g. 0.25: a Pi's "
        "share), a cgroup v1 cpu group; the robots, clients and plans stay outside",
    )
    ap.add_argument(
        "--quota-period",
        type=float,
        default=0.01,
        metavar="S",
        help="the quota's accounting period, seconds (0.01)",
    )
    ap.add_argument("--one-run", metavar="JSON", help=argparse.SUPPRESS)
    ap.add_argument("--client", action="store_true", help=argparse.SUPPRESS)
    return ap


if __name__ == "__main__":
    args = _parser().parse_args()
    if args.client:
        asyncio.run(_client_main())
    elif args.one_run:
        _emit("run", result=asyncio.run(_run_once(json.loads(args.one_run))))
    else:
        if not 1 <= args.robots <= 6:
            sys.exit("--robots: the demo restaurant has 6 home spots")
        sys.exit(main(args))
