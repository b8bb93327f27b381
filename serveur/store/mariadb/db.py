"""MariaDB plumbing for :mod:`serveur.store.mariadb.store`: URL, pool, transactions, retries,
migrations.

Driver: asyncmy. Compared with aiomysql (looked at in November 2026): asyncmy had six releases
from August to November 2026 with wheels for CPython 3.9-3.14 on x86_64 *and* aarch64 (the
Pi 4/5 on 64-bit Raspberry Pi OS), ships type stubs (``py.typed``: checked by ``mypy
--strict`` here without ignores) and has no dependencies; aiomysql's last release is from
October 2025, it is untyped and rides on PyMySQL. asyncmy's risk is one maintainer with
bursty releases (2025 had none); it keeps aiomysql's pool API, so switching would be small.
On a 32-bit Pi OS (armv7) asyncmy has no wheel and builds from source (needs a C compiler).

Transactions. A unit of work is a coroutine function given a :class:`~serveur.store.sql.Tx`
(here a :class:`MariaDBTx`); :meth:`Database.write` runs it in one transaction and *may run it
again*: that is why the work is a function and not the body of an ``async with``. It is re-run
only when the first run surely did not commit:

* the server rolled it back itself (deadlock 1213, which is also Galera's certification
  failure, or lock wait timeout 1205), at any point, COMMIT included;
* the connection broke before COMMIT was sent (the server rolls back an open transaction
  when its client goes away, and a restarted server never saw it commit);
* a constraint refused it once (duplicate key, foreign key): a concurrent transaction won a
  race that the work's own checks could not see yet; the re-run sees the winner's row and
  answers as the SQLite store would (a resend, a NotFound, a precise Conflict). A second
  refusal is a :class:`~serveur.errors.Conflict`.

A connection lost while COMMIT was in flight leaves the outcome unknown: that is never
retried (it could apply the work twice) but reported as a StoreError with
``outcome="unknown"``; requests with idempotency keys can then be resent safely. Retries
wait with a capped exponential backoff and stop after ``retry_for`` seconds, which is also how
long a restarting database is waited for.

Isolation. Sessions run READ COMMITTED: writers lock the rows their checks depend on with
``SELECT ... FOR UPDATE`` (parents before children: task, then robot, then orders) and
enforce every transition again with conditional UPDATEs whose matched-row count must be right
(``CLIENT.FOUND_ROWS``: matched rows, like SQLite, not just changed ones); READ COMMITTED
takes no gap locks, so unrelated inserts do not queue behind them. Multi-statement reads run
REPEATABLE READ with a consistent snapshot, so a task and its stops come from one instant.
"""

from __future__ import annotations

import asyncio
import os
import random
import re
import time
from collections.abc import Awaitable, Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar
from urllib.parse import parse_qsl, unquote, urlsplit

import asyncmy
from asyncmy.constants import CLIENT
from asyncmy.cursors import DictCursor

from serveur.errors import Conflict, ServeurError, StoreError
from serveur.store.mariadb import backup as maintenance
from serveur.store.migrations import SITE_HISTORY, Migration, load_migrations
from serveur.store.sql import MARIADB, Dialect, Mode, Tx

__all__ = [
    "DEFAULT_PORT",
    "ENV_PASSWORD",
    "ENV_URL",
    "MIGRATION_LOCK_TIMEOUT",
    "Database",
    "MariaDBConfig",
    "MariaDBTx",
    "split_statements",
]

T = TypeVar("T")

#: The whole database URL, used when the URL given is the bare ``mariadb://``.
ENV_URL = "SERVEUR_DB"
#: The password, used when the URL has none (keeps it out of ``ps`` and shell history).
ENV_PASSWORD = "SERVEUR_DB_PASSWORD"
DEFAULT_PORT = 3306
#: How long a starting server waits for another one that is migrating the same database.
MIGRATION_LOCK_TIMEOUT = 60

# Server errors after which the server has rolled the transaction back (or only the statement,
# 1205, after which we roll back): a re-run cannot apply anything twice.
_ROLLED_BACK = frozenset({1205, 1213})
# Client/server errors that mean the connection is gone or unusable.
_CONNECTION_LOST = frozenset({1053, 1927, 2003, 2006, 2013, 2055, 4031})
# Refused by a constraint: duplicate key, foreign key (parent missing / child exists), CHECK.
_CONSTRAINT = frozenset({1062, 1216, 1217, 1451, 1452, 1557, 3819, 4025})
_SESSION = (
    "SET SESSION sql_mode = 'STRICT_ALL_TABLES,ERROR_FOR_DIVISION_BY_ZERO,"
    "NO_ENGINE_SUBSTITUTION,NO_ZERO_DATE,NO_ZERO_IN_DATE',"
    " SESSION tx_isolation = 'READ-COMMITTED', SESSION innodb_lock_wait_timeout = 10,"
    " SESSION time_zone = '+00:00'"
)
_NAME = re.compile(r"^[A-Za-z0-9_$]{1,64}$")


@dataclass(frozen=True, slots=True)
class MariaDBConfig:
    """Where and how to connect; built from a URL by :meth:`from_url`."""

    host: str
    port: int
    user: str
    database: str
    password: str = field(default="", repr=False)
    unix_socket: str | None = None
    pool_size: int = 10
    connect_timeout: float = 10.0
    retry_for: float = 30.0

    @classmethod
    def from_url(cls, url: str, environ: Mapping[str, str] | None = None) -> MariaDBConfig:
        """Parse ``mariadb://user[:password]@host[:port]/database[?option=value...]``.

        Precedence: the bare URL ``mariadb://`` means "take the whole URL from
        ``$SERVEUR_DB``"; a password in the URL wins over ``$SERVEUR_DB_PASSWORD``, which is
        used only when the URL has none. Options: ``socket`` (a Unix socket path instead of
        TCP), ``pool_size``, ``connect_timeout`` and ``retry_for`` (seconds).
        """
        env = os.environ if environ is None else environ
        if url.rstrip("/") in ("mariadb:", "mysql:"):
            if not env.get(ENV_URL):
                raise StoreError(f"{url!r} takes its URL from ${ENV_URL}, which is not set")
            url = env[ENV_URL]
            if url.rstrip("/") in ("mariadb:", "mysql:"):
                raise StoreError(f"${ENV_URL} must be a full mariadb:// URL")
        parts = urlsplit(url)
        shown = redact(url)
        if parts.scheme not in ("mariadb", "mysql"):
            raise StoreError(f"not a MariaDB URL: {shown}", url=shown)
        database = unquote(parts.path.lstrip("/"))
        if not _NAME.match(database):
            raise StoreError(
                "the MariaDB URL needs a database name (letters, digits, _ and $): "
                "mariadb://user:password@host:port/database",
                url=shown,
            )
        try:
            port = parts.port or DEFAULT_PORT
            options = dict(parse_qsl(parts.query, strict_parsing=bool(parts.query)))
            known = {"socket", "pool_size", "connect_timeout", "retry_for"}
            if set(options) - known:
                raise ValueError(f"unknown option(s) {sorted(set(options) - known)}")
            pool_size = int(options.get("pool_size", 10))
            connect_timeout = float(options.get("connect_timeout", 10.0))
            retry_for = float(options.get("retry_for", 30.0))
            if pool_size < 1 or connect_timeout <= 0 or retry_for < 0:
                raise ValueError("pool_size, connect_timeout and retry_for must be positive")
        except ValueError as exc:
            raise StoreError(f"bad MariaDB URL {shown}: {exc}", url=shown) from exc
        user = unquote(parts.username or "")
        if not user:
            raise StoreError(f"the MariaDB URL needs a user: {shown}", url=shown)
        password = parts.password
        return cls(
            host=parts.hostname or "localhost",
            port=port,
            user=user,
            database=database,
            password=unquote(password) if password is not None else env.get(ENV_PASSWORD, ""),
            unix_socket=options.get("socket"),
            pool_size=pool_size,
            connect_timeout=connect_timeout,
            retry_for=retry_for,
        )

    def describe(self) -> str:
        """The URL without the password, for logs and error messages."""
        where = self.unix_socket or f"{self.host}:{self.port}"
        return f"mariadb://{self.user}@{where}/{self.database}"


def redact(url: str) -> str:
    """``url`` with its password replaced by ``***``."""
    return re.sub(r"^([a-z]+://[^:/@]*):[^@]*@", r"\1:***@", url)


def split_statements(script: str) -> list[str]:
    """A migration script as statements: split at ``;`` outside quotes and comments."""
    statements: list[str] = []
    buf: list[str] = []
    i, n = 0, len(script)
    while i < n:
        ch = script[i]
        if ch in "'\"`":
            end = i + 1
            while end < n and script[end] != ch:
                end += 2 if script[end] == "\\" else 1
            buf.append(script[i : end + 1])
            i = end + 1
        elif script.startswith("--", i) or ch == "#":
            i = script.find("\n", i) if "\n" in script[i:] else n
        elif script.startswith("/*", i):
            end = script.find("*/", i + 2)
            i = n if end < 0 else end + 2
        elif ch == ";":
            statements.append("".join(buf).strip())
            buf = []
            i += 1
        else:
            buf.append(ch)
            i += 1
    statements.append("".join(buf).strip())
    return [s for s in statements if s]


class MariaDBTx:
    """One connection inside one unit of work: :class:`~serveur.store.sql.Tx` in portable SQL
    (``?`` placeholders, turned into asyncmy's ``%s``), rows as dicts."""

    def __init__(self, conn: asyncmy.Connection) -> None:
        self.conn = conn

    @property
    def dialect(self) -> Dialect:
        return MARIADB

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        async with self.conn.cursor(DictCursor) as cur:
            await cur.execute(MARIADB.sql(sql), tuple(params))
            rows: list[dict[str, Any]] = list(await cur.fetchall())
            return rows

    async def one(self, sql: str, params: Sequence[Any] = ()) -> dict[str, Any] | None:
        rows = await self.all(sql, params)
        return rows[0] if rows else None

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        """Execute a write; the number of rows its WHERE matched."""
        async with self.conn.cursor() as cur:
            return int(await cur.execute(MARIADB.sql(sql), tuple(params)))

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        """Execute an INSERT; the AUTO_INCREMENT id it was given."""
        async with self.conn.cursor() as cur:
            await cur.execute(MARIADB.sql(sql), tuple(params))
            return int(cur.lastrowid)

    async def many(self, sql: str, rows: Sequence[Sequence[Any]]) -> None:
        if rows:
            async with self.conn.cursor() as cur:
                await cur.executemany(MARIADB.sql(sql), [tuple(r) for r in rows])

    async def script(self, sql: str) -> None:
        """Execute one statement of a migration as it is written (no parameters)."""
        async with self.conn.cursor() as cur:
            await cur.execute(sql)


class _Retry(Exception):
    """This attempt surely did not commit and may be run again."""

    def __init__(self, cause: BaseException, *, constraint: bool = False) -> None:
        super().__init__(str(cause))
        self.cause = cause
        self.constraint = constraint


def _code(exc: BaseException) -> int | None:
    args = getattr(exc, "args", ())
    return args[0] if args and isinstance(args[0], int) else None


def _lost(exc: BaseException) -> bool:
    """True when ``exc`` says the connection is gone (or was never made)."""
    if isinstance(exc, asyncmy.errors.InterfaceError | ConnectionError | EOFError):
        return True
    if isinstance(exc, asyncio.IncompleteReadError | OSError):
        return True
    return _code(exc) in _CONNECTION_LOST


class Database:
    """A pool of sessions to one MariaDB database, and transactions on it."""

    def __init__(self, config: MariaDBConfig, history: str = SITE_HISTORY) -> None:
        """``history``: the migrations package applied at open (the site's by default)."""
        self.config = config
        self.history = history
        self._pool: asyncmy.Pool | None = None
        self._opening = asyncio.Lock()
        #: Attempts re-run after a surely-uncommitted failure (tests and logs read it).
        self.retries = 0
        #: Units of work between taking a connection and giving it back.
        self._in_flight = 0

    @property
    def is_open(self) -> bool:
        return self._pool is not None

    @property
    def dialect(self) -> Dialect:
        return MARIADB

    def busy(self) -> bool:
        """True while a unit of work waits on the MariaDB server. asyncmy runs on the event
        loop, but the answer comes from another process: a virtual-time loop (a replay, the
        tests) that jumped meanwhile would see the query take virtual seconds."""
        return self._in_flight > 0

    async def open(self) -> None:
        """Create the pool (retrying while the server starts) and apply the migrations."""
        async with self._opening:
            if self._pool is not None:
                return
            pool = await self._with_retries(self._create_pool, "connecting")
            self._pool = pool
            try:
                await self._with_retries(self._migrate, "migrating")
            except BaseException:
                self._pool = None
                pool.close()
                await pool.wait_closed()
                raise

    async def _create_pool(self) -> asyncmy.Pool:
        cfg = self.config
        kwargs: dict[str, Any] = {
            "user": cfg.user,
            "password": cfg.password,
            "database": cfg.database,
            "charset": "utf8mb4",
            "autocommit": True,
            "client_flag": CLIENT.FOUND_ROWS,
            "init_command": _SESSION,
            "connect_timeout": cfg.connect_timeout,
        }
        if cfg.unix_socket:
            kwargs["unix_socket"] = cfg.unix_socket
        else:
            kwargs["host"], kwargs["port"] = cfg.host, cfg.port
        try:
            return await asyncmy.create_pool(
                minsize=1, maxsize=cfg.pool_size, pool_recycle=3600, **kwargs
            )
        except Exception as exc:
            if _lost(exc) or _code(exc) in _ROLLED_BACK:
                raise _Retry(exc) from exc
            raise self._error(exc, "cannot connect") from exc

    async def close(self) -> None:
        async with self._opening:
            pool, self._pool = self._pool, None
            if pool is not None:
                pool.close()
                await pool.wait_closed()

    # -- units of work ------------------------------------------------------------------

    async def transact(self, work: Callable[[Tx], Awaitable[T]], mode: Mode) -> T:
        """Run ``work`` as a ``write``, ``read`` or ``auto`` unit of work (see below)."""
        if mode == "write":
            return await self.write(work)
        return await (self.read(work) if mode == "read" else self.auto(work))

    async def write(self, work: Callable[[Tx], Awaitable[T]]) -> T:
        """Run ``work`` in one READ COMMITTED transaction, re-run while surely uncommitted."""
        return await self._with_retries(lambda: self._attempt(work, "write"), "writing")

    async def read(self, work: Callable[[Tx], Awaitable[T]]) -> T:
        """Run ``work`` in one read-only transaction that sees one consistent snapshot."""
        return await self._with_retries(lambda: self._attempt(work, "read"), "reading")

    async def auto(self, work: Callable[[Tx], Awaitable[T]]) -> T:
        """Run ``work`` in autocommit: single reads, or one idempotent write (safe to re-run
        even when its outcome is unknown, like saving an absolute pose)."""
        return await self._with_retries(lambda: self._attempt(work, "auto"), "reading")

    async def _with_retries(self, attempt: Callable[[], Awaitable[T]], doing: str) -> T:
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.config.retry_for
        delay, refused = 0.02, 0
        while True:
            try:
                return await attempt()
            except _Retry as retry:
                if retry.constraint:
                    refused += 1
                    if refused > 1:
                        raise Conflict(f"refused by the database: {retry.cause}") from retry.cause
                    self.retries += 1
                    continue  # the re-run sees the winner's row: no wait needed
                if loop.time() + delay > deadline:
                    raise self._error(retry.cause, f"{doing} failed") from retry.cause
                self.retries += 1
                # Jitter: two servers that deadlocked must not retry in lockstep.
                await asyncio.sleep(delay * (0.5 + random.random()))
                delay = min(delay * 2, 1.0)

    async def _attempt(self, work: Callable[[Tx], Awaitable[T]], mode: Mode) -> T:
        self._in_flight += 1
        try:
            return await self._attempt_on_a_connection(work, mode)
        finally:
            self._in_flight -= 1

    async def _attempt_on_a_connection(self, work: Callable[[Tx], Awaitable[T]], mode: Mode) -> T:
        pool = self._pool
        if pool is None:
            raise StoreError("store is not open")
        try:
            conn = await pool.acquire()
        except Exception as exc:
            if _lost(exc):
                raise _Retry(exc) from exc
            raise self._error(exc, "cannot connect") from exc
        committing = False
        keep = False
        try:
            if mode == "write":
                await conn.begin()
            elif mode == "read":
                await MariaDBTx(conn).run("SET TRANSACTION ISOLATION LEVEL REPEATABLE READ")
                await MariaDBTx(conn).run("START TRANSACTION WITH CONSISTENT SNAPSHOT, READ ONLY")
            result = await work(MariaDBTx(conn))
            if mode != "auto":
                committing = True
                await conn.commit()
            keep = True
            return result
        except ServeurError:
            # The work refused the request: roll back and keep the connection if it can.
            keep = await self._rollback(conn, mode)
            raise
        except ValueError as exc:
            # A row the domain records refuse (pydantic errors are ValueErrors): the database,
            # not the request, is wrong.
            keep = await self._rollback(conn, mode)
            raise StoreError(f"database error: {exc}") from exc
        except Exception as exc:
            code = _code(exc)
            if code in _ROLLED_BACK:
                keep = await self._rollback(conn, mode)
                raise _Retry(exc) from exc
            if _lost(exc):
                if committing and mode == "write":
                    raise StoreError(
                        f"connection lost during COMMIT: the change may or may not have been"
                        f" saved ({exc})",
                        outcome="unknown",
                    ) from exc
                raise _Retry(exc) from exc
            keep = await self._rollback(conn, mode)
            if code in _CONSTRAINT and mode == "write":
                raise _Retry(exc, constraint=True) from exc
            raise self._error(exc, "database error") from exc
        finally:
            # Anything else (a cancelled caller above all) may have left a statement half sent
            # or half read: the connection cannot be trusted, so it is closed, which makes the
            # server roll back whatever it had open. The pool drops closed connections.
            if not keep:
                conn.close()
            pool.release(conn)

    @staticmethod
    async def _rollback(conn: asyncmy.Connection, mode: str) -> bool:
        """Roll back; whether the connection is still fit for the pool."""
        if mode == "auto":
            return True
        try:
            await conn.rollback()
        except Exception:
            return False
        return True

    def _error(self, exc: BaseException, what: str) -> StoreError:
        return StoreError(f"{what} on {self.config.describe()}: {exc}", code=_code(exc))

    # -- maintenance ----------------------------------------------------------------------

    async def backup(self, path: str | Path) -> None:
        """A SQLite copy of every row (:func:`serveur.store.mariadb.backup.backup`)."""
        await maintenance.backup(self, path)

    async def replace_with(self, backup: Path) -> None:
        """Every row replaced by the backup's, in one transaction
        (:func:`serveur.store.mariadb.backup.restore`)."""
        await self.open()
        try:
            await maintenance.restore(self, backup)
        finally:
            await self.close()

    async def integrity_check(self) -> str:
        return await maintenance.integrity_check(self)

    # -- migrations -----------------------------------------------------------------------

    async def _migrate(self) -> None:
        """Apply the MariaDB history under ``GET_LOCK``, so two servers starting at once take
        turns instead of running the same DDL together; the second one finds it all applied.

        The lock is per connection and per database name, and MariaDB frees it by itself if
        the connection dies, so a crashed server cannot leave the next start waiting.
        """
        history = load_migrations("mariadb", self.history)
        pool = self._pool
        assert pool is not None
        lock = f"serveur.migrate.{self.config.database}"
        try:
            async with pool.acquire() as conn:
                db = MariaDBTx(conn)
                try:
                    got = await db.one(
                        "SELECT GET_LOCK(?, ?) AS got", (lock, MIGRATION_LOCK_TIMEOUT)
                    )
                    if not got or got["got"] != 1:
                        raise StoreError(
                            f"another server has been migrating {self.config.describe()} for"
                            f" over {MIGRATION_LOCK_TIMEOUT} s"
                        )
                    await self._apply(db, history)
                finally:
                    if conn.connected:
                        await db.all("SELECT RELEASE_LOCK(?)", (lock,))
        except ServeurError:
            raise
        except Exception as exc:
            if _lost(exc) or _code(exc) in _ROLLED_BACK:
                raise _Retry(exc) from exc
            raise self._error(exc, "migration failed") from exc

    async def _apply(self, db: MariaDBTx, history: list[Migration]) -> None:
        # Looked up first rather than CREATE ... IF NOT EXISTS, which needs the CREATE right
        # even when the table exists: a migrated database opens with SELECT/INSERT/UPDATE/
        # DELETE alone, so a site may take the DDL rights back after the upgrade.
        exists = await db.one(
            "SELECT 1 AS yes FROM information_schema.tables"
            " WHERE table_schema = DATABASE() AND table_name = 'schema_migrations'"
        )
        if not exists:
            await self._create_history(db)
        applied = {r["version"] for r in await db.all("SELECT version FROM schema_migrations")}
        unknown = applied - {m.version for m in history}
        if unknown:
            raise StoreError(
                f"{self.config.describe()} has migrations this serveur does not know"
                f" ({sorted(unknown)}): it was written by a newer version",
                versions=sorted(unknown),
            )
        for m in history:
            if m.version in applied:
                continue
            # DDL commits statement by statement; every statement of a MariaDB migration can
            # run again, so a version cut short by a crash is simply applied again.
            for statement in split_statements(m.sql):
                await db.script(statement)
            await db.run(
                "INSERT INTO schema_migrations (version, name, applied_at) VALUES (?, ?, ?)",
                (m.version, m.name, time.time()),
            )

    @staticmethod
    async def _create_history(db: MariaDBTx) -> None:
        await db.script(
            "CREATE TABLE IF NOT EXISTS schema_migrations ("
            " version INT NOT NULL PRIMARY KEY, name VARCHAR(255) NOT NULL,"
            " applied_at DOUBLE NOT NULL"
            ") ENGINE = InnoDB DEFAULT CHARSET = utf8mb4 COLLATE = utf8mb4_nopad_bin"
        )
