"""The core's tests run on virtual time: an event loop whose clock jumps to the next timer
when every task waits (serveur.replay.vtime, after trio's autojump clock).

A robot driving to a table, a table timeout of three minutes, a hand-over after two: each costs
the CPU time of the frames exchanged, not seconds of wall time, and no test waits on the
wall clock for something that is a matter of rules. Sockets stay real (loopback: a frame sent
is readable by its peer before ``send`` returns); SQLite's thread holds time still while a
query runs (``restaurant`` registers the store's ``busy``).
"""

from __future__ import annotations

import asyncio
from collections.abc import Iterator, Mapping
from typing import Any

import pytest

from serveur.app import App
from serveur.replay.vtime import VirtualTimeLoop


def pytest_asyncio_loop_factories(config: Any, item: Any) -> Mapping[str, Any]:
    """Virtual time, but for tests marked ``wall_clock`` (rates per wall second)."""
    if item.get_closest_marker("wall_clock") is not None:
        return {"wall-clock": asyncio.SelectorEventLoop}
    return {"virtual-time": VirtualTimeLoop}


@pytest.fixture(autouse=True)
def _queries_hold_time(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every server a test starts on a virtual-time loop holds time still while its SQLite
    queries run in aiosqlite's thread (the replay does the same for its server)."""
    start = App.start

    async def holding(self: App) -> App:
        loop = asyncio.get_running_loop()
        if isinstance(loop, VirtualTimeLoop):
            loop.add_busy(self.store.busy)
        return await start(self)

    monkeypatch.setattr(App, "start", holding)
    yield
