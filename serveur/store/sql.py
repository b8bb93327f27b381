"""What the store's SQL is written against: a :class:`Db` that runs units of work in
transactions, the :class:`Tx` one unit of work gets, and the :class:`Dialect` that says what
differs between SQLite and MariaDB.

Every statement of :mod:`serveur.store` is written once, in the SQL both databases accept:
``?`` placeholders, identifiers that are keywords (``table``, ``key``) quoted with backticks
(SQLite accepts MySQL's quotes), ``UPDATE`` then ``INSERT`` when nothing matched instead of an
upsert (row counts are matched rows on both: ``CLIENT.FOUND_ROWS`` on MariaDB), and the new
row's id from the driver (``lastrowid``) instead of ``RETURNING``. What cannot be written the
same is the dialect's: see :class:`Dialect`.

A unit of work is a coroutine function of a :class:`Tx`, not the body of an ``async with``,
because the MariaDB backend runs it again when it surely did not commit (a deadlock, a lost
connection): it must compute everything from its arguments and what it reads.
"""

from __future__ import annotations

import functools
from collections.abc import Awaitable, Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol, TypeVar

from serveur.errors import InvalidField

__all__ = ["MARIADB", "SQLITE", "Db", "Dialect", "Mode", "Tx", "one", "sql_in"]

T = TypeVar("T")

#: ``write``: one transaction that keeps what it read true until it commits (SQLite's
#: ``BEGIN IMMEDIATE``; MariaDB's READ COMMITTED with the rows locked ``FOR UPDATE``);
#: ``read``: one consistent snapshot; ``auto``: each statement on its own (single reads, or
#: one idempotent write).
Mode = Literal["write", "read", "auto"]


@dataclass(frozen=True, slots=True)
class Dialect:
    """What differs between the SQL of two databases, and nothing else."""

    #: The migration files' dialect (``migrations/NNN_name.<name>.sql``).
    name: Literal["sqlite", "mariadb"]
    #: How the driver marks a parameter: ``?`` (sqlite3) or ``%s`` (asyncmy, which then
    #: reads ``%`` as its escape: a literal one is written ``%%``).
    placeholder: Literal["?", "%s"]
    #: True where transactions run side by side and a writer locks the rows it checks with
    #: ``SELECT ... FOR UPDATE`` (MariaDB); False where one writer holds the whole database
    #: from its first statement (SQLite's ``BEGIN IMMEDIATE``), which has no such clause.
    row_locks: bool
    #: The aggregate that gathers ids into a JSON array (``NULL`` over no rows on MariaDB).
    json_ids: str
    #: The longest name (robot, waypoint, key, event kind) a column takes: MariaDB's
    #: VARCHAR(255); SQLite's TEXT has no limit.
    max_name: int | None

    @property
    def for_update(self) -> str:
        """The clause a writer's SELECT ends with to lock what it read until COMMIT."""
        return " FOR UPDATE" if self.row_locks else ""

    def sql(self, portable: str) -> str:
        """``portable`` (``?`` placeholders, no ``?`` in literals) for this driver."""
        return portable if self.placeholder == "?" else _percent(portable)

    def check_name(self, value: object, field: str) -> str:
        """``value`` if it is a non-blank string the name columns can hold."""
        if not isinstance(value, str) or not value.strip():
            raise InvalidField(f"{field} must be a non-empty string", field=field)
        if self.max_name is not None and len(value) > self.max_name:
            raise InvalidField(f"{field} is longer than {self.max_name} characters", field=field)
        return value


@functools.lru_cache(maxsize=1024)
def _percent(portable: str) -> str:
    return portable.replace("%", "%%").replace("?", "%s")


SQLITE = Dialect(
    name="sqlite", placeholder="?", row_locks=False, json_ids="json_group_array", max_name=None
)
MARIADB = Dialect(
    name="mariadb", placeholder="%s", row_locks=True, json_ids="JSON_ARRAYAGG", max_name=255
)


class Tx(Protocol):
    """One unit of work's statements, in portable SQL; rows come back as dicts."""

    @property
    def dialect(self) -> Dialect: ...

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]: ...

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        """Execute a write; the number of rows its WHERE matched."""
        ...

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        """Execute an INSERT; the id the database gave the new row."""
        ...

    async def many(self, sql: str, rows: Sequence[Sequence[Any]]) -> None: ...


class Db(Protocol):
    """A database the store's parts run their units of work on (one per backend)."""

    @property
    def dialect(self) -> Dialect: ...

    async def open(self) -> None:
        """Connect and apply the migrations not applied yet; a second call does nothing."""
        ...

    async def close(self) -> None:
        """Close the connection(s); safe to call twice."""
        ...

    def busy(self) -> bool:
        """True while a query may be running outside the event loop (see Store.busy)."""
        ...

    async def transact(self, work: Callable[[Tx], Awaitable[T]], mode: Mode) -> T:
        """Run ``work`` as one unit of work (see :data:`Mode`); a ServeurError it raises
        rolls back and passes through, a database failure becomes a StoreError (a refused
        constraint a Conflict)."""
        ...

    async def backup(self, path: str | Path) -> None:
        """Write a consistent copy of the live database to ``path`` (replaced atomically)."""
        ...

    async def integrity_check(self) -> str:
        """``"ok"`` when the database is sound, else the problems found, one per line."""
        ...

    async def replace_with(self, backup: Path) -> None:
        """Make the database hold what the checked backup file ``backup`` (a SQLite copy, as
        :meth:`backup` writes) holds; called while the database is closed (a restore: the
        server is stopped). Whole or not at all."""
        ...


def sql_in(column: str, values: Sequence[object]) -> str:
    """``column IN (?, ...)``; false for no values (MariaDB refuses ``IN ()``)."""
    return f"{column} IN ({', '.join('?' * len(values))})" if values else "0"


async def one(tx: Tx, sql: str, params: Sequence[Any] = ()) -> dict[str, Any] | None:
    """The first row of ``sql``, or None."""
    rows = await tx.all(sql, params)
    return rows[0] if rows else None
