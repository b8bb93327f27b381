"""The MariaDB backend of the store, for sites that outgrow one SQLite file (docs/mariadb.md).

Owns :mod:`~serveur.store.mariadb.db` (URL, pool, transactions, retries, migrations: the
:class:`~serveur.store.mariadb.db.Database`), :mod:`~serveur.store.mariadb.backup` (a backup
written as a SQLite file the SQLite backend opens, so it may use that backend; the integrity
check) and :mod:`~serveur.store.mariadb.store` (the store on that Database). The SQL itself is
the store's parts', written once for both backends.

May import: serveur.domain, serveur.status, serveur.store.base, serveur.store.sql,
serveur.store.migrations, serveur.store.sqlite.
"""

__all__: list[str] = []
