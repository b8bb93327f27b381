"""What the console's "Back up now" costs a restaurant in service: the copy's time, and how long
staff requests wait meanwhile, on a database the size of a year of service.

The server runs in a child process under a CPU quota (``--quota``, 0.5 of a core by default,
a cgroup v1 ``cpu`` group as bench/bench_camera.py does: the Pi's share), on a SQLite file
filled first with ``--events`` events and ``--audit`` audit rows (a busy restaurant writes
about 3,000 events and 1,500 audit rows a day: the defaults are a year). This script is the
tablets: a probe connection sends ``ping`` every ``--period`` (20 ms: the event loop's
answer, no database) and a staff connection creates a dish every 100 ms (a write: it waits
for the store while the copy holds it). Their latencies are taken for ``--before`` seconds of
quiet, then while an owner connection's ``backup_now`` runs (the copy, then its read-back
check), and reported per phase (p50 / p99 / max) with the backup's time and size.

Run: ``python bench/bench_backup.py [--events 1100000] [--audit 550000] [--quota 0.5]
[--repeat 3] [--json out.json]``. Loopback only; every wait is bounded; the server stops with
the bench.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import os
import random
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_camera import limit, unlimit  # the same cgroup helpers

KINDS = ("order.created", "order.ready", "task.created", "robot.status", "stop.arrived")


def fill(db: Path, events: int, audit: int) -> None:
    """A serveur database (its own migrations) with a year's events and audit rows."""
    from serveur.maps.navigation import load_demo
    from serveur.store.sqlite.store import SQLiteStore

    async def schema() -> None:
        async with SQLiteStore(db) as store:
            from serveur.app import import_waypoints

            await import_waypoints(store, load_demo()[1].values(), now=time.time())

    asyncio.run(schema())
    rng = random.Random(0)
    t0 = time.time() - 365 * 86400
    con = sqlite3.connect(db)
    with con:
        con.executemany(
            "INSERT INTO events (ts, kind, robot, task_id, order_id, data) VALUES (?,?,?,?,?,?)",
            (
                (
                    t0 + i * 28.0,
                    KINDS[i % len(KINDS)],
                    f"r{i % 3 + 1}",
                    None,
                    None,
                    json.dumps({"table": f"T{rng.randint(1, 16)}", "seq": i % 7}),
                )
                for i in range(events)
            ),
        )
        con.executemany(
            "INSERT INTO audit (ts, actor, role, peer, verb, target, outcome, data)"
            " VALUES (?,?,?,?,?,?,?,?)",
            (
                (t0 + i * 57.0, "user:ana", "staff", "10.0.0.31:51234", "go", "r1", "ok", "{}")
                for i in range(audit)
            ),
        )
    con.execute("PRAGMA wal_checkpoint(TRUNCATE)")
    con.close()


# -- the server (child process) ---------------------------------------------------------------


async def child(db: str, backups: str) -> None:
    from serveur.app import App

    app = App(db, port=0, backups=backups)
    await app.start()
    token = await app.issue_token("staff", label="bench")
    # Backups need an owner's session (the accounts scope: no token has it).
    password = app.first_owner_password
    print(json.dumps({"url": app.url, "token": token, "password": password}), flush=True)
    with contextlib.suppress(asyncio.CancelledError):
        await asyncio.Event().wait()  # until the bench stops it
    await app.close()


# -- the tablets ---------------------------------------------------------------------------------


async def ticker(url: str, token: str, msg: dict[str, Any], period: float, out: list) -> None:
    """Send ``msg`` every ``period`` s on a fixed schedule; (sent at, latency) of each reply."""
    async with connect(url, additional_headers={"Authorization": f"Bearer {token}"}) as ws:
        n = 0
        start = time.monotonic()
        while True:
            n += 1
            body = {**msg, "id": n}
            if msg.get("clientmsg") == "create":
                body["key"] = f"bench-{os.getpid()}-{n}"
            sent = time.monotonic()
            await ws.send(json.dumps(body))
            reply = json.loads(await asyncio.wait_for(ws.recv(), 60))
            assert reply.get("servermsg") == "ok", reply
            out.append((sent, time.monotonic() - sent))
            await asyncio.sleep(max(0.0, start + n * period - time.monotonic()))


def summary(latencies: list[float]) -> dict[str, float]:
    ms = sorted(x * 1000 for x in latencies)
    if not ms:
        return {}
    return {
        "n": len(ms),
        "p50_ms": round(statistics.median(ms), 1),
        "p99_ms": round(ms[min(len(ms) - 1, int(len(ms) * 0.99))], 1),
        "max_ms": round(ms[-1], 1),
    }


async def once(args: argparse.Namespace, db: Path, folder: Path) -> dict[str, Any]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, __file__, "--child", str(db), str(folder), stdout=subprocess.PIPE
    )
    try:
        assert proc.stdout is not None
        line = b""
        while not line.startswith(b"{"):
            line = await asyncio.wait_for(proc.stdout.readline(), 120)
            if not line:
                raise RuntimeError("the server ended before it listened")
        info = json.loads(line)
        quota = limit(proc.pid, args.quota)
        pings: list[tuple[float, float]] = []
        writes: list[tuple[float, float]] = []
        dish = {"clientmsg": "create", "type": "order", "dish": "Laksa", "table": "T3"}
        tasks = [
            asyncio.create_task(
                ticker(info["url"], info["token"], {"clientmsg": "ping"}, args.period, pings)
            ),
            asyncio.create_task(
                ticker(info["url"], info["token"], {**dish, "status": "ordered"}, 0.1, writes)
            ),
        ]
        await asyncio.sleep(args.before)  # the quiet phase (the bench's pacing)
        async with connect(info["url"]) as ws:
            login = {"clientmsg": "login", "id": 0, "username": "owner"}
            await ws.send(json.dumps({**login, "password": info["password"]}))
            logged = json.loads(await asyncio.wait_for(ws.recv(), 30))
            assert logged["servermsg"] == "ok", logged
            b0 = time.monotonic()
            await ws.send(json.dumps({"clientmsg": "site", "id": 1, "action": "backup_now"}))
            reply = json.loads(await asyncio.wait_for(ws.recv(), 600))
            b1 = time.monotonic()
        assert reply.get("servermsg") == "ok", reply
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)

        def phase(rows: list[tuple[float, float]], during: bool) -> list[float]:
            return [lat for sent, lat in rows if (b0 <= sent <= b1) == during]

        during = [(sent, lat) for sent, lat in writes if b0 <= sent <= b1]
        worst = max(during, key=lambda w: w[1], default=(b0, 0.0))
        return {
            "quota": quota,
            # When the slowest write was sent, from the backup's start (the copy, then its check).
            "worst_write_at_s": round(worst[0] - b0, 2),
            "backup_s": round(b1 - b0, 2),
            "size_mb": round(reply["backup"]["size"] / 1e6, 1),
            "check": reply["backup"]["check"],
            "ping_before": summary(phase(pings, False)),
            "ping_during": summary(phase(pings, True)),
            "write_before": summary(phase(writes, False)),
            "write_during": summary(phase(writes, True)),
        }
    finally:
        unlimit(proc.pid)
        with contextlib.suppress(ProcessLookupError):
            proc.terminate()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(proc.wait(), 20)
        if proc.returncode is None:
            proc.kill()


async def main(args: argparse.Namespace) -> dict[str, Any]:
    with tempfile.TemporaryDirectory(prefix="serveur-bench-backup-") as tmp:
        db = Path(tmp) / "serveur.db"
        t = time.monotonic()
        await asyncio.to_thread(fill, db, args.events, args.audit)
        print(
            f"filled {db.stat().st_size / 1e6:.0f} MB in {time.monotonic() - t:.0f} s",
            file=sys.stderr,
        )
        runs = []
        for i in range(args.repeat):
            run = await once(args, db, Path(tmp) / f"backups-{i}")
            print(json.dumps(run), file=sys.stderr)
            runs.append(run)
    med = {
        "backup_s": statistics.median(r["backup_s"] for r in runs),
        "size_mb": runs[0]["size_mb"],
        **{
            f"{k}_{m}": statistics.median(r[k][m] for r in runs)
            for k in ("ping_before", "ping_during", "write_before", "write_during")
            for m in ("p50_ms", "p99_ms", "max_ms")
        },
    }
    return {
        "events": args.events,
        "audit": args.audit,
        "quota": runs[0]["quota"],
        "median": med,
        "runs": runs,
    }


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        with contextlib.suppress(KeyboardInterrupt):
            asyncio.run(child(sys.argv[2], sys.argv[3]))
        sys.exit(0)
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--events", type=int, default=1_100_000)
    ap.add_argument("--audit", type=int, default=550_000)
    ap.add_argument("--quota", type=float, default=0.5)
    ap.add_argument("--period", type=float, default=0.02)
    ap.add_argument("--before", type=float, default=5.0)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--json")
    a = ap.parse_args()
    result = asyncio.run(main(a))
    print(json.dumps(result["median"], indent=1))
    if a.json:
        Path(a.json).write_text(json.dumps(result, indent=1))
