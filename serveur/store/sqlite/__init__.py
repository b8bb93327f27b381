"""The SQLite backend of the store: one aiosqlite connection in WAL mode (the default).

Owns :mod:`~serveur.store.sqlite.store` (:class:`~serveur.store.sqlite.store.SQLiteStore`),
:mod:`~serveur.store.sqlite.tasks` (trips) and :mod:`~serveur.store.sqlite.rows` (the
connection, transactions, the SELECTs both share).

May import: serveur.domain, serveur.status, serveur.store.base, serveur.store.accounts,
serveur.store.service, serveur.store.site, serveur.store.live,
serveur.store.migrations.
"""

__all__: list[str] = []
