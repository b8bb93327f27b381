"""Reading a store's events for the statistics, page by page (any backend).

The only part of :mod:`serveur.stats` that does I/O: the computation
(:mod:`serveur.stats.compute`) takes the records this returns.
"""

from __future__ import annotations

from serveur.domain import EventRecord
from serveur.store.base import Store

__all__ = ["load_events"]

PAGE = 5000


async def load_events(store: Store, *, page: int = PAGE) -> list[EventRecord]:
    """Every event of ``store``, oldest first, read ``page`` at a time (``list_events``
    with the last id seen), so that neither backend is asked for the whole table at once."""
    out: list[EventRecord] = []
    last = 0
    while batch := await store.events.list_events(since_id=last, limit=page):
        out += batch
        last = batch[-1].id
        if len(batch) < page:
            break
    return out
