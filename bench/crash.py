"""Crash-safety soak: a longer service with more SIGKILLs of the server (loopback only).

The CI variant is ``tests/store/test_crash.py`` (20 kills, 15 orders); this runs the same service,
kill points and checks (``tests/crash_service.py``) at any size, for several seeds, and prints
a summary. It stops by itself; any violated invariant ends it with the assertion and exit 1.

    python bench/crash.py --kills 100 --carts 30 --seeds 1 2 3
"""

from __future__ import annotations

import argparse
import asyncio
import sys
import tempfile
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # for tests.crash_service

from tests.crash_service import CrashConfig, run_crash


async def main(ns: argparse.Namespace) -> int:
    failed = 0
    for seed in ns.seeds:
        cfg = CrashConfig(
            seed=seed,
            kills=ns.kills,
            robots=ns.robots,
            carts=ns.carts,
            cart_size=ns.cart_size,
            time_scale=ns.time_scale,
            max_updates=ns.max_updates,
            max_wait=ns.max_wait,
            finish_timeout=ns.finish_timeout,
        )
        log = print if ns.verbose else None
        with tempfile.TemporaryDirectory(prefix="serveur-crash-") as tmp:
            try:
                r = await run_crash(Path(tmp), cfg, log=log)
            except AssertionError as exc:
                failed += 1
                print(f"seed {seed}: FAILED: {exc}", flush=True)
                continue
        starts = sum(p == "at start-up" for p in r.kill_points)
        mid = sum(0 < d < r.orders for d in r.delivered_at_kill)
        print(
            f"seed {seed}: {r.kills} kills ({starts} during start-up, {mid} with the service"
            f" part-delivered), {r.checks} database checks, {r.delivered}/{r.orders} orders"
            f" delivered exactly once, integrity_check {r.integrity}, {r.wall:.1f} s",
            flush=True,
        )
    return 1 if failed else 0


if __name__ == "__main__":
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3])
    p.add_argument("--kills", type=int, default=60)
    p.add_argument("--robots", type=int, default=2)
    p.add_argument("--carts", type=int, default=16)
    p.add_argument("--cart-size", type=int, default=3)
    p.add_argument("--time-scale", type=float, default=10.0)
    p.add_argument("--max-updates", type=int, default=12)
    p.add_argument("--max-wait", type=float, default=1.2)
    p.add_argument("--finish-timeout", type=float, default=120.0)
    p.add_argument("-v", "--verbose", action="store_true")
    sys.exit(asyncio.run(main(p.parse_args())))
