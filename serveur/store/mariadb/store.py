"""The MariaDB backend of :class:`~serveur.store.base.Store`, for sites outgrowing one SQLite file.

The store's parts run unchanged on a :class:`~serveur.store.mariadb.db.Database` (the shared
test suite runs against both backends): the same checks, the same events, in the same
transactions. What differs is how concurrent writers are kept apart, and the dialect says it:
SQLite has one writer at a time; MariaDB runs transactions side by side, so each writer first
locks the rows its checks read (``SELECT ... FOR UPDATE``: a task before its robot, orders in id
order, so that lock orders never cross), then enforces each transition again with a
conditional UPDATE and its row count. Two servers, or many clients of one, can therefore never
put a dish on two trips or give a robot two trips: the loser waits for the winner's COMMIT,
re-reads, and gets the Conflict the SQLite store would give. Connections, the pool, retries
after deadlocks and lost connections, and migrations live in
:mod:`serveur.store.mariadb.db`, which may run a unit of work again when it surely did not
commit.
"""

from __future__ import annotations

from collections.abc import Mapping

from serveur.store.base import Store
from serveur.store.mariadb.db import Database, MariaDBConfig

__all__ = ["MariaDBStore"]


class MariaDBStore(Store):
    """The store in one MariaDB (or MySQL-compatible Galera) database."""

    def __init__(self, config: MariaDBConfig) -> None:
        self.config = config
        self._database = Database(config)
        super().__init__(self._database)

    @classmethod
    def from_url(cls, url: str, environ: Mapping[str, str] | None = None) -> MariaDBStore:
        """See :meth:`MariaDBConfig.from_url` for the URL and the environment variables."""
        return cls(MariaDBConfig.from_url(url, environ))

    def __repr__(self) -> str:
        return f"MariaDBStore({self.config.describe()!r})"

    @property
    def retries(self) -> int:
        """Transactions re-run so far after a surely-uncommitted failure."""
        return self._database.retries
