"""The SQLite backend of :class:`~serveur.store.base.Store`: the store on a
:class:`~serveur.store.sqlite.db.SQLiteDb` (one aiosqlite connection, WAL; its concurrency
model is described there).
"""

from __future__ import annotations

from pathlib import Path

import aiosqlite

from serveur.store.base import Store
from serveur.store.sqlite.db import BUSY_TIMEOUT_MS, SQLiteDb, split_sql

__all__ = ["BUSY_TIMEOUT_MS", "SQLiteStore", "split_sql"]


class SQLiteStore(Store):
    """The store in one SQLite file (``":memory:"`` works for throw-away uses)."""

    def __init__(self, path: str | Path) -> None:
        self.path = str(path)
        self._sqlite = SQLiteDb(self.path)
        super().__init__(self._sqlite)

    def __repr__(self) -> str:
        return f"SQLiteStore({self.path!r})"

    @property
    def _db(self) -> aiosqlite.Connection | None:
        """The open connection (tests reach it to make the disk refuse writes)."""
        return self._sqlite.connection
