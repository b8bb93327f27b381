"""The centre's database: every site's events exactly once, the sites, the centre's accounts.

Written against :mod:`serveur.store.sql` like the site's store, so the same two backends run
it (MariaDB for a chain, SQLite for a test or a tiny chain) with their own migration history
(``migrations/hq/``). :meth:`HqStore.take` is the idempotent step: it re-reads the site's
``stored`` under a row lock in the same transaction as the inserts, so even two consumers
(or a consumer restarted mid-batch) store each number once and never past a hole.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from types import TracebackType
from typing import Any, Self

from serveur.domain import EventRecord
from serveur.errors import Conflict, InvalidField, StoreError
from serveur.store.sql import Db, Tx, one

__all__ = ["HQ_HISTORY", "HqStore", "SiteRow", "open_hq_db"]

HQ_HISTORY = "serveur.migrations.hq"


@dataclass(frozen=True, slots=True)
class SiteRow:
    site: str
    stored: int
    head: int
    heard_at: float | None
    site_time: float | None
    state: str | None
    state_at: float | None
    first_at: float


def open_hq_db(url: str) -> Db:
    """The (unopened) database of the centre at ``url`` (``mariadb://...`` or a SQLite path)."""
    if url.startswith(("mariadb://", "mysql://")):
        try:
            from serveur.store.mariadb.db import Database, MariaDBConfig
        except ImportError as exc:
            raise StoreError(f"the MariaDB backend needs its driver: {exc}") from exc
        return Database(MariaDBConfig.from_url(url), HQ_HISTORY)
    from serveur.store.factory import sqlite_file
    from serveur.store.sqlite.db import SQLiteDb

    path = sqlite_file(url)
    return SQLiteDb(str(path) if path is not None else url, HQ_HISTORY)


_SITE = "SELECT site, stored, head, heard_at, site_time, state, state_at, first_at FROM hq_site"


class HqStore:
    def __init__(self, db: Db) -> None:
        self.db = db

    async def __aenter__(self) -> Self:
        await self.db.open()
        return self

    async def __aexit__(
        self, t: type[BaseException] | None, e: BaseException | None, tb: TracebackType | None
    ) -> None:
        await self.db.close()

    async def sites(self) -> list[SiteRow]:
        found = await self.db.transact(lambda tx: tx.all(f"{_SITE} ORDER BY site"), "auto")
        return [SiteRow(**r) for r in found]

    async def _ensure(self, tx: Tx, site: str, now: float) -> dict[str, Any]:
        row = await one(tx, f"{_SITE} WHERE site = ?{tx.dialect.for_update}", (site,))
        if row is None:
            await tx.run("INSERT INTO hq_site (site, first_at) VALUES (?, ?)", (site, now))
            row = await one(tx, f"{_SITE} WHERE site = ?{tx.dialect.for_update}", (site,))
            assert row is not None
        return row

    async def take(self, site: str, first: int, events: Sequence[EventRecord], now: float) -> int:
        """Store ``events`` numbered from ``first`` after what the site already has; the
        site's ``stored`` after it. Numbers at or below ``stored`` are skipped (duplicates);
        a batch that would leave a hole stores nothing."""

        async def work(tx: Tx) -> int:
            row = await self._ensure(tx, site, now)
            stored = int(row["stored"])
            if first > stored + 1:
                return stored
            fresh = [(first + i, e) for i, e in enumerate(events) if first + i > stored]
            if not fresh:
                return stored
            await tx.many(
                "INSERT INTO hq_event (site, seq, id, ts, kind, robot, task_id, order_id, data)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                [
                    (
                        site,
                        seq,
                        e.id,
                        e.ts,
                        e.kind,
                        e.robot,
                        e.task_id,
                        e.order_id,
                        json.dumps(e.data, ensure_ascii=False, separators=(",", ":")),
                    )
                    for seq, e in fresh
                ],
            )
            last = fresh[-1][0]
            await tx.run(
                "UPDATE hq_site SET stored = ?, head = CASE WHEN head > ? THEN head ELSE ? END"
                " WHERE site = ?",
                (last, last, last, site),
            )
            return last

        return await self.db.transact(work, "write")

    async def heard(
        self, site: str, now: float, *, head: int | None, site_time: float | None
    ) -> None:
        async def work(tx: Tx) -> None:
            row = await self._ensure(tx, site, now)
            new_head = max(int(row["head"]), head or 0)
            await tx.run(
                "UPDATE hq_site SET heard_at = ?, head = ?,"
                " site_time = COALESCE(?, site_time) WHERE site = ?",
                (now, new_head, site_time, site),
            )

        await self.db.transact(work, "write")

    async def set_state(self, site: str, state: str, now: float) -> None:
        """The site went ``up`` or ``down`` (recorded once per change)."""

        async def work(tx: Tx) -> None:
            await self._ensure(tx, site, now)
            await tx.run(
                "UPDATE hq_site SET state = ?, state_at = ? WHERE site = ?", (state, now, site)
            )
            await tx.run(
                "INSERT INTO hq_liveness (site, at, state) VALUES (?, ?, ?)", (site, now, state)
            )

        await self.db.transact(work, "write")

    async def liveness(self, site: str) -> list[tuple[float, str]]:
        sql = "SELECT at, state FROM hq_liveness WHERE site = ? ORDER BY id"
        found = await self.db.transact(lambda tx: tx.all(sql, (site,)), "auto")
        return [(float(r["at"]), str(r["state"])) for r in found]

    async def events(
        self, site: str, *, after: int = 0, limit: int = 5000
    ) -> list[tuple[int, EventRecord]]:
        """The site's events numbered above ``after``, in order: (seq, event)."""
        sql = (
            "SELECT seq, id, ts, kind, robot, task_id, order_id, data FROM hq_event"
            " WHERE site = ? AND seq > ? ORDER BY seq LIMIT ?"
        )
        found = await self.db.transact(lambda tx: tx.all(sql, (site, after, limit)), "auto")
        out = []
        for r in found:
            seq = int(r.pop("seq"))
            r["data"] = json.loads(r["data"])
            out.append((seq, EventRecord(**r)))
        return out

    async def add_user(self, name: str, password_hash: str, now: float) -> None:
        if not name or len(name) > 255:
            raise InvalidField("a name is 1-255 characters", field="name")

        async def work(tx: Tx) -> None:
            if await one(tx, "SELECT name FROM hq_user WHERE name = ?", (name,)):
                raise Conflict(f"there is already an account {name!r}", name=name)
            await tx.run(
                "INSERT INTO hq_user (name, password_hash, created_at) VALUES (?, ?, ?)",
                (name, password_hash, now),
            )

        await self.db.transact(work, "write")

    async def password_hash(self, name: str) -> str | None:
        sql = "SELECT password_hash FROM hq_user WHERE name = ?"
        row = await self.db.transact(lambda tx: one(tx, sql, (name,)), "auto")
        return None if row is None else str(row["password_hash"])
