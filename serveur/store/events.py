"""The events trail read and appended to: one part of :class:`~serveur.store.base.Store`.

Every change of the store appends its own ``events`` row in its own transaction
(:func:`serveur.store.rows.add_event`); :meth:`Events.add_event` is for what goes with no
change of the store (a robot's report). Readers poll with the last id they saw.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from serveur.domain import EventRecord
from serveur.errors import InvalidField
from serveur.store import rows
from serveur.store.checks import to_json
from serveur.store.sql import Db, Tx, one

__all__ = ["Events"]


class Events:
    """Event methods of the store (``store.events``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def add_event(
        self,
        kind: str,
        *,
        robot: str | None = None,
        task_id: int | None = None,
        order_id: int | None = None,
        data: Mapping[str, Any] | None = None,
        now: float,
    ) -> EventRecord:
        """Append an event that goes with no state change of the store (a robot's report)."""
        self._db.dialect.check_name(kind, "kind")
        to_json(dict(data or {}))  # refuse bad data before touching the database

        async def work(tx: Tx) -> EventRecord:
            event_id = await rows.add_event(
                tx, kind, now, robot=robot, task_id=task_id, order_id=order_id, data=data
            )
            row = await one(tx, f"{rows.EVENT} WHERE id = ?", (event_id,))
            assert row is not None
            return rows.event_record(row)

        return await self._db.transact(work, "write")

    async def list_events(self, *, since_id: int = 0, limit: int = 1000) -> list[EventRecord]:
        """Events with ``id > since_id``, oldest first: poll with the last id seen."""
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")
        sql = f"{rows.EVENT} WHERE id > ? ORDER BY id LIMIT ?"
        found = await self._db.transact(lambda tx: tx.all(sql, (since_id, limit)), "auto")
        return [rows.event_record(r) for r in found]
