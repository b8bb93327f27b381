"""The dinner service's own records: the menu, blocked tables, each step of a dish, skipped stops.

Written once for every SQL backend, like :mod:`serveur.store.accounts`: the statements are
plain SQL run through :meth:`~serveur.store.accounts.AccountsMixin._portable`, and each change
is one transaction that re-checks its precondition with a conditional UPDATE and its row
count (two staff voiding the same dish: one wins, the other gets a Conflict), and appends its
``events`` row in the same transaction, with who asked (``by``) where a person did.
"""

from __future__ import annotations

import json
from abc import abstractmethod
from collections.abc import Sequence
from typing import Any

from serveur.domain import (
    ORDER_STEPS,
    DishAction,
    MenuItem,
    Order,
    OrderStatus,
    TableBlock,
    Task,
)
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.accounts import AccountsMixin, SqlTx
from serveur.store.live import WAYPOINT_NAMED

__all__ = ["ServiceMixin", "check_note", "check_quantity"]

_MENU = "SELECT dish, category, price_cents, available, position FROM menu"
_BLOCK = "SELECT waypoint, reason, robot, since FROM table_block"


def check_quantity(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 99:
        raise InvalidField("quantity must be a whole number from 1 to 99", field="quantity")
    return value


def check_note(value: object) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or len(value) > 200:
        raise InvalidField("note must be text of at most 200 characters", field="note")
    return value.strip() or None


async def _one(db: SqlTx, sql: str, params: Sequence[Any]) -> dict[str, Any] | None:
    rows = await db.all(sql, params)
    return rows[0] if rows else None


async def _event(
    db: SqlTx,
    kind: str,
    now: float,
    *,
    robot: str | None = None,
    task_id: int | None = None,
    order_id: int | None = None,
    data: dict[str, Any] | None = None,
) -> None:
    await db.insert(
        "INSERT INTO events (ts, kind, robot, task_id, order_id, data) VALUES (?, ?, ?, ?, ?, ?)",
        (now, kind, robot, task_id, order_id, json.dumps(data or {}, separators=(",", ":"))),
    )


def _menu_item(row: dict[str, Any]) -> MenuItem:
    return MenuItem(**{**row, "available": bool(row["available"])})


def _block(row: dict[str, Any]) -> TableBlock:
    return TableBlock(
        table=row["waypoint"], reason=row["reason"], robot=row["robot"], since=row["since"]
    )


class ServiceMixin(AccountsMixin):
    """Menu, table-block, dish-step and skip methods of :class:`~serveur.store.base.Store`."""

    @abstractmethod
    async def get_order(self, order_id: int) -> Order: ...

    @abstractmethod
    async def get_task(self, task_id: int) -> Task: ...

    # -- the menu ---------------------------------------------------------------------------

    async def list_menu(self) -> list[MenuItem]:
        async def work(db: SqlTx) -> list[MenuItem]:
            return [_menu_item(r) for r in await db.all(f"{_MENU} ORDER BY position, dish")]

        return await self._portable(work, write=False)

    async def put_dish(self, item: MenuItem, *, now: float, by: str | None = None) -> MenuItem:
        """Add a dish to the menu, or change it (category, price, availability, place)."""
        if not item.dish.strip() or len(item.dish) > 64 or item.dish != item.dish.strip():
            raise InvalidField("a dish name has 1 to 64 characters, no outer spaces", field="name")
        if len(item.category) > 64:
            raise InvalidField("a category has at most 64 characters", field="category")
        if item.price_cents is not None and item.price_cents < 0:
            raise InvalidField("a price cannot be negative", field="price_cents")

        async def work(db: SqlTx) -> MenuItem:
            values = (item.category, item.price_cents, int(item.available), item.position, now)
            changed = await db.run(
                "UPDATE menu SET category = ?, price_cents = ?, available = ?, position = ?,"
                " updated_at = ? WHERE dish = ?",
                (*values, item.dish),
            )
            if not changed:
                await db.run(
                    "INSERT INTO menu (category, price_cents, available, position, updated_at,"
                    " dish) VALUES (?, ?, ?, ?, ?, ?)",
                    (*values, item.dish),
                )
            data = {**item.model_dump(), "by": by}
            await _event(db, "menu.changed" if changed else "menu.added", now, data=data)
            row = await _one(db, f"{_MENU} WHERE dish = ?", (item.dish,))
            assert row is not None
            return _menu_item(row)

        return await self._portable(work, write=True)

    # -- tables no robot is sent to -----------------------------------------------------------

    async def list_blocks(self) -> list[TableBlock]:
        async def work(db: SqlTx) -> list[TableBlock]:
            return [_block(r) for r in await db.all(f"{_BLOCK} ORDER BY since, waypoint")]

        return await self._portable(work, write=False)

    async def block_table(
        self, table: str, reason: str, *, robot: str | None, now: float
    ) -> TableBlock:
        """Keep ``table`` out of every trip; a table already blocked keeps its first reason."""

        async def work(db: SqlTx) -> TableBlock:
            if not await _one(db, WAYPOINT_NAMED, (table,)):
                raise NotFound(f"no waypoint named {table!r}", waypoint=table)
            row = await _one(db, f"{_BLOCK} WHERE waypoint = ?", (table,))
            if row is None:
                await db.run(
                    "INSERT INTO table_block (waypoint, reason, robot, since) VALUES (?, ?, ?, ?)",
                    (table, reason, robot, now),
                )
                data = {"table": table, "reason": reason}
                await _event(db, "table.blocked", now, robot=robot, data=data)
                row = await _one(db, f"{_BLOCK} WHERE waypoint = ?", (table,))
                assert row is not None
            return _block(row)

        return await self._portable(work, write=True)

    async def unblock_table(self, table: str, *, now: float, by: str | None = None) -> bool:
        """Staff cleared the table; False if it was not blocked."""

        async def work(db: SqlTx) -> bool:
            if not await db.run("DELETE FROM table_block WHERE waypoint = ?", (table,)):
                return False
            await _event(db, "table.cleared", now, data={"table": table, "by": by})
            return True

        return await self._portable(work, write=True)

    # -- a dish's steps -------------------------------------------------------------------------

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

        async def work(db: SqlTx) -> None:
            row = await _one(db, "SELECT status, res_table FROM orders WHERE id = ?", (order_id,))
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
                    if not await _one(db, WAYPOINT_NAMED, (table,)):
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
            if await db.run(sql, (*params, order_id, *(s.value for s in allowed))) != 1:
                raise Conflict(f"order {order_id} changed meanwhile", order=order_id)
            await _event(db, f"order.{_EVENT[action]}", now, order_id=order_id, data=data)

        await self._portable(work, write=True)
        return await self.get_order(order_id)

    # -- a table skipped ---------------------------------------------------------------------

    async def skip_stop(
        self, task_id: int, seq: int, *, now: float, reason: str, by: str | None = None
    ) -> Task:
        """The robot leaves the current stop unserved (staff's skip, or the table's timeout):
        the stop is ``skipped``, its dishes ``returned`` (they go back to the pass, off the
        trip, for staff to send again or void), and the trip moves on to its next stop."""

        async def work(db: SqlTx) -> None:
            task = await _one(
                db, "SELECT robot_name, status, current_stop FROM task WHERE id = ?", (task_id,)
            )
            if task is None:
                raise NotFound(f"no task {task_id}", task=task_id)
            stop = await _one(
                db,
                "SELECT waypoint, status FROM task_stop WHERE task_id = ? AND seq = ?",
                (task_id, seq),
            )
            if (
                task["status"] != "active"
                or task["current_stop"] != seq
                or stop is None
                or stop["status"] not in ("pending", "arrived")
            ):
                raise Conflict(
                    f"stop {seq} of task {task_id} is not the one being served",
                    task=task_id,
                    seq=seq,
                    status=None if stop is None else stop["status"],
                )
            moved = await db.run(
                "UPDATE task SET current_stop = current_stop + 1"
                " WHERE id = ? AND status = 'active' AND current_stop = ?",
                (task_id, seq),
            )
            if moved != 1:
                raise Conflict(f"task {task_id} moved on meanwhile", task=task_id, seq=seq)
            table = stop["waypoint"]
            returned = [
                r["id"]
                for r in await db.all(
                    "SELECT id FROM orders WHERE task_num = ? AND res_table = ?"
                    " AND status = 'assigned' ORDER BY id",
                    (task_id, table),
                )
            ]
            # The stop keeps the ids of what it carried (migration 008), the dishes leave.
            await db.run(
                "UPDATE task_stop SET status = 'skipped', done_at = ?, returned = ?"
                " WHERE task_id = ? AND seq = ?",
                (now, json.dumps(returned), task_id, seq),
            )
            await db.run(
                "UPDATE orders SET status = 'returned', task_num = NULL, returned_at = ?"
                " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                (now, task_id, table),
            )
            data = {"seq": seq, "table": table, "orders": returned, "reason": reason, "by": by}
            await _event(
                db, "stop.skipped", now, robot=task["robot_name"], task_id=task_id, data=data
            )

        await self._portable(work, write=True)
        return await self.get_task(task_id)

    async def drop_stops(self, task_id: int, tables: Sequence[str], *, now: float) -> Task:
        """Take ``tables`` off a queued trip (blocked since it was planned): their dishes go
        back to ``pending``; a trip left with no stop is cancelled."""

        async def work(db: SqlTx) -> None:
            task = await _one(db, "SELECT status FROM task WHERE id = ?", (task_id,))
            if task is None:
                raise NotFound(f"no task {task_id}", task=task_id)
            if task["status"] != "queued":
                raise Conflict(f"task {task_id} is {task['status']}, not queued", task=task_id)
            dropped: list[int] = []
            for table in tables:
                dropped += [
                    r["id"]
                    for r in await db.all(
                        "SELECT id FROM orders WHERE task_num = ? AND res_table = ?",
                        (task_id, table),
                    )
                ]
                await db.run(
                    "UPDATE orders SET status = 'pending', task_num = NULL, dispatched_at = NULL"
                    " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                    (task_id, table),
                )
                await db.run(
                    "DELETE FROM task_stop WHERE task_id = ? AND waypoint = ?", (task_id, table)
                )
            left = await db.all(
                "SELECT seq FROM task_stop WHERE task_id = ? ORDER BY seq", (task_id,)
            )
            # Renumber 0..n-1 (``current_stop`` indexes them), through numbers no stop has,
            # so that no two stops share one on the way.
            for i, row in enumerate(left):
                await db.run(
                    "UPDATE task_stop SET seq = ? WHERE task_id = ? AND seq = ?",
                    (_RENUMBER + i, task_id, row["seq"]),
                )
            await db.run(
                "UPDATE task_stop SET seq = seq - ? WHERE task_id = ?", (_RENUMBER, task_id)
            )
            data = {"tables": list(tables), "orders": dropped, "reason": "table blocked"}
            await _event(db, "task.stops_dropped", now, task_id=task_id, data=data)
            if not left:
                await db.run(
                    "UPDATE task SET status = 'cancelled', finished_at = ? WHERE id = ?",
                    (now, task_id),
                )
                await _event(
                    db, "task.cancelled", now, task_id=task_id, data={"reason": "table blocked"}
                )

        await self._portable(work, write=True)
        return await self.get_task(task_id)

    async def set_trays(self, robot: str, trays: int | None, *, now: float) -> None:
        """How many tables one trip of ``robot`` may serve (None: the site's default)."""
        if trays is not None and (isinstance(trays, bool) or not 1 <= trays <= 12):
            raise InvalidField("trays must be a whole number from 1 to 12", field="trays")

        async def work(db: SqlTx) -> None:
            if not await db.run("UPDATE robot_info SET trays = ? WHERE name = ?", (trays, robot)):
                row = await _one(db, "SELECT trays FROM robot_info WHERE name = ?", (robot,))
                if row is None:
                    raise NotFound(f"no robot named {robot!r}", robot=robot)
            await _event(db, "robot.trays", now, robot=robot, data={"trays": trays})

        await self._portable(work, write=True)


_RENUMBER = 1_000_000  # above any stop number (a trip has at most a few hundred stops)
_DONE = {
    DishAction.COOKING: "started",
    DishAction.READY: "marked ready",
    DishAction.VOID: "voided",
    DishAction.EDIT: "edited",
}
_EVENT = {
    DishAction.COOKING: "cooking",
    DishAction.READY: "ready",
    DishAction.VOID: "voided",
    DishAction.EDIT: "edited",
}
