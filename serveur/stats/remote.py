"""The ``stats`` verb: the statistics over the protocol, computed off the server's event loop.

Reading a season of events and computing its figures is CPU-bound pure Python (seconds for a
year of services on a Pi): run on the loop it would stall every robot link and screen, and in
a thread it would still hold the GIL. So the server runs ``serveur stats --json`` — the very
command an owner types — as a child process that opens the database itself (SQLite reads in
WAL mode, MariaDB over its own connection), and replies with what it printed. The database
is named to the child through ``$SERVEUR_DB``, never on its command line (a MariaDB URL may
hold a password). A store with no file (``:memory:``, tests) cannot be opened twice: its
events are read here and computed in a worker thread.

One computation at a time: a second request waits for the first (an owner pressing the
button twice must not cost two cores during service). ``last_service`` is no computation: one
aggregate query of the orders, answered at once (the forecast's default day).
"""

from __future__ import annotations

import asyncio
import json
import logging
import os
import sys
from datetime import tzinfo
from typing import Any

from serveur import protocol as P
from serveur.errors import InvalidField, ServeurError
from serveur.stats.periods import parse_offset, parse_when, period_of
from serveur.store.base import Store

__all__ = ["StatsService", "when_range"]

log = logging.getLogger(__name__)

#: The longest a computation may take before it is given up (wall seconds).
TIMEOUT = 120.0


def when_range(
    utc_offset: str | None,
    start: str | None,
    end: str | None,
    names: tuple[str, str] = ("start", "end"),
) -> tuple[tzinfo | None, float | None, float | None]:
    """A request's time zone and ``[start, end)`` in epoch seconds (a day alone: from its
    start, to its end); InvalidField naming the field (``names``) that does not parse."""
    field = "utc_offset"
    try:
        tz = None if utc_offset is None else parse_offset(utc_offset)
        field = names[0]
        lo = None if start is None else parse_when(start, tz)
        field = names[1]
        hi = None if end is None else parse_when(end, tz, end=True)
    except ValueError as exc:
        raise InvalidField(str(exc), field=field) from None
    return tz, lo, hi


def _in_memory(db: str | None) -> bool:
    return db is None or ":memory:" in db or "mode=memory" in db


class StatsService:
    """Answers ``stats`` requests for one server. ``db``: the database as the server was
    given it (a SQLite file or URL, or mariadb://...); None: compute in-process."""

    def __init__(self, store: Store, db: str | None) -> None:
        self._store = store
        self._db = None if _in_memory(db) else db
        self._one = asyncio.Lock()

    async def handle(
        self, msg: P.StatsFigures | P.StatsTrips | P.StatsLastService
    ) -> dict[str, Any]:
        if isinstance(msg, P.StatsLastService):
            return await self.last_service(msg)
        tz, start, end = when_range(msg.utc_offset, msg.start, msg.end)
        if start is not None and end is not None and end <= start:
            raise InvalidField("end is not after start", field="end")
        async with self._one:
            if self._db is None:
                doc = await self._here(msg, tz, start, end)
            else:
                doc = await self._child(msg)
        return {"stats": doc}

    async def last_service(self, msg: P.StatsLastService) -> dict[str, Any]:
        """The latest service day before ``msg.before`` whose dishes a forecast can replay
        (None: the restaurant never had one), at the request's offset."""
        tz, before, _ = when_range(msg.utc_offset, msg.before, None, ("before", "end"))
        assert before is not None
        ts = await self._store.orders.last_ready(before)
        return {"last_service": None if ts is None else period_of(ts, "day", tz).label}

    async def _child(self, msg: P.StatsFigures | P.StatsTrips) -> dict[str, Any]:
        args = [sys.executable, "-m", "serveur.cli", "stats", "--json"]
        if isinstance(msg, P.StatsTrips):
            args.append("--trips")
        else:
            args += ["--by", msg.by]
        for flag, value in (("--from", msg.start), ("--to", msg.end)):
            if value is not None:
                args += [flag, value]
        if msg.utc_offset is not None:
            args += ["--utc-offset", msg.utc_offset]
        assert self._db is not None
        env = {**os.environ, "SERVEUR_DB": self._db}
        proc = await asyncio.create_subprocess_exec(
            *args,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
            env=env,
        )
        try:
            out, err = await asyncio.wait_for(proc.communicate(), TIMEOUT)
        except TimeoutError:
            msg_ = f"the statistics took over {TIMEOUT:g} s: ask a shorter range"
            raise ServeurError(msg_) from None
        finally:
            if proc.returncode is None:  # cancelled or timed out: do not leave it behind
                proc.kill()
                await proc.wait()
        if proc.returncode != 0:
            tail = err.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
            log.warning("serveur stats exited with %s: %s", proc.returncode, tail[0])
            raise ServeurError(f"the statistics could not be computed: {tail[0]}")
        doc: dict[str, Any] = json.loads(out)
        return doc

    async def _here(
        self,
        msg: P.StatsFigures | P.StatsTrips,
        tz: tzinfo | None,
        start: float | None,
        end: float | None,
    ) -> dict[str, Any]:
        from serveur.stats.load import load_events

        events = await load_events(self._store)
        by = msg.by if isinstance(msg, P.StatsFigures) else None
        return await asyncio.to_thread(_compute, events, by, tz, start, end)


def _compute(
    events: Any, by: str | None, tz: tzinfo | None, start: float | None, end: float | None
) -> dict[str, Any]:
    from serveur.stats.compute import read_events, table
    from serveur.stats.document import figures_document, trips_document

    log_ = read_events(events)
    if by is None:
        return trips_document(log_, start, end)
    rows, total = table(log_, by, tz, start=start, end=end)
    return figures_document(rows, total)
