"""How many simulated robots one CPU core keeps in real time.

Run: ``python bench/bench_sim.py`` (about two minutes; figures go into the "## Simulator"
section of docs/performance.md). Loopback only; every step is bounded in time.

For each fleet size N of the ramp, the simulator (this process, pinned to ONE core with
``os.sched_setaffinity``) runs N robots at time scale 1. A separate client process, pinned to
the other cores so that its CPU is not counted against the simulator, opens one websocket per
robot and subscribes to ``/amcl_pose`` (10 Hz) and ``/scan`` (5 Hz, 360 rays). After a warm-up
the bench measures, over a fixed window: the messages *stamped* inside the window that reached
the client (vs 10 and 5 per robot-second) and how late (99th percentile of arrival - stamp;
the sim clock is wall time at scale 1), physics steps taken vs the 20 Hz due (sim time slipping
= not real time), and the simulator's CPU (user + system, all its threads). Two workloads:
robots parked (a scan at rest re-uses its ray-cast) and robots driving between tables
non-stop (a fresh ray-cast every scan, path following, goals and plans).

N "sustains real time" when both rates are >= 97 % of expected, p99 latency < 100 ms, physics
>= 99 % and CPU < 95 %. The ramp of each workload stops after the first size that does not.
Pinning gives the simulator a core to itself only if nothing else runs there: on a shared
machine other processes' load shows up as lower rates at a lower CPU figure.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import datetime
import itertools
import math
import multiprocessing as mp
import os
import platform
import re
import resource
import sys
import time
from dataclasses import dataclass
from multiprocessing.connection import Connection
from typing import Any

from websockets.asyncio.client import connect

from serveur.maps.navigation import load_demo
from serveur.robot_sim import TICK, Simulation, start_simulation
from serveur.robots import rosbridge as rb

EXPECTED_HZ = {"/amcl_pose": 10.0, "/scan": 5.0}
PREFIXES = {topic: f'{{"op":"publish","topic":"{topic}"'.encode() for topic in EXPECTED_HZ}
STAMP = re.compile(rb'"stamp":\{"secs":(\d+),"nsecs":(\d+)\}')
DRAIN = 1.0  # s the client keeps listening after the window, for messages still in flight


# -- the client process ----------------------------------------------------------------------


def _client_main(conn: Connection, urls: list[str], cores: set[int]) -> None:
    if cores:
        os.sched_setaffinity(0, cores)
    asyncio.run(_client(conn, urls))


async def _client(conn: Connection, urls: list[str]) -> None:
    """Receive everything; report, per topic, the messages stamped inside the window and how
    late they arrived (the simulator stamps with its clock, which at scale 1 is wall time)."""
    seen: dict[str, list[tuple[float, float]]] = {t: [] for t in EXPECTED_HZ}  # (stamp, arrival)
    state = {"recording": False}
    ready = asyncio.Event()
    scanned: set[int] = set()
    loop = asyncio.get_running_loop()

    async def one(i: int, url: str) -> None:
        async with connect(url, max_size=None, compression=None) as ws:
            for topic in EXPECTED_HZ:
                await ws.send(rb.encode(rb.op_subscribe(topic)))
            while True:
                frame = await ws.recv(decode=False)
                arrival = time.time()
                for topic, prefix in PREFIXES.items():
                    if frame.startswith(prefix):
                        if state["recording"]:
                            m = STAMP.search(frame, 0, 200)
                            assert m is not None
                            seen[topic].append((int(m[1]) + int(m[2]) * 1e-9, arrival))
                        elif topic == "/scan" and i not in scanned:
                            scanned.add(i)
                            if len(scanned) == len(urls):
                                ready.set()
                        break

    tasks = [asyncio.ensure_future(one(i, u)) for i, u in enumerate(urls)]
    try:
        await asyncio.wait_for(ready.wait(), 60)
        conn.send("ready")
        state["recording"] = True
        ru0 = resource.getrusage(resource.RUSAGE_SELF)
        e0, e1 = await loop.run_in_executor(None, conn.recv)  # the window, in sim epoch
        ru1 = resource.getrusage(resource.RUSAGE_SELF)
        await asyncio.sleep(DRAIN)
        state["recording"] = False
        report: dict[str, Any] = {
            "cpu": (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
        }
        for topic, items in seen.items():
            inside = [a - s for s, a in items if e0 <= s < e1]
            inside.sort()
            report[topic] = {
                "count": len(inside),
                "p99": inside[int(0.99 * (len(inside) - 1))] if inside else math.inf,
            }
        conn.send(report)
    finally:
        for t in tasks:
            t.cancel()
        await asyncio.gather(*tasks, return_exceptions=True)


# -- the simulator side ----------------------------------------------------------------------


@dataclass
class Step:
    n: int
    moving: bool
    window: float
    rates: dict[str, float]  # stamped in the window and received / expected
    latency: float  # worst topic's 99th percentile of (arrival - stamp), s
    physics: float  # physics steps taken / due
    sim_cpu: float  # fraction of one core
    client_cpu: float

    @property
    def sustained(self) -> bool:
        return (
            min(self.rates.values()) >= 0.97
            and self.physics >= 0.99
            and self.sim_cpu < 0.95
            and self.latency < 0.1
        )


async def _drive(sim: Simulation) -> None:
    """Keep every robot driving: a new table as soon as the last goal is over."""
    _, waypoints = load_demo()
    tables = [w for w in waypoints.values() if w.kind in ("table", "pass")]
    counter = itertools.count()
    while True:
        for i, robot in enumerate(sim.robots):
            if not any(s[1] not in rb.TERMINAL_STATUSES for s in robot.goal_statuses):
                w = tables[(i * 7 + next(counter)) % len(tables)]
                goal = rb.move_base_action_goal(
                    f"{robot.name}-{next(counter)}", w.x, w.y, w.yaw, stamp=sim.clock.epoch()
                )
                robot.inbox.handle_publish("/move_base/goal", goal)
        await asyncio.sleep(0.25)


def _ticks(sim: Simulation) -> int:
    return sum(r._ticks for r in sim.robots)


async def measure(n: int, *, moving: bool, warmup: float, window: float, cores: set[int]) -> Step:
    sim = await start_simulation(n, port=0, seed=1, time_scale=1.0)
    driver = asyncio.ensure_future(_drive(sim)) if moving else None
    ctx = mp.get_context("spawn")
    here, there = ctx.Pipe()
    proc = ctx.Process(target=_client_main, args=(there, sim.urls, cores), daemon=True)
    proc.start()
    loop = asyncio.get_running_loop()
    try:
        ready = await asyncio.wait_for(loop.run_in_executor(None, here.recv), 90)
        assert ready == "ready"
        await asyncio.sleep(warmup)
        ru0, t0, k0 = resource.getrusage(resource.RUSAGE_SELF), time.monotonic(), _ticks(sim)
        e0 = sim.clock.epoch()
        await asyncio.sleep(window)
        ru1, t1, k1 = resource.getrusage(resource.RUSAGE_SELF), time.monotonic(), _ticks(sim)
        e1 = sim.clock.epoch()
        here.send((e0, e1))
        report: dict[str, Any] = await asyncio.wait_for(loop.run_in_executor(None, here.recv), 30)
    finally:
        if driver is not None:
            driver.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await driver
        proc.join(10)
        if proc.is_alive():
            proc.terminate()
        await sim.close()
    wall = t1 - t0
    cpu = (ru1.ru_utime - ru0.ru_utime) + (ru1.ru_stime - ru0.ru_stime)
    rates = {t: report[t]["count"] / (EXPECTED_HZ[t] * n * (e1 - e0)) for t in EXPECTED_HZ}
    latency = max(report[t]["p99"] for t in EXPECTED_HZ)
    physics = (k1 - k0) / (n * wall / TICK)
    return Step(n, moving, wall, rates, latency, physics, cpu / wall, report["cpu"] / wall)


def _row(s: Step) -> str:
    return (
        f"| {s.n:>4} | {'driving' if s.moving else 'parked':>7} | "
        f"{s.rates['/amcl_pose'] * 100:6.1f} % | {s.rates['/scan'] * 100:6.1f} % | "
        f"{s.latency * 1000:6.1f} ms | "
        f"{s.physics * 100:6.1f} % | {s.sim_cpu * 100:5.1f} % | {s.client_cpu * 100:5.1f} % | "
        f"{'yes' if s.sustained else 'NO'} |"
    )


async def main_async(args: argparse.Namespace) -> None:
    sim_core = min(os.sched_getaffinity(0))
    others = os.sched_getaffinity(0) - {sim_core}
    os.sched_setaffinity(0, {sim_core})
    print(
        f"# bench_sim {datetime.date.today()} - {platform.python_implementation()} "
        f"{platform.python_version()}, {os.cpu_count()} CPUs, sim on core {sim_core}, "
        f"client on {sorted(others) or 'the same core (!)'}; warm-up {args.warmup} s, "
        f"window {args.window} s"
    )
    print(
        "|    N | robots  | amcl_pose | scan     | p99 latency | physics  | sim CPU | client CPU "
        "| real time |"
    )
    print(
        "|-----:|:-------:|----------:|---------:|------------:|---------:|--------:|-----------:"
        "|:---------:|"
    )
    for moving in (False, True) if args.workload == "both" else (args.workload == "driving",):
        for n in args.ramp:
            step = await measure(
                n, moving=moving, warmup=args.warmup, window=args.window, cores=others
            )
            print(_row(step), flush=True)
            if not step.sustained:
                break


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--ramp",
        type=lambda s: [int(v) for v in s.split(",")],
        default=[10, 25, 50, 75, 100, 150, 200, 300, 400, 500],
        help="fleet sizes, comma-separated (the demo map has room for 539 robots)",
    )
    parser.add_argument("--warmup", type=float, default=2.0, help="seconds before measuring")
    parser.add_argument("--window", type=float, default=5.0, help="seconds measured per step")
    parser.add_argument("--workload", choices=("parked", "driving", "both"), default="both")
    parser.add_argument("--max-seconds", type=float, default=300.0, help="stop the ramp after this")
    args = parser.parse_args()
    if not hasattr(os, "sched_setaffinity"):
        sys.exit("bench_sim needs os.sched_setaffinity (Linux)")
    asyncio.run(main_async(args))


if __name__ == "__main__":
    main()
