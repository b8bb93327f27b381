"""Reading a backup before it is trusted: is it a serveur database this version can open, is
it whole, what does it hold, and what would replacing the live database with it lose.

A file from a tablet can be anything (a photo renamed ``.db``, another program's SQLite file,
a backup from a newer serveur, a copy cut short), so it is opened read-only and ``immutable``
(SQLite neither locks nor writes it, and never looks for a ``-wal``), its migration history is
compared with this version's, and its integrity is checked before anything current changes.
Another program's SQLite file would otherwise pass: opening it as a store would migrate it
into an empty restaurant.

The functions here are blocking (SQLite does the work); callers run them in a thread.
"""

from __future__ import annotations

import functools
import os
import sqlite3
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any
from urllib.parse import quote

from serveur.errors import BackupError
from serveur.store.migrations import load_migrations
from serveur.store.sql import Tx

__all__ = ["INSPECT_SECONDS", "BackupSummary", "inspect_backup", "lost_since"]

#: The longest a backup's reading may take (its integrity check on a Pi's SD card included).
INSPECT_SECONDS = 300.0

#: What the console shows of a backup, and how each is counted.
_COUNTS = {
    "orders": "SELECT count(*) FROM orders",
    "trips": "SELECT count(*) FROM task",
    "places": "SELECT count(*) FROM waypoints WHERE removed_at IS NULL",
    "robots": "SELECT count(*) FROM robot_info WHERE removed_at IS NULL",
    "people": "SELECT count(*) FROM users",
}
#: The newest row of each (ids only grow): what a restore loses is what came after.
_TOP_IDS = {"orders": "SELECT max(id) FROM orders", "trips": "SELECT max(id) FROM task"}


@dataclass(frozen=True)
class BackupSummary:
    check: str  # "ok", or what the integrity check found
    last_activity: float | None  # the newest event or audited request in it
    counts: dict[str, int] = field(default_factory=dict)
    top_ids: dict[str, int] = field(default_factory=dict)

    def info(self) -> dict[str, Any]:
        return {"check": self.check, "last_activity": self.last_activity, **self.counts}


def inspect_backup(path: str | Path) -> BackupSummary:
    """Check the file at ``path`` as a serveur backup; :class:`BackupError` if it is not one
    (``reason``: ``not_a_backup`` or ``newer``). A damaged one is returned with its ``check``:
    the shelf lists it as damaged, a restore refuses it."""
    uri = f"file:{quote(os.fspath(path))}?mode=ro&immutable=1"
    try:
        con = sqlite3.connect(uri, uri=True)
    except sqlite3.Error as exc:
        raise BackupError(f"cannot open it: {exc}", reason="not_a_backup") from exc
    deadline = time.monotonic() + INSPECT_SECONDS
    # Stops a query that runs away (a crafted file's recursive view): "interrupted", refused.
    con.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
    try:
        return _inspect(con)
    except sqlite3.Error as exc:
        raise BackupError(f"it is not a serveur database ({exc})", reason="not_a_backup") from exc
    finally:
        con.close()


def _schema(con: sqlite3.Connection) -> set[tuple[str, str, str]]:
    """The database's own objects (tables, indexes, views, triggers) and their SQL."""
    rows = con.execute("SELECT type, name, coalesce(sql, '') FROM sqlite_master").fetchall()
    return {
        (t, n, q) for t, n, q in rows if not n.startswith("sqlite_") and n != "schema_migrations"
    }


@functools.cache
def _expected_schema(version: int) -> frozenset[tuple[str, str, str]]:
    """The objects this serveur's migrations 1..``version`` make, in a scratch database: a
    backup written by serveur has exactly these (nothing added: no view or trigger of its own,
    which would run in the live database after a restore)."""
    con = sqlite3.connect(":memory:")
    try:
        for m in load_migrations("sqlite"):
            if m.version <= version:
                con.executescript(m.sql)
        return frozenset(_schema(con))
    finally:
        con.close()


def _inspect(con: sqlite3.Connection) -> BackupSummary:
    rows = con.execute("SELECT version, name FROM schema_migrations").fetchall()
    known = {m.version: m.name for m in load_migrations("sqlite")}
    history = dict(rows)
    if not history or history.get(1) != known[1]:
        raise BackupError("it is not a serveur database", reason="not_a_backup")
    newer = sorted(v for v in history if v not in known)
    if newer:
        raise BackupError(
            "it was written by a newer serveur: update this one first", reason="newer"
        )
    if any(history[v] != known[v] for v in history) or sorted(history) != list(
        range(1, max(history) + 1)
    ):
        raise BackupError("it is not a serveur database", reason="not_a_backup")
    if _schema(con) != _expected_schema(max(history)):
        raise BackupError(
            "it is not a serveur database as serveur writes it (its tables were changed)",
            reason="not_a_backup",
        )
    problems = [str(r[0]) for r in con.execute("PRAGMA integrity_check")]
    problems += [
        f"foreign key: {r[0]} row {r[1]} refers to a missing {r[2]}"
        for r in con.execute("PRAGMA foreign_key_check")
    ]
    check = "ok" if problems == ["ok"] else "\n".join(p for p in problems if p != "ok")
    if check != "ok":
        return BackupSummary(check, None)
    last = con.execute(
        "SELECT max(t) FROM (SELECT max(ts) AS t FROM events UNION ALL SELECT max(ts) FROM audit)"
    ).fetchone()[0]
    counts = {}
    for key, sql in _COUNTS.items():
        try:
            counts[key] = int(con.execute(sql).fetchone()[0])
        except sqlite3.OperationalError:  # an old backup without the column: migrated later
            counts[key] = int(con.execute(sql.partition(" WHERE ")[0]).fetchone()[0])
    top = {k: int(con.execute(sql).fetchone()[0] or 0) for k, sql in _TOP_IDS.items()}
    return BackupSummary(check, None if last is None else float(last), counts, top)


async def lost_since(tx: Tx, backup: BackupSummary) -> dict[str, int]:
    """What the live database holds that ``backup`` does not: its orders and trips made after
    the backup's newest (both backends: plain SQL through the store's transaction)."""
    out = {}
    for key, table in (("orders", "orders"), ("trips", "task")):
        rows = await tx.all(
            f"SELECT count(*) AS n FROM {table} WHERE id > ?", (backup.top_ids.get(key, 0),)
        )
        out[key] = int(rows[0]["n"])
    return out
