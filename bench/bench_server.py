"""Server benchmarks on loopback: latency vs a raw websockets echo, fan-out, dispatch, footprint.

Four processes, so that the load never shares an interpreter with what it measures:

* ``serveur sim`` — N simulated robots (default 10) publishing AMCL pose at 10 Hz;
* ``serveur run`` — the server as a site runs it (trips wait at the pass, Loading, until
  staff press Go: no ``--auto-depart``), with the robots registered and the demo restaurant
  (plus extra home spots so every robot has one);
* a raw ``websockets`` echo server (same library, same settings as the server's endpoint);
* this process — C clients (default 200), the restaurant's staff and guests, and the
  measurements.

Phases (every one bounded in count and time; the script stops everything it started):

1. **footprint** — server RSS and CPU over ``--idle`` seconds with the robots parked at
   home and the clients connected, subscribed to ``robots``, sending nothing. Parked robots
   are measured as they are on site: in a run of their own first, the simulator's AMCL as
   the amcl node (``--idle-amcl real``: silent while a robot stands still; the other phases
   need the simulator's 10 Hz poses); the same figure with 10 Hz poses is reported beside it;
2. then **the service** starts and runs to the end: the staff client (this process) puts
   every robot in automatic, sends a dish to a table as a cart (``create order``, ``create
   task``, to the ``--tables`` nearest the pass in turn) whenever a robot waits free at home,
   presses Go (``go``) as soon as the trip is Loading, and the guests press Food collected
   (``next``) as soon as it is Delivered. So the ten robots are on the move nearly all the
   time, as in a busy service, and their poses stream (a parked robot's do not reach the
   screens);
3. **latency** — clients also watch ``pose:<robot>`` (each one robot's, at most 10 Hz while
   it moves), and a probe times ``--samples`` requests (``data`` unsubscribing from ``map``:
   parsed, validated and answered by the server, no database) alternately to serveur and to
   the echo server. The probe is a process of its own, as a tablet is (``--probe-in-process``:
   the old method, from this process). The stream frames the clients received are counted:
   the phase is only valid under the load it claims (``--min-frames``, 1,000 a second);
4. **fan-out** — every client subscribes to ``pose:r1``; for each update, the time from the
   robot's stamp to the *last* client's receipt (at least ``--fanout-seconds`` x 4 updates:
   r1 must be moving);
5. **dispatch** — the service's own trips for ``--dispatch-seconds``, clients back to
   ``robots`` only: ``create task`` sent -> the robot seen Loading with that trip (the
   dispatcher chose it, the trip is stored), and ``go`` sent -> the goal appears on the
   robot's ``/move_base/goal`` (the bench subscribes to each robot's rosbridge).

The exit code is 0 when every target holds (``TARGETS``; the figures and the verdict are
printed as JSON), 1 when one does not, or when a phase did not run under its load.

Run: ``python bench/bench_server.py`` (about three minutes, 20-30 trips timed).
``--latency-only`` stops after phase 3; ``--footprint-only`` after phase 1; ``--sim-spread``
spreads the simulated robots' publish phases (``serveur sim --spread-phases``); ``--pin``
puts the servers and the load on different CPUs, ``--rt`` runs the servers and the probe
under SCHED_RR (``--server-nice N`` at nice N instead), and ``--isolate`` is both, to shield
the figures from a shared host's noise. ``--profile`` writes a pyinstrument profile of the
server (``pip install pyinstrument``) to ``bench-server-profile.txt``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import itertools
import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection, connect
from websockets.asyncio.server import ServerConnection, serve

from serveur.maps.mapio import demo_map_path, demo_waypoints_path

HZ = os.sysconf("SC_CLK_TCK")


def pct(values: list[float], q: float) -> float:
    s = sorted(values)
    return s[max(0, math.ceil(q / 100 * len(s)) - 1)] if s else math.nan


# -- the raw echo server (its own process) -----------------------------------------------------


async def _echo_main() -> None:
    async def echo(ws: ServerConnection) -> None:
        async for frame in ws:
            await ws.send(frame)

    async with serve(echo, "127.0.0.1", 0, compression=None, max_queue=32) as srv:
        port = next(iter(srv.sockets)).getsockname()[1]
        print(port, flush=True)
        await asyncio.Future()


# -- process helpers ---------------------------------------------------------------------------


def _proc_stats(pid: int) -> tuple[float, int]:
    """(CPU seconds used, RSS bytes) of a process, from /proc."""
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    cpu = (int(fields[11]) + int(fields[12])) / HZ
    rss = 0
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            rss = int(line.split()[1]) * 1024
    return cpu, rss


def _sched(pid: int) -> tuple[int, int, int]:
    """(ns on a CPU, ns runnable but waiting for one, times run) of a process's main thread
    (serveur's event loop): /proc/PID/schedstat. The wait is the host's share of a tail."""
    run, wait, slices = Path(f"/proc/{pid}/schedstat").read_text().split()
    return int(run), int(wait), int(slices)


def _sched_delta(before: tuple[int, int, int], after: tuple[int, int, int]) -> dict[str, float]:
    run, wait, slices = (b - a for a, b in zip(before, after, strict=True))
    return {
        "cpu_ms": run / 1e6,
        "runqueue_wait_ms": wait / 1e6,
        "wakeups": slices,
        "mean_wait_us": wait / 1e3 / max(1, slices),
    }


def _world(tmp: Path, robots: int) -> tuple[Path, Path]:
    """The demo map with ``robots`` home spots (the demo has six) for both sim and server."""
    shutil.copy(demo_map_path(), tmp / "room.yaml")
    text = (tmp / "room.yaml").read_text()
    image = demo_map_path().with_name(text.split("image:")[1].split()[0])
    shutil.copy(image, tmp / image.name)
    wps = json.loads(demo_waypoints_path().read_text())["waypoints"]
    wps = [w for w in wps if w["kind"] != "home"]
    for i in range(robots):
        x = 3.6 + i * (9.0 / max(1, robots - 1)) if robots > 1 else 4.0
        wps.append(
            {"name": f"home{i + 1}", "x": round(x, 2), "y": 10.8, "yaw": 1.5708, "kind": "home"}
        )
    wp = tmp / "room_waypoints.json"
    wp.write_text(json.dumps({"waypoints": wps}))
    return tmp / "room.yaml", wp


async def _start(cmd: list[str], lines: int) -> tuple[asyncio.subprocess.Process, list[str]]:
    proc = await asyncio.create_subprocess_exec(
        *cmd, stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.DEVNULL
    )
    assert proc.stdout is not None
    out = []
    for _ in range(lines):
        out.append((await asyncio.wait_for(proc.stdout.readline(), 60)).decode().strip())
    return proc, out


# -- clients -----------------------------------------------------------------------------------


class Load:
    """One client connection: replies by id; the robots it heard of (with the time each
    update came, ``_seen``); stream frames counted; pose:r1 receipt times for the fan-out."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.n = 0
        self.pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self.fanout: dict[float, float] | None = None
        self.robots: dict[str, dict[str, Any]] = {}
        self.changed = asyncio.Event()
        self.streamed = 0  # pose: frames received
        self.task = asyncio.create_task(self.read())

    async def until(self, cond: Any, limit: float = 60.0) -> None:
        """Wait for a condition on the robots this client has heard of."""

        async def wait() -> None:
            while not cond():
                self.changed.clear()
                await self.changed.wait()

        await asyncio.wait_for(wait(), limit)

    async def read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                now = time.time()
                if '"servermsg":"update"' in frame:
                    if '"topic":"pose:' in frame:
                        self.streamed += 1
                        if self.fanout is not None and '"topic":"pose:r1"' in frame:
                            self.fanout[json.loads(frame)["data"]["stamp"]] = now
                    elif '"topic":"robots"' in frame:
                        r = json.loads(frame)["data"]
                        r["_seen"] = time.perf_counter()
                        self.robots[r["name"]] = r
                        self.changed.set()
                    continue
                msg = json.loads(frame)
                fut = self.pending.pop(msg.get("id"), None)
                if fut is not None and not fut.done():
                    fut.set_result(msg)

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        self.n += 1
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self.pending[self.n] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": self.n, **fields}))
        return await asyncio.wait_for(fut, 30)


class Service:
    """The restaurant's staff and guests on the staff connection, as a site runs its service.

    Staff send a dish to a table (a cart of one: ``create order``, ``create task``) whenever a
    robot waits free at home with no trip queued for it, and press Go as soon as a robot is
    Loading; guests press Food collected as soon as their robot is Delivered. ``tables`` are
    taken in turn (the bench's: the ``--tables`` nearest the pass, for many short trips).
    Every trip's two dispatch steps are timed: ``create task`` sent -> the robot seen Loading
    with it (``assign``), and ``go`` sent -> the goal on the robot's ``/move_base/goal``
    (``go``), the latter read on the robot's own rosbridge (``sim_urls``, robot ``r{i+1}`` on
    the i-th).
    """

    def __init__(self, staff: Load, tables: list[str], sim_urls: list[str]) -> None:
        self.staff = staff
        self.tables = tables
        self.sim_urls = sim_urls
        self.assign: list[tuple[float, float]] = []  # (when, seconds)
        self.go: list[tuple[float, float]] = []
        self.trips = 0
        self.errors: list[str] = []
        self._created: dict[int, float] = {}  # task -> create sent (perf_counter), until Loading
        self._pressed: set[tuple[str, str, int]] = set()  # (verb, robot, task) in flight
        self._go_sent: dict[str, float] = {}  # robot -> go sent, until its goal is seen
        self._next_table = 0
        self._tasks: list[asyncio.Task[None]] = []
        self._watchers: list[ClientConnection] = []

    async def start(self) -> None:
        for i, url in enumerate(self.sim_urls):
            ws = await connect(url, compression=None, max_size=2**24)
            await ws.send(json.dumps({"op": "subscribe", "topic": "/move_base/goal"}))
            self._watchers.append(ws)
            self._tasks.append(asyncio.create_task(self._watch_goals(f"r{i + 1}", ws)))
        for n in sorted(self.staff.robots):
            await self.staff.call("control", robot=n, action="auto")
        self._tasks.append(asyncio.create_task(self._run()))

    async def stop(self) -> None:
        for t in self._tasks:
            t.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        for ws in self._watchers:
            await ws.close()

    def moving(self) -> int:
        return sum(r["status"] in ("Delivering", "Transit") for r in self.staff.robots.values())

    async def _watch_goals(self, robot: str, ws: ClientConnection) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in ws:
                t = time.perf_counter()
                if json.loads(frame).get("op") == "publish":
                    sent = self._go_sent.pop(robot, None)
                    if sent is not None:
                        self.go.append((t, t - sent))

    async def _run(self) -> None:
        staff = self.staff
        while True:
            staff.changed.clear()
            for name, r in list(staff.robots.items()):
                task = r.get("current_task")
                if r["status"] == "Loading" and task is not None:
                    made = self._created.pop(task, None)
                    if made is not None:
                        self.assign.append((r["_seen"], r["_seen"] - made))
                    self._press("go", name, task)
                elif r["status"] == "Delivered" and task is not None:
                    self._press("next", name, task)
            free = sum(
                r["status"] == "Awaiting" and r.get("current_task") is None
                for r in staff.robots.values()
            )
            for _ in range(free - len(self._created)):
                self._spawn(self._cart())
            await staff.changed.wait()

    def _press(self, verb: str, robot: str, task: int) -> None:
        key = (verb, robot, task)
        if key not in self._pressed:
            self._pressed.add(key)
            self._spawn(self._send(verb, robot, task))

    async def _send(self, verb: str, robot: str, task: int) -> None:
        if verb == "go":
            self._go_sent[robot] = time.perf_counter()
        reply = await self.staff.call(verb, robot=robot, task=task)
        if reply["servermsg"] != "ok":
            self.errors.append(f"{verb} {robot} trip {task}: {reply.get('code')}")
        elif verb == "go":
            self.trips += 1

    async def _cart(self) -> None:
        table = self.tables[self._next_table % len(self.tables)]
        self._next_table += 1
        placeholder = -self._next_table  # counted as queued until the task has its id
        self._created[placeholder] = 0.0
        try:
            order = await self.staff.call("create", type="order", dish="x", table=table)
            t0 = time.perf_counter()
            reply = await self.staff.call("create", type="task", orders=[order["order"]["id"]])
        finally:
            del self._created[placeholder]
        if reply["servermsg"] != "ok":
            self.errors.append(f"create task for {table}: {reply.get('code')}")
            return
        tid = reply["tasks"][0]["id"]
        seen = next((r for r in self.staff.robots.values() if r.get("current_task") == tid), None)
        if seen is not None and seen["status"] == "Loading":  # the update came before the reply
            self.assign.append((seen["_seen"], seen["_seen"] - t0))
        else:
            self._created[tid] = t0
        self.staff.changed.set()

    def _spawn(self, job: Any) -> None:
        task = asyncio.create_task(job)
        self._tasks.append(task)
        task.add_done_callback(self._reraise)

    def _reraise(self, task: asyncio.Task[None]) -> None:
        if not task.cancelled() and task.exception() is not None:
            self.errors.append(repr(task.exception()))

    def window(self, since: float) -> dict[str, float]:
        assign = [d for t, d in self.assign if t >= since]
        go = [d for t, d in self.go if t >= since]
        return {
            "trips": len(go),
            "assign_p50_ms": 1e3 * pct(assign, 50),
            "assign_p99_ms": 1e3 * pct(assign, 99),
            "go_p50_ms": 1e3 * pct(go, 50),
            "go_p99_ms": 1e3 * pct(go, 99),
        }


def _latency_stats(srv: list[float], raw: list[float]) -> dict[str, float]:
    return {
        "serveur_p50_ms": 1e3 * pct(srv, 50),
        "serveur_p90_ms": 1e3 * pct(srv, 90),
        "serveur_p99_ms": 1e3 * pct(srv, 99),
        "echo_p50_ms": 1e3 * pct(raw, 50),
        "echo_p90_ms": 1e3 * pct(raw, 90),
        "echo_p99_ms": 1e3 * pct(raw, 99),
        "ratio_p50": pct(srv, 50) / pct(raw, 50),
        "ratio_p99": pct(srv, 99) / pct(raw, 99),
    }


_PROBE_REQ = json.dumps({"clientmsg": "data", "id": 0, "topics": ["map"], "unsubscribe": True})


async def phase_latency(probe: Load, echo_url: str, samples: int) -> dict[str, float]:
    """The probe from this process (``--probe-in-process``): its loop also reads the 199
    clients' 2,000 frames/s, so its own jitter lands on both serveur's and echo's figures."""
    async with connect(echo_url, compression=None) as echo:
        return await _alternate(
            lambda: probe.call("data", topics=["map"], unsubscribe=True), echo, samples
        )


async def _alternate(
    ask: Callable[[], Awaitable[object]], echo: ClientConnection, samples: int
) -> dict[str, float]:
    """``samples`` pairs, after 50 of warm-up: ``ask`` serveur, then echo the same frame;
    2 ms apart, so the probe itself is no load."""
    srv: list[float] = []
    raw: list[float] = []
    for i in range(samples + 50):
        t = time.perf_counter()
        await ask()
        a = time.perf_counter() - t
        t = time.perf_counter()
        await echo.send(_PROBE_REQ)
        await echo.recv()
        b = time.perf_counter() - t
        if i >= 50:  # warm-up
            srv.append(a)
            raw.append(b)
        await asyncio.sleep(0.002)
    return _latency_stats(srv, raw)


async def _probe_main(url: str, echo_url: str, token: str, samples: int) -> None:
    """The probe in a process of its own (the default), as a real tablet is: one connection
    to serveur (subscribed to ``robots``, like the staff client of the in-process probe) and
    one to the echo server, alternating requests; prints the stats as one JSON line."""
    auth = {"Authorization": f"Bearer {token}"}
    async with (
        connect(url, compression=None, max_size=2**24, additional_headers=auth) as ws,
        connect(echo_url, compression=None) as echo,
    ):

        async def call(n: int, **fields: Any) -> None:
            await ws.send(json.dumps({"clientmsg": "data", "id": n, **fields}))
            while True:
                frame = await ws.recv()
                if '"servermsg":"update"' not in frame and json.loads(frame).get("id") == n:
                    return

        await call(1, topics=["robots"])
        ids = itertools.count(2)
        stats = await _alternate(
            lambda: call(next(ids), topics=["map"], unsubscribe=True), echo, samples
        )
    print(json.dumps(stats), flush=True)


async def phase_latency_process(
    url: str, echo_url: str, token: str, samples: int, prefix: list[str]
) -> dict[str, float]:
    proc = await asyncio.create_subprocess_exec(
        *prefix,
        sys.executable,
        __file__,
        "--probe",
        url,
        echo_url,
        token,
        str(samples),
        stdout=asyncio.subprocess.PIPE,
    )
    out, _ = await asyncio.wait_for(proc.communicate(), 60 + samples * 0.05)
    if proc.returncode != 0:
        raise RuntimeError(f"probe process failed ({proc.returncode})")
    stats: dict[str, float] = json.loads(out.decode().strip().splitlines()[-1])
    return stats


async def phase_fanout(clients: list[Load], seconds: float) -> dict[str, float]:
    for c in clients:
        c.fanout = {}
    await asyncio.gather(*(c.call("data", topics=["pose:r1"]) for c in clients))
    await asyncio.sleep(seconds)
    for c in clients:
        await c.call("data", topics=["pose:r1"], unsubscribe=True)
    stamps: dict[float, list[float]] = {}
    for c in clients:
        assert c.fanout is not None
        for stamp, t in c.fanout.items():
            stamps.setdefault(stamp, []).append(t - stamp)
        c.fanout = None
    full = [v for v in stamps.values() if len(v) == len(clients)]
    last = [max(v) for v in full]
    first = [min(v) for v in full]
    spread = [max(v) - min(v) for v in full]
    return {
        "updates": len(stamps),
        "reached_all": len(full),
        "last_client_p50_ms": 1e3 * pct(last, 50),
        "last_client_p99_ms": 1e3 * pct(last, 99),
        # stamp -> the first client: the link, the pose gate's pacing (a pose that comes
        # within 0.1 s of the last one published waits for the interval), one send
        "first_client_p50_ms": 1e3 * pct(first, 50),
        "first_client_p99_ms": 1e3 * pct(first, 99),
        # first -> last client of the same pose: the fan-out to 200 (and this process
        # reading 200 copies)
        "spread_p50_ms": 1e3 * pct(spread, 50),
        "spread_p99_ms": 1e3 * pct(spread, 99),
    }


#: What each figure must be for the run to pass (docs/performance.md, "Server"), and the
#: load a phase must have run under for its figures to mean anything.
TARGETS: dict[str, tuple[str, str, float]] = {
    # name: (phase, key, limit); "<=" a maximum, ">=" (key prefixed "min:") a minimum
    "idle CPU <= 1 % of a core": ("footprint", "idle_cpu_percent", 1.0),
    "RSS <= 60 MB": ("footprint", "rss_mb", 60.0),
    "request p99 <= 1.5x the echo's": ("latency", "ratio_p99", 1.5),
    "request p50 <= 2x the echo's": ("latency", "ratio_p50", 2.0),
    "fan-out p99 <= 25 ms": ("fanout", "last_client_p99_ms", 25.0),
    "dispatch: create task -> Loading p99 <= 50 ms": ("dispatch", "assign_p99_ms", 50.0),
    "dispatch: go -> goal on the robot p99 <= 50 ms": ("dispatch", "go_p99_ms", 50.0),
}


def verdict(results: dict[str, Any], ns: argparse.Namespace) -> dict[str, str]:
    """Each target and load check that applies to the phases run: "ok" or why not."""
    out: dict[str, str] = {}
    for name, (phase, key, limit) in TARGETS.items():
        if phase in results:
            value = results[phase][key]
            out[name] = "ok" if value <= limit else f"FAILED: {value:.2f}"
    if "latency" in results:
        rate = results["latency"]["stream_frames_per_s"]
        out[f"latency under load: >= {ns.min_frames} pose frames/s out"] = (
            "ok" if rate >= ns.min_frames else f"FAILED: {rate:.0f} frames/s"
        )
    if "fanout" in results:
        least = int(4 * ns.fanout_seconds)
        got = results["fanout"]["reached_all"]
        out[f"fan-out under load: >= {least} updates reached all"] = (
            "ok" if got >= least else f"FAILED: {got}"
        )
    if "dispatch" in results:
        least = max(1, int(ns.dispatch_seconds / 10))
        d = results["dispatch"]
        out[f"dispatch: >= {least} trips"] = (
            "ok" if d["trips"] >= least else f"FAILED: {d['trips']}"
        )
    if "service" in results:
        errors = results["service"]["errors"]
        out["service: every request answered ok"] = "ok" if not errors else f"FAILED: {errors[:3]}"
    return out


async def main(ns: argparse.Namespace) -> dict[str, Any]:
    results: dict[str, Any] = {
        "clients": ns.clients,
        "robots": ns.robots,
        "sim_phases": "spread" if ns.sim_spread else "lock-step",
        "cpus": "pinned" if ns.pin else "shared",
        "priority": "SCHED_RR" if ns.rt else f"nice {ns.server_nice}",
    }
    procs: list[asyncio.subprocess.Process] = []
    with tempfile.TemporaryDirectory(prefix="serveur-bench-") as tmpdir:
        tmp = Path(tmpdir)
        room, wps = _world(tmp, ns.robots)
        try:
            sim, urls = await _start(
                [
                    sys.executable,
                    "-m",
                    "serveur.cli",
                    "sim",
                    "--robots",
                    str(ns.robots),
                    "--port",
                    "0",
                    "--map",
                    str(room),
                    *(["--spread-phases"] if ns.sim_spread else []),
                    "--amcl",
                    ns.amcl,
                ],
                ns.robots,
            )
            procs.append(sim)
            prefix = _prefix(ns, cpu=0)  # the servers' CPU and priority
            echo, [echo_port] = await _start(
                [*prefix, sys.executable, __file__, "--echo-server"], 1
            )
            procs.append(echo)
            results["echo_port"] = int(echo_port)
            port = _free_port()
            # A staff token for the load clients; all of them come from 127.0.0.1, so the
            # per-address cap and the per-connection rate limit are lifted for the bench.
            token = subprocess.run(  # noqa: ASYNC221 - once, before anything runs
                [
                    sys.executable,
                    "-m",
                    "serveur.cli",
                    "token",
                    "create",
                    "--role",
                    "staff",
                    "--db",
                    str(tmp / "bench.db"),
                ],
                check=True,
                capture_output=True,
                text=True,
            ).stdout.strip()
            auth = {"Authorization": f"Bearer {token}"}
            cmd = [
                sys.executable,
                "-m",
                "serveur.cli",
                "run",
                "--port",
                str(port),
                "--max-connections-per-address",
                "100000",
                "--rate-limit",
                "100000",
                "--db",
                str(tmp / "bench.db"),
                "--map",
                str(room),
                "--waypoints",
                str(wps),
            ]
            for i, url in enumerate(urls):
                cmd += ["--robot", f"r{i + 1}={url},home=home{i + 1}"]
            if ns.profile:
                cmd = [
                    sys.executable,
                    "-m",
                    "pyinstrument",
                    "-r",
                    "text",
                    "-o",
                    "bench-server-profile.txt",
                    *cmd[1:],
                ]
            server, _ = await _start([*prefix, *cmd], 1)
            procs.append(server)
            url = f"ws://127.0.0.1:{port}/ws"
            # Browsers never send websocket pings (only the server's keepalive pings them):
            # the clients' own pings, websockets' default, would be load no tablet makes.
            clients = [
                Load(
                    await connect(
                        url,
                        compression=None,
                        max_size=2**24,
                        additional_headers=auth,
                        ping_interval=None,
                    )
                )
                for _ in range(ns.clients)
            ]
            await asyncio.gather(*(c.call("data", topics=["robots"]) for c in clients))
            staff = clients[0]
            snap = await staff.call("data", topics=["robots"])
            staff.robots = {r["name"]: r for r in snap["data"]["robots"]}
            await staff.until(lambda: all(r["status"] != "Offline" for r in staff.robots.values()))
            spid = server.pid
            # Settling: the robots' first snapshots, their poses saved once, the clients'
            # subscriptions; what is left after it is what an idle server does for ever.
            await asyncio.sleep(ns.settle)
            seconds = int(ns.idle)
            cpu = [_proc_stats(spid)[0]]  # CPU seconds used, once a second
            for _ in range(seconds):
                await asyncio.sleep(1.0)
                cpu.append(_proc_stats(spid)[0])
            per_s = [round(100 * (b - a), 1) for a, b in itertools.pairwise(cpu)]
            rss = _proc_stats(spid)[1]
            results["footprint"] = {
                "rss_mb": rss / 2**20,
                "idle_cpu_percent": 100 * (cpu[-1] - cpu[0]) / seconds,
                "idle_seconds": seconds,
                "settle_seconds": ns.settle,
                "idle_cpu_per_second": per_s,
            }
            print("footprint", results["footprint"], flush=True)
            if ns.footprint_only:
                for c in clients:
                    await c.ws.close()
                return results
            wps = (await staff.call("data", topics=["waypoints"]))["data"]["waypoints"]
            pas = next(w for w in wps if w["kind"] == "pass")
            tables = [
                w["name"]
                for w in sorted(
                    (w for w in wps if w["kind"] == "table"),
                    key=lambda w: math.hypot(w["x"] - pas["x"], w["y"] - pas["y"]),
                )[: ns.tables]
            ]
            service = Service(staff, tables, urls)
            await service.start()
            try:
                await _phases(ns, results, clients, service, url, token, spid, echo)
            finally:
                await service.stop()
                results["service"] = {
                    "trips": service.trips,
                    "errors": service.errors,
                    "robots_moving_at_end": service.moving(),
                }
            for c in clients:
                await c.ws.close()
        finally:
            for p in reversed(procs):
                if p.returncode is None:
                    p.send_signal(2)  # SIGINT: each process shuts down cleanly
                    try:
                        await asyncio.wait_for(p.wait(), 15)
                    except TimeoutError:
                        p.kill()
                        await p.wait()
    return results


async def _phases(
    ns: argparse.Namespace,
    results: dict[str, Any],
    clients: list[Load],
    service: Service,
    url: str,
    token: str,
    spid: int,
    echo: asyncio.subprocess.Process,
) -> None:
    """Phases 3-5, the service running."""
    staff = clients[0]
    # The service under way: robots leave as soon as they are loaded.
    await staff.until(lambda: service.moving() >= max(1, ns.robots // 2), 60)
    await asyncio.gather(
        *(c.call("data", topics=[f"pose:r{1 + i % ns.robots}"]) for i, c in enumerate(clients[1:]))
    )
    streamed0 = sum(c.streamed for c in clients)
    cpu0, _ = _proc_stats(spid)
    sched0 = _sched(spid), _sched(echo.pid)
    t0 = time.monotonic()
    echo_url = f"ws://127.0.0.1:{results['echo_port']}"
    if ns.probe_in_process:
        results["latency"] = await phase_latency(staff, echo_url, ns.samples)
    else:
        results["latency"] = await phase_latency_process(
            url, echo_url, token, ns.samples, _prefix(ns, cpu=None)
        )
    lat = results["latency"]
    took = time.monotonic() - t0
    lat["probe"] = "in-process" if ns.probe_in_process else "own process"
    lat["seconds"] = took
    lat["stream_frames_per_s"] = (sum(c.streamed for c in clients) - streamed0) / took
    cpu1, rss = _proc_stats(spid)
    lat["server_cpu_percent"] = 100 * (cpu1 - cpu0) / took
    lat["rss_mb_watching"] = rss / 2**20
    # how long each server waited for a CPU while runnable, over the latency phase
    lat["serveur_sched"] = _sched_delta(sched0[0], _sched(spid))
    lat["echo_sched"] = _sched_delta(sched0[1], _sched(echo.pid))
    print("latency", lat, flush=True)
    for i, c in enumerate(clients[1:]):
        await c.call("data", topics=[f"pose:r{1 + i % ns.robots}"], unsubscribe=True)
    if ns.latency_only:
        return
    results["fanout"] = await phase_fanout(clients, ns.fanout_seconds)
    print("fanout", results["fanout"], flush=True)
    since = time.perf_counter()
    await asyncio.sleep(ns.dispatch_seconds)
    results["dispatch"] = service.window(since)
    print("dispatch", results["dispatch"], flush=True)


def _prefix(ns: argparse.Namespace, cpu: int | None) -> list[str]:
    """The command prefix for a measured process (a server, or the probe when ``cpu`` is
    None: it stays on the load's CPU, which it inherits from this process under ``--pin``)."""
    out: list[str] = []
    if ns.rt:
        out += ["chrt", "-r", "1"]
    elif ns.server_nice:
        out += ["nice", "-n", str(ns.server_nice)]
    if ns.pin and cpu is not None:
        out += ["taskset", "-c", str(cpu)]
    return out


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, default=200)
    ap.add_argument("--robots", type=int, default=10)
    ap.add_argument("--samples", type=int, default=2000)
    ap.add_argument("--idle", type=float, default=20.0, help="seconds of idle measurement")
    ap.add_argument(
        "--amcl",
        choices=("continuous", "real"),
        default="continuous",
        help="the simulated robots' AMCL (serveur sim --amcl): 10 Hz whatever happens, or as "
        "the amcl node, silent while parked",
    )
    ap.add_argument(
        "--idle-amcl",
        choices=("continuous", "real"),
        default="real",
        help="the AMCL of the parked robots whose idle CPU is measured (default real: as the "
        "amcl node, silent while parked; measured in a run of its own before the others)",
    )
    ap.add_argument(
        "--settle",
        type=float,
        default=2.0,
        help="seconds after every robot is online before the idle measurement (2)",
    )
    ap.add_argument("--fanout-seconds", type=float, default=20.0)
    ap.add_argument(
        "--dispatch-seconds",
        type=float,
        default=90.0,
        help="seconds of the service whose trips' dispatch is timed",
    )
    ap.add_argument(
        "--min-frames",
        type=float,
        default=1000.0,
        help="pose frames a second the clients must receive in the latency phase (199 "
        "clients, each watching one of 10 moving robots: ~1,300 with the server's pose gate, "
        "which publishes a pose that moved 8 cm, at most 10 a second)",
    )
    ap.add_argument(
        "--tables",
        type=int,
        default=8,
        help="the service sends dishes to the N tables nearest the pass, in turn",
    )
    ap.add_argument("--profile", action="store_true")
    ap.add_argument(
        "--footprint-only", action="store_true", help="stop after the RSS / idle CPU phase"
    )
    ap.add_argument(
        "--probe-in-process",
        action="store_true",
        help="time the probe from the load process (the old method) instead of its own process",
    )
    ap.add_argument(
        "--sim-spread",
        action="store_true",
        help="serveur sim --spread-phases: robot i's poses i/N of the period after robot 0's",
    )
    ap.add_argument(
        "--pin",
        action="store_true",
        help="serveur and the echo server on CPU 0; the simulator, the load clients and the "
        "probe on CPU 1",
    )
    ap.add_argument(
        "--rt",
        action="store_true",
        help="serveur, the echo server and the probe under SCHED_RR priority 1 (chrt, needs "
        "root), both servers alike",
    )
    ap.add_argument(
        "--server-nice",
        type=int,
        default=0,
        metavar="N",
        help="serveur, the echo server and the probe at nice N (negative needs root)",
    )
    ap.add_argument(
        "--isolate",
        action="store_true",
        help="--pin --rt: what is measured is shielded from other work on a shared host",
    )
    ap.add_argument("--latency-only", action="store_true", help="stop after the latency phase")
    ap.add_argument("--echo-server", action="store_true", help=argparse.SUPPRESS)
    ap.add_argument("--probe", nargs=4, help=argparse.SUPPRESS)
    args = ap.parse_args()
    if args.probe:
        purl, pecho, ptoken, psamples = args.probe
        asyncio.run(_probe_main(purl, pecho, ptoken, int(psamples)))
        sys.exit(0)
    if args.echo_server:
        with contextlib.suppress(KeyboardInterrupt):
            asyncio.run(_echo_main())
        sys.exit(0)
    if args.isolate:
        args.pin = args.rt = True
    if args.pin:
        os.sched_setaffinity(0, {1})  # the load clients and the simulator (started from here)
    parked = None
    if args.idle_amcl != args.amcl and not args.latency_only:
        # Parked robots first, as they are on site: a real amcl node publishes nothing while
        # its robot stands still; the streaming phases keep the simulator's 10 Hz poses.
        idle_args = argparse.Namespace(**{**vars(args), "amcl": args.idle_amcl})
        idle_args.footprint_only = True
        parked = asyncio.run(main(idle_args))["footprint"]
    out = asyncio.run(main(args))
    if parked is not None:
        streaming = out["footprint"]
        out["footprint"] = {
            **parked,
            "amcl": args.idle_amcl,
            "rss_mb": max(parked["rss_mb"], streaming["rss_mb"]),
            "idle_cpu_percent_amcl_streaming": streaming["idle_cpu_percent"],
        }
    out["verdict"] = verdict(out, args)
    print(json.dumps(out, indent=1))
    failed = [name for name, v in out["verdict"].items() if v != "ok"]
    print("targets:", "all met" if not failed else "NOT met: " + "; ".join(failed))
    sys.exit(1 if failed else 0)
