"""The SQLite backend of the store: one aiosqlite connection in WAL mode (the default).

Owns :mod:`~serveur.store.sqlite.db` (:class:`~serveur.store.sqlite.db.SQLiteDb`: the
connection, its migrations and transactions, backup and integrity check) and
:mod:`~serveur.store.sqlite.store` (:class:`~serveur.store.sqlite.store.SQLiteStore`, the store
on that Db). The SQL itself is the store's parts', written once for both backends.

May import: serveur.domain, serveur.status, serveur.store.base, serveur.store.sql,
serveur.store.migrations.
"""

__all__: list[str] = []
