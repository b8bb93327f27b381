"""``serveur backup`` and ``serveur check``: database upkeep while the server runs.

Both open their own connection to the database the server is using, so neither needs the
server stopped:

* ``serveur backup PATH`` writes a consistent copy (the store's online backup: for SQLite,
  SQLite's backup API reading one snapshot, which WAL lets run beside the server's writes;
  for MariaDB a SQLite file of the same rows). The copy appears at ``PATH`` whole or not at
  all, and is checked before the command reports success: a backup nobody can restore is
  worse than none, because it is trusted.
* ``serveur check`` runs the store's integrity check (``PRAGMA integrity_check`` and the
  foreign keys on SQLite) and exits 1 when it finds anything.

To restore, stop the server and copy the backup over the database file (removing the old
file's ``-wal`` and ``-shm`` companions), then start the server: it reconciles every robot
with its trip as after any restart.
"""

from __future__ import annotations

import argparse
import os
import sys
from pathlib import Path

from serveur.errors import ServeurError
from serveur.store.factory import open_store

__all__ = ["add_maintenance_parser", "backup", "check"]


async def backup(db: str, path: str | Path) -> str:
    """Copy the live database ``db`` to ``path``; the copy's integrity check result."""
    async with open_store(db) as store:
        await store.backup(path)
    async with open_store(str(path)) as copy:
        return await copy.integrity_check()


async def check(db: str) -> str:
    """``"ok"`` or the problems found in ``db``, one per line."""
    async with open_store(db) as store:
        return await store.integrity_check()


async def _cmd_backup(ns: argparse.Namespace) -> int:
    if (ns.path is None) == (ns.into is None):
        print("serveur backup: give a PATH or --into FOLDER (one of the two)", file=sys.stderr)
        return 2
    try:
        if ns.into is not None:
            # The server's backups folder is named by its rules (serveur.core.backups), a
            # layer above the store: the CLI hands that maker in (serveur.cli).
            return int(await ns.backup_into(ns.db, ns.into))
        report = await backup(ns.db, ns.path)
    except ServeurError as exc:
        print(f"backup failed: {exc}", file=sys.stderr)
        return 1
    if report != "ok":
        print(f"backup written to {ns.path} but it is damaged:\n{report}", file=sys.stderr)
        return 1
    print(f"backup of {ns.db} written to {ns.path} (integrity check: ok)")
    return 0


async def _cmd_check(ns: argparse.Namespace) -> int:
    try:
        report = await check(ns.db)
    except ServeurError as exc:
        print(f"check failed: {exc}", file=sys.stderr)
        return 1
    print(report)
    return 0 if report == "ok" else 1


def _db_argument(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--db",
        default=os.environ.get("SERVEUR_DB", "./serveur.db"),
        help="the server's database (default: $SERVEUR_DB, else ./serveur.db)",
    )


def add_maintenance_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur backup`` and ``serveur check`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "backup",
        help="write a consistent copy of the (live) database",
        description="Copy the database while the server keeps running; the copy is checked.",
    )
    p.add_argument("path", nargs="?", help="where to write the copy (replaced atomically)")
    p.add_argument(
        "--into",
        metavar="FOLDER",
        help="instead of PATH: into the server's backups folder, named and listed as the"
        " console's 'Back up now' (serveur run --backups)",
    )
    _db_argument(p)
    p.set_defaults(func=_cmd_backup, is_async=True)
    c = sub.add_parser("check", help="check the database's integrity (exit 1 on problems)")
    _db_argument(c)
    c.set_defaults(func=_cmd_check, is_async=True)
