"""Simulated time, shared by the server, the robot links and the simulator.

Everything that waits or stamps in serveur asks a :class:`Clock` instead of ``time`` or
``asyncio.sleep``. With :class:`ScaledClock` a 4-hour dinner service replays in a minute and
every timeout (goal acknowledgement, heartbeat, stale ``cmd_vel``) scales with it, so the server
and the simulator agree on what "2 seconds" means. :class:`FakeClock` (after trio's MockClock)
lets pure tests move time by hand instead of sleeping.
"""

from __future__ import annotations

import asyncio
import heapq
import itertools
import time
from typing import Protocol, runtime_checkable

__all__ = ["Clock", "FakeClock", "ScaledClock"]


@runtime_checkable
class Clock(Protocol):
    """Simulated time. ``now`` is monotonic seconds; ``epoch`` is Unix time for ROS stamps."""

    @property
    def time_scale(self) -> float: ...

    def now(self) -> float: ...

    def epoch(self) -> float: ...

    async def sleep(self, seconds: float) -> None: ...

    def wall(self, seconds: float) -> float:
        """Wall-clock seconds that ``seconds`` of simulated time take (for asyncio timeouts)."""
        ...


class ScaledClock:
    """Simulated time running ``time_scale`` times faster than the wall clock."""

    def __init__(self, time_scale: float = 1.0, *, start_epoch: float | None = None) -> None:
        if not time_scale > 0:
            raise ValueError("time_scale must be > 0")
        self._scale = float(time_scale)
        self._mono0 = time.monotonic()
        self._epoch0 = time.time() if start_epoch is None else start_epoch

    @property
    def time_scale(self) -> float:
        return self._scale

    def now(self) -> float:
        return (time.monotonic() - self._mono0) * self._scale

    def epoch(self) -> float:
        return self._epoch0 + self.now()

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds) / self._scale)

    def wall(self, seconds: float) -> float:
        return max(0.0, seconds) / self._scale


class FakeClock:
    """A clock that only moves when told to: ``advance(dt)`` wakes every sleeper due by then."""

    def __init__(self, start: float = 0.0, *, start_epoch: float = 1_700_000_000.0) -> None:
        self._now = start
        self._epoch0 = start_epoch - start
        self._sleepers: list[tuple[float, int, asyncio.Future[None]]] = []
        self._counter = itertools.count()
        self._asleep = asyncio.Event()  # set while someone sleeps: see :meth:`someone_sleeps`

    @property
    def time_scale(self) -> float:
        return 1.0

    def now(self) -> float:
        return self._now

    def epoch(self) -> float:
        return self._epoch0 + self._now

    async def sleep(self, seconds: float) -> None:
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        heapq.heappush(self._sleepers, (self._now + max(0.0, seconds), next(self._counter), fut))
        self._asleep.set()
        await fut

    async def someone_sleeps(self) -> None:
        """Wait until a task sleeps on this clock: a test advances time once the task it
        drives is waiting for it, not before (that time would pass unseen)."""
        if not any(not f.done() for *_, f in self._sleepers):
            self._asleep.clear()
            await self._asleep.wait()

    def wall(self, seconds: float) -> float:
        return max(0.0, seconds)

    async def advance(self, seconds: float) -> None:
        """Move time forward, waking sleepers in deadline order and letting each one run."""
        target = self._now + seconds
        while self._sleepers and self._sleepers[0][0] <= target:
            when, _, fut = heapq.heappop(self._sleepers)
            self._now = max(self._now, when)
            if not fut.done():
                fut.set_result(None)
            for _ in range(5):
                await asyncio.sleep(0)
        self._now = target
        for _ in range(5):
            await asyncio.sleep(0)
