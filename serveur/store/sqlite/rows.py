"""Rows of the SQLite store: the connection, its migrations and transactions, the SELECTs, the
lookups every transaction starts from, the event and idempotency-key writes. Shared by
:mod:`serveur.store.sqlite.store` (robots, waypoints, orders, events, maintenance) and
:mod:`serveur.store.sqlite.tasks` (trips), which are split only to keep each module readable;
:class:`SQLiteRows` is their common base. The concurrency model is described in
:mod:`serveur.store.sqlite.store`.

Every lookup takes the transaction's :class:`aiosqlite.Connection` from :meth:`SQLiteRows._tx`;
the ``sql_*`` helpers are the few ways a statement is run on it.
"""

from __future__ import annotations

import asyncio
import json
import re
import sqlite3
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Mapping, Sequence
from contextlib import asynccontextmanager
from typing import Any, Literal, TypeVar

import aiosqlite

from serveur.domain import EventRecord, Order, Robot, Stop, Task, WaypointRecord
from serveur.errors import Conflict, NotFound, StoreError
from serveur.store.base import SqlTx, Store, to_json
from serveur.store.live import ROBOT, WAYPOINT
from serveur.store.migrations import load_migrations

__all__ = [
    "BUSY_TIMEOUT_MS",
    "EVENT",
    "ORDER",
    "ROBOT",
    "TASK",
    "WAYPOINT",
    "SQLiteRows",
    "event_record",
    "split_sql",
    "sql_all",
    "sql_in",
    "sql_insert",
    "sql_one",
    "sql_run",
]

#: How long a writer waits for another process's write transaction before giving up.
BUSY_TIMEOUT_MS = 10_000
#: STRICT tables need 3.37 (Raspberry Pi OS bookworm ships 3.40).
_MIN_SQLITE = (3, 37, 0)
#: The line by which a migration asks to run with foreign keys off (a table rebuild).
_FK_OFF = "-- serveur: foreign_keys off"

ORDER = (
    'SELECT id, dish, res_table AS "table", status, task_num AS task_id, key, ready_at,'
    " dispatched_at, delivered_at, quantity, note, ordered_at, returned_at, voided_at FROM orders"
)
EVENT = "SELECT id, ts, kind, robot, task_id, order_id, data FROM events"
TASK = (
    "SELECT id, robot_name AS robot, status, current_stop, created_at, started_at, finished_at"
    " FROM task"
)
# A stop's dishes are the trip's orders for its table (see 001_init), and those it carried
# before it was skipped (returned, 008): gathered per stop in the same query, so a task list
# costs two statements whatever its size.
_STOPS = (
    'SELECT s.task_id, s.seq, s.waypoint AS "table", s.status, s.arrived_at, s.done_at,'
    " s.returned, (SELECT json_group_array(o.id) FROM orders AS o"
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


def sql_in(column: str, values: Sequence[object]) -> str:
    return f"{column} IN ({', '.join('?' * len(values))})"


async def sql_all(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> list[Any]:
    return list(await db.execute_fetchall(sql, params))


async def sql_one(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> Any:
    rows = await sql_all(db, sql, params)
    return rows[0] if rows else None


async def sql_run(db: aiosqlite.Connection, sql: str, params: Sequence[Any] = ()) -> int:
    """Execute a write; its row count (what conditional UPDATEs are checked with)."""
    async with db.execute(sql, params) as cur:
        return cur.rowcount


async def sql_insert(db: aiosqlite.Connection, sql: str, params: Sequence[Any]) -> int:
    async with db.execute(sql, params) as cur:
        rowid = cur.lastrowid
    if rowid is None:  # pragma: no cover - an INSERT always sets it
        raise StoreError("INSERT returned no row id")
    return rowid


def event_record(row: Any) -> EventRecord:
    fields = dict(row)
    fields["data"] = json.loads(fields["data"])
    return EventRecord(**fields)


T = TypeVar("T")


class _PortableTx:
    """:class:`~serveur.store.base.SqlTx` over aiosqlite: rows as dicts."""

    def __init__(self, db: aiosqlite.Connection) -> None:
        self._db = db

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        return [dict(r) for r in await sql_all(self._db, sql, params)]

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        return await sql_run(self._db, sql, params)

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        return await sql_insert(self._db, sql, params)


class SQLiteRows(Store):
    """The connection, transactions and lookups shared by the SQLite store's modules (abstract)."""

    path: str
    _db: aiosqlite.Connection | None
    _lock: asyncio.Lock

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

    def busy(self) -> bool:
        # Every statement runs under the lock, on aiosqlite's thread.
        return self._lock.locked()

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
        simulated timeline. ``PRAGMA foreign_keys`` is ignored inside a transaction, and a
        table another table refers to cannot be rebuilt with them on (dropping it deletes its
        rows first; deferring the check does not help, the count of violations is not undone
        by the rename). A migration that rebuilds one says so with the line
        ``-- serveur: foreign_keys off``: it runs with them off, and ``foreign_key_check`` must
        find nothing before it commits (SQLite's own procedure for "other kinds of table
        schema changes").
        """
        await db.execute(
            "CREATE TABLE IF NOT EXISTS schema_migrations ("
            " version INTEGER PRIMARY KEY, name TEXT NOT NULL, applied_at REAL NOT NULL) STRICT"
        )
        history = load_migrations("sqlite")
        applied = {r[0] for r in await sql_all(db, "SELECT version FROM schema_migrations")}
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
            rebuild = _FK_OFF in m.sql
            if rebuild:
                await db.execute("PRAGMA foreign_keys = OFF")
            await db.execute("BEGIN IMMEDIATE")
            try:
                # Another process may have applied it while we waited for the write lock.
                if not await sql_one(
                    db, "SELECT 1 FROM schema_migrations WHERE version = ?", (m.version,)
                ):
                    for statement in split_sql(m.sql):
                        await db.execute(statement)
                    if rebuild:
                        broken = await sql_all(db, "PRAGMA foreign_key_check")
                        if broken:
                            raise StoreError(
                                f"migration {m.version:03d} would break foreign keys:"
                                f" {[tuple(r) for r in broken[:5]]}",
                                version=m.version,
                            )
                    await db.execute(
                        "INSERT INTO schema_migrations (version, name, applied_at)"
                        " VALUES (?, ?, ?)",
                        (m.version, m.name, time.time()),
                    )
                await db.commit()
            except BaseException:
                await asyncio.shield(db.rollback())
                raise
            finally:
                if rebuild:
                    await db.execute("PRAGMA foreign_keys = ON")

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
        return await sql_insert(
            db,
            "INSERT INTO events (ts, kind, robot, task_id, order_id, data)"
            " VALUES (?, ?, ?, ?, ?, ?)",
            (now, kind, robot, task_id, order_id, to_json(dict(data or {}))),
        )

    # -- lookups used inside transactions ------------------------------------------------

    @staticmethod
    async def _robot(db: aiosqlite.Connection, name: str) -> Robot:
        row = await sql_one(db, f"{ROBOT} AND name = ?", (name,))
        if row is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return Robot(**dict(row))

    @staticmethod
    async def _waypoint(db: aiosqlite.Connection, name: str) -> WaypointRecord:
        row = await sql_one(db, f"{WAYPOINT} AND name = ?", (name,))
        if row is None:
            raise NotFound(f"no waypoint named {name!r}", waypoint=name)
        return WaypointRecord(**dict(row))

    @staticmethod
    async def _order(db: aiosqlite.Connection, order_id: int) -> Order:
        row = await sql_one(db, f"{ORDER} WHERE id = ?", (order_id,))
        if row is None:
            raise NotFound(f"no order {order_id}", order=order_id)
        return Order(**dict(row))

    @staticmethod
    async def _tasks(
        db: aiosqlite.Connection, where: str, params: Sequence[Any] = ()
    ) -> list[Task]:
        tasks = await sql_all(db, f"{TASK} WHERE {where} ORDER BY id", params)
        if not tasks:
            return []
        stops: dict[int, list[dict[str, Any]]] = {}
        for row in await sql_all(db, _STOPS.format(where=where), params):
            stop = dict(row)
            carried = {*json.loads(stop["orders"]), *json.loads(stop.pop("returned"))}
            stop["orders"] = sorted(carried)
            stops.setdefault(stop.pop("task_id"), []).append(stop)
        return [Task(**dict(t), stops=[Stop(**s) for s in stops.get(t["id"], [])]) for t in tasks]

    async def _task(self, db: aiosqlite.Connection, task_id: int) -> Task:
        found = await self._tasks(db, "id = ?", (task_id,))
        if not found:
            raise NotFound(f"no task {task_id}", task=task_id)
        return found[0]

    @staticmethod
    async def _replayed(
        db: aiosqlite.Connection, key: str, kind: str, fingerprint: str
    ) -> dict[str, Any] | None:
        """The stored result of an earlier request with ``key``; Conflict if it differed."""
        row = await sql_one(
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
        await sql_run(
            db,
            "INSERT INTO idempotency (key, kind, fingerprint, result, created_at)"
            " VALUES (?, ?, ?, ?, ?)",
            (key, kind, fingerprint, to_json(dict(result)), now),
        )

    @staticmethod
    async def _free_robot(db: aiosqlite.Connection, task_id: int, now: float) -> None:
        await sql_run(
            db,
            "UPDATE robot_info SET current_task = NULL, updated_at = ? WHERE current_task = ?",
            (now, task_id),
        )


def _probe(path: str) -> None:
    """Raise sqlite3.Error if ``path`` cannot be opened (creating the file, as connect would)."""
    sqlite3.connect(path).close()
