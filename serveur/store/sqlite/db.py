"""The SQLite database under the store: one aiosqlite connection in WAL mode, its migrations
and its transactions (:class:`SQLiteDb`, the :class:`~serveur.store.sql.Db` of the SQLite
backend).

Concurrency model. One aiosqlite connection runs every statement on one worker thread, so the
event loop never blocks on disk. An :class:`asyncio.Lock` gives that connection to one
unit of work at a time: without it two coroutines would interleave statements inside one SQLite
transaction. Every ``write`` is one ``BEGIN IMMEDIATE`` transaction: it takes the database's
write lock up front, so writers in *other processes* on the same file serialise too (waiting
up to ``busy_timeout``) instead of failing half-way with "database is locked" when a read
transaction tries to upgrade. Preconditions are checked and then enforced again by
conditional UPDATEs whose row count must match; the partial UNIQUE indexes of the schema are a
last line of defence whose violations surface as :class:`~serveur.errors.Conflict`.

A ``read`` that needs several statements (a task and its stops) runs in one deferred
transaction so it sees one snapshot; WAL lets it run while another process writes.
"""

from __future__ import annotations

import asyncio
import os
import re
import sqlite3
import time
from collections.abc import Awaitable, Callable, Sequence
from pathlib import Path
from typing import Any, TypeVar

import aiosqlite

from serveur.errors import Conflict, InvalidField, ServeurError, StoreError
from serveur.store.migrations import SITE_HISTORY, load_migrations
from serveur.store.sql import SQLITE, Dialect, Mode, Tx

__all__ = ["BUSY_TIMEOUT_MS", "SQLiteDb", "split_sql"]

T = TypeVar("T")

#: How long a writer waits for another process's write transaction before giving up.
BUSY_TIMEOUT_MS = 10_000
#: STRICT tables need 3.37 (Raspberry Pi OS bookworm ships 3.40).
_MIN_SQLITE = (3, 37, 0)
#: The line by which a migration asks to run with foreign keys off (a table rebuild).
_FK_OFF = "-- serveur: foreign_keys off"


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


class _SQLiteTx:
    """:class:`~serveur.store.sql.Tx` over the connection: rows as dicts.

    Each statement is **one** trip to aiosqlite's thread and back: the statement, its rows
    (made dicts there), its row count or new id, and the cursor closed, all in one function
    run on that thread; and a transaction's ``BEGIN`` goes with its first statement. Every
    trip is two thread wake-ups (the worker's, then the event loop's), and on a loaded CPU
    each waits its turn: a staff request of some fifteen statements paid for thirty-odd trips
    before (execute, then close; BEGIN alone), and its reply time grew with the host's load
    (bench/bench_pi.py, docs/performance.md "The Pi budget"). aiosqlite runs what it is given
    on its thread through ``Connection._execute`` (what its own ``execute_fetchall`` uses);
    a newer aiosqlite without it fails every store test at once.
    """

    def __init__(self, conn: aiosqlite.Connection, begin: str | None = None) -> None:
        self._conn = conn
        self._begin = begin  # sent with the first statement; None once sent (or ``auto``)
        self.begun = False

    @property
    def dialect(self) -> Dialect:
        return SQLITE

    async def _on_thread(self, fn: Callable[..., T], *args: Any) -> T:
        begin, self._begin = self._begin, None
        if begin is not None:
            self.begun = True
        # aiosqlite's own way onto its thread (untyped).
        result: T = await self._conn._execute(  # type: ignore[no-untyped-call]
            _with_begin, self._conn, begin, fn, *args
        )
        return result

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        return await self._on_thread(_rows, sql, params)

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        return await self._on_thread(_rowcount, sql, params)

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        rowid = await self._on_thread(_lastrowid, sql, params)
        if rowid is None:  # pragma: no cover - an INSERT always sets it
            raise StoreError("INSERT returned no row id")
        return rowid

    async def many(self, sql: str, rows: Sequence[Sequence[Any]]) -> None:
        await self._on_thread(_executemany, sql, rows)


# What one statement does on aiosqlite's thread (``_SQLiteTx``): ``conn`` is its sqlite3
# connection, used there only.


def _with_begin(
    conn: aiosqlite.Connection, begin: str | None, fn: Callable[..., T], *args: Any
) -> T:
    raw: sqlite3.Connection = conn._conn
    if begin is not None:
        raw.execute(begin).close()
    return fn(raw, *args)


def _rows(raw: sqlite3.Connection, sql: str, params: Sequence[Any]) -> list[dict[str, Any]]:
    cur = raw.execute(sql, params)
    try:
        return [dict(r) for r in cur.fetchall()]
    finally:
        cur.close()


def _rowcount(raw: sqlite3.Connection, sql: str, params: Sequence[Any]) -> int:
    cur = raw.execute(sql, params)
    try:
        return cur.rowcount
    finally:
        cur.close()


def _lastrowid(raw: sqlite3.Connection, sql: str, params: Sequence[Any]) -> int | None:
    cur = raw.execute(sql, params)
    try:
        return cur.lastrowid
    finally:
        cur.close()


def _executemany(raw: sqlite3.Connection, sql: str, rows: Sequence[Sequence[Any]]) -> None:
    raw.executemany(sql, rows).close()


class SQLiteDb:
    """One SQLite file (``":memory:"`` works for throw-away uses) and its one connection."""

    def __init__(self, path: str, history: str = SITE_HISTORY) -> None:
        """``history``: the migrations package applied at open (the site's by default)."""
        self.path = path
        self.history = history
        self.connection: aiosqlite.Connection | None = None
        self._lock = asyncio.Lock()

    @property
    def dialect(self) -> Dialect:
        return SQLITE

    async def open(self) -> None:
        async with self._lock:
            if self.connection is None:
                self.connection = await self._connect()

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
            db, self.connection = self.connection, None
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
        history = load_migrations("sqlite", self.history)
        applied = {r[0] for r in await db.execute_fetchall("SELECT version FROM schema_migrations")}
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
                if not await db.execute_fetchall(
                    "SELECT 1 FROM schema_migrations WHERE version = ?", (m.version,)
                ):
                    for statement in split_sql(m.sql):
                        await db.execute(statement)
                    if rebuild:
                        broken = list(await db.execute_fetchall("PRAGMA foreign_key_check"))
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

    async def transact(self, work: Callable[[Tx], Awaitable[T]], mode: Mode) -> T:
        """Run ``work`` with the connection alone (``auto``: single statements only).

        A ServeurError raised inside rolls back and passes through; a sqlite3 error rolls
        back and becomes StoreError (or Conflict for a constraint, which means a concurrent
        change won a race the explicit checks could not see).
        """
        async with self._lock:
            db = self.connection
            if db is None:
                raise StoreError("store is not open")
            try:
                try:
                    # BEGIN goes with the first statement (one trip to the thread fewer); a
                    # unit of work that sent none has no transaction to commit.
                    begin = {"write": "BEGIN IMMEDIATE", "read": "BEGIN"}.get(mode)
                    tx = _SQLiteTx(db, begin)
                    result = await work(tx)
                    if tx.begun:
                        await db.commit()
                    return result
                except BaseException:
                    if mode != "auto":
                        # Unconditional and shielded: a caller cancelled while its BEGIN or
                        # a statement was still queued must not leave the transaction open.
                        # aiosqlite runs requests in order, so the rollback comes after them
                        # and before anything the next caller sends, and sqlite3's rollback()
                        # is a no-op when no transaction is open.
                        await asyncio.shield(db.rollback())
                    raise
            except ServeurError:
                raise
            except sqlite3.IntegrityError as exc:
                raise Conflict(f"refused by the database: {exc}") from exc
            except sqlite3.Error as exc:
                raise StoreError(f"database error: {exc}") from exc
            except ValueError as exc:
                # aiosqlite's "Connection closed", or a row the domain records refuse (pydantic
                # errors are ValueErrors): either way the database, not the request, is wrong.
                raise StoreError(f"database error: {exc}") from exc

    # -- maintenance ----------------------------------------------------------------------

    async def backup(self, path: str | Path) -> None:
        """Copy with SQLite's online backup API into ``path.tmp``, then rename it.

        The rename makes the copy appear whole or not at all: a crash mid-backup never leaves
        a truncated file where the last good backup was. The copy is read by a connection of
        its own, in one step: one read transaction, so one consistent snapshot, which WAL lets
        run while the server's connection goes on writing (a year of service is a few seconds
        of copying: bench/bench_backup.py; through the server's own connection every request
        waited for it). A database in memory has no other connection: it is copied through
        the server's.
        """
        target = Path(path)
        if await asyncio.to_thread(_same_path, target, self.path):
            raise InvalidField("the backup path is the live database", field="path")
        tmp = target.with_name(target.name + ".tmp")
        if self.path != ":memory:":
            try:
                await asyncio.to_thread(_copy_file_db, self.path, tmp, target)
            except (OSError, sqlite3.Error) as exc:
                raise StoreError(f"backup to {target} failed: {exc}") from exc
            return

        async def work(_: Tx) -> None:
            db = self.connection
            assert db is not None  # transact holds the open connection
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

        await self.transact(work, "auto")

    async def replace_with(self, backup: Path) -> None:
        """The backup file takes the database file's place (renamed: whole or not at all; it
        is migrated forward when the database is opened next)."""
        if self.connection is not None:
            raise StoreError("a database is replaced only while it is closed")
        await asyncio.to_thread(_replace_file, self.path, backup)

    async def integrity_check(self) -> str:
        """``PRAGMA integrity_check`` and every foreign key (``PRAGMA foreign_key_check``)."""

        async def work(tx: Tx) -> list[str]:
            problems = [str(r["integrity_check"]) for r in await tx.all("PRAGMA integrity_check")]
            return problems + [
                f"foreign key: {r['table']} row {r['rowid']} refers to a missing {r['parent']}"
                for r in await tx.all("PRAGMA foreign_key_check")
            ]

        problems = await self.transact(work, "read")
        return "\n".join(problems) if problems != ["ok"] else "ok"


def _copy_file_db(db: str, tmp: Path, target: Path) -> None:
    """:meth:`SQLiteDb.backup` of a file: all pages in one step from a connection of its own."""
    tmp.unlink(missing_ok=True)
    src = sqlite3.connect(db)
    try:
        src.execute(f"PRAGMA busy_timeout = {BUSY_TIMEOUT_MS}")
        dst = sqlite3.connect(tmp)
        try:
            src.backup(dst)  # pages=-1: every page in one step, one snapshot
        finally:
            dst.close()
    finally:
        src.close()
    os.replace(tmp, target)


def _replace_file(db: str, new: Path) -> None:
    """Put ``new`` where the database ``db`` is (nothing has it open). The old file's
    ``-wal`` and ``-shm`` go first, or SQLite would replay the old database's last
    transactions into the restored one; the rename is atomic."""
    target = Path(db)
    for extra in ("-wal", "-shm", "-journal"):
        target.with_name(target.name + extra).unlink(missing_ok=True)
    os.replace(new, target)


def _same_path(a: Path, b: str) -> bool:
    return b != ":memory:" and a.resolve() == Path(b).resolve()


def _probe(path: str) -> None:
    """Raise sqlite3.Error if ``path`` cannot be opened (creating the file, as connect would)."""
    sqlite3.connect(path).close()
