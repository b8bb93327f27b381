"""The SQLite backend of :class:`~serveur.store.Store` (one aiosqlite connection, WAL).

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
import json
import os
import re
import sqlite3
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Collection, Mapping, Sequence
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any, Literal, TypeVar

import aiosqlite

from serveur.domain import (
    EventRecord,
    Order,
    OrderStatus,
    Robot,
    Stop,
    StopStatus,
    Task,
    TaskStatus,
    WaypointRecord,
)
from serveur.errors import Conflict, InvalidField, NotFound, StoreError
from serveur.status import RobotMode, RobotStatus
from serveur.store import (
    SqlTx,
    Store,
    check_finite,
    check_text,
    check_trips,
    digest,
    load_migrations,
    plan_stop_order,
    status_values,
    to_json,
    trips_fingerprint,
)

__all__ = ["BUSY_TIMEOUT_MS", "SQLiteStore", "split_sql"]

#: How long a writer waits for another process's write transaction before giving up.
BUSY_TIMEOUT_MS = 10_000
#: STRICT tables need 3.37 (Raspberry Pi OS bookworm ships 3.40).
_MIN_SQLITE = (3, 37, 0)

_ROBOT = (
    "SELECT name, url, home, kinematics, mode, status, resume, current_task, battery, x, y, yaw,"
    " last_error, updated_at, status_since FROM robot_info"
)
_WAYPOINT = "SELECT name, x, y, yaw, kind FROM waypoints"
_ORDER = (
    'SELECT id, dish, res_table AS "table", status, task_num AS task_id, key, ready_at,'
    " dispatched_at, delivered_at FROM orders"
)
_EVENT = "SELECT id, ts, kind, robot, task_id, order_id, data FROM events"
_TASK = (
    "SELECT id, robot_name AS robot, status, current_stop, created_at, started_at, finished_at"
    " FROM task"
)
# A stop's dishes are the trip's orders for its table (see 001_init): gathered per stop in the
# same query, so a task list costs two statements whatever its size.
_STOPS = (
    'SELECT s.task_id, s.seq, s.waypoint AS "table", s.status, s.arrived_at, s.done_at,'
    " (SELECT json_group_array(o.id) FROM orders AS o"
    "   WHERE o.task_num = s.task_id AND o.res_table = s.waypoint) AS orders"
    " FROM task_stop AS s WHERE s.task_id IN (SELECT id FROM task WHERE {where})"
    " ORDER BY s.task_id, s.seq"
)


def split_sql(script: str) -> list[str]:
    """Split a migration script into statements (sqlite3 runs one per ``execute``).

    ``executescript`` cannot be used: it commits first, so a migration could not run inside
    the transaction that records it. ``sqlite3.complete_statement`` knows about strings,
    comments and trigger bodies, so a ``;`` inside them does not cut a statement.
    """
    statements: list[str] = []
    buf = ""
    for piece in script.split(";"):
        buf += piece + ";"
        if sqlite3.complete_statement(buf):
            if _has_code(buf):
                statements.append(buf.strip())
            buf = ""
    if _has_code(buf[:-1]):
        raise StoreError("migration ends with an incomplete statement")
    return statements


def _has_code(sql: str) -> bool:
    sql = re.sub(r"/\*.*?\*/", "", re.sub(r"--[^\n]*", "", sql), flags=re.S)
    return bool(sql.replace(";", "").strip())


def _in(column: str, values: Sequence[object]) -> str:
    return f"{column} IN ({', '.join('?' * len(values))})"


async def _all(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> list[Any]:
    return list(await db.execute_fetchall(sql, params))


async def _one(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> Any:
    rows = await _all(db, sql, params)
    return rows[0] if rows else None


async def _run(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> int:
    """Execute a write; its row count (what conditional UPDATEs are checked with)."""
    async with db.execute(sql, params) as cur:
        return cur.rowcount


async def _insert(db: aiosqlite.Connection, sql: str, params: Sequence[Any]) -> int:
    async with db.execute(sql, params) as cur:
        rowid = cur.lastrowid
    if rowid is None:  # pragma: no cover - an INSERT always sets it
        raise StoreError("INSERT returned no row id")
    return rowid


def _event_record(row: Any) -> EventRecord:
    fields = dict(row)
    fields["data"] = json.loads(fields["data"])
    return EventRecord(**fields)


T = TypeVar("T")


class _PortableTx:
    """:class:`~serveur.store.SqlTx` over aiosqlite: rows as dicts."""

    def __init__(self, db: aiosqlite.Connection) -> None:
        self._db = db

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        return [dict(r) for r in await _all(self._db, sql, params)]

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        return await _run(self._db, sql, params)

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        return await _insert(self._db, sql, params)


class SQLiteStore(Store):
    """The store in one SQLite file (``":memory:"`` works for throw-away uses)."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        self._db: aiosqlite.Connection | None = None
        self._lock = asyncio.Lock()

    def __repr__(self) -> str:
        return f"SQLiteStore({self.path!r})"

    # -- connection, transactions, migrations -------------------------------------------

    async def open(self) -> None:
        async with self._lock:
            if self._db is None:
                self._db = await self._connect()

    async def _connect(self) -> aiosqlite.Connection:
        if sqlite3.sqlite_version_info < _MIN_SQLITE:
            raise StoreError(f"SQLite {sqlite3.sqlite_version} is too old: 3.37 or newer needed")
        try:
            # Probe first, in a plain thread: after a failed connect aiosqlite still reports
            # its own clean-up to the event loop, which may be closed by then (an unopenable
            # path at start would end in a thread traceback instead of one clear error).
            await asyncio.to_thread(_probe, self.path)
            db = await aiosqlite.connect(self.path, isolation_level=None)
        except sqlite3.Error as exc:
            raise StoreError(f"cannot open {self.path}: {exc}", path=self.path) from exc
        try:
            db.row_factory = sqlite3.Row
            # First, so that switching to WAL also waits for another process's transaction.
            await db.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
            await db.execute("PRAGMA journal_mode = WAL")
            # In WAL mode NORMAL fsyncs at checkpoints, not at every commit. A commit is in the
            # WAL file (the OS page cache) before it returns, so a crash of this process loses
            # nothing; only an OS crash or power cut can lose the last transactions, and it
            # never corrupts the file. FULL would fsync each commit: slow on the Pi's SD card,
            # and wearing it, for state the robots re-report within seconds anyway.
            await db.execute("PRAGMA synchronous = NORMAL")
            await db.execute("PRAGMA foreign_keys = ON")
            await self._migrate(db)
        except BaseException as exc:
            await db.close()
            if isinstance(exc, sqlite3.Error):
                raise StoreError(f"cannot open {self.path}: {exc}", path=self.path) from exc
            raise
        return db

    async def close(self) -> None:
        async with self._lock:
            db, self._db = self._db, None
            if db is not None:
                try:
                    await db.close()
                except sqlite3.Error as exc:
                    raise StoreError(f"closing {self.path}: {exc}") from exc

    async def _migrate(self, db: aiosqlite.Connection) -> None:
        """Apply the migrations not yet recorded, each in its own ``BEGIN IMMEDIATE``.

        ``applied_at`` is wall time: migrating is a real-world event, not part of a service's
        simulated timeline. Note for later migrations: ``PRAGMA foreign_keys`` is ignored
        inside a transaction; a table rebuild must use ``PRAGMA defer_foreign_keys = ON``.
        """
        await db.execute(
            "CREATE TABLE IF NOT EXISTS schema_migrations ("
            " version INTEGER PRIMARY KEY, name TEXT NOT NULL, applied_at REAL NOT NULL) STRICT"
        )
        history = load_migrations("sqlite")
        applied = {r[0] for r in await _all(db, "SELECT version FROM schema_migrations")}
        unknown = applied - {m.version for m in history}
        if unknown:
            raise StoreError(
                f"{self.path} has migrations this serveur does not know ({sorted(unknown)}):"
                " it was written by a newer version",
                versions=sorted(unknown),
            )
        for m in history:
            if m.version in applied:
                continue
            await db.execute("BEGIN IMMEDIATE")
            try:
                # Another process may have applied it while we waited for the write lock.
                if not await _one(
                    db, "SELECT 1 FROM schema_migrations WHERE version = ?", (m.version,)
                ):
                    for statement in split_sql(m.sql):
                        await db.execute(statement)
                    await db.execute(
                        "INSERT INTO schema_migrations (version, name, applied_at)"
                        " VALUES (?, ?, ?)",
                        (m.version, m.name, time.time()),
                    )
                await db.commit()
            except BaseException:
                await asyncio.shield(db.rollback())
                raise

    @asynccontextmanager
    async def _tx(
        self, mode: Literal["write", "read", "auto"]
    ) -> AsyncIterator[aiosqlite.Connection]:
        """The connection, alone, inside a transaction (``auto``: single statements only).

        A ServeurError raised inside rolls back and passes through; a sqlite3 error rolls
        back and becomes StoreError (or Conflict for a constraint, which means a concurrent
        change won a race the explicit checks could not see).
        """
        async with self._lock:
            db = self._db
            if db is None:
                raise StoreError("store is not open")
            try:
                try:
                    if mode != "auto":
                        await db.execute("BEGIN IMMEDIATE" if mode == "write" else "BEGIN")
                    yield db
                    if mode != "auto":
                        await db.commit()
                except BaseException:
                    if mode != "auto":
                        # Unconditional and shielded: a caller cancelled while its BEGIN or
                        # a statement was still queued must not leave the transaction open.
                        # aiosqlite runs requests in order, so the rollback comes after them
                        # and before anything the next caller sends, and sqlite3's rollback()
                        # is a no-op when no transaction is open.
                        await asyncio.shield(db.rollback())
                    raise
            except sqlite3.IntegrityError as exc:
                raise Conflict(f"refused by the database: {exc}") from exc
            except sqlite3.Error as exc:
                raise StoreError(f"database error: {exc}") from exc
            except ValueError as exc:
                # aiosqlite's "Connection closed", or a row the domain records refuse (pydantic
                # errors are ValueErrors): either way the database, not the request, is wrong.
                raise StoreError(f"database error: {exc}") from exc

    async def _portable(self, work: Callable[[SqlTx], Awaitable[T]], *, write: bool) -> T:
        async with self._tx("write" if write else "read") as db:
            return await work(_PortableTx(db))

    async def _event(
        self,
        db: aiosqlite.Connection,
        kind: str,
        now: float,
        *,
        robot: str | None = None,
        task_id: int | None = None,
        order_id: int | None = None,
        data: Mapping[str, Any] | None = None,
    ) -> int:
        return await _insert(
            db,
            "INSERT INTO events (ts, kind, robot, task_id, order_id, data)"
            " VALUES (?, ?, ?, ?, ?, ?)",
            (now, kind, robot, task_id, order_id, to_json(dict(data or {}))),
        )

    # -- lookups used inside transactions ------------------------------------------------

    @staticmethod
    async def _robot(db: aiosqlite.Connection, name: str) -> Robot:
        row = await _one(db, f"{_ROBOT} WHERE name = ?", (name,))
        if row is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return Robot(**dict(row))

    @staticmethod
    async def _waypoint(db: aiosqlite.Connection, name: str) -> WaypointRecord:
        row = await _one(db, f"{_WAYPOINT} WHERE name = ?", (name,))
        if row is None:
            raise NotFound(f"no waypoint named {name!r}", waypoint=name)
        return WaypointRecord(**dict(row))

    @staticmethod
    async def _order(db: aiosqlite.Connection, order_id: int) -> Order:
        row = await _one(db, f"{_ORDER} WHERE id = ?", (order_id,))
        if row is None:
            raise NotFound(f"no order {order_id}", order=order_id)
        return Order(**dict(row))

    @staticmethod
    async def _tasks(
        db: aiosqlite.Connection, where: str, params: Sequence[Any] = ()
    ) -> list[Task]:
        tasks = await _all(db, f"{_TASK} WHERE {where} ORDER BY id", params)
        if not tasks:
            return []
        stops: dict[int, list[dict[str, Any]]] = {}
        for row in await _all(db, _STOPS.format(where=where), params):
            stop = dict(row)
            stop["orders"] = sorted(json.loads(stop["orders"]))
            stops.setdefault(stop.pop("task_id"), []).append(stop)
        return [Task(**dict(t), stops=[Stop(**s) for s in stops.get(t["id"], [])]) for t in tasks]

    async def _task(self, db: aiosqlite.Connection, task_id: int) -> Task:
        found = await self._tasks(db, "id = ?", (task_id,))
        if not found:
            raise NotFound(f"no task {task_id}", task=task_id)
        return found[0]

    # -- robots -------------------------------------------------------------------------

    async def add_robot(
        self, name: str, url: str, *, home: str | None, kinematics: str = "omni", now: float
    ) -> Robot:
        check_text(name, "name")
        check_text(url, "url")
        check_text(kinematics, "kinematics")
        async with self._tx("write") as db:
            row = await _one(db, f"{_ROBOT} WHERE name = ?", (name,))
            if row is not None:
                robot = Robot(**dict(row))
                if (robot.url, robot.home, robot.kinematics) == (url, home, kinematics):
                    return robot
                raise Conflict(
                    f"a robot named {name!r} exists with another url, home or kinematics",
                    robot=name,
                )
            if home is not None:
                await self._waypoint(db, home)
            await _run(
                db,
                "INSERT INTO robot_info (name, url, home, kinematics, updated_at, status_since)"
                " VALUES (?, ?, ?, ?, ?, ?)",
                (name, url, home, kinematics, now, now),
            )
            data = {"url": url, "home": home, "kinematics": kinematics}
            await self._event(db, "robot.added", now, robot=name, data=data)
            return await self._robot(db, name)

    async def update_robot(
        self,
        name: str,
        *,
        url: str | None = None,
        home: str | None = None,
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
            if (new_url, new_home) == (robot.url, robot.home):
                return robot
            if new_home is not None and new_home != robot.home:
                await self._waypoint(db, new_home)
            if now is None:
                now = (await _one(db, "SELECT coalesce(max(ts), 0) FROM events"))[0]
            await _run(
                db,
                "UPDATE robot_info SET url = ?, home = ? WHERE name = ?",
                (new_url, new_home, name),
            )
            data = {"url": new_url, "home": new_home}
            await self._event(db, "robot.updated", float(now or 0.0), robot=name, data=data)
            return await self._robot(db, name)

    async def get_robot(self, name: str) -> Robot:
        async with self._tx("auto") as db:
            return await self._robot(db, name)

    async def list_robots(self) -> list[Robot]:
        async with self._tx("auto") as db:
            return [Robot(**dict(r)) for r in await _all(db, f"{_ROBOT} ORDER BY name")]

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
            changed = await _run(
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
            changed = await _run(
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
            row = await _one(db, f"{_WAYPOINT} WHERE name = ?", (wp.name,))
            values = (wp.x, wp.y, wp.yaw, wp.kind.value, wp.name)
            if row is None:
                await _run(
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
                await _run(
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
            rows = await _all(db, f"{_WAYPOINT} ORDER BY name")
        return [WaypointRecord(**dict(r)) for r in rows]

    async def delete_waypoint(self, name: str, *, now: float) -> None:
        async with self._tx("write") as db:
            await self._waypoint(db, name)
            orders = await _one(db, "SELECT count(*) FROM orders WHERE res_table = ?", (name,))
            robots = [
                r[0] for r in await _all(db, "SELECT name FROM robot_info WHERE home = ?", (name,))
            ]
            if orders[0] or robots:
                raise Conflict(
                    f"waypoint {name!r} is used by {orders[0]} order(s) and as home of"
                    f" {len(robots)} robot(s)",
                    waypoint=name,
                    orders=orders[0],
                    robots=robots,
                )
            await _run(db, "DELETE FROM waypoints WHERE name = ?", (name,))
            await self._event(db, "waypoint.deleted", now, data={"name": name})

    # -- orders -------------------------------------------------------------------------

    async def add_order(
        self, dish: str, table: str, *, ready_at: float, key: str | None = None, now: float
    ) -> Order:
        check_text(dish, "dish")
        check_text(table, "table")
        check_finite(ready_at, "ready_at")
        if key is not None:
            check_text(key, "key")
        fingerprint = digest(["order", dish, table])
        async with self._tx("write") as db:
            if key is not None:
                done = await self._replayed(db, key, "order", fingerprint)
                if done is not None:
                    return await self._order(db, done["order_id"])
            await self._waypoint(db, table)
            order_id = await _insert(
                db,
                "INSERT INTO orders (dish, res_table, key, ready_at) VALUES (?, ?, ?, ?)",
                (dish, table, key, ready_at),
            )
            if key is not None:
                await self._remember(db, key, "order", fingerprint, {"order_id": order_id}, now)
            data = {"dish": dish, "table": table, "key": key, "ready_at": ready_at}
            await self._event(db, "order.created", now, order_id=order_id, data=data)
            return await self._order(db, order_id)

    @staticmethod
    async def _replayed(
        db: aiosqlite.Connection, key: str, kind: str, fingerprint: str
    ) -> dict[str, Any] | None:
        """The stored result of an earlier request with ``key``; Conflict if it differed."""
        row = await _one(
            db, "SELECT kind, fingerprint, result FROM idempotency WHERE key = ?", (key,)
        )
        if row is None:
            return None
        if row["kind"] != kind or row["fingerprint"] != fingerprint:
            raise Conflict(f"key {key!r} was already used for another request", key=key)
        result: dict[str, Any] = json.loads(row["result"])
        return result

    @staticmethod
    async def _remember(
        db: aiosqlite.Connection,
        key: str,
        kind: str,
        fingerprint: str,
        result: Mapping[str, Any],
        now: float,
    ) -> None:
        await _run(
            db,
            "INSERT INTO idempotency (key, kind, fingerprint, result, created_at)"
            " VALUES (?, ?, ?, ?, ?)",
            (key, kind, fingerprint, to_json(dict(result)), now),
        )

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
            where.append(_in("status", statuses))
            params.extend(statuses)
        if table is not None:
            where.append("res_table = ?")
            params.append(table)
        if task_id is not None:
            where.append("task_num = ?")
            params.append(task_id)
        async with self._tx("auto") as db:
            rows = await _all(db, f"{_ORDER} WHERE {' AND '.join(where)} ORDER BY id", params)
        return [Order(**dict(r)) for r in rows]

    async def cancel_order(self, order_id: int, *, now: float) -> Order:
        async with self._tx("write") as db:
            order = await self._order(db, order_id)
            changed = await _run(
                db,
                "UPDATE orders SET status = 'cancelled' WHERE id = ? AND status = 'pending'",
                (order_id,),
            )
            if changed != 1:
                raise Conflict(
                    f"order {order_id} is {order.status.value}: only a pending order can be"
                    " cancelled",
                    order=order_id,
                    status=order.status.value,
                )
            await self._event(db, "order.cancelled", now, order_id=order_id)
            return await self._order(db, order_id)

    async def cart(self, table: str) -> list[Order]:
        async with self._tx("read") as db:
            await self._waypoint(db, table)
            rows = await _all(
                db,
                f"{_ORDER} WHERE res_table = ? AND status IN ('assigned', 'delivered')"
                " ORDER BY ready_at, id",
                (table,),
            )
        return [Order(**dict(r)) for r in rows]

    # -- tasks --------------------------------------------------------------------------

    async def create_tasks(
        self,
        trips: Sequence[Sequence[tuple[str, Sequence[int]]]],
        *,
        key: str | None = None,
        fingerprint: str = "",
        now: float,
    ) -> list[Task]:
        if key is not None:
            check_text(key, "key")
        async with self._tx("write") as db:
            if key is not None:
                plan_digest = fingerprint or trips_fingerprint(trips)
                done = await self._replayed(db, key, "tasks", plan_digest)
                if done is not None:
                    ids = done["task_ids"]
                    return await self._tasks(db, _in("id", ids), ids)
            plan = check_trips(trips)
            wanted = [oid for trip in plan for _, ids in trip for oid in ids]
            rows = await _all(
                db, f"SELECT id, res_table, status FROM orders WHERE {_in('id', wanted)}", wanted
            )
            found = {r["id"]: r for r in rows}
            missing = sorted(set(wanted) - set(found))
            if missing:
                raise NotFound(f"no order(s) {missing}", orders=missing)
            misplaced = sorted(
                oid
                for trip in plan
                for table, ids in trip
                for oid in ids
                if found[oid]["res_table"] != table
            )
            if misplaced:
                raise InvalidField(
                    f"order(s) {misplaced} are for another table than their stop",
                    field="trips",
                    orders=misplaced,
                )
            taken = sorted(oid for oid in wanted if found[oid]["status"] != "pending")
            if taken:
                raise Conflict(f"order(s) {taken} are not pending", orders=taken)
            task_ids = [await self._queue_trip(db, trip, now) for trip in plan]
            if key is not None:
                result = {"task_ids": task_ids}
                await self._remember(db, key, "tasks", plan_digest, result, now)
            return await self._tasks(db, _in("id", task_ids), task_ids)

    async def _queue_trip(
        self, db: aiosqlite.Connection, trip: list[tuple[str, list[int]]], now: float
    ) -> int:
        task_id = await _insert(db, "INSERT INTO task (created_at) VALUES (?)", (now,))
        await db.executemany(
            "INSERT INTO task_stop (task_id, seq, waypoint) VALUES (?, ?, ?)",
            [(task_id, seq, table) for seq, (table, _) in enumerate(trip)],
        )
        ids = [oid for _, stop_ids in trip for oid in stop_ids]
        changed = await _run(
            db,
            f"UPDATE orders SET status = 'assigned', task_num = ?"
            f" WHERE {_in('id', ids)} AND status = 'pending'",
            (task_id, *ids),
        )
        if changed != len(ids):  # pragma: no cover - checked above in this transaction
            raise Conflict("an order was assigned concurrently", orders=ids)
        stops = [{"table": table, "orders": stop_ids} for table, stop_ids in trip]
        await self._event(db, "task.created", now, task_id=task_id, data={"stops": stops})
        return task_id

    async def get_task(self, task_id: int) -> Task:
        async with self._tx("read") as db:
            return await self._task(db, task_id)

    async def list_tasks(
        self,
        *,
        status: TaskStatus | Collection[TaskStatus] | None = None,
        robot: str | None = None,
    ) -> list[Task]:
        where: list[str] = ["1"]
        params: list[Any] = []
        statuses = status_values(status, TaskStatus)
        if statuses is not None:
            where.append(_in("status", statuses))
            params.extend(statuses)
        if robot is not None:
            where.append("robot_name = ?")
            params.append(robot)
        async with self._tx("read") as db:
            return await self._tasks(db, " AND ".join(where), params)

    async def start_task(
        self, task_id: int, robot: str, *, stop_order: Sequence[str] | None = None, now: float
    ) -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            rob = await self._robot(db, robot)
            if task.status is not TaskStatus.QUEUED:
                raise Conflict(
                    f"task {task_id} is {task.status.value}, not queued",
                    task=task_id,
                    status=task.status.value,
                )
            if rob.current_task is not None:
                raise Conflict(
                    f"robot {robot!r} is busy with task {rob.current_task}",
                    robot=robot,
                    task=rob.current_task,
                )
            if stop_order is not None:
                await self._reorder(db, task, stop_order)
            changed = await _run(
                db,
                "UPDATE task SET status = 'active', robot_name = ?, started_at = ?"
                " WHERE id = ? AND status = 'queued'",
                (robot, now, task_id),
            )
            if changed == 1:
                changed = await _run(
                    db,
                    "UPDATE robot_info SET current_task = ?, updated_at = ?"
                    " WHERE name = ? AND current_task IS NULL",
                    (task_id, now, robot),
                )
            if changed != 1:  # pragma: no cover - checked above in this transaction
                raise Conflict(f"task {task_id} or robot {robot!r} was taken concurrently")
            await _run(
                db,
                "UPDATE orders SET dispatched_at = ? WHERE task_num = ? AND status = 'assigned'",
                (now, task_id),
            )
            started = await self._task(db, task_id)
            tables = [s.table for s in started.stops]
            data = {"robot": robot, "stops": tables}
            await self._event(db, "task.started", now, robot=robot, task_id=task_id, data=data)
            return started

    @staticmethod
    async def _reorder(db: aiosqlite.Connection, task: Task, stop_order: Sequence[str]) -> None:
        """Renumber the stops still to serve in ``stop_order``; done stops keep 0..k-1."""
        wanted = plan_stop_order(task, stop_order)
        if wanted is None:
            return
        first, n = task.current_stop, len(task.stops)
        # Out of the way first: (task_id, seq) is the key, so swapping in place would collide.
        await _run(
            db,
            "UPDATE task_stop SET seq = seq + ? WHERE task_id = ? AND seq >= ?",
            (n, task.id, first),
        )
        await db.executemany(
            "UPDATE task_stop SET seq = ? WHERE task_id = ? AND waypoint = ?",
            [(first + i, task.id, table) for i, table in enumerate(wanted)],
        )

    async def _active_stop(
        self, db: aiosqlite.Connection, task_id: int, seq: int, action: str
    ) -> tuple[Task, Any]:
        task = await self._task(db, task_id)
        if not 0 <= seq < len(task.stops):
            raise NotFound(f"task {task_id} has no stop {seq}", task=task_id, seq=seq)
        stop = task.stops[seq]
        if task.status is not TaskStatus.ACTIVE:
            raise Conflict(
                f"cannot {action}: task {task_id} is {task.status.value}",
                task=task_id,
                status=task.status.value,
            )
        return task, stop

    async def arrive_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task, stop = await self._active_stop(db, task_id, seq, "arrive")
            if stop.status is StopStatus.ARRIVED:
                return task
            changed = await _run(
                db,
                "UPDATE task_stop SET status = 'arrived', arrived_at = ?"
                " WHERE task_id = ? AND seq = ? AND status = 'pending' AND EXISTS"
                " (SELECT 1 FROM task WHERE id = ? AND status = 'active' AND current_stop = ?)",
                (now, task_id, seq, task_id, seq),
            )
            if changed != 1:
                raise Conflict(
                    f"stop {seq} of task {task_id} is {stop.status.value}, and the current stop"
                    f" is {task.current_stop}",
                    task=task_id,
                    seq=seq,
                    status=stop.status.value,
                )
            data = {"seq": seq, "table": stop.table}
            await self._event(db, "stop.arrived", now, robot=task.robot, task_id=task_id, data=data)
            return await self._task(db, task_id)

    async def complete_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task, stop = await self._active_stop(db, task_id, seq, "complete a stop")
            changed = await _run(
                db,
                "UPDATE task SET current_stop = current_stop + 1"
                " WHERE id = ? AND status = 'active' AND current_stop = ?",
                (task_id, seq),
            )
            if changed == 1:
                changed = await _run(
                    db,
                    "UPDATE task_stop SET status = 'done', done_at = ?"
                    " WHERE task_id = ? AND seq = ? AND status IN ('pending', 'arrived')",
                    (now, task_id, seq),
                )
            if changed != 1:
                raise Conflict(
                    f"stop {seq} of task {task_id} is {stop.status.value}, and the current stop"
                    f" is {task.current_stop}",
                    task=task_id,
                    seq=seq,
                    status=stop.status.value,
                )
            await _run(
                db,
                "UPDATE orders SET status = 'delivered', delivered_at = ?"
                " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                (now, task_id, stop.table),
            )
            data = {"seq": seq, "table": stop.table, "orders": stop.orders}
            await self._event(db, "stop.done", now, robot=task.robot, task_id=task_id, data=data)
            return await self._task(db, task_id)

    async def finish_task(self, task_id: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            changed = await _run(
                db,
                "UPDATE task SET status = 'done', finished_at = ?"
                " WHERE id = ? AND status = 'active' AND NOT EXISTS"
                " (SELECT 1 FROM task_stop WHERE task_id = ? AND status <> 'done')",
                (now, task_id, task_id),
            )
            if changed != 1:
                left = sum(s.status is not StopStatus.DONE for s in task.stops)
                raise Conflict(
                    f"task {task_id} is {task.status.value} with {left} stop(s) not done",
                    task=task_id,
                    status=task.status.value,
                )
            await self._free_robot(db, task_id, now)
            await self._event(db, "task.finished", now, robot=task.robot, task_id=task_id)
            return await self._task(db, task_id)

    @staticmethod
    async def _free_robot(db: aiosqlite.Connection, task_id: int, now: float) -> None:
        await _run(
            db,
            "UPDATE robot_info SET current_task = NULL, updated_at = ? WHERE current_task = ?",
            (now, task_id),
        )

    async def cancel_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            returned = [
                r[0]
                for r in await _all(
                    db,
                    "SELECT id FROM orders WHERE task_num = ? AND status = 'assigned' ORDER BY id",
                    (task_id,),
                )
            ]
            changed = await _run(
                db,
                "UPDATE task SET status = 'cancelled', finished_at = ?"
                " WHERE id = ? AND status IN ('queued', 'active')",
                (now, task_id),
            )
            if changed != 1:
                raise Conflict(
                    f"task {task_id} is {task.status.value}: only a queued or active task can"
                    " be cancelled",
                    task=task_id,
                    status=task.status.value,
                )
            await _run(
                db,
                "UPDATE orders SET status = 'pending', task_num = NULL, dispatched_at = NULL"
                " WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await _run(
                db,
                "UPDATE task_stop SET status = 'skipped'"
                " WHERE task_id = ? AND status IN ('pending', 'arrived')",
                (task_id,),
            )
            await self._free_robot(db, task_id, now)
            data = {"reason": reason, "orders_returned": returned}
            await self._event(
                db, "task.cancelled", now, robot=task.robot, task_id=task_id, data=data
            )
            return await self._task(db, task_id)

    async def requeue_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            if task.status is TaskStatus.ACTIVE and task.current_stop >= len(task.stops):
                raise Conflict(
                    f"task {task_id} has every stop done: finish it instead", task=task_id
                )
            changed = await _run(
                db,
                "UPDATE task SET status = 'queued', robot_name = NULL, started_at = NULL"
                " WHERE id = ? AND status = 'active'",
                (task_id,),
            )
            if changed != 1:
                raise Conflict(
                    f"task {task_id} is {task.status.value}: only an active task can be requeued",
                    task=task_id,
                    status=task.status.value,
                )
            await _run(
                db,
                "UPDATE task_stop SET status = 'pending', arrived_at = NULL"
                " WHERE task_id = ? AND status = 'arrived'",
                (task_id,),
            )
            await _run(
                db,
                "UPDATE orders SET dispatched_at = NULL WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await self._free_robot(db, task_id, now)
            data = {"reason": reason, "robot": task.robot}
            await self._event(
                db, "task.requeued", now, robot=task.robot, task_id=task_id, data=data
            )
            return await self._task(db, task_id)

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
            return _event_record(await _one(db, f"{_EVENT} WHERE id = ?", (event_id,)))

    async def list_events(self, *, since_id: int = 0, limit: int = 1000) -> list[EventRecord]:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")
        async with self._tx("auto") as db:
            rows = await _all(db, f"{_EVENT} WHERE id > ? ORDER BY id LIMIT ?", (since_id, limit))
        return [_event_record(r) for r in rows]

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
            problems = [r[0] for r in await _all(db, "PRAGMA integrity_check")]
            problems += [
                f"foreign key: {r[0]} row {r[1]} refers to a missing {r[2]}"
                for r in await _all(db, "PRAGMA foreign_key_check")
            ]
        return "\n".join(problems) if problems != ["ok"] else "ok"


def _same_path(a: Path, b: str) -> bool:
    return b != ":memory:" and a.resolve() == Path(b).resolve()


def _probe(path: str) -> None:
    """Raise sqlite3.Error if ``path`` cannot be opened (creating the file, as connect would)."""
    sqlite3.connect(path).close()
