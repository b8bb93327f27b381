"""Camera relay: serveur against a minimal asyncio fan-out of the same frames, side by side.

One robot camera (a fake rosbridge in this process) publishes 640x480 JPEGs (``--kb``, 40 kB:
noise, so they do not compress below a real picture's size) at ``--fps`` (10) as CBOR
``sensor_msgs/CompressedImage``, stamped with the wall time they were sent. Two relays, each in
a child process under the same CPU quota (``--quota``, 0.5 of a core, a cgroup v1 ``cpu``
group; a Raspberry Pi 4 core is some 3x slower than a PC's, so half a core is generous to
neither), take that one stream and serve ``--viewers`` (5) tablets, one after the other:

* **serveur** — an :class:`serveur.app.App` with one robot whose ``camera`` option names the
  topic: the viewers log in with a token and send ``camera`` ``watch``; the server opens one
  subscription and relays (core/camera.py, server.py);
* **baseline** — the least an asyncio program can do: one websockets client subscribed to the
  same topic and a websockets server that sends each frame, with the same header
  (wire/camera.py), to every connected viewer, in a loop of ``send`` (no latest-wins, no
  per-viewer pacing, no protocol, no login).

For ``--seconds`` (20) after a 2 s warm-up, the tablets (this process) record each frame's
latency (received minus the source's stamp: one clock) and the relay's CPU time is read from
``/proc/<pid>/stat``; before them, ``--idle`` (10) seconds with nobody watching give the
process's background (serveur's timers and a robot link that keeps retrying: the fake bridge
answers no move_base status). Reported per relay: CPU (% of a core) in all, idle, and the
difference (the relay's own), latency p50/p95/max, frames per viewer; and serveur's CPU over
the baseline's, in all and the relay's own, and its p95 minus the baseline's (goal: at most
1.5x, at most 20 ms). Loopback only; every wait is bounded; the children are stopped when done.

Run: ``python bench/bench_camera.py [--seconds 20] [--repeat 3] [--quota 0.5] [--json out.json]``.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import io
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import cbor2
import numpy as np
from PIL import Image
from websockets.asyncio.client import connect
from websockets.asyncio.server import ServerConnection, serve

TOPIC = "/camera/image/compressed"
CGROUP = Path("/sys/fs/cgroup/cpu")


def noisy_jpeg(kb: int) -> bytes:
    """A 640x480 JPEG of about ``kb`` kB (noise over a gradient: real pictures' size)."""
    rng = np.random.default_rng(0)
    base = np.linspace(0, 255, 640)[None, :, None] * np.ones((480, 1, 3))
    for amp in range(2, 120, 2):
        img = np.clip(base + rng.normal(0, amp, base.shape), 0, 255).astype(np.uint8)
        out = io.BytesIO()
        Image.fromarray(img, "RGB").save(out, "JPEG", quality=80)
        if out.tell() >= kb * 1000:
            return out.getvalue()
    return out.getvalue()


# -- the source: a rosbridge that publishes the camera ---------------------------------------


async def source(fps: float, jpeg: bytes) -> tuple[Any, list[int]]:
    """A fake rosbridge on 127.0.0.1: every client that subscribes to TOPIC gets the frames
    (CBOR); other ops are ignored. Returns the server and a one-item list: frames sent."""
    subscribers: set[ServerConnection] = set()
    sent = [0]

    async def handler(ws: ServerConnection) -> None:
        with contextlib.suppress(Exception):
            async for raw in ws:
                op = json.loads(raw) if isinstance(raw, str) else {}
                if op.get("op") == "subscribe" and op.get("topic") == TOPIC:
                    subscribers.add(ws)
        subscribers.discard(ws)

    async def publish() -> None:
        period = 1.0 / fps
        next_at = time.monotonic()
        while True:
            next_at += period
            await asyncio.sleep(max(0.0, next_at - time.monotonic()))
            now = time.time()
            secs = int(now)
            msg = {
                "header": {
                    "seq": sent[0],
                    "stamp": {"secs": secs, "nsecs": int((now - secs) * 1e9)},
                },
                "format": "jpeg",
                "data": jpeg,
            }
            frame = cbor2.dumps({"op": "publish", "topic": TOPIC, "msg": msg})
            for ws in list(subscribers):
                with contextlib.suppress(Exception):
                    await ws.send(frame)
            sent[0] += 1

    server = await serve(handler, "127.0.0.1", 0, max_size=2**24, compression=None)
    asyncio.get_running_loop().create_task(publish())
    return server, sent


# -- the two relays (child processes) ------------------------------------------------------


async def run_serveur(source_url: str) -> None:
    from serveur.app import App, RobotSpec
    from serveur.clock import ScaledClock
    from serveur.maps.navigation import load_demo

    grid, waypoints = load_demo()
    db = Path(tempfile.mkdtemp()) / "bench.db"
    spec = RobotSpec("r1", source_url, None, link={"camera": TOPIC})
    app = App(db, port=0, clock=ScaledClock(1.0), nav_map=grid, waypoints=waypoints, robots=[spec])
    await app.start()
    token = await app.issue_token("staff", label="bench")
    print(json.dumps({"url": app.url, "token": token}), flush=True)
    await asyncio.Event().wait()


async def run_baseline(source_url: str) -> None:
    from serveur.robots.camera import frame_of
    from serveur.wire.camera import camera_frame

    viewers: set[ServerConnection] = set()

    async def handler(ws: ServerConnection) -> None:
        viewers.add(ws)
        with contextlib.suppress(Exception):
            await ws.wait_closed()
        viewers.discard(ws)

    # No per-message deflate anywhere (websockets' default): JPEG does not compress, and
    # serveur's server and camera connection have it off too.
    server = await serve(handler, "127.0.0.1", 0, max_size=2**24, compression=None)
    port = server.sockets[0].getsockname()[1]
    print(json.dumps({"url": f"ws://127.0.0.1:{port}/", "token": None}), flush=True)
    seq = 0
    async with connect(source_url, max_size=2**24, compression=None) as up:
        sub = {"op": "subscribe", "topic": TOPIC, "compression": "cbor", "queue_length": 1}
        await up.send(json.dumps(sub))
        async for raw in up:
            got = frame_of(raw, TOPIC)
            if got is None:
                continue
            seq += 1
            jpeg, captured = got
            now = time.time()
            msg = camera_frame("r1", seq, captured, now, now, jpeg)
            for ws in list(viewers):
                with contextlib.suppress(Exception):
                    await ws.send(msg)


# -- the tablets and the measurement --------------------------------------------------------


def cpu_seconds(pid: int) -> float:
    fields = Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")


def limit(pid: int, quota: float) -> str:
    """Put ``pid`` under a CPU quota (cgroup v1 cpu); what was done, for the report."""
    group = CGROUP / f"serveur-bench-{os.getpid()}-{pid}"
    try:
        group.mkdir()
        (group / "cpu.cfs_period_us").write_text("100000")
        (group / "cpu.cfs_quota_us").write_text(str(int(quota * 100000)))
        (group / "cgroup.procs").write_text(str(pid))
    except OSError as exc:
        return f"no quota ({exc})"
    return f"{quota:g} of a core"


def unlimit(pid: int) -> None:
    group = CGROUP / f"serveur-bench-{os.getpid()}-{pid}"
    with contextlib.suppress(OSError):
        group.rmdir()


async def watch(url: str, token: str | None, seconds: float, out: list[float]) -> int:
    """One tablet: connect, watch r1, record each frame's latency (s) after the warm-up."""
    from serveur.wire.camera import read_camera_frame

    headers = {"Authorization": f"Bearer {token}"} if token else {}
    frames = 0
    async with connect(url, additional_headers=headers, max_size=2**24, compression=None) as ws:
        if token:
            await ws.send(
                json.dumps({"clientmsg": "camera", "id": 1, "robot": "r1", "watch": True})
            )
        start = time.monotonic()
        with contextlib.suppress(TimeoutError):
            async with asyncio.timeout(seconds + 2.0):
                async for msg in ws:
                    if not isinstance(msg, bytes):
                        continue
                    header, _ = read_camera_frame(msg)
                    if time.monotonic() - start >= 2.0:  # warm-up over
                        out.append(time.time() - header["captured"])
                        frames += 1
    return frames


async def measure(kind: str, args: argparse.Namespace, source_url: str) -> dict[str, Any]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable, __file__, "--child", kind, source_url, stdout=subprocess.PIPE
    )
    try:
        assert proc.stdout is not None
        line = b""
        while not line.startswith(b"{"):  # the child's own output before its address
            line = await asyncio.wait_for(proc.stdout.readline(), 60)
            if not line:
                raise RuntimeError(f"the {kind} relay ended before it listened")
        info = json.loads(line)
        quota = limit(proc.pid, args.quota)
        # The relay's own background (serveur: its timers, a robot link that retries) with
        # nobody watching, to tell the relay's cost from the server's.
        await asyncio.sleep(2.0)  # start-up over (the bench's pacing)
        idle0, i0 = cpu_seconds(proc.pid), time.monotonic()
        await asyncio.sleep(args.idle)  # the window measured (not a wait for a result)
        idle = (cpu_seconds(proc.pid) - idle0) / (time.monotonic() - i0)
        latencies: list[float] = []
        tasks = [
            asyncio.create_task(watch(info["url"], info["token"], args.seconds, latencies))
            for _ in range(args.viewers)
        ]
        await asyncio.sleep(2.0)  # warm-up (the bench's own pacing, not a wait for a result)
        cpu0, t0 = cpu_seconds(proc.pid), time.monotonic()
        frames = await asyncio.gather(*tasks)
        cpu = (cpu_seconds(proc.pid) - cpu0) / (time.monotonic() - t0)
        lat = sorted(latencies)
        return {
            "relay": kind,
            "quota": quota,
            "cpu_pct": round(100 * cpu, 2),
            "idle_cpu_pct": round(100 * idle, 2),
            "relay_cpu_pct": round(100 * max(0.0, cpu - idle), 2),
            "p50_ms": round(1000 * statistics.median(lat), 1),
            "p95_ms": round(1000 * lat[int(0.95 * (len(lat) - 1))], 1),
            "max_ms": round(1000 * lat[-1], 1),
            "frames_per_viewer": [int(f) for f in frames],
        }
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
        unlimit(proc.pid)


async def main(args: argparse.Namespace) -> dict[str, Any]:
    jpeg = noisy_jpeg(args.kb)
    server, _sent = await source(args.fps, jpeg)
    url = f"ws://127.0.0.1:{server.sockets[0].getsockname()[1]}"
    runs: dict[str, list[dict[str, Any]]] = {"baseline": [], "serveur": []}
    try:
        for _ in range(args.repeat):  # alternating, so a slow minute of the machine hits both
            for kind in runs:
                runs[kind].append(await measure(kind, args, url))
                print(json.dumps(runs[kind][-1]), flush=True)
    finally:
        server.close()

    def med(kind: str, key: str) -> float:
        return float(statistics.median(r[key] for r in runs[kind]))

    base_cpu, ours_cpu = med("baseline", "cpu_pct"), med("serveur", "cpu_pct")
    ours_idle = med("serveur", "idle_cpu_pct")
    summary = {
        "frame_kb": round(len(jpeg) / 1000, 1),
        "fps": args.fps,
        "viewers": args.viewers,
        "seconds": args.seconds,
        "repeat": args.repeat,
        "baseline_cpu_pct": base_cpu,
        "serveur_cpu_pct": ours_cpu,
        "serveur_idle_cpu_pct": ours_idle,
        # The whole process against the whole baseline: serveur's includes a restaurant
        # server's own work (its robot link, timers, the store) that goes on with nobody
        # watching.
        "cpu_ratio": round(ours_cpu / max(0.01, base_cpu), 2),
        # What watching adds to serveur (its CPU watching minus its CPU with nobody watching:
        # the relay, upstream included) against the baseline's whole CPU (it does nothing but
        # relay).
        "relay_vs_baseline": round(max(0.0, ours_cpu - ours_idle) / max(0.01, base_cpu), 2),
        "added_p95_ms": round(med("serveur", "p95_ms") - med("baseline", "p95_ms"), 1),
        "results": runs,
    }
    print(json.dumps({k: v for k, v in summary.items() if k != "results"}))
    return summary


if __name__ == "__main__":
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        kind, url = sys.argv[2], sys.argv[3]
        asyncio.run(run_serveur(url) if kind == "serveur" else run_baseline(url))
        sys.exit(0)
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seconds", type=float, default=20.0)
    p.add_argument("--viewers", type=int, default=5)
    p.add_argument("--fps", type=float, default=10.0)
    p.add_argument("--kb", type=int, default=40)
    p.add_argument("--quota", type=float, default=0.5)
    p.add_argument("--idle", type=float, default=10.0, help="seconds of CPU with no viewer")
    p.add_argument("--repeat", type=int, default=1, help="runs of each relay; medians reported")
    p.add_argument("--json")
    args = p.parse_args()
    summary = asyncio.run(main(args))
    if args.json:
        Path(args.json).write_text(json.dumps(summary, indent=2))
