"""The SQLite backend goes to aiosqlite's thread once per statement (serveur/store/sqlite/db.py).

Every trip to that thread and back is two wake-ups that each wait their turn on a loaded CPU,
so a staff request's reply time grows with their number (docs/performance.md, "The Pi
budget"). These count the trips for the shapes of work the store's parts do, and check that
folding BEGIN into the first statement kept transactions whole.
"""

from __future__ import annotations

import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import aiosqlite.core
import pytest

from serveur.errors import Conflict
from serveur.store.sql import Tx
from serveur.store.sqlite.db import SQLiteDb

pytestmark = pytest.mark.timeout(30)


@pytest.fixture
def trips(monkeypatch: pytest.MonkeyPatch) -> Iterator[list[str]]:
    """The name of each function aiosqlite ran on its thread."""
    seen: list[str] = []
    real = aiosqlite.core.Connection._execute

    async def counting(self: Any, fn: Any, *args: Any, **kwargs: Any) -> Any:
        seen.append(getattr(fn, "__name__", repr(fn)))
        return await real(self, fn, *args, **kwargs)

    monkeypatch.setattr(aiosqlite.core.Connection, "_execute", counting)
    yield seen


async def _db(tmp_path: Path) -> SQLiteDb:
    db = SQLiteDb(str(tmp_path / "t.db"))
    await db.open()
    return db


async def test_a_write_is_one_trip_per_statement_and_one_to_commit(
    tmp_path: Path, trips: list[str]
) -> None:
    db = await _db(tmp_path)
    try:
        await db.transact(
            lambda tx: tx.run("CREATE TABLE t (id INTEGER PRIMARY KEY, v TEXT)"), "write"
        )
        trips.clear()

        async def work(tx: Tx) -> tuple[int, int, list[dict[str, Any]]]:
            new = await tx.insert("INSERT INTO t (v) VALUES (?)", ("a",))
            await tx.many("INSERT INTO t (v) VALUES (?)", [("b",), ("c",)])
            changed = await tx.run("UPDATE t SET v = 'z' WHERE id >= ?", (2,))
            return new, changed, await tx.all("SELECT id, v FROM t ORDER BY id")

        new, changed, rows = await db.transact(work, "write")
        assert (new, changed) == (1, 2)
        assert rows == [{"id": 1, "v": "a"}, {"id": 2, "v": "z"}, {"id": 3, "v": "z"}]
        # BEGIN IMMEDIATE went with the insert: four statements, then the commit.
        assert len(trips) == 5, trips
        trips.clear()
        await db.transact(lambda tx: tx.all("SELECT count(*) AS n FROM t"), "read")
        assert len(trips) == 2, trips  # BEGIN with the select, then the commit
        trips.clear()
        await db.transact(lambda tx: tx.all("SELECT count(*) AS n FROM t"), "auto")
        assert len(trips) == 1, trips
    finally:
        await db.close()


async def test_a_failed_write_leaves_nothing_and_the_next_one_works(tmp_path: Path) -> None:
    db = await _db(tmp_path)
    try:
        await db.transact(lambda tx: tx.run("CREATE TABLE t (v TEXT UNIQUE)"), "write")

        async def twice(tx: Tx) -> None:
            await tx.insert("INSERT INTO t (v) VALUES (?)", ("a",))
            await tx.insert("INSERT INTO t (v) VALUES (?)", ("a",))

        with pytest.raises(Conflict):  # the UNIQUE index: the first insert rolled back too
            await db.transact(twice, "write")
        assert await db.transact(lambda tx: tx.all("SELECT v FROM t"), "read") == []
        await db.transact(lambda tx: tx.insert("INSERT INTO t (v) VALUES ('b')", ()), "write")
        rows = sqlite3.connect(tmp_path / "t.db").execute("SELECT v FROM t").fetchall()
        assert rows == [("b",)]  # committed: another connection sees it
    finally:
        await db.close()


async def test_a_unit_of_work_without_statements_opens_no_transaction(
    tmp_path: Path, trips: list[str]
) -> None:
    db = await _db(tmp_path)
    trips.clear()  # opening's own statements (the migrations)
    try:

        async def nothing(tx: Tx) -> int:
            return 7

        assert await db.transact(nothing, "write") == 7
        assert trips == []
        # ...and the connection is not left inside a transaction.
        await db.transact(lambda tx: tx.run("CREATE TABLE t (v TEXT)"), "write")
        assert db.connection is not None and not db.connection.in_transaction
    finally:
        await db.close()
