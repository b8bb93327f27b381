"""Persistence: the store, the schema history and the SQL backends.

Owns :mod:`~serveur.store.base` (the :class:`~serveur.store.base.Store`, composed of parts),
the parts, each written once for every backend (:mod:`~serveur.store.robots`,
:mod:`~serveur.store.waypoints`, :mod:`~serveur.store.orders`, :mod:`~serveur.store.tasks`,
:mod:`~serveur.store.events`, :mod:`~serveur.store.accounts`, :mod:`~serveur.store.service`,
:mod:`~serveur.store.zones`), what they are written against (:mod:`~serveur.store.sql`: the
Db, Tx and Dialect; :mod:`~serveur.store.rows`: the lookups they share;
:mod:`~serveur.store.checks`: the checks they share), :mod:`~serveur.store.migrations` (the
numbered SQL files), :mod:`~serveur.store.factory` (the backend for a database URL — the only
module that imports the backends), :mod:`~serveur.store.maintenance` (``serveur
backup|check``) and the backends :mod:`serveur.store.sqlite` and :mod:`serveur.store.mariadb`,
which are only a Db each. Every SQL statement of serveur lives here; the rest of the server
speaks in :mod:`serveur.domain` records.

May import: serveur.domain, serveur.status.
"""

__all__: list[str] = []
