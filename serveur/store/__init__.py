"""Persistence: the store interface, the schema history and the SQL backends.

Owns :mod:`~serveur.store.base` (the abstract :class:`~serveur.store.base.Store` and the
checks every backend applies), :mod:`~serveur.store.migrations` (the numbered SQL files),
:mod:`~serveur.store.accounts` (users, tokens, audit in portable SQL),
:mod:`~serveur.store.factory` (the backend for a database URL — the only module that
imports the backends), :mod:`~serveur.store.maintenance` (``serveur backup|check``) and the
backends :mod:`serveur.store.sqlite` and :mod:`serveur.store.mariadb`. Every SQL statement
of serveur lives here; the rest of the server speaks in :mod:`serveur.domain` records.

May import: serveur.domain, serveur.status.
"""

__all__: list[str] = []
