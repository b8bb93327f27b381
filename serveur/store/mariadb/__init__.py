"""The MariaDB backend of the store, for sites that outgrow one SQLite file (docs/mariadb.md).

Owns :mod:`~serveur.store.mariadb.db` (URL, pool, retries, migrations),
:mod:`~serveur.store.mariadb.store`, :mod:`~serveur.store.mariadb.tasks` (trips) and
:mod:`~serveur.store.mariadb.rows`. Its ``backup`` writes a SQLite file the SQLite backend
opens, so it may use that backend.

May import: serveur.domain, serveur.status, serveur.store.base, serveur.store.accounts,
serveur.store.service, serveur.store.site, serveur.store.live,
serveur.store.migrations, serveur.store.sqlite.
"""

__all__: list[str] = []
