"""The outbox read and moved on: one part of :class:`~serveur.store.base.Store` (issue 34).

Every event takes the site's next outbox number in its own transaction
(:func:`serveur.store.rows.add_event`, migration 013). The chain's shipper
(:mod:`serveur.chain.shipper`) reads them in order from here, notes what the broker
acknowledged (``sent``: it resumes after it, after a restart or a day offline) and what the
centre says it stored (``confirmed``); a row is deleted only once confirmed *and* older than
the retention period, so a centre that lost something can still ask for it again.
"""

from __future__ import annotations

from dataclasses import dataclass

from serveur.domain import EventRecord
from serveur.errors import InvalidField
from serveur.store import rows
from serveur.store.sql import Db, Tx, one

__all__ = ["Numbered", "Outbox", "OutboxState"]


@dataclass(frozen=True, slots=True)
class Numbered:
    """An event with its outbox number."""

    seq: int
    event: EventRecord


@dataclass(frozen=True, slots=True)
class OutboxState:
    """Where the outbox stands, as the owner's screen shows it.

    ``head`` is the last number given, ``sent`` the last the broker acknowledged,
    ``confirmed`` the last the centre stored; ``size`` the rows kept and ``oldest_unsent_at``
    the time of the oldest event the broker has not acknowledged (None: all sent).
    """

    head: int
    sent: int
    sent_at: float | None
    confirmed: int
    size: int
    oldest_unsent_at: float | None

    @property
    def unsent(self) -> int:
        return self.head - self.sent


_EVENTS = (
    "SELECT o.seq AS seq, e.id AS id, e.ts AS ts, e.kind AS kind, e.robot AS robot,"
    " e.task_id AS task_id, e.order_id AS order_id, e.data AS data"
    " FROM outbox o JOIN events e ON e.id = o.event_id"
)


def _count(value: object, field: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 0:
        raise InvalidField(f"{field} must be a whole number >= 0", field=field)
    return value


class Outbox:
    """Outbox methods of the store (``store.outbox``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def after(self, seq: int, *, limit: int = 500) -> list[Numbered]:
        """The events numbered above ``seq``, in order, at most ``limit``; fewer than asked
        (or none) means the outbox holds no more now. Numbers already pruned are skipped:
        the first returned may be above ``seq + 1`` only if the centre confirmed them."""
        _count(seq, "seq")
        if _count(limit, "limit") < 1:
            raise InvalidField("limit must be a positive integer", field="limit")
        sql = f"{_EVENTS} WHERE o.seq > ? ORDER BY o.seq LIMIT ?"
        found = await self._db.transact(lambda tx: tx.all(sql, (seq, limit)), "auto")
        out = []
        for row in found:
            number = int(row.pop("seq"))
            out.append(Numbered(number, rows.event_record(row)))
        return out

    async def state(self) -> OutboxState:
        async def work(tx: Tx) -> OutboxState:
            s = await one(tx, "SELECT head, sent, sent_at, confirmed FROM outbox_state")
            assert s is not None, "migration 013 writes outbox_state's row"
            kept = await one(tx, "SELECT COUNT(*) AS n FROM outbox")
            oldest = await one(tx, "SELECT MIN(at) AS at FROM outbox WHERE seq > ?", (s["sent"],))
            return OutboxState(
                head=int(s["head"]),
                sent=int(s["sent"]),
                sent_at=s["sent_at"],
                confirmed=int(s["confirmed"]),
                size=int(kept["n"]) if kept else 0,
                oldest_unsent_at=oldest["at"] if oldest else None,
            )

        return await self._db.transact(work, "read")

    async def mark_sent(self, seq: int, now: float) -> None:
        """The broker acknowledged every event up to ``seq``: the shipper resumes after it.

        Never moves back (a late acknowledgement of an older batch changes nothing) and never
        past ``head``."""
        _count(seq, "seq")
        sql = (
            "UPDATE outbox_state SET sent = ?, sent_at = ? WHERE id = 1 AND sent < ? AND head >= ?"
        )
        await self._db.transact(lambda tx: tx.run(sql, (seq, now, seq, seq)), "write")

    async def rewind(self, seq: int) -> None:
        """Send again from after ``seq`` (the centre asked for what it misses)."""
        _count(seq, "seq")
        sql = "UPDATE outbox_state SET sent = ? WHERE id = 1 AND sent > ?"
        await self._db.transact(lambda tx: tx.run(sql, (seq, seq)), "write")

    async def confirm(self, seq: int) -> None:
        """The centre stored every event up to ``seq`` (never moves back, never past head)."""
        _count(seq, "seq")
        sql = "UPDATE outbox_state SET confirmed = ? WHERE id = 1 AND confirmed < ? AND head >= ?"
        await self._db.transact(lambda tx: tx.run(sql, (seq, seq, seq)), "write")

    async def prune(self, now: float, retention: float) -> int:
        """Delete the rows the centre confirmed that are older than ``retention`` seconds;
        how many went. The events stay: only their place in the queue goes."""

        async def work(tx: Tx) -> int:
            s = await one(tx, "SELECT confirmed, sent FROM outbox_state")
            assert s is not None
            upto = min(int(s["confirmed"]), int(s["sent"]))
            return await tx.run(
                "DELETE FROM outbox WHERE seq <= ? AND at < ?", (upto, now - retention)
            )

        return await self._db.transact(work, "write")
