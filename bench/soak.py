"""Soak: 500 clients and 10 robots through a bounded service; memory growth, errors, seq gaps.

Three processes on loopback, every one stopped by this script:

* ``serveur sim`` — the robots (demo room with one home spot per robot), time-scaled;
* ``serveur run`` — the server, same time scale, its log kept in a file and scanned;
* this process — ``--clients`` watchers subscribed to ``robots``, ``orders`` and ``tasks``
  (every fiftieth also to one robot's ``pose:`` stream), plus one staff client that sends a
  seeded stream of carts (1-4 dishes at random tables) for ``--duration`` wall seconds,
  presses Go on every robot Loading at the pass (the server runs without ``--auto-depart``,
  as sites do), "food collected" at every table and "continue" on any robot in Error.

After the load it stops sending, lets the robots finish (``--drain`` seconds at most), then
judges every watcher that was not disconnected: its ``seq`` numbers must have no gap, and
its view must match the database — each order it was told about delivered, each trip done
(no update lost). Server RSS is sampled every second; growth is measured from the end of the
warm-up (the first ``--warmup`` seconds of load: connections made, caches filled) to the end
of the load. Prints a JSON report.

    python bench/soak.py                     # 500 clients, 10 robots, 180 s of load
    python bench/soak.py --duration 30       # a quick look
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import random
import sqlite3
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import websockets
from bench_server import _free_port, _proc_stats, _world
from websockets.asyncio.client import ClientConnection, connect


class Watcher:
    """A tablet that keeps up: the latest record of every order, task and robot it hears of."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.n = 0
        self.pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self.records: dict[str, dict[Any, dict[str, Any]]] = {
            "orders": {},
            "tasks": {},
            "robots": {},
        }
        self.last_seq = 0
        self.gaps = 0
        self.frames = 0
        self.close_code: int | None = None
        self.changed = asyncio.Event()
        self.task = asyncio.create_task(self.read())

    async def read(self) -> None:
        try:
            async for frame in self.ws:
                self.frames += 1
                msg = json.loads(frame)
                if msg["servermsg"] == "update":
                    if self.last_seq and msg["seq"] != self.last_seq + 1:
                        self.gaps += 1
                    self.last_seq = msg["seq"]
                    topic = msg["topic"]
                    if topic in self.records:
                        key = "name" if topic == "robots" else "id"
                        self.records[topic][msg["data"][key]] = msg["data"]
                        self.changed.set()
                    continue
                fut = self.pending.pop(msg.get("id"), None)
                if fut is not None and not fut.done():
                    fut.set_result(msg)
        except websockets.exceptions.ConnectionClosed:
            pass
        self.close_code = self.ws.close_code

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        self.n += 1
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self.pending[self.n] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": self.n, **fields}))
        return await asyncio.wait_for(fut, 60)

    async def subscribe(self, *topics: str) -> None:
        reply = await self.call("data", topics=list(topics))
        for topic, snap in reply["data"].items():
            if topic in self.records:
                key = "name" if topic == "robots" else "id"
                for rec in snap:
                    self.records[topic][rec[key]] = rec

    async def until(self, cond: Any, limit: float) -> bool:
        async def wait() -> None:
            while not cond():
                self.changed.clear()
                await self.changed.wait()

        try:
            await asyncio.wait_for(wait(), limit)
            return True
        except TimeoutError:
            return False


async def _start(cmd: list[str], lines: int, stderr: Any) -> tuple[Any, list[str]]:
    proc = await asyncio.create_subprocess_exec(*cmd, stdout=asyncio.subprocess.PIPE, stderr=stderr)
    assert proc.stdout is not None
    out = [(await asyncio.wait_for(proc.stdout.readline(), 60)).decode().strip()]
    while len(out) < lines:
        out.append((await asyncio.wait_for(proc.stdout.readline(), 60)).decode().strip())
    return proc, out


async def staff_loop(
    staff: Watcher, robots: list[str], rng: random.Random, tables: list[str], ns: Any, stats: Any
) -> None:
    """Carts at a steady pace while the load lasts; food collected and continue always."""
    load_end = time.monotonic() + ns.duration
    next_cart = time.monotonic()
    orders = staff.records["orders"]
    while True:
        now = time.monotonic()
        if now < load_end and now >= next_cart:
            queued = sum(t["status"] == "queued" for t in staff.records["tasks"].values())
            if queued < len(robots):  # a kitchen does not pile up more than it can send
                ids = []
                for _ in range(rng.randint(1, 4)):
                    rep = await staff.call(
                        "create", type="order", dish="soak", table=rng.choice(tables)
                    )
                    ids.append(rep["order"]["id"])
                    orders.setdefault(rep["order"]["id"], rep["order"])
                rep = await staff.call("create", type="task", orders=ids)
                if rep["servermsg"] != "ok":
                    stats["errors"].append(rep)
                stats["orders"] += len(ids)
            next_cart = now + ns.cart_every
        for name in robots:
            status = staff.records["robots"].get(name, {}).get("status")
            # Trips wait at the pass (Loading) until staff press Go, as on a site without
            # --auto-depart (the server's default).
            verb = {"Loading": "go", "Delivered": "next", "Error": "continue"}.get(status or "")
            if verb == "continue":
                reason = staff.records["robots"][name].get("last_error") or "?"
                stats["error_reasons"][reason] = stats["error_reasons"].get(reason, 0) + 1
            if verb:
                rep = await staff.call(verb, robot=name)
                if rep["servermsg"] == "ok":
                    staff.records["robots"][name] = rep["robot"]
                    stats[{"go": "departures", "next": "served"}.get(verb, "continues")] += 1
                elif rep["code"] != "not_allowed_in_status":
                    stats["errors"].append(rep)
        await staff.until(lambda: True, 0)  # yield
        await asyncio.sleep(0.05)


async def main(ns: argparse.Namespace) -> dict[str, Any]:
    rng = random.Random(ns.seed)
    report: dict[str, Any] = {"clients": ns.clients, "robots": ns.robots, "seconds": ns.duration}
    procs: list[Any] = []
    with tempfile.TemporaryDirectory(prefix="serveur-soak-") as tmpdir:
        tmp = Path(tmpdir)
        room, wps = _world(tmp, ns.robots)
        db = tmp / "soak.db"
        log_path = tmp / "server.log"
        log = log_path.open("w")
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
                    "--time-scale",
                    str(ns.time_scale),
                ],
                ns.robots,
                asyncio.subprocess.DEVNULL,
            )
            procs.append(sim)
            urls = [u.split()[-1] if " " in u else u for u in urls]
            urls = [u[u.index("ws://") :] for u in urls]
            port = _free_port()
            # A staff token for the load; the clients all come from 127.0.0.1, so the
            # per-address cap and the per-connection rate limit are lifted for the soak.
            made = await asyncio.create_subprocess_exec(
                sys.executable,
                "-m",
                "serveur.cli",
                "token",
                "create",
                "--role",
                "staff",
                "--db",
                str(db),
                stdout=asyncio.subprocess.PIPE,
                stderr=asyncio.subprocess.DEVNULL,
            )
            token = (await made.communicate())[0].decode().strip()
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
                str(db),
                "--map",
                str(room),
                "--waypoints",
                str(wps),
                "--time-scale",
                str(ns.time_scale),
            ]
            for i, url in enumerate(urls):
                cmd += ["--robot", f"r{i + 1}={url},home=home{i + 1}"]
            server, _ = await _start(cmd, 1, log)
            procs.append(server)
            url = f"ws://127.0.0.1:{port}/ws"
            names = [f"r{i + 1}" for i in range(ns.robots)]

            staff = Watcher(
                await connect(url, compression=None, max_size=2**24, additional_headers=auth)
            )
            await staff.subscribe("robots", "orders", "tasks", "waypoints")
            await staff.until(
                lambda: all(
                    staff.records["robots"].get(n, {}).get("status", "Offline") != "Offline"
                    for n in names
                ),
                60,
            )
            for n in names:
                await staff.call("control", robot=n, action="auto")
            tables = sorted(
                w["name"]
                for w in (await staff.call("data", topics=["waypoints"]))["data"]["waypoints"]
                if w["kind"] == "table"
            )
            watchers: list[Watcher] = []
            for i in range(ns.clients):
                w = Watcher(
                    await connect(url, compression=None, max_size=2**24, additional_headers=auth)
                )
                topics = ["robots", "orders", "tasks"]
                if i % 50 == 0:
                    topics.append(f"pose:{names[i // 50 % len(names)]}")
                await w.subscribe(*topics)
                watchers.append(w)
            print(f"{len(watchers)} clients connected", flush=True)

            stats: dict[str, Any] = {
                "orders": 0,
                "served": 0,
                "departures": 0,
                "continues": 0,
                "errors": [],
                "error_reasons": {},
            }
            rss: list[tuple[float, int]] = []
            cpu0, _ = _proc_stats(server.pid)
            t0 = time.monotonic()
            staff_task = asyncio.create_task(staff_loop(staff, names, rng, tables, ns, stats))
            while (elapsed := time.monotonic() - t0) < ns.duration:
                rss.append((elapsed, _proc_stats(server.pid)[1]))
                if staff_task.done():
                    staff_task.result()
                await asyncio.sleep(1.0)
            cpu1, rss_end = _proc_stats(server.pid)
            load_wall = time.monotonic() - t0
            # Drain: no new carts; the robots finish what was sent.
            all_done = await staff.until(
                lambda: (
                    all(o["status"] == "delivered" for o in staff.records["orders"].values())
                    and all(
                        staff.records["robots"].get(n, {}).get("status") == "Awaiting"
                        for n in names
                    )
                ),
                ns.drain,
            )
            staff_task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await staff_task

            # Judge the watchers against the database.
            con = sqlite3.connect(db)
            truth_orders = dict(con.execute("SELECT id, status FROM orders"))
            truth_tasks = dict(con.execute("SELECT id, status FROM task"))
            con.close()

            def lost(w: Watcher) -> int:
                o = w.records["orders"]
                t = w.records["tasks"]
                return sum(o.get(i, {}).get("status") != s for i, s in truth_orders.items()) + sum(
                    t.get(i, {}).get("status") != s for i, s in truth_tasks.items()
                )

            # Let slow readers catch up with what was sent (bounded): then compare.
            live = [w for w in watchers if w.close_code is None]
            await asyncio.gather(*(w.until(lambda w=w: lost(w) == 0, ns.catch_up) for w in live))
            lost_by = [lost(w) for w in live]
            warm = [r for t, r in rss if t >= ns.warmup]
            base = warm[0] if warm else rss[0][1]
            report.update(
                orders=stats["orders"],
                orders_delivered=sum(s == "delivered" for s in truth_orders.values()),
                trips=len(truth_tasks),
                departures=stats["departures"],
                stops_served=stats["served"],
                continues_after_error=stats["continues"],
                robot_error_reasons=stats["error_reasons"],
                service_finished=all_done,
                request_errors=stats["errors"][:10],
                request_error_count=len(stats["errors"]),
                server_rss_mb_after_warmup=round(base / 2**20, 1),
                server_rss_mb_end=round(rss_end / 2**20, 1),
                server_rss_mb_peak=round(max(r for _, r in rss) / 2**20, 1),
                memory_growth_percent=round(100 * (rss_end - base) / base, 2),
                server_cpu_percent=round(100 * (cpu1 - cpu0) / load_wall, 1),
                frames_to_clients=sum(w.frames for w in watchers),
                clients_disconnected=sum(w.close_code is not None for w in watchers),
                close_codes=sorted({w.close_code for w in watchers if w.close_code is not None}),
                seq_gaps=sum(w.gaps for w in watchers),
                clients_with_lost_updates=sum(n > 0 for n in lost_by),
                lost_updates=sum(lost_by),
            )
            for w in [staff, *watchers]:
                await w.ws.close()
        finally:
            for p in reversed(procs):
                if p.returncode is None:
                    p.send_signal(2)  # SIGINT: each process shuts down cleanly
                    try:
                        await asyncio.wait_for(p.wait(), 30)
                    except TimeoutError:
                        p.kill()
                        await p.wait()
            log.close()
        text = log_path.read_text(errors="replace")
        report["server_log_errors"] = text.count(" ERROR ") + text.count("Traceback")
        report["server_log_warnings"] = text.count(" WARNING ")
        report["robot_link_drops"] = text.count(": link down (")
        warnings = [ln for ln in text.splitlines() if " WARNING " in ln or " ERROR " in ln]
        report["server_log_sample"] = warnings[:5]
        report["server_exit_code"] = procs[-1].returncode if procs else None
    return report


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--clients", type=int, default=500)
    ap.add_argument("--robots", type=int, default=10)
    ap.add_argument("--duration", type=float, default=180.0, help="wall seconds of load")
    ap.add_argument("--warmup", type=float, default=30.0, help="seconds before RSS is the base")
    ap.add_argument("--drain", type=float, default=120.0, help="max seconds to finish trips")
    ap.add_argument("--catch-up", type=float, default=30.0, help="max seconds for clients")
    ap.add_argument("--cart-every", type=float, default=1.0, help="wall seconds between carts")
    ap.add_argument("--time-scale", type=float, default=5.0)
    ap.add_argument("--seed", type=int, default=0)
    out = asyncio.run(main(ap.parse_args()))
    print(json.dumps(out, indent=1))
    ok = (
        out["service_finished"]
        and out["seq_gaps"] == 0
        and out["lost_updates"] == 0
        and out["server_log_errors"] == 0
        and out["request_error_count"] == 0
    )
    sys.exit(0 if ok else 1)
