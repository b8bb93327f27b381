"""The orders' rows: a dish ordered, each step of its life in the kitchen, voided, and a table's
cart. One part of :class:`~serveur.store.base.Store`, written once for every backend.

Each change is one transaction that re-checks its precondition with a conditional UPDATE and
its row count (two staff voiding the same dish: one wins, the other gets a Conflict) and
appends its ``events`` row in the same transaction, with who asked (``by``) where a person did.
What the dishes do on a trip (assigned, delivered, returned) is :mod:`serveur.store.tasks`'.
"""

from __future__ import annotations

from collections.abc import Collection
from typing import Any

from serveur.domain import ORDER_STEPS, DishAction, Order, OrderStatus
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store import rows
from serveur.store.checks import check_new_order, check_note, check_quantity, status_values
from serveur.store.live import WAYPOINT_NAMED
from serveur.store.sql import Db, Tx, one, sql_in

__all__ = ["Orders"]


class Orders:
    """Order methods of the store (``store.orders``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def add_order(
        self,
        dish: str,
        table: str,
        *,
        ready_at: float | None,
        key: str | None = None,
        now: float,
        quantity: int = 1,
        note: str | None = None,
        status: OrderStatus = OrderStatus.PENDING,
        special: str | None = None,
    ) -> Order:
        """A dish for ``table``: ready at the pass (``pending``, at ``ready_at``) or just
        ``ordered`` (the kitchen marks it ready later); ``key`` makes a resend return the same
        order."""
        note, ready_at, fingerprint = check_new_order(
            dish,
            table,
            ready_at=ready_at,
            quantity=quantity,
            note=note,
            status=status,
            special=special,
        )
        if key is not None:
            self._db.dialect.check_name(key, "key")

        async def work(tx: Tx) -> Order:
            if key is not None:
                done = await rows.replayed(tx, key, "order", fingerprint)
                if done is not None:
                    return await rows.get_order(tx, done["order_id"])
            await rows.get_waypoint(tx, table)
            order_id = await tx.insert(
                "INSERT INTO orders (dish, res_table, `key`, ready_at, status, quantity, note,"
                " ordered_at, special) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (dish, table, key, ready_at, status.value, quantity, note, now, special),
            )
            if key is not None:
                await rows.remember(tx, key, "order", fingerprint, {"order_id": order_id}, now)
            data = {
                "dish": dish,
                "table": table,
                "key": key,
                "ready_at": ready_at,
                "status": status.value,
                "quantity": quantity,
                "note": note,
            }
            if special is not None:
                data["special"] = special
            await rows.add_event(tx, "order.created", now, order_id=order_id, data=data)
            return await rows.get_order(tx, order_id)

        return await self._db.transact(work, "write")

    async def get_order(self, order_id: int) -> Order:
        return await self._db.transact(lambda tx: rows.get_order(tx, order_id), "auto")

    async def list_orders(
        self,
        *,
        status: OrderStatus | Collection[OrderStatus] | None = None,
        table: str | None = None,
        task_id: int | None = None,
    ) -> list[Order]:
        """Orders matching every given filter, by id."""
        where: list[str] = ["1"]
        params: list[Any] = []
        statuses = status_values(status, OrderStatus)
        if statuses is not None:
            where.append(sql_in("status", statuses))
            params.extend(statuses)
        if table is not None:
            where.append("res_table = ?")
            params.append(table)
        if task_id is not None:
            where.append("task_num = ?")
            params.append(task_id)
        sql = f"{rows.ORDER} WHERE {' AND '.join(where)} ORDER BY id"
        return [Order(**r) for r in await self._db.transact(lambda tx: tx.all(sql, params), "auto")]

    async def last_ready(self, before: float) -> float | None:
        """When the latest dish first ready at the pass before ``before`` was ready (voided
        dishes left out), or None: one aggregate, so the console can ask which day last had a
        service without the server reading every order of a year (``list_orders`` would)."""
        sql = "SELECT max(ready_at) AS t FROM orders WHERE ready_at < ? AND status <> ?"
        row = await self._db.transact(
            lambda tx: one(tx, sql, (before, OrderStatus.VOIDED.value)), "auto"
        )
        t = None if row is None else row["t"]
        return None if t is None else float(t)

    async def cancel_order(self, order_id: int, *, now: float) -> Order:
        """Void a dish that has not left the pass (an order on a trip is a Conflict)."""
        return await self.step_order(order_id, DishAction.VOID, now=now)

    async def cart(self, table: str) -> list[Order]:
        """The table's assigned and delivered orders, oldest first (the guest's cart)."""

        async def work(tx: Tx) -> list[dict[str, Any]]:
            await rows.get_waypoint(tx, table)
            return await tx.all(
                f"{rows.ORDER} WHERE res_table = ? AND status IN ('assigned', 'delivered')"
                " ORDER BY ready_at, id",
                (table,),
            )

        return [Order(**r) for r in await self._db.transact(work, "read")]

    async def step_order(
        self,
        order_id: int,
        action: DishAction,
        *,
        now: float,
        by: str | None = None,
        quantity: int | None = None,
        note: str | None = None,
        table: str | None = None,
    ) -> Order:
        """One step of a dish's life (:data:`~serveur.domain.ORDER_STEPS`), or a Conflict
        naming its status if the dish is not (or no longer) where the step starts from."""
        allowed, to = ORDER_STEPS[action]
        if quantity is not None:
            check_quantity(quantity)
        given_note = note is not None  # "" clears the note, None leaves it
        note = check_note(note)

        async def work(tx: Tx) -> None:
            row = await one(tx, "SELECT status, res_table FROM orders WHERE id = ?", (order_id,))
            if row is None:
                raise NotFound(f"no order {order_id}", order=order_id)
            status = OrderStatus(row["status"])
            if status not in allowed:
                raise Conflict(
                    f"order {order_id} is {status.value}: it cannot be {_DONE[action]}",
                    order=order_id,
                    status=status.value,
                )
            ok = ", ".join("?" * len(allowed))
            data: dict[str, Any] = {"from": status.value, "by": by}
            sets: list[str] = []
            params: list[Any] = []
            if action is DishAction.EDIT:
                if quantity is not None:
                    sets.append("quantity = ?")
                    params.append(quantity)
                    data["quantity"] = quantity
                if given_note:
                    sets.append("note = ?")
                    params.append(note)
                    data["note"] = note
                if table is not None and table != row["res_table"]:
                    if not await one(tx, WAYPOINT_NAMED, (table,)):
                        raise NotFound(f"no waypoint named {table!r}", waypoint=table)
                    sets.append("res_table = ?")
                    params.append(table)
                    data["table"] = table
            else:
                assert to is not None
                sets.append("status = ?")
                params.append(to.value)
                if to is OrderStatus.PENDING:
                    # A returned dish sent again keeps its first ready time (it has waited
                    # since then: the dispatcher ranks it so, the statistics count it so)
                    # and is off any trip until it is dispatched again.
                    sets += ["ready_at = COALESCE(ready_at, ?)", "dispatched_at = NULL"]
                    params.append(now)
                elif to is OrderStatus.VOIDED:
                    sets.append("voided_at = ?")
                    params.append(now)
                data["to"] = to.value
            if not sets:  # an edit
                if quantity is None and not given_note and table is None:
                    raise InvalidField("edit needs a quantity, a note or a table", field="action")
                return  # what was asked is so already: nothing to change or record
            sql = f"UPDATE orders SET {', '.join(sets)} WHERE id = ? AND status IN ({ok})"
            if await tx.run(sql, (*params, order_id, *(s.value for s in allowed))) != 1:
                raise Conflict(f"order {order_id} changed meanwhile", order=order_id)
            await rows.add_event(tx, f"order.{_EVENT[action]}", now, order_id=order_id, data=data)

        await self._db.transact(work, "write")
        return await self.get_order(order_id)


_DONE = {
    DishAction.COOKING: "started",
    DishAction.READY: "marked ready",
    DishAction.VOID: "voided",
    DishAction.EDIT: "edited",
}
#: The event of each step: ``order.<name>``.
_EVENT = {
    DishAction.COOKING: "cooking",
    DishAction.READY: "ready",
    DishAction.VOID: "voided",
    DishAction.EDIT: "edited",
}
