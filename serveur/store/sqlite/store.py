"""The SQLite backend of :class:`~serveur.store.base.Store` (one aiosqlite connection, WAL).

Concurrency model. One aiosqlite connection runs every statement on one worker thread, so the
event loop never blocks on disk. An :class:`asyncio.Lock` gives that connection to one
operation at a time: without it two coroutines would interleave statements inside one SQLite
transaction. Every mutation is one ``BEGIN IMMEDIATE`` transaction: it takes the database's
write lock up front, so writers in *other processes* on the same file serialise too (waiting
up to ``busy_timeout``) instead of failing half-way with "database is locked" when a read
transaction tries to upgrade. Preconditions are checked and then enforced again by
conditional UPDATEs whose row count must match; the partial UNIQUE indexes of the schema are a
last line of defence whose violations surface as :class:`~serveur.errors.Conflict`.

Reads that need several statements (a task and its stops) run in one deferred transaction so
they see one snapshot; WAL lets them run while another process writes.
"""

from __future__ import annotations

import asyncio
import os
import sqlite3
from collections.abc import Collection, Mapping
from pathlib import Path
from typing import Any

from serveur.domain import EventRecord, Order, OrderStatus, Robot, WaypointRecord
from serveur.errors import Conflict, InvalidField, NotFound, StoreError
from serveur.status import RobotMode, RobotStatus
from serveur.store.base import (
    check_finite,
    check_new_order,
    check_text,
    link_json,
    status_values,
)
from serveur.store.site import REVIVE_ROBOT, REVIVE_WAYPOINT
from serveur.store.sqlite.rows import (
    BUSY_TIMEOUT_MS,
    EVENT,
    ORDER,
    ROBOT,
    WAYPOINT,
    event_record,
    split_sql,
    sql_all,
    sql_in,
    sql_insert,
    sql_one,
    sql_run,
)
from serveur.store.sqlite.tasks import SQLiteTasks

__all__ = ["BUSY_TIMEOUT_MS", "SQLiteStore", "split_sql"]


class SQLiteStore(SQLiteTasks):
    """The store in one SQLite file (``":memory:"`` works for throw-away uses)."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        self._db = None
        self._lock = asyncio.Lock()

    def __repr__(self) -> str:
        return f"SQLiteStore({self.path!r})"

    # -- robots -------------------------------------------------------------------------

    async def add_robot(
        self,
        name: str,
        url: str,
        *,
        home: str | None,
        kinematics: str = "omni",
        link: Mapping[str, str] | None = None,
        now: float,
    ) -> Robot:
        check_text(name, "name")
        check_text(url, "url")
        check_text(kinematics, "kinematics")
        async with self._tx("write") as db:
            row = await sql_one(db, f"{ROBOT} AND name = ?", (name,))
            if row is not None:
                robot = Robot(**dict(row))
                if (robot.url, robot.home, robot.kinematics, robot.link) == (
                    url,
                    home,
                    kinematics,
                    dict(link or {}),
                ):
                    return robot
                raise Conflict(
                    f"a robot named {name!r} exists with another url, home, kinematics or link",
                    robot=name,
                )
            if home is not None:
                await self._waypoint(db, home)
            revive = (url, home, kinematics, link_json(link), now, now, name)
            if not await sql_run(db, REVIVE_ROBOT, revive):
                await sql_run(
                    db,
                    "INSERT INTO robot_info (name, url, home, kinematics, link, updated_at,"
                    " status_since) VALUES (?, ?, ?, ?, ?, ?, ?)",
                    (name, url, home, kinematics, link_json(link), now, now),
                )
            data: dict[str, Any] = {"url": url, "home": home, "kinematics": kinematics}
            if link:
                data["link"] = dict(link)
            await self._event(db, "robot.added", now, robot=name, data=data)
            return await self._robot(db, name)

    async def update_robot(
        self,
        name: str,
        *,
        url: str | None = None,
        home: str | None = None,
        link: Mapping[str, str] | None = None,
        now: float | None = None,
    ) -> Robot:
        """Change url and/or home. ``now`` (an addition to the agreed signature) stamps the
        event; without it the event gets the latest event's time, keeping the trail ordered
        (wall time would not match a simulated clock)."""
        if url is not None:
            check_text(url, "url")
        if home is not None:
            check_text(home, "home")
        async with self._tx("write") as db:
            robot = await self._robot(db, name)
            new_url = robot.url if url is None else url
            new_home = robot.home if home is None else home
            new_link = robot.link if link is None else dict(link)
            if (new_url, new_home, new_link) == (robot.url, robot.home, robot.link):
                return robot
            if new_home is not None and new_home != robot.home:
                await self._waypoint(db, new_home)
            if now is None:
                now = (await sql_one(db, "SELECT coalesce(max(ts), 0) FROM events"))[0]
            await sql_run(
                db,
                "UPDATE robot_info SET url = ?, home = ?, link = ? WHERE name = ?",
                (new_url, new_home, link_json(new_link), name),
            )
            data: dict[str, Any] = {"url": new_url, "home": new_home}
            if new_link != robot.link:
                data["link"] = new_link
            await self._event(db, "robot.updated", float(now or 0.0), robot=name, data=data)
            return await self._robot(db, name)

    async def get_robot(self, name: str) -> Robot:
        async with self._tx("auto") as db:
            return await self._robot(db, name)

    async def list_robots(self) -> list[Robot]:
        async with self._tx("auto") as db:
            return [Robot(**dict(r)) for r in await sql_all(db, f"{ROBOT} ORDER BY name")]

    async def save_robot_state(
        self,
        name: str,
        *,
        status: RobotStatus,
        mode: RobotMode,
        resume: RobotStatus | None,
        last_error: str | None,
        now: float,
        event: str = "robot.status",
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        try:
            values = (
                RobotStatus(status).value,
                RobotMode(mode).value,
                None if resume is None else RobotStatus(resume).value,
            )
        except ValueError as exc:
            raise InvalidField(str(exc), field="status") from exc
        check_text(event, "event")
        async with self._tx("write") as db:
            changed = await sql_run(
                db,
                # status_since first: MariaDB assigns left to right, so it must still see
                # the old status (SQLite always does).
                "UPDATE robot_info SET"
                " status_since = CASE WHEN status = ? THEN status_since ELSE ? END,"
                " status = ?, mode = ?, resume = ?, last_error = ?,"
                " updated_at = ? WHERE name = ?",
                (values[0], now, *values, last_error, now, name),
            )
            if changed != 1:
                raise NotFound(f"no robot named {name!r}", robot=name)
            payload: dict[str, Any] = {
                "status": values[0],
                "mode": values[1],
                "resume": values[2],
                "last_error": last_error,
            }
            payload.update(data or {})
            await self._event(db, event, now, robot=name, data=payload)
            return await self._robot(db, name)

    async def save_robot_pose(
        self, name: str, *, x: float, y: float, yaw: float, battery: float | None, now: float
    ) -> None:
        pose = (check_finite(x, "x"), check_finite(y, "y"), check_finite(yaw, "yaw"))
        if battery is not None and not 0.0 <= check_finite(battery, "battery") <= 1.0:
            raise InvalidField("battery must be between 0 and 1", field="battery")
        async with self._tx("auto") as db:
            changed = await sql_run(
                db,
                "UPDATE robot_info SET x = ?, y = ?, yaw = ?, battery = ?, updated_at = ?"
                " WHERE name = ?",
                (*pose, battery, now, name),
            )
        if changed != 1:
            raise NotFound(f"no robot named {name!r}", robot=name)

    # -- waypoints ----------------------------------------------------------------------

    async def put_waypoint(
        self, wp: WaypointRecord, *, replace: bool = False, now: float
    ) -> WaypointRecord:
        check_text(wp.name, "name")
        for field in ("x", "y", "yaw"):
            check_finite(getattr(wp, field), field)
        async with self._tx("write") as db:
            row = await sql_one(db, f"{WAYPOINT} AND name = ?", (wp.name,))
            values = (wp.x, wp.y, wp.yaw, wp.kind.value, wp.name)
            if row is None:
                if not await sql_run(db, REVIVE_WAYPOINT, values):
                    await sql_run(
                        db,
                        "INSERT INTO waypoints (x, y, yaw, kind, name, created_at)"
                        " VALUES (?, ?, ?, ?, ?, ?)",
                        (*values, now),
                    )
            else:
                existing = WaypointRecord(**dict(row))
                if existing == wp:
                    return existing
                if not replace:
                    raise Conflict(
                        f"waypoint {wp.name!r} exists with another pose or kind",
                        waypoint=wp.name,
                    )
                await sql_run(
                    db,
                    "UPDATE waypoints SET x = ?, y = ?, yaw = ?, kind = ? WHERE name = ?",
                    values,
                )
            data = {"x": wp.x, "y": wp.y, "yaw": wp.yaw, "kind": wp.kind.value}
            data["replaced"] = row is not None
            await self._event(db, "waypoint.saved", now, data={"name": wp.name, **data})
            return await self._waypoint(db, wp.name)

    async def get_waypoint(self, name: str) -> WaypointRecord:
        async with self._tx("auto") as db:
            return await self._waypoint(db, name)

    async def list_waypoints(self) -> list[WaypointRecord]:
        async with self._tx("auto") as db:
            rows = await sql_all(db, f"{WAYPOINT} ORDER BY name")
        return [WaypointRecord(**dict(r)) for r in rows]

    async def delete_waypoint(self, name: str, *, now: float) -> None:
        async with self._tx("write") as db:
            await self._waypoint(db, name)
            orders = await sql_one(db, "SELECT count(*) FROM orders WHERE res_table = ?", (name,))
            robots = [
                r[0]
                for r in await sql_all(db, "SELECT name FROM robot_info WHERE home = ?", (name,))
            ]
            if orders[0] or robots:
                raise Conflict(
                    f"waypoint {name!r} is used by {orders[0]} order(s) and as home of"
                    f" {len(robots)} robot(s)",
                    waypoint=name,
                    orders=orders[0],
                    robots=robots,
                )
            await sql_run(db, "DELETE FROM waypoints WHERE name = ?", (name,))
            await self._event(db, "waypoint.deleted", now, data={"name": name})

    # -- orders -------------------------------------------------------------------------

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
    ) -> Order:
        note, ready_at, fingerprint = check_new_order(
            dish, table, ready_at=ready_at, quantity=quantity, note=note, status=status
        )
        if key is not None:
            check_text(key, "key")
        async with self._tx("write") as db:
            if key is not None:
                done = await self._replayed(db, key, "order", fingerprint)
                if done is not None:
                    return await self._order(db, done["order_id"])
            await self._waypoint(db, table)
            order_id = await sql_insert(
                db,
                "INSERT INTO orders (dish, res_table, key, ready_at, status, quantity, note,"
                " ordered_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (dish, table, key, ready_at, status.value, quantity, note, now),
            )
            if key is not None:
                await self._remember(db, key, "order", fingerprint, {"order_id": order_id}, now)
            data = {
                "dish": dish,
                "table": table,
                "key": key,
                "ready_at": ready_at,
                "status": status.value,
                "quantity": quantity,
                "note": note,
            }
            await self._event(db, "order.created", now, order_id=order_id, data=data)
            return await self._order(db, order_id)

    async def get_order(self, order_id: int) -> Order:
        async with self._tx("auto") as db:
            return await self._order(db, order_id)

    async def list_orders(
        self,
        *,
        status: OrderStatus | Collection[OrderStatus] | None = None,
        table: str | None = None,
        task_id: int | None = None,
    ) -> list[Order]:
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
        async with self._tx("auto") as db:
            rows = await sql_all(db, f"{ORDER} WHERE {' AND '.join(where)} ORDER BY id", params)
        return [Order(**dict(r)) for r in rows]

    async def cart(self, table: str) -> list[Order]:
        async with self._tx("read") as db:
            await self._waypoint(db, table)
            rows = await sql_all(
                db,
                f"{ORDER} WHERE res_table = ? AND status IN ('assigned', 'delivered')"
                " ORDER BY ready_at, id",
                (table,),
            )
        return [Order(**dict(r)) for r in rows]

    # -- events -------------------------------------------------------------------------

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
        check_text(kind, "kind")
        async with self._tx("write") as db:
            event_id = await self._event(
                db, kind, now, robot=robot, task_id=task_id, order_id=order_id, data=data
            )
            return event_record(await sql_one(db, f"{EVENT} WHERE id = ?", (event_id,)))

    async def list_events(self, *, since_id: int = 0, limit: int = 1000) -> list[EventRecord]:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")
        async with self._tx("auto") as db:
            rows = await sql_all(db, f"{EVENT} WHERE id > ? ORDER BY id LIMIT ?", (since_id, limit))
        return [event_record(r) for r in rows]

    # -- maintenance --------------------------------------------------------------------

    async def backup(self, path: str | Path) -> None:
        """Copy with SQLite's online backup API into ``path.tmp``, then rename it.

        The rename makes the copy appear whole or not at all: a crash mid-backup never leaves
        a truncated file where the last good backup was.
        """
        target = Path(path)
        if await asyncio.to_thread(_same_path, target, self.path):
            raise InvalidField("the backup path is the live database", field="path")
        tmp = target.with_name(target.name + ".tmp")
        async with self._tx("auto") as db:
            try:
                await asyncio.to_thread(tmp.unlink, missing_ok=True)
                # Used from aiosqlite's thread, hence check_same_thread=False.
                dst = await asyncio.to_thread(sqlite3.connect, tmp, check_same_thread=False)
                try:
                    await db.backup(dst)
                finally:
                    await asyncio.to_thread(dst.close)
                await asyncio.to_thread(os.replace, tmp, target)
            except OSError as exc:
                raise StoreError(f"backup to {target} failed: {exc}") from exc

    async def integrity_check(self) -> str:
        async with self._tx("read") as db:
            problems = [r[0] for r in await sql_all(db, "PRAGMA integrity_check")]
            problems += [
                f"foreign key: {r[0]} row {r[1]} refers to a missing {r[2]}"
                for r in await sql_all(db, "PRAGMA foreign_key_check")
            ]
        return "\n".join(problems) if problems != ["ok"] else "ok"


def _same_path(a: Path, b: str) -> bool:
    return b != ":memory:" and a.resolve() == Path(b).resolve()
