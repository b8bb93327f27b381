"""The MariaDB backend's maintenance: a backup written as a SQLite file, and the integrity check
(``CHECK TABLE`` and every foreign key, row by row).
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sqlite3
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from serveur.errors import StoreError
from serveur.store.sql import Db, Tx

__all__ = ["FOREIGN_KEYS", "TABLES", "backup", "integrity_check", "restore"]

# Tables in parent-before-child order, as the SQLite schema has them (for backups).
TABLES = (
    "users",
    "tokens",
    "audit",
    "waypoints",
    "robot_info",
    "task",
    "task_stop",
    "idempotency",
    "till_job",
    "till_ticket",
    "orders",
    "events",
    "menu",
    "table_block",
    "settings",
    "zones",
    "site_map",
    "site_backdrop",
    "call",
    "call_button",
    "till_name",
    "till_setting",
    "outbox",
    "outbox_state",
)
# Every foreign key, as (table, its key, column, parent table, parent key), for the check.
FOREIGN_KEYS = (
    ("tokens", "id", "user_name", "users", "name"),
    ("robot_info", "name", "home", "waypoints", "name"),
    ("robot_info", "name", "current_task", "task", "id"),
    ("task", "id", "robot_name", "robot_info", "name"),
    ("task_stop", "task_id", "task_id", "task", "id"),
    ("task_stop", "task_id", "waypoint", "waypoints", "name"),
    ("orders", "id", "res_table", "waypoints", "name"),
    ("orders", "id", "task_num", "task", "id"),
    ("table_block", "waypoint", "waypoint", "waypoints", "name"),
    ("robot_info", "name", "dock", "waypoints", "name"),
    ("call", "id", "table_name", "waypoints", "name"),
    ("call", "id", "task_id", "task", "id"),
    ("call_button", "name", "table_name", "waypoints", "name"),
    ("till_ticket", "id", "job_id", "till_job", "id"),
    ("till_ticket", "id", "of_ticket", "till_ticket", "id"),
    ("orders", "id", "ticket_id", "till_ticket", "id"),
)


async def backup(db: Db, path: str | Path) -> None:
    """Copy every row, read in one consistent snapshot, into a SQLite file at ``path``.

    The copy is a database the SQLite backend opens as it is (``serveur run --db
    copy.db``): the same schema history, so it can be inspected, served from, or checked
    with the store's ``integrity_check`` without a MariaDB server. It is written to ``path.tmp``
    and renamed, so a crash never leaves half a backup where the last good one was. For
    backups of the server itself use ``mariadb-dump --single-transaction`` (docs/mariadb.md).
    """
    from serveur.store.sqlite.store import SQLiteStore

    target = Path(path)
    tmp = target.with_name(target.name + ".tmp")
    try:
        await asyncio.to_thread(tmp.unlink, missing_ok=True)
        async with SQLiteStore(tmp):  # the SQLite schema, from its own migrations
            pass
        columns = await asyncio.to_thread(_sqlite_columns, tmp)

        async def work(tx: Tx) -> dict[str, list[dict[str, Any]]]:
            return {
                table: await tx.all(
                    f"SELECT {', '.join(f'`{c}`' for c in columns[table])} FROM `{table}`"
                )
                for table in TABLES
            }

        rows = await db.transact(work, "read")
        await asyncio.to_thread(_fill_sqlite, tmp, columns, rows)
        await asyncio.to_thread(os.replace, tmp, target)
    except (OSError, sqlite3.Error) as exc:
        raise StoreError(f"backup to {target} failed: {exc}") from exc


async def restore(db: Db, path: Path) -> None:
    """Replace every row of every table with the SQLite backup's at ``path``, in one
    transaction (a failure leaves the database as it was).

    The backup is first brought to this version's schema (opened as a SQLite store: its own
    migrations run), so an older copy restores too; ``schema_migrations`` itself is left as it
    is. Foreign keys are checked by the copy's own integrity check before (a restore is only
    offered for a checked backup), not row by row here: ``robot_info`` and ``task`` refer to
    each other, so no insertion order satisfies both. Only the live tables' own columns are
    copied (a name is never taken from the file into SQL), and rows go in batches of
    :data:`_BATCH`, so a year of events never sits in memory at once.
    """
    from serveur.store.sqlite.store import SQLiteStore

    try:
        async with SQLiteStore(path):
            pass
        in_file = await asyncio.to_thread(_sqlite_columns, path)
    except (OSError, sqlite3.Error) as exc:
        raise StoreError(f"cannot read the backup {path}: {exc}") from exc

    async def work(tx: Tx) -> None:
        await tx.run("SET FOREIGN_KEY_CHECKS = 0")
        try:
            for table in reversed(TABLES):
                await tx.run(f"DELETE FROM `{table}`")
            for table in TABLES:
                live = {
                    str(r["name"])
                    for r in await tx.all(
                        "SELECT COLUMN_NAME AS name FROM information_schema.COLUMNS"
                        " WHERE TABLE_SCHEMA = DATABASE() AND TABLE_NAME = ?",
                        (table,),
                    )
                }
                cols = [c for c in in_file[table] if c in live]
                names = ", ".join(f"`{c}`" for c in cols)
                marks = ", ".join("?" for _ in cols)
                after = None
                while True:
                    batch, after = await asyncio.to_thread(_batch, path, table, cols, after)
                    if not batch:
                        break
                    await tx.many(f"INSERT INTO `{table}` ({names}) VALUES ({marks})", batch)
        finally:
            await tx.run("SET FOREIGN_KEY_CHECKS = 1")

    try:
        await db.transact(work, "write")
    except sqlite3.Error as exc:
        raise StoreError(f"cannot read the backup {path}: {exc}") from exc


#: Rows read from a backup and inserted at a time (MariaDB restore).
_BATCH = 2000


def _batch(
    path: Path, table: str, cols: list[str], after: int | None
) -> tuple[list[tuple[Any, ...]], int | None]:
    """The next rows of ``table`` after rowid ``after`` (the live table's column names,
    quoted), and the last rowid read."""
    names = ", ".join(f'"{c}"' for c in cols)
    with contextlib.closing(sqlite3.connect(path)) as conn:
        rows = conn.execute(
            f"SELECT rowid, {names} FROM `{table}` WHERE rowid > ? ORDER BY rowid LIMIT ?",
            (-(2**63) if after is None else after, _BATCH),
        ).fetchall()
    if not rows:
        return [], after
    return [tuple(r[1:]) for r in rows], int(rows[-1][0])


async def integrity_check(db: Db) -> str:
    """``CHECK TABLE`` on every table, and every foreign key checked row by row (they
    only hold while nobody ran with ``foreign_key_checks = 0``)."""

    async def work(tx: Tx) -> list[str]:
        problems = [
            f"{r['Table']}: {r['Msg_text']}"
            for r in await tx.all(f"CHECK TABLE {', '.join(f'`{t}`' for t in TABLES)}")
            if (r["Msg_type"], r["Msg_text"]) != ("status", "OK")
        ]
        for table, key, column, parent, parent_key in FOREIGN_KEYS:
            orphans = await tx.all(
                f"SELECT c.{key} AS row_key FROM `{table}` AS c"
                f" LEFT JOIN `{parent}` AS p ON p.{parent_key} = c.{column}"
                f" WHERE c.{column} IS NOT NULL AND p.{parent_key} IS NULL"
            )
            problems += [
                f"foreign key: {table} row {r['row_key']} refers to a missing {parent}"
                for r in orphans
            ]
        return problems

    problems = await db.transact(work, "auto")
    return "\n".join(problems) if problems else "ok"


def _sqlite_columns(path: Path) -> dict[str, list[str]]:
    with contextlib.closing(sqlite3.connect(path)) as conn:
        return {t: [r[1] for r in conn.execute(f"PRAGMA table_info(`{t}`)")] for t in TABLES}


def _fill_sqlite(
    path: Path, columns: Mapping[str, list[str]], rows: Mapping[str, list[dict[str, Any]]]
) -> None:
    with contextlib.closing(sqlite3.connect(path, isolation_level=None)) as conn:
        conn.execute("PRAGMA foreign_keys = OFF")  # robot_info and task refer to each other
        conn.execute("BEGIN")
        for table in TABLES:
            conn.execute(f"DELETE FROM `{table}`")  # the menu a fresh schema is seeded with
            cols = columns[table]
            names = ", ".join(f'"{c}"' for c in cols)
            conn.executemany(
                f"INSERT INTO `{table}` ({names}) VALUES ({', '.join('?' * len(cols))})",
                [tuple(r[c] for c in cols) for r in rows[table]],
            )
        problems = conn.execute("PRAGMA foreign_key_check").fetchall()
        if problems:
            conn.execute("ROLLBACK")
            raise sqlite3.IntegrityError(f"the copy breaks foreign keys: {problems[:5]}")
        conn.execute("COMMIT")
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
