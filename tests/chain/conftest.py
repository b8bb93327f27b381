"""The store tests' database fixtures (``backend``: SQLite and MariaDB; ``store``), for the
outbox's tests here."""

from tests.store.test_store import backend, store

__all__ = ["backend", "store"]
