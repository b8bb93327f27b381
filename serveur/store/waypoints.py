"""The waypoints' rows: saving, renaming and removing the places robots drive to, and what
depends on one. One part of :class:`~serveur.store.base.Store`, written once for every backend.

A removed waypoint keeps its row, marked ``removed_at`` (past trips and orders name it); every
read skips it (:mod:`serveur.store.live`), and saving the name again revives the row. Renaming
and removing re-check, in their own transaction, what still depends on the waypoint, so a
concurrent order or trip cannot be stranded.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Final

from serveur.domain import WaypointRecord
from serveur.errors import Conflict, InvalidField
from serveur.store import rows
from serveur.store.checks import check_finite
from serveur.store.live import ROBOT, WAYPOINT, WAYPOINT_NAMED
from serveur.store.sql import Db, Tx, one

__all__ = ["OPEN_ORDER_STATUSES", "REVIVE_WAYPOINT", "Dependents", "Waypoints"]

#: Order statuses that still need their table (an assigned one is on a trip, counted as a trip).
OPEN_ORDER_STATUSES = ("ordered", "cooking", "pending", "returned")

#: A removed waypoint saved again. Parameters: x, y, yaw, kind, name.
REVIVE_WAYPOINT: Final = (
    "UPDATE waypoints SET x = ?, y = ?, yaw = ?, kind = ?, removed_at = NULL"
    " WHERE name = ? AND removed_at IS NOT NULL"
)

_OPEN = ", ".join(f"'{s}'" for s in OPEN_ORDER_STATUSES)


@dataclass(frozen=True, slots=True)
class Dependents:
    """What depends on a waypoint now (history does not count: it keeps the old name)."""

    homes: list[str] = field(default_factory=list)  # robots parked there
    orders: list[int] = field(default_factory=list)  # open orders for the table
    trips: list[int] = field(default_factory=list)  # queued or active trips stopping there
    tokens: list[int] = field(default_factory=list)  # active table-screen tokens for it
    blocked: bool = False
    docks: list[str] = field(default_factory=list)  # robots whose charger it is
    buttons: list[str] = field(default_factory=list)  # live call buttons of the table

    @property
    def blocking(self) -> bool:
        """True if removing the waypoint would strand something (tokens and a block do not:
        they end with the table)."""
        return bool(self.homes or self.orders or self.trips or self.docks)

    def as_dict(self) -> dict[str, Any]:
        return {
            "homes": self.homes,
            "orders": self.orders,
            "trips": self.trips,
            "tokens": self.tokens,
            "blocked": self.blocked,
            "docks": self.docks,
            "buttons": self.buttons,
        }


class Waypoints:
    """Waypoint methods of the store (``store.waypoints``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def put_waypoint(
        self, wp: WaypointRecord, *, replace: bool = False, now: float
    ) -> WaypointRecord:
        """Create a waypoint, or overwrite it with ``replace``; an identical resend is a no-op."""
        self._db.dialect.check_name(wp.name, "name")
        for name in ("x", "y", "yaw"):
            check_finite(getattr(wp, name), name)

        async def work(tx: Tx) -> WaypointRecord:
            row = await one(tx, WAYPOINT_NAMED + tx.dialect.for_update, (wp.name,))
            values = (wp.x, wp.y, wp.yaw, wp.kind.value, wp.name)
            if row is None:
                if not await tx.run(REVIVE_WAYPOINT, values):
                    await tx.run(
                        "INSERT INTO waypoints (x, y, yaw, kind, name, created_at)"
                        " VALUES (?, ?, ?, ?, ?, ?)",
                        (*values, now),
                    )
            else:
                existing = WaypointRecord(**row)
                if existing == wp:
                    return existing
                if not replace:
                    raise Conflict(
                        f"waypoint {wp.name!r} exists with another pose or kind",
                        waypoint=wp.name,
                    )
                await tx.run(
                    "UPDATE waypoints SET x = ?, y = ?, yaw = ?, kind = ? WHERE name = ?", values
                )
            data: dict[str, Any] = {"x": wp.x, "y": wp.y, "yaw": wp.yaw, "kind": wp.kind.value}
            data["replaced"] = row is not None
            await rows.add_event(tx, "waypoint.saved", now, data={"name": wp.name, **data})
            return await rows.get_waypoint(tx, wp.name)

        return await self._db.transact(work, "write")

    async def get_waypoint(self, name: str) -> WaypointRecord:
        return await self._db.transact(lambda tx: rows.get_waypoint(tx, name), "auto")

    async def list_waypoints(self) -> list[WaypointRecord]:
        """All waypoints, by name."""
        found = await self._db.transact(lambda tx: tx.all(f"{WAYPOINT} ORDER BY name"), "auto")
        return [WaypointRecord(**r) for r in found]

    async def delete_waypoint(self, name: str, *, now: float) -> None:
        """Delete a waypoint no order and no robot's home refers to."""

        async def work(tx: Tx) -> None:
            # Locked: an order or robot being added for it waits (its foreign key check needs
            # a shared lock on this row), so the counts below cannot miss it.
            await rows.get_waypoint(tx, name, lock=True)
            orders = await one(tx, "SELECT count(*) AS n FROM orders WHERE res_table = ?", (name,))
            n_orders = int(orders["n"]) if orders else 0
            robots = [
                r["name"]
                for r in await tx.all("SELECT name FROM robot_info WHERE home = ?", (name,))
            ]
            if n_orders or robots:
                raise Conflict(
                    f"waypoint {name!r} is used by {n_orders} order(s) and as home of"
                    f" {len(robots)} robot(s)",
                    waypoint=name,
                    orders=n_orders,
                    robots=robots,
                )
            await tx.run("DELETE FROM waypoints WHERE name = ?", (name,))
            await rows.add_event(tx, "waypoint.deleted", now, data={"name": name})

        await self._db.transact(work, "write")

    async def waypoint_dependents(self, name: str) -> Dependents:
        """What depends on waypoint ``name`` now (NotFound if there is none)."""

        async def work(tx: Tx) -> Dependents:
            await rows.get_waypoint(tx, name)
            return await _dependents(tx, name)

        return await self._db.transact(work, "read")

    async def rename_waypoint(
        self, old: str, new: str, *, now: float, by: str | None = None
    ) -> tuple[WaypointRecord, Dependents]:
        """Rename a waypoint no trip is bound for: robots' homes, open orders, its block and
        its table screens' tokens follow it. Returns the new waypoint and what moved."""

        async def work(tx: Tx) -> tuple[WaypointRecord, Dependents]:
            wp = await rows.get_waypoint(tx, old)
            if new == old:
                raise InvalidField("the new name is the current name", field="name")
            deps = await _dependents(tx, old)
            if deps.trips:
                raise Conflict(
                    f"trips {deps.trips} are bound for {old}: rename it when they are over",
                    waypoint=old,
                    trips=deps.trips,
                )
            if await one(tx, WAYPOINT_NAMED, (new,)):
                raise Conflict(f"a waypoint named {new!r} exists", waypoint=new)
            pose = (wp.x, wp.y, wp.yaw, wp.kind.value, new)
            if not await tx.run(REVIVE_WAYPOINT, pose):
                await tx.run(
                    "INSERT INTO waypoints (x, y, yaw, kind, name, created_at)"
                    " VALUES (?, ?, ?, ?, ?, ?)",
                    (*pose, now),
                )
            await tx.run("UPDATE robot_info SET home = ? WHERE home = ?", (new, old))
            await tx.run("UPDATE robot_info SET dock = ? WHERE dock = ?", (new, old))
            # The table's buttons and open calls follow it (a press of a button of a renamed
            # table still calls it).
            await tx.run(
                "UPDATE call_button SET table_name = ? WHERE table_name = ? AND revoked_at IS NULL",
                (new, old),
            )
            await tx.run(
                "UPDATE `call` SET table_name = ? WHERE table_name = ?"
                " AND answered_at IS NULL AND cancelled_at IS NULL",
                (new, old),
            )
            await tx.run(
                f"UPDATE orders SET res_table = ? WHERE res_table = ? AND status IN ({_OPEN})",
                (new, old),
            )
            block = await one(
                tx, "SELECT reason, robot, since FROM table_block WHERE waypoint = ?", (old,)
            )
            if block is not None:
                await tx.run("DELETE FROM table_block WHERE waypoint = ?", (old,))
                await tx.run(
                    "INSERT INTO table_block (waypoint, reason, robot, since) VALUES (?, ?, ?, ?)",
                    (new, block["reason"], block["robot"], block["since"]),
                )
            await tx.run(
                "UPDATE tokens SET tbl = ? WHERE tbl = ? AND revoked_at IS NULL", (new, old)
            )
            await tx.run("UPDATE waypoints SET removed_at = ? WHERE name = ?", (now, old))
            data = {"name": old, "to": new, "by": by, **deps.as_dict()}
            await rows.add_event(tx, "waypoint.renamed", now, data=data)
            return await rows.get_waypoint(tx, new), deps

        return await self._db.transact(work, "write")

    async def remove_waypoint(self, name: str, *, now: float, by: str | None = None) -> Dependents:
        """Remove a waypoint nothing open depends on (Conflict naming what does). Its table
        screens' tokens are revoked and its block cleared. Returns what it had."""

        async def work(tx: Tx) -> Dependents:
            await rows.get_waypoint(tx, name)
            deps = await _dependents(tx, name)
            if deps.blocking:
                raise Conflict(
                    f"{name} is still needed: {_describe(deps)}", waypoint=name, **deps.as_dict()
                )
            await rows.revoke_where(tx, "role = 'table-screen' AND tbl = ?", (name,), now)
            # Its buttons end with the table, and its open calls are cancelled.
            await tx.run(
                "UPDATE call_button SET revoked_at = ? WHERE table_name = ? AND revoked_at IS NULL",
                (now, name),
            )
            await tx.run(
                "UPDATE `call` SET cancelled_at = ?, cancelled_by = ? WHERE table_name = ?"
                " AND answered_at IS NULL AND cancelled_at IS NULL",
                (now, by or "removed", name),
            )
            await tx.run("DELETE FROM table_block WHERE waypoint = ?", (name,))
            await tx.run("UPDATE waypoints SET removed_at = ? WHERE name = ?", (now, name))
            data = {"name": name, "by": by, **deps.as_dict()}
            await rows.add_event(tx, "waypoint.removed", now, data=data)
            return deps

        return await self._db.transact(work, "write")


async def _dependents(tx: Tx, name: str) -> Dependents:
    homes = await tx.all(f"{ROBOT} AND home = ? ORDER BY name", (name,))
    orders = await tx.all(
        f"SELECT id FROM orders WHERE res_table = ? AND status IN ({_OPEN}) ORDER BY id", (name,)
    )
    trips = await tx.all(
        "SELECT DISTINCT t.id FROM task t JOIN task_stop s ON s.task_id = t.id"
        " WHERE s.waypoint = ? AND t.status IN ('queued', 'active') ORDER BY t.id",
        (name,),
    )
    tokens = await tx.all(
        "SELECT id FROM tokens WHERE revoked_at IS NULL AND role = 'table-screen' AND tbl = ?"
        " ORDER BY id",
        (name,),
    )
    block = await one(tx, "SELECT 1 AS yes FROM table_block WHERE waypoint = ?", (name,))
    docks = await tx.all(f"{ROBOT} AND dock = ? ORDER BY name", (name,))
    buttons = await tx.all(
        "SELECT name FROM call_button WHERE table_name = ? AND revoked_at IS NULL ORDER BY name",
        (name,),
    )
    return Dependents(
        homes=[str(r["name"]) for r in homes],
        orders=[int(r["id"]) for r in orders],
        trips=[int(r["id"]) for r in trips],
        tokens=[int(r["id"]) for r in tokens],
        blocked=block is not None,
        docks=[str(r["name"]) for r in docks],
        buttons=[str(r["name"]) for r in buttons],
    )


def _describe(deps: Dependents) -> str:
    parts = []
    if deps.homes:
        parts.append(f"home of {', '.join(deps.homes)}")
    if deps.orders:
        parts.append(f"{len(deps.orders)} open order(s)")
    if deps.trips:
        parts.append(f"trips {deps.trips}")
    if deps.docks:
        parts.append(f"the charger of {', '.join(deps.docks)}")
    return "; ".join(parts)
