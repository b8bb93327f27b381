"""What the owner changes about the site: robots edited or removed, waypoints renamed or removed,
the site's settings, and the audit trail searched.

Written once for every SQL backend, like :mod:`serveur.store.service`. A robot or waypoint is
never deleted: past trips, stops and orders name it (foreign keys), and a service's history
must stay whole. Removal marks the row (``removed_at``, migration 006) and the live reads skip
it; registering the name again (``add_robot``, ``put_waypoint``) revives the row through
:data:`REVIVE_ROBOT`/:data:`REVIVE_WAYPOINT` with the new fields. Renaming a waypoint is a new
waypoint, the open references moved to it, and the old one removed: past orders keep the name
they were served under, which is what the statistics and the trip history show.

Each change re-checks what depends on its target inside its own transaction, so a trip
dispatched to a table at the moment the owner removes it makes one of the two fail, never both
succeed.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

from serveur.domain import AuditRecord, Robot, WaypointRecord
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.accounts import SqlTx, _audit, _revoke_where
from serveur.store.live import ROBOT, ROBOT_NAMED, WAYPOINT_NAMED
from serveur.store.service import ServiceMixin, _event, _one

__all__ = [
    "OPEN_ORDER_STATUSES",
    "REVIVE_ROBOT",
    "REVIVE_WAYPOINT",
    "AuditQuery",
    "Dependents",
    "SiteMixin",
]

#: Order statuses that still need their table (an assigned one is on a trip, counted as a trip).
OPEN_ORDER_STATUSES = ("ordered", "cooking", "pending", "returned")

#: A removed robot registered again: its row, reset to a new robot's state with the new fields.
#: Parameters: url, home, kinematics, link (JSON), updated_at, status_since, name.
REVIVE_ROBOT = (
    "UPDATE robot_info SET url = ?, home = ?, kinematics = ?, link = ?, mode = 'off',"
    " status = 'Offline', resume = NULL, current_task = NULL, battery = NULL, x = NULL,"
    " y = NULL, yaw = NULL, last_error = NULL, trays = NULL, updated_at = ?, status_since = ?,"
    " removed_at = NULL WHERE name = ? AND removed_at IS NOT NULL"
)
#: A removed waypoint saved again. Parameters: x, y, yaw, kind, name.
REVIVE_WAYPOINT = (
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

    @property
    def blocking(self) -> bool:
        """True if removing the waypoint would strand something (tokens and a block do not:
        they end with the table)."""
        return bool(self.homes or self.orders or self.trips)

    def as_dict(self) -> dict[str, Any]:
        return {
            "homes": self.homes,
            "orders": self.orders,
            "trips": self.trips,
            "tokens": self.tokens,
            "blocked": self.blocked,
        }


@dataclass(frozen=True, slots=True)
class AuditQuery:
    """A search of the audit trail: every given field must match; newest first."""

    actor: str | None = None
    verb: str | None = None
    outcome: str | None = None
    target: str | None = None
    since: float | None = None
    until: float | None = None
    before_id: int | None = None
    limit: int = 100


async def _dependents(db: SqlTx, name: str) -> Dependents:
    homes = await db.all(f"{ROBOT} AND home = ? ORDER BY name", (name,))
    orders = await db.all(
        f"SELECT id FROM orders WHERE res_table = ? AND status IN ({_OPEN}) ORDER BY id", (name,)
    )
    trips = await db.all(
        "SELECT DISTINCT t.id FROM task t JOIN task_stop s ON s.task_id = t.id"
        " WHERE s.waypoint = ? AND t.status IN ('queued', 'active') ORDER BY t.id",
        (name,),
    )
    tokens = await db.all(
        "SELECT id FROM tokens WHERE revoked_at IS NULL AND role = 'table-screen' AND tbl = ?"
        " ORDER BY id",
        (name,),
    )
    block = await _one(db, "SELECT 1 FROM table_block WHERE waypoint = ?", (name,))
    return Dependents(
        homes=[str(r["name"]) for r in homes],
        orders=[int(r["id"]) for r in orders],
        trips=[int(r["id"]) for r in trips],
        tokens=[int(r["id"]) for r in tokens],
        blocked=block is not None,
    )


async def _live_waypoint(db: SqlTx, name: str) -> WaypointRecord:
    row = await _one(db, WAYPOINT_NAMED, (name,))
    if row is None:
        raise NotFound(f"no waypoint named {name!r}", waypoint=name)
    return WaypointRecord(**row)


class SiteMixin(ServiceMixin):
    """Robot, waypoint, settings and audit-search methods of :class:`~serveur.store.base.Store`."""

    # -- robots -----------------------------------------------------------------------------

    async def edit_robot(
        self, name: str, changes: Mapping[str, Any], *, now: float, by: str | None = None
    ) -> Robot:
        """Change a robot's ``url``, ``home``, ``kinematics``, ``link`` (a dict) and/or
        ``trays`` (None: the site's); fields not in ``changes`` are kept. One event lists
        what changed; nothing changed is a no-op."""
        allowed = {"url", "home", "kinematics", "link", "trays"}
        if not changes or set(changes) - allowed:
            raise InvalidField(f"a robot edit changes some of {sorted(allowed)}", field="changes")

        async def work(db: SqlTx) -> Robot:
            row = await _one(db, ROBOT_NAMED, (name,))
            if row is None:
                raise NotFound(f"no robot named {name!r}", robot=name)
            old = {**row, "link": json.loads(row["link"] or "{}")}
            new = {k: v for k, v in changes.items() if old[k] != v}
            if new.get("home") is not None:
                await _live_waypoint(db, new["home"])
            if new:
                sets = ", ".join(f"{k} = ?" for k in new)
                values = [
                    json.dumps(v, sort_keys=True) if k == "link" else v for k, v in new.items()
                ]
                await db.run(
                    f"UPDATE robot_info SET {sets}, updated_at = ? WHERE name = ?",
                    (*values, now, name),
                )
                await _event(db, "robot.updated", now, robot=name, data={**new, "by": by})
            return await self._robot_tx(db, name)

        return await self._portable(work, write=True)

    async def remove_robot(self, name: str, *, now: float, by: str | None = None) -> list[int]:
        """Remove a robot with no trip (Conflict otherwise); its screen tokens are revoked.
        Returns the revoked token ids."""

        async def work(db: SqlTx) -> list[int]:
            row = await _one(db, ROBOT_NAMED, (name,))
            if row is None:
                raise NotFound(f"no robot named {name!r}", robot=name)
            if row["current_task"] is not None:
                raise Conflict(
                    f"robot {name} is on trip {row['current_task']}: cancel it first",
                    robot=name,
                    trip=row["current_task"],
                )
            await db.run(
                "UPDATE robot_info SET removed_at = ?, status = 'Offline', mode = 'off',"
                " resume = NULL, updated_at = ? WHERE name = ?",
                (now, now, name),
            )
            revoked = await _revoke_where(db, "role = 'robot-screen' AND robot = ?", (name,), now)
            await _event(db, "robot.removed", now, robot=name, data={"by": by, "tokens": revoked})
            return revoked

        return await self._portable(work, write=True)

    async def _robot_tx(self, db: SqlTx, name: str) -> Robot:
        row = await _one(db, ROBOT_NAMED, (name,))
        assert row is not None
        return Robot(**row)

    # -- waypoints --------------------------------------------------------------------------

    async def waypoint_dependents(self, name: str) -> Dependents:
        """What depends on waypoint ``name`` now (NotFound if there is none)."""

        async def work(db: SqlTx) -> Dependents:
            await _live_waypoint(db, name)
            return await _dependents(db, name)

        return await self._portable(work, write=False)

    async def rename_waypoint(
        self, old: str, new: str, *, now: float, by: str | None = None
    ) -> tuple[WaypointRecord, Dependents]:
        """Rename a waypoint no trip is bound for: robots' homes, open orders, its block and
        its table screens' tokens follow it. Returns the new waypoint and what moved."""

        async def work(db: SqlTx) -> tuple[WaypointRecord, Dependents]:
            wp = await _live_waypoint(db, old)
            if new == old:
                raise InvalidField("the new name is the current name", field="name")
            deps = await _dependents(db, old)
            if deps.trips:
                raise Conflict(
                    f"trips {deps.trips} are bound for {old}: rename it when they are over",
                    waypoint=old,
                    trips=deps.trips,
                )
            if await _one(db, WAYPOINT_NAMED, (new,)):
                raise Conflict(f"a waypoint named {new!r} exists", waypoint=new)
            pose = (wp.x, wp.y, wp.yaw, wp.kind.value, new)
            if not await db.run(REVIVE_WAYPOINT, pose):
                await db.run(
                    "INSERT INTO waypoints (x, y, yaw, kind, name, created_at)"
                    " VALUES (?, ?, ?, ?, ?, ?)",
                    (*pose, now),
                )
            await db.run("UPDATE robot_info SET home = ? WHERE home = ?", (new, old))
            await db.run(
                f"UPDATE orders SET res_table = ? WHERE res_table = ? AND status IN ({_OPEN})",
                (new, old),
            )
            block = await _one(
                db, "SELECT reason, robot, since FROM table_block WHERE waypoint = ?", (old,)
            )
            if block is not None:
                await db.run("DELETE FROM table_block WHERE waypoint = ?", (old,))
                await db.run(
                    "INSERT INTO table_block (waypoint, reason, robot, since) VALUES (?, ?, ?, ?)",
                    (new, block["reason"], block["robot"], block["since"]),
                )
            await db.run(
                "UPDATE tokens SET tbl = ? WHERE tbl = ? AND revoked_at IS NULL", (new, old)
            )
            await db.run("UPDATE waypoints SET removed_at = ? WHERE name = ?", (now, old))
            await _event(
                db,
                "waypoint.renamed",
                now,
                data={"name": old, "to": new, "by": by, **deps.as_dict()},
            )
            return await _live_waypoint(db, new), deps

        return await self._portable(work, write=True)

    async def remove_waypoint(self, name: str, *, now: float, by: str | None = None) -> Dependents:
        """Remove a waypoint nothing open depends on (Conflict naming what does). Its table
        screens' tokens are revoked and its block cleared. Returns what it had."""

        async def work(db: SqlTx) -> Dependents:
            await _live_waypoint(db, name)
            deps = await _dependents(db, name)
            if deps.blocking:
                raise Conflict(
                    f"{name} is still needed: {_describe(deps)}", waypoint=name, **deps.as_dict()
                )
            await _revoke_where(db, "role = 'table-screen' AND tbl = ?", (name,), now)
            await db.run("DELETE FROM table_block WHERE waypoint = ?", (name,))
            await db.run("UPDATE waypoints SET removed_at = ? WHERE name = ?", (now, name))
            data = {"name": name, "by": by, **deps.as_dict()}
            await _event(db, "waypoint.removed", now, data=data)
            return deps

        return await self._portable(work, write=True)

    # -- settings ---------------------------------------------------------------------------

    async def get_settings(self) -> dict[str, Any]:
        """The settings the owner saved (name -> value); absent ones keep the server's."""

        async def work(db: SqlTx) -> dict[str, Any]:
            rows = await db.all("SELECT name, value FROM settings ORDER BY name")
            return {str(r["name"]): json.loads(r["value"]) for r in rows}

        return await self._portable(work, write=False)

    async def put_settings(
        self, values: Mapping[str, Any], *, now: float, by: str | None = None
    ) -> dict[str, Any]:
        """Save settings (already checked by the caller); returns all saved settings."""

        async def work(db: SqlTx) -> dict[str, Any]:
            for name, value in values.items():
                body = json.dumps(value, separators=(",", ":"))
                if not await db.run(
                    "UPDATE settings SET value = ?, updated_at = ?, updated_by = ? WHERE name = ?",
                    (body, now, by, name),
                ):
                    await db.run(
                        "INSERT INTO settings (name, value, updated_at, updated_by)"
                        " VALUES (?, ?, ?, ?)",
                        (name, body, now, by),
                    )
            await _event(db, "settings.changed", now, data={**values, "by": by})
            rows = await db.all("SELECT name, value FROM settings ORDER BY name")
            return {str(r["name"]): json.loads(r["value"]) for r in rows}

        return await self._portable(work, write=True)

    # -- the audit trail, searched ----------------------------------------------------------

    async def search_audit(self, q: AuditQuery) -> list[AuditRecord]:
        """Audit records matching ``q``, newest first (page on with ``before_id``)."""
        if not 1 <= q.limit <= 500:
            raise InvalidField("limit is from 1 to 500", field="limit")
        where: list[str] = []
        params: list[Any] = []
        texts: tuple[tuple[str, str | None], ...] = (
            ("actor", q.actor),
            ("verb", q.verb),
            ("outcome", q.outcome),
            ("target", q.target),
        )
        for column, value in texts:
            if value is not None:
                where.append(f"{column} = ?")
                params.append(value)
        bounds: tuple[tuple[str, float | None], ...] = (
            ("ts >= ?", q.since),
            ("ts < ?", q.until),
            ("id < ?", q.before_id),
        )
        for cond, bound in bounds:
            if bound is not None:
                where.append(cond)
                params.append(bound)
        clause = f" WHERE {' AND '.join(where)}" if where else ""

        async def work(db: SqlTx) -> list[AuditRecord]:
            rows = await db.all(
                "SELECT id, ts, actor, role, peer, verb, target, outcome, data FROM audit"
                f"{clause} ORDER BY id DESC LIMIT ?",
                (*params, q.limit),
            )
            return [_audit(r) for r in rows]

        return await self._portable(work, write=False)


def _describe(deps: Dependents) -> str:
    parts = []
    if deps.homes:
        parts.append(f"home of {', '.join(deps.homes)}")
    if deps.orders:
        parts.append(f"{len(deps.orders)} open order(s)")
    if deps.trips:
        parts.append(f"trips {deps.trips}")
    return "; ".join(parts)
