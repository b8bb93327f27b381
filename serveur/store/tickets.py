"""The till's print jobs and tickets, the till's item names and its settings. One part of
:class:`~serveur.store.base.Store`, written once for every backend (migration 012).

Nothing the till sends is dropped: a job's bytes are kept whole before anything reads them,
and each of its tickets is a row whatever becomes of it. A ticket becomes orders **once**:
its key (what its reading says: the ticket's number, table and dishes) is the ``first_key``
of the ticket that ordered, UNIQUE, written in the same transaction as the orders, so a
reprint, or the same ticket reaching two connections at once, finds the first one instead of
making more orders (on MariaDB the loser's UPDATE hits the unique index and its transaction
is re-run, as for the ``idempotency`` keys).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

from serveur.domain import ORDER_STEPS, DishAction, Order, OrderStatus, TillTicket
from serveur.errors import Conflict, NotFound
from serveur.store import rows
from serveur.store.checks import check_new_order, to_json
from serveur.store.sql import Db, Tx, one, sql_in

__all__ = ["NewDish", "Tickets", "Voided"]

_TICKET: Final = (
    "SELECT t.id, t.job_id AS job, t.part, t.received_at, t.text, t.status, t.`key`,"
    " t.table_name AS `table`, t.reading, t.problem, t.of_ticket, t.read_at, t.handled_by,"
    " j.source FROM till_ticket AS t JOIN till_job AS j ON j.id = t.job_id"
)
#: A dish a void may still withdraw: the statuses the kitchen's own ``void`` starts from.
_VOIDABLE: Final = tuple(sorted(s.value for s in ORDER_STEPS[DishAction.VOID][0]))


@dataclass(frozen=True, slots=True)
class NewDish:
    """A dish a ticket orders: the menu's name (or the till's, when it maps to none)."""

    dish: str
    quantity: int
    note: str | None = None


@dataclass(frozen=True, slots=True)
class Voided:
    """What a void ticket did: the orders voided or reduced, and the plates it could not
    withdraw (not found, or already on a robot), by dish."""

    orders: tuple[int, ...]
    missing: tuple[tuple[str, int], ...]


def _ticket(row: dict[str, Any]) -> TillTicket:
    reading = row.get("reading")
    data = {**row, "reading": json.loads(reading) if reading else None}
    data["lines"] = str(row["text"]).split("\n") if row["text"] else []
    del data["text"]
    return TillTicket(**data)


class Tickets:
    """Print jobs, tickets, item names and settings of the till (``store.tickets``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    # -- jobs and tickets -------------------------------------------------------------------

    async def add_job(
        self, source: str, raw: bytes, tickets: Sequence[str], *, now: float
    ) -> list[TillTicket]:
        """Keep a job's bytes and one row per ticket (its text as printed), unread yet."""

        async def work(tx: Tx) -> list[TillTicket]:
            job = await tx.insert(
                "INSERT INTO till_job (received_at, source, raw) VALUES (?, ?, ?)",
                (now, source[:255], raw),
            )
            ids = [
                await tx.insert(
                    "INSERT INTO till_ticket (job_id, part, received_at, text) VALUES (?, ?, ?, ?)",
                    (job, part, now, text),
                )
                for part, text in enumerate(tickets)
            ]
            return [await self._get(tx, i) for i in ids]

        return await self._db.transact(work, "write")

    async def set_forwarded(self, job_id: int, forwarded: bool) -> None:
        await self._db.transact(
            lambda tx: tx.run(
                "UPDATE till_job SET forwarded = ? WHERE id = ?", (int(forwarded), job_id)
            ),
            "write",
        )

    async def _get(self, tx: Tx, ticket_id: int) -> TillTicket:
        row = await one(tx, f"{_TICKET} WHERE t.id = ?", (ticket_id,))
        if row is None:
            raise NotFound(f"no ticket {ticket_id}", ticket=ticket_id)
        return _ticket(row)

    async def _first(self, tx: Tx, key: str) -> int | None:
        """The ticket that ordered (or voided) with ``key``, locked, if any."""
        row = await one(
            tx, "SELECT id FROM till_ticket WHERE first_key = ?" + tx.dialect.for_update, (key,)
        )
        return None if row is None else int(row["id"])

    async def first(self, key: str) -> TillTicket | None:
        """The ticket that ordered (or voided) with ``key``, if any."""
        row = await self._db.transact(
            lambda tx: one(tx, f"{_TICKET} WHERE t.first_key = ?", (key,)), "auto"
        )
        return None if row is None else _ticket(row)

    async def _reprint(
        self,
        tx: Tx,
        ticket_id: int,
        first: int,
        key: str,
        table: str,
        reading: dict[str, Any],
        now: float,
    ) -> TillTicket:
        """The ticket is ``first`` printed again: kept, nothing ordered or withdrawn."""
        await tx.run(
            "UPDATE till_ticket SET status = 'reprint', `key` = ?, table_name = ?, reading = ?,"
            " problem = NULL, of_ticket = ?, read_at = ? WHERE id = ?",
            (key, table, to_json(reading), first, now, ticket_id),
        )
        return await self._get(tx, ticket_id)

    async def get(self, ticket_id: int) -> TillTicket:
        return await self._db.transact(lambda tx: self._get(tx, ticket_id), "auto")

    async def job_bytes(self, ticket_id: int) -> bytes:
        sql = (
            "SELECT j.raw FROM till_job AS j JOIN till_ticket AS t ON t.job_id = j.id"
            " WHERE t.id = ?"
        )
        row = await self._db.transact(lambda tx: one(tx, sql, (ticket_id,)), "auto")
        if row is None:
            raise NotFound(f"no ticket {ticket_id}", ticket=ticket_id)
        return bytes(row["raw"])

    async def recent(
        self, *, status: Sequence[str] | None = None, before: int | None = None, limit: int = 50
    ) -> list[TillTicket]:
        """Tickets, newest first (``before``: ids below it, for the next page)."""
        where: list[str] = ["1"]
        params: list[Any] = []
        if status:
            where.append(sql_in("t.status", status))
            params.extend(status)
        if before is not None:
            where.append("t.id < ?")
            params.append(before)
        sql = f"{_TICKET} WHERE {' AND '.join(where)} ORDER BY t.id DESC LIMIT {int(limit)}"
        found = await self._db.transact(lambda tx: tx.all(sql, params), "auto")
        return [_ticket(r) for r in found]

    async def unread(self) -> list[TillTicket]:
        """Every ticket nobody could read nor handled, oldest first."""
        sql = f"{_TICKET} WHERE t.status = 'unread' ORDER BY t.id"
        return [_ticket(r) for r in await self._db.transact(lambda tx: tx.all(sql), "auto")]

    async def mark_unread(
        self, ticket_id: int, reading: dict[str, Any] | None, problem: str, *, now: float
    ) -> TillTicket:
        async def work(tx: Tx) -> TillTicket:
            await tx.run(
                "UPDATE till_ticket SET reading = ?, problem = ?, read_at = ?"
                " WHERE id = ? AND status = 'unread'",
                (to_json(reading) if reading else None, problem, now, ticket_id),
            )
            return await self._get(tx, ticket_id)

        return await self._db.transact(work, "write")

    async def handled(self, ticket_id: int, *, by: str, now: float) -> TillTicket:
        """Staff added an unread ticket's dishes by hand: it leaves the list of unread ones."""

        async def work(tx: Tx) -> TillTicket:
            if not await tx.run(
                "UPDATE till_ticket SET status = 'by_hand', handled_by = ?, read_at = ?"
                " WHERE id = ? AND status = 'unread'",
                (by, now, ticket_id),
            ):
                found = await self._get(tx, ticket_id)
                raise Conflict(
                    f"ticket {ticket_id} is {found.status} now, not unread",
                    ticket=ticket_id,
                    status=found.status,
                )
            await rows.add_event(tx, "till.by_hand", now, data={"ticket": ticket_id, "by": by})
            return await self._get(tx, ticket_id)

        return await self._db.transact(work, "write")

    async def order(
        self,
        ticket_id: int,
        key: str,
        table: str,
        reading: dict[str, Any],
        dishes: Sequence[NewDish],
        *,
        now: float,
    ) -> tuple[TillTicket, list[Order]]:
        """The ticket's dishes as ``ordered`` orders on ``table``, once per ``key``: a ticket
        with a key already ordered is a reprint of that one (no new order)."""
        checked = [
            check_new_order(
                d.dish,
                table,
                ready_at=None,
                quantity=d.quantity,
                note=d.note,
                status=OrderStatus.ORDERED,
            )
            for d in dishes
        ]
        self._db.dialect.check_name(key, "key")

        async def work(tx: Tx) -> tuple[TillTicket, list[Order]]:
            first = await self._first(tx, key)
            if first is not None:
                return await self._reprint(tx, ticket_id, first, key, table, reading, now), []
            await rows.get_waypoint(tx, table)
            made: list[Order] = []
            for d, (note, _, _) in zip(dishes, checked, strict=True):
                order_id = await tx.insert(
                    "INSERT INTO orders (dish, res_table, ready_at, status, quantity, note,"
                    " ordered_at, ticket_id) VALUES (?, ?, NULL, ?, ?, ?, ?, ?)",
                    (d.dish, table, OrderStatus.ORDERED.value, d.quantity, note, now, ticket_id),
                )
                data = {
                    "dish": d.dish,
                    "table": table,
                    "status": OrderStatus.ORDERED.value,
                    "quantity": d.quantity,
                    "note": note,
                    "ticket": ticket_id,
                }
                await rows.add_event(tx, "order.created", now, order_id=order_id, data=data)
                made.append(await rows.get_order(tx, order_id))
            await tx.run(
                "UPDATE till_ticket SET status = 'ordered', first_key = ?, `key` = ?,"
                " table_name = ?, reading = ?, problem = NULL, read_at = ? WHERE id = ?",
                (key, key, table, to_json(reading), now, ticket_id),
            )
            return await self._get(tx, ticket_id), made

        return await self._db.transact(work, "write")

    async def void(
        self,
        ticket_id: int,
        key: str,
        table: str,
        reading: dict[str, Any],
        dishes: Sequence[NewDish],
        *,
        now: float,
    ) -> tuple[TillTicket, list[Order], Voided]:
        """Withdraw a void ticket's dishes from the table's dishes the till ordered and no
        robot took yet (the newest first; a dish of 3 voided by 1 becomes 2), once per key."""
        self._db.dialect.check_name(key, "key")

        async def work(tx: Tx) -> tuple[TillTicket, list[Order], Voided]:
            first = await self._first(tx, key)
            if first is not None:
                done = await self._reprint(tx, ticket_id, first, key, table, reading, now)
                return done, [], Voided((), ())
            changed: dict[int, Order] = {}
            missing: list[tuple[str, int]] = []
            for d in dishes:
                left = d.quantity
                found = await tx.all(
                    f"{rows.ORDER} WHERE res_table = ? AND dish = ? AND ticket_id IS NOT NULL"
                    f" AND {sql_in('status', _VOIDABLE)} ORDER BY id DESC",
                    (table, d.dish, *_VOIDABLE),
                )
                for row in found:
                    if left <= 0:
                        break
                    order = Order(**row)
                    if order.quantity > left:
                        await tx.run(
                            "UPDATE orders SET quantity = ? WHERE id = ?",
                            (order.quantity - left, order.id),
                        )
                        await rows.add_event(
                            tx,
                            "order.edited",
                            now,
                            order_id=order.id,
                            data={
                                "quantity": order.quantity - left,
                                "by": "till",
                                "ticket": ticket_id,
                            },
                        )
                        left = 0
                    else:
                        await tx.run(
                            "UPDATE orders SET status = ?, voided_at = ? WHERE id = ?",
                            (OrderStatus.VOIDED.value, now, order.id),
                        )
                        await rows.add_event(
                            tx,
                            "order.voided",
                            now,
                            order_id=order.id,
                            data={"by": "till", "ticket": ticket_id},
                        )
                        left -= order.quantity
                    changed[order.id] = await rows.get_order(tx, order.id)
                if left > 0:
                    missing.append((d.dish, left))
            result = Voided(tuple(changed), tuple(missing))
            problem = (
                "not withdrawn (already on a robot, or never ordered): "
                + ", ".join(f"{q} x {name}" for name, q in missing)
                if missing
                else None
            )
            await tx.run(
                "UPDATE till_ticket SET status = 'void', first_key = ?, `key` = ?,"
                " table_name = ?, reading = ?, problem = ?, read_at = ? WHERE id = ?",
                (key, key, table, to_json(reading), problem, now, ticket_id),
            )
            return await self._get(tx, ticket_id), list(changed.values()), result

        return await self._db.transact(work, "write")

    async def orders_of(self, ticket_id: int) -> list[Order]:
        sql = f"{rows.ORDER} WHERE ticket_id = ? ORDER BY id"
        found = await self._db.transact(lambda tx: tx.all(sql, (ticket_id,)), "auto")
        return [Order(**r) for r in found]

    # -- the till's item names --------------------------------------------------------------

    async def names(self) -> dict[str, str]:
        """The till's item name -> the menu's dish."""
        sql = "SELECT pos_name, dish FROM till_name ORDER BY pos_name"
        found = await self._db.transact(lambda tx: tx.all(sql), "auto")
        return {str(r["pos_name"]): str(r["dish"]) for r in found}

    async def set_names(
        self, pairs: dict[str, str | None], *, now: float, by: str
    ) -> dict[str, str]:
        """Map (or, with None, unmap) the till's names; returns the whole mapping."""

        async def work(tx: Tx) -> None:
            for pos_name, dish in pairs.items():
                await tx.run("DELETE FROM till_name WHERE pos_name = ?", (pos_name,))
                if dish is not None:
                    await tx.run(
                        "INSERT INTO till_name (pos_name, dish, updated_at) VALUES (?, ?, ?)",
                        (pos_name, dish, now),
                    )
            await rows.add_event(
                tx, "till.names", now, data={"names": {k: v for k, v in pairs.items()}, "by": by}
            )

        await self._db.transact(work, "write")
        return await self.names()

    # -- settings ---------------------------------------------------------------------------

    async def settings(self) -> dict[str, Any]:
        return await self._db.transact(lambda tx: rows.get_settings(tx, "till_setting"), "auto")

    async def put_settings(self, values: dict[str, Any], *, now: float, by: str) -> dict[str, Any]:
        async def work(tx: Tx) -> None:
            for name, value in values.items():
                await rows.put_setting(tx, "till_setting", name, value, now, by)
            await rows.add_event(tx, "till.settings", now, data={"names": sorted(values), "by": by})

        await self._db.transact(work, "write")
        return await self.settings()
