"""Choosing a store backend from a database URL.

The one place that knows every backend: :mod:`serveur.store.base` (the interface) never
imports its implementations, and each backend imports only the interface, so the store
package has no import circle. The MariaDB backend is imported only when a MariaDB URL is
given, so a SQLite site needs no MariaDB driver installed.
"""

from __future__ import annotations

from pathlib import Path

from serveur.errors import StoreError
from serveur.store.base import Store

__all__ = ["open_store", "sqlite_file"]


def open_store(url: str) -> Store:
    """The (unopened) store for ``url``.

    ``sqlite:///abs/path.db``, ``sqlite:relative.db`` or a bare path give a
    :class:`~serveur.store.sqlite.store.SQLiteStore`;
    ``mariadb://user:password@host:port/database`` a
    :class:`~serveur.store.mariadb.store.MariaDBStore` (asyncmy must be installed: the ``mariadb``
    extra).
    """
    if url.startswith(("mariadb://", "mysql://")):
        # mariadb://user[:password]@host[:port]/database; the bare "mariadb://" reads the
        # whole URL from $SERVEUR_DB, a URL without a password reads $SERVEUR_DB_PASSWORD
        # (see serveur.store.mariadb.db.MariaDBConfig.from_url and docs/mariadb.md).
        try:
            from serveur.store.mariadb.store import MariaDBStore
        except ImportError as exc:
            raise StoreError(
                f"the MariaDB backend needs its driver: pip install 'serveur[mariadb]' ({exc})"
            ) from exc
        return MariaDBStore.from_url(url)
    from serveur.store.sqlite.store import SQLiteStore

    return SQLiteStore(_sqlite_path(url))


def sqlite_file(url: str) -> Path | None:
    """The file of a SQLite database ``url`` (as :func:`open_store` reads it), or None for
    another backend or a database in memory."""
    if url.startswith(("mariadb://", "mysql://")):
        return None
    path = _sqlite_path(url)
    return None if path == ":memory:" else Path(path)


def _sqlite_path(url: str) -> str:
    if url.startswith("sqlite://"):
        path = url[len("sqlite://") :]
        if not path.startswith("/"):
            raise StoreError(
                "sqlite URL must be sqlite:///absolute/path or sqlite:relative/path", url=url
            )
    elif url.startswith("sqlite:"):
        path = url[len("sqlite:") :]
    elif "://" in url:
        raise StoreError(f"unsupported database URL {url!r}", url=url)
    else:
        path = url
    if not path:
        raise StoreError("empty database path", url=url)
    return path
