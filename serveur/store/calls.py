"""Guests' calls and the Wi-Fi call buttons. One part of :class:`~serveur.store.base.Store`,
written once for every backend.

At most one call per table and kind is open: the database says so (a partial UNIQUE index on
SQLite, a generated column's UNIQUE index on MariaDB, migration 011), so a button pressed
fifty times, or pressed on two tablets at once, is one call with fifty presses. A button's
token is kept as its SHA-256 digest, like the API tokens.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any, Final

from serveur.domain import Call, CallButton, CallKind
from serveur.errors import Conflict, NotFound
from serveur.store import rows
from serveur.store.sql import Db, Tx, one

__all__ = ["Calls"]

_CALL: Final = (
    "SELECT id, table_name AS `table`, kind, source, opened_at, presses, escalated_at,"
    " answered_at, answered_by, cancelled_at, cancelled_by, task_id FROM `call`"
)
_OPEN: Final = "answered_at IS NULL AND cancelled_at IS NULL"
_BUTTON: Final = (
    "SELECT name, table_name AS `table`, kind, created_at, revoked_at, last_press FROM call_button"
)


class Calls:
    """Calls and call buttons in the store."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def open_call(
        self, table: str, kind: CallKind, source: str, *, now: float
    ) -> tuple[Call, bool]:
        """Open a call, or merge it into the open one of the same table and kind (its presses
        counted). Returns the call and whether it was merged."""

        async def work(tx: Tx) -> tuple[Call, bool]:
            await rows.get_waypoint(tx, table)
            found = await one(
                tx,
                f"{_CALL} WHERE table_name = ? AND kind = ? AND {_OPEN}{tx.dialect.for_update}",
                (table, kind.value),
            )
            if found is not None:
                await tx.run("UPDATE `call` SET presses = presses + 1 WHERE id = ?", (found["id"],))
                return await _get(tx, int(found["id"])), True
            call_id = await tx.insert(
                "INSERT INTO `call` (table_name, kind, source, opened_at) VALUES (?, ?, ?, ?)",
                (table, kind.value, source, now),
            )
            data = {"table": table, "kind": kind.value, "source": source}
            await rows.add_event(tx, "call.opened", now, data={"call": call_id, **data})
            return await _get(tx, call_id), False

        return await self._db.transact(work, "write")

    async def close(
        self, call_id: int, how: str, by: str | None, *, now: float, task_id: int | None = None
    ) -> Call:
        """``how``: ``answered`` or ``cancelled``. Conflict if the call is already closed;
        an answer naming ``task_id`` must be the bussing trip sent for it."""

        async def work(tx: Tx) -> Call:
            call = await _get(tx, call_id, lock=True)
            if call.answered_at is not None or call.cancelled_at is not None:
                state = "answered" if call.answered_at is not None else "cancelled"
                raise Conflict(f"call {call_id} was already {state}", call=call_id, state=state)
            if task_id is not None and call.task_id != task_id:
                raise Conflict(f"call {call_id} is not trip {task_id}'s", call=call_id)
            await tx.run(
                f"UPDATE `call` SET {how}_at = ?, {how}_by = ? WHERE id = ? AND {_OPEN}",
                (now, by, call_id),
            )
            data = {"call": call_id, "table": call.table, "kind": call.kind.value, "by": by}
            data["after"] = round(now - call.opened_at, 3)
            await rows.add_event(tx, f"call.{how}", now, task_id=call.task_id, data=data)
            return await _get(tx, call_id)

        if how not in ("answered", "cancelled"):
            raise ValueError(how)
        return await self._db.transact(work, "write")

    async def escalate(self, call_id: int, *, now: float) -> Call | None:
        """Mark an open call escalated (once); None if it was closed or escalated meanwhile."""

        async def work(tx: Tx) -> Call | None:
            changed = await tx.run(
                f"UPDATE `call` SET escalated_at = ? WHERE id = ? AND escalated_at IS NULL"
                f" AND {_OPEN}",
                (now, call_id),
            )
            if changed != 1:
                return None
            call = await _get(tx, call_id)
            data = {"call": call_id, "table": call.table, "kind": call.kind.value}
            await rows.add_event(tx, "call.escalated", now, data=data)
            return call

        return await self._db.transact(work, "write")

    async def set_task(self, call_id: int, task_id: int | None) -> Call:
        """Link (or unlink) the bussing trip sent for a call."""

        async def work(tx: Tx) -> Call:
            await tx.run("UPDATE `call` SET task_id = ? WHERE id = ?", (task_id, call_id))
            return await _get(tx, call_id)

        return await self._db.transact(work, "write")

    async def get(self, call_id: int) -> Call:
        return await self._db.transact(lambda tx: _get(tx, call_id), "auto")

    async def open_calls(self) -> list[Call]:
        """The calls still open, oldest first."""

        async def work(tx: Tx) -> list[Call]:
            return [Call(**r) for r in await tx.all(f"{_CALL} WHERE {_OPEN} ORDER BY id")]

        return await self._db.transact(work, "auto")

    async def calls_between(self, start: float, end: float) -> list[Call]:
        """Calls opened in [start, end), for the statistics."""

        async def work(tx: Tx) -> list[Call]:
            found = await tx.all(
                f"{_CALL} WHERE opened_at >= ? AND opened_at < ? ORDER BY id", (start, end)
            )
            return [Call(**r) for r in found]

        return await self._db.transact(work, "auto")

    # -- buttons ------------------------------------------------------------------------------

    async def add_button(
        self, name: str, table: str, kind: CallKind, digest: str, *, now: float
    ) -> CallButton:
        """Register a button (Conflict if the name is taken, even by a revoked one: a name
        in the audit trail keeps meaning one button)."""

        async def work(tx: Tx) -> CallButton:
            await rows.get_waypoint(tx, table)
            if await one(tx, f"{_BUTTON} WHERE name = ?", (name,)) is not None:
                raise Conflict(f"a button is already named {name!r}", button=name)
            await tx.run(
                "INSERT INTO call_button (name, table_name, kind, digest, created_at)"
                " VALUES (?, ?, ?, ?, ?)",
                (name, table, kind.value, digest, now),
            )
            data = {"button": name, "table": table, "kind": kind.value}
            await rows.add_event(tx, "button.added", now, data=data)
            return await _button(tx, name)

        return await self._db.transact(work, "write")

    async def buttons(self) -> list[CallButton]:
        async def work(tx: Tx) -> list[CallButton]:
            return [CallButton(**r) for r in await tx.all(f"{_BUTTON} ORDER BY name")]

        return await self._db.transact(work, "auto")

    async def revoke_button(self, name: str, *, now: float) -> CallButton:
        async def work(tx: Tx) -> CallButton:
            await _button(tx, name)
            await tx.run(
                "UPDATE call_button SET revoked_at = ? WHERE name = ? AND revoked_at IS NULL",
                (now, name),
            )
            await rows.add_event(tx, "button.revoked", now, data={"button": name})
            return await _button(tx, name)

        return await self._db.transact(work, "write")

    async def button_by_digest(self, digest: str) -> CallButton | None:
        """The button whose token has this digest (revoked or not), or None."""

        async def work(tx: Tx) -> CallButton | None:
            row = await one(tx, f"{_BUTTON} WHERE digest = ?", (digest,))
            return CallButton(**row) if row is not None else None

        return await self._db.transact(work, "auto")

    async def pressed(self, name: str, *, now: float) -> None:
        async def work(tx: Tx) -> None:
            await tx.run("UPDATE call_button SET last_press = ? WHERE name = ?", (now, name))

        await self._db.transact(work, "write")


async def _get(tx: Tx, call_id: int, *, lock: bool = False) -> Call:
    row: Mapping[str, Any] | None = await one(
        tx, f"{_CALL} WHERE id = ?{tx.dialect.for_update if lock else ''}", (call_id,)
    )
    if row is None:
        raise NotFound(f"no call {call_id}", call=call_id)
    return Call(**row)


async def _button(tx: Tx, name: str) -> CallButton:
    row = await one(tx, f"{_BUTTON} WHERE name = ?", (name,))
    if row is None:
        raise NotFound(f"no button named {name!r}", button=name)
    return CallButton(**row)
