"""Virtual time for replays: an event loop whose clock jumps to the next timer when idle.

A replay accelerated with :class:`~serveur.clock.ScaledClock` follows the wall clock, so every
scheduling jitter of the host (another process, a garbage collection) moves simulated events by
``jitter x time_scale``: two runs of the same log differ, and a starved run is wrong. Here the
loop's own clock is virtual (after trio's autojump clock and the ``looptime`` library): it
stands still while anything can run, and only when nothing can — no callback ready, no socket
readable or writable, no worker thread busy — does it jump to the next timer. The order of
events then depends only on the program, so a replay is repeatable, and the loop never sleeps,
so it runs as fast as the CPU allows.

"Nothing can run" needs care with threads: SQLite queries run in aiosqlite's worker thread and
report back through the loop's self-pipe, and a jump while one runs would let time pass during a
query. Callers register *busy* predicates (the store's lock is held while any query is in
flight); while one is true the loop blocks on the real selector instead of jumping. Sockets
must be local (loopback: a frame sent is readable by its peer before ``send`` returns), which
the replay's are.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import contextvars
import selectors
import time
from collections.abc import Callable
from typing import Any, TypeVar, TypeVarTuple, Unpack

__all__ = ["LoopClock", "VirtualTimeLoop"]

_T = TypeVar("_T")
_Ts = TypeVarTuple("_Ts")

#: Real seconds the loop waits on the selector while a busy predicate holds, before asking again.
_BUSY_POLL = 0.05
#: The smallest jump of virtual time (seconds).
_QUANTUM = 1e-6


class _JumpingSelector(selectors.BaseSelector):
    """Wraps the loop's selector: an idle ``select(timeout)`` advances virtual time instead."""

    def __init__(self, real: selectors.BaseSelector, loop: VirtualTimeLoop) -> None:
        self._real = real
        self._loop = loop

    def register(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._real.register(fileobj, events, data)

    def unregister(self, fileobj: Any) -> selectors.SelectorKey:
        return self._real.unregister(fileobj)

    def modify(self, fileobj: Any, events: int, data: Any = None) -> selectors.SelectorKey:
        return self._real.modify(fileobj, events, data)

    def get_key(self, fileobj: Any) -> selectors.SelectorKey:
        return self._real.get_key(fileobj)

    def get_map(self) -> Any:
        return self._real.get_map()

    def close(self) -> None:
        self._real.close()

    def select(self, timeout: float | None = None) -> list[tuple[selectors.SelectorKey, int]]:
        events = self._real.select(0)
        if events or timeout == 0:
            return events
        while self._loop.busy():
            events = self._real.select(_BUSY_POLL if timeout is None else min(timeout, _BUSY_POLL))
            if events:
                return events
        if timeout is None:  # nothing scheduled at all: only the outside world can wake us
            return self._real.select(None)
        # At least a microsecond: a wait of 1e-13 s (a deadline minus a time that rounded just
        # below it) added to a clock at 10,000 s would not move it, and the waiter would wake
        # to the same time forever.
        self._loop.advance(max(timeout, _QUANTUM))
        return []


class VirtualTimeLoop(asyncio.SelectorEventLoop):
    """A selector event loop on virtual time (see the module docstring)."""

    def __init__(self) -> None:
        super().__init__()
        self._vtime = 0.0
        self._busy: list[Callable[[], bool]] = []
        self._executor_jobs = 0
        self._selector = _JumpingSelector(self._selector, self)  # type: ignore[has-type]

    def time(self) -> float:
        return self._vtime

    def advance(self, seconds: float) -> None:
        self._vtime += max(0.0, seconds)

    def call_later(
        self,
        delay: float,
        callback: Callable[[Unpack[_Ts]], object],
        *args: *_Ts,
        context: contextvars.Context | None = None,
    ) -> asyncio.TimerHandle:
        # A positive delay below the quantum would not move the clock (see _QUANTUM): a
        # "wait until t" loop could wake at the same instant forever.
        if delay > 0:
            delay = max(delay, _QUANTUM)
        return super().call_later(delay, callback, *args, context=context)

    def add_busy(self, predicate: Callable[[], bool]) -> None:
        """While ``predicate()`` is true, time does not jump (work outside the loop runs)."""
        self._busy.append(predicate)

    def busy(self) -> bool:
        return self._executor_jobs > 0 or any(p() for p in self._busy)

    def run_in_executor(
        self,
        executor: concurrent.futures.Executor | None,
        func: Callable[[Unpack[_Ts]], _T],
        *args: *_Ts,
    ) -> asyncio.Future[_T]:
        """As the base class; time does not jump until the job is done (asyncio.to_thread)."""
        fut = super().run_in_executor(executor, func, *args)
        self._executor_jobs += 1

        def done(_: asyncio.Future[_T]) -> None:
            self._executor_jobs -= 1

        fut.add_done_callback(done)
        return fut


class LoopClock:
    """:class:`~serveur.clock.Clock` on the running loop's time (virtual under VirtualTimeLoop).

    ``time_scale`` is infinite in spirit; it reports ``scale`` for code that sizes wall-clock
    allowances by it (none apply: every wait is on loop time).
    """

    def __init__(self, *, start_epoch: float | None = None, scale: float = 1.0) -> None:
        self._epoch0 = time.time() if start_epoch is None else start_epoch
        self._scale = scale
        self._t0: float | None = None

    @property
    def time_scale(self) -> float:
        return self._scale

    def now(self) -> float:
        t = asyncio.get_running_loop().time()
        if self._t0 is None:
            self._t0 = t
        return t - self._t0

    def epoch(self) -> float:
        return self._epoch0 + self.now()

    async def sleep(self, seconds: float) -> None:
        await asyncio.sleep(max(0.0, seconds))

    def wall(self, seconds: float) -> float:
        return max(0.0, seconds)
