"""Virtual time (serveur/replay/vtime.py): the clock jumps only when nothing can run.

The replay's determinism rests on these properties: timers fire in deadline order without
waiting, a query in a worker thread (or anything a busy predicate covers) finishes before time
moves on, data in flight on a loopback socket is delivered before time moves on, and a wait
for a deadline that float rounding puts a hair away still ends.
"""

from __future__ import annotations

import asyncio
import math
import threading
import time
from collections.abc import Coroutine
from typing import Any, TypeVar

import pytest
from websockets.asyncio.client import connect
from websockets.asyncio.server import ServerConnection, serve

from serveur.replay.vtime import LoopClock, VirtualTimeLoop

T = TypeVar("T")


def run(coro: Coroutine[Any, Any, T]) -> T:
    with asyncio.Runner(loop_factory=VirtualTimeLoop) as runner:
        return runner.run(coro)


def test_an_hour_of_timers_fires_in_order_without_waiting() -> None:
    async def main() -> list[tuple[str, float]]:
        loop = asyncio.get_running_loop()
        fired: list[tuple[str, float]] = []

        async def after(name: str, delay: float) -> None:
            await asyncio.sleep(delay)
            fired.append((name, loop.time()))

        await asyncio.gather(after("c", 3600.0), after("a", 0.5), after("b", 61.25))
        return fired

    wall = time.perf_counter()
    assert run(main()) == [("a", 0.5), ("b", 61.25), ("c", 3600.0)]
    assert time.perf_counter() - wall < 30.0  # an hour of sleeping was not slept


def test_time_stands_still_while_a_worker_thread_runs() -> None:
    async def main() -> list[tuple[str, float]]:
        loop = asyncio.get_running_loop()
        seen: list[tuple[str, float]] = []

        async def query() -> None:
            await asyncio.to_thread(time.sleep, 0.2)  # a slow query, 0.2 s of real time
            seen.append(("query", loop.time()))

        async def timer() -> None:
            await asyncio.sleep(0.001)
            seen.append(("timer", loop.time()))

        await asyncio.gather(query(), timer())
        return seen

    assert run(main()) == [("query", 0.0), ("timer", 0.001)]


def test_a_busy_predicate_holds_time_until_it_clears() -> None:
    async def main() -> list[tuple[str, float]]:
        loop = asyncio.get_running_loop()
        assert isinstance(loop, VirtualTimeLoop)
        working = threading.Event()
        working.set()
        loop.add_busy(working.is_set)
        seen: list[tuple[str, float]] = []

        def outside() -> None:  # e.g. aiosqlite's own thread, not the loop's executor
            time.sleep(0.2)
            seen.append(("outside", loop.time()))
            working.clear()

        threading.Thread(target=outside).start()
        await asyncio.sleep(5.0)
        seen.append(("timer", loop.time()))
        return seen

    assert run(main()) == [("outside", 0.0), ("timer", 5.0)]


def test_a_deadline_a_hair_away_is_still_reached() -> None:
    """A service clock counted from an offset (as the replay's is): a deadline one ulp ahead
    in service time is a delay the loop's own, larger, time cannot represent."""

    async def main() -> int:
        loop = asyncio.get_running_loop()
        await asyncio.sleep(10_000.0)
        t0 = loop.time() - 0.1

        def now() -> float:
            return loop.time() - t0

        deadline = math.nextafter(now(), math.inf)
        turns = 0
        while now() < deadline and turns < 1000:
            turns += 1
            await asyncio.sleep(deadline - now())
        return turns

    assert run(main()) == 1


def test_loopback_round_trips_take_no_virtual_time() -> None:
    async def main() -> list[float]:
        loop = asyncio.get_running_loop()

        async def echo(ws: ServerConnection) -> None:
            async for msg in ws:
                await ws.send(f"{msg}@{loop.time():.3f}")

        stamps: list[float] = []
        async with serve(echo, "127.0.0.1", 0) as server:
            port = server.sockets[0].getsockname()[1]
            async with connect(f"ws://127.0.0.1:{port}") as ws:
                for i in range(5):
                    sent = loop.time()
                    await ws.send(str(i))
                    reply = await ws.recv()
                    assert reply == f"{i}@{sent:.3f}"  # answered at the time it was sent
                    stamps.append(loop.time() - sent)
                    await asyncio.sleep(1.5)
        return stamps

    assert run(main()) == [0.0] * 5


def test_loop_clock_counts_from_its_first_use() -> None:
    async def main() -> tuple[float, float, float]:
        await asyncio.sleep(7.0)
        clock = LoopClock(start_epoch=1_700_000_000.0)
        first = clock.now()
        await clock.sleep(2.5)
        return first, clock.now(), clock.epoch()

    assert run(main()) == (0.0, 2.5, pytest.approx(1_700_000_002.5))
