"""The dinner service's own records: the menu, the tables no robot is sent to, the owner's
settings. One part of :class:`~serveur.store.base.Store`, written once for every backend: each
change is one unit of work that appends its ``events`` row, with who asked (``by``).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from serveur.domain import MenuItem, TableBlock
from serveur.errors import InvalidField, NotFound
from serveur.store import rows
from serveur.store.live import WAYPOINT_NAMED
from serveur.store.orders import _EVENT as _EVENT  # a dish's step events (tests read them here)
from serveur.store.sql import Db, Tx, one

__all__ = ["Service"]

_MENU = "SELECT dish, category, price_cents, available, position FROM menu"
_BLOCK = "SELECT waypoint, reason, robot, since FROM table_block"


def _menu_item(row: dict[str, Any]) -> MenuItem:
    return MenuItem(**{**row, "available": bool(row["available"])})


def _block(row: dict[str, Any]) -> TableBlock:
    return TableBlock(
        table=row["waypoint"], reason=row["reason"], robot=row["robot"], since=row["since"]
    )


class Service:
    """Menu, table-block and settings methods of the store (``store.service``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    # -- the menu ---------------------------------------------------------------------------

    async def list_menu(self) -> list[MenuItem]:
        async def work(tx: Tx) -> list[MenuItem]:
            return [_menu_item(r) for r in await tx.all(f"{_MENU} ORDER BY position, dish")]

        return await self._db.transact(work, "read")

    async def put_dish(self, item: MenuItem, *, now: float, by: str | None = None) -> MenuItem:
        """Add a dish to the menu, or change it (category, price, availability, place)."""
        if not item.dish.strip() or len(item.dish) > 64 or item.dish != item.dish.strip():
            raise InvalidField("a dish name has 1 to 64 characters, no outer spaces", field="name")
        if len(item.category) > 64:
            raise InvalidField("a category has at most 64 characters", field="category")
        if item.price_cents is not None and item.price_cents < 0:
            raise InvalidField("a price cannot be negative", field="price_cents")

        async def work(tx: Tx) -> MenuItem:
            values = (item.category, item.price_cents, int(item.available), item.position, now)
            changed = await tx.run(
                "UPDATE menu SET category = ?, price_cents = ?, available = ?, position = ?,"
                " updated_at = ? WHERE dish = ?",
                (*values, item.dish),
            )
            if not changed:
                await tx.run(
                    "INSERT INTO menu (category, price_cents, available, position, updated_at,"
                    " dish) VALUES (?, ?, ?, ?, ?, ?)",
                    (*values, item.dish),
                )
            data = {**item.model_dump(), "by": by}
            await rows.add_event(tx, "menu.changed" if changed else "menu.added", now, data=data)
            row = await one(tx, f"{_MENU} WHERE dish = ?", (item.dish,))
            assert row is not None
            return _menu_item(row)

        return await self._db.transact(work, "write")

    # -- tables no robot is sent to -----------------------------------------------------------

    async def list_blocks(self) -> list[TableBlock]:
        async def work(tx: Tx) -> list[TableBlock]:
            return [_block(r) for r in await tx.all(f"{_BLOCK} ORDER BY since, waypoint")]

        return await self._db.transact(work, "read")

    async def block_table(
        self, table: str, reason: str, *, robot: str | None, now: float
    ) -> TableBlock:
        """Keep ``table`` out of every trip; a table already blocked keeps its first reason."""

        async def work(tx: Tx) -> TableBlock:
            if not await one(tx, WAYPOINT_NAMED, (table,)):
                raise NotFound(f"no waypoint named {table!r}", waypoint=table)
            row = await one(tx, f"{_BLOCK} WHERE waypoint = ?", (table,))
            if row is None:
                await tx.run(
                    "INSERT INTO table_block (waypoint, reason, robot, since) VALUES (?, ?, ?, ?)",
                    (table, reason, robot, now),
                )
                data = {"table": table, "reason": reason}
                await rows.add_event(tx, "table.blocked", now, robot=robot, data=data)
                row = await one(tx, f"{_BLOCK} WHERE waypoint = ?", (table,))
                assert row is not None
            return _block(row)

        return await self._db.transact(work, "write")

    async def unblock_table(self, table: str, *, now: float, by: str | None = None) -> bool:
        """Staff cleared the table; False if it was not blocked."""

        async def work(tx: Tx) -> bool:
            if not await tx.run("DELETE FROM table_block WHERE waypoint = ?", (table,)):
                return False
            await rows.add_event(tx, "table.cleared", now, data={"table": table, "by": by})
            return True

        return await self._db.transact(work, "write")

    # -- settings ---------------------------------------------------------------------------

    async def get_settings(self) -> dict[str, Any]:
        """The settings the owner saved (name -> value); absent ones keep the server's."""

        return await self._db.transact(lambda tx: rows.get_settings(tx, "settings"), "read")

    async def put_settings(
        self, values: Mapping[str, Any], *, now: float, by: str | None = None
    ) -> dict[str, Any]:
        """Save settings (already checked by the caller); returns all saved settings."""

        async def work(tx: Tx) -> dict[str, Any]:
            for name, value in values.items():
                await rows.put_setting(tx, "settings", name, value, now, by)
            await rows.add_event(tx, "settings.changed", now, data={**values, "by": by})
            return await rows.get_settings(tx, "settings")

        return await self._db.transact(work, "write")
