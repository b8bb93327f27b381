"""The MariaDB backend of :class:`~serveur.store.base.Store`, for sites outgrowing one SQLite file.

Same answers as :class:`~serveur.store.sqlite.store.SQLiteStore` for every request (the shared test
suite runs against both), the same checks (the validation helpers of :mod:`serveur.store.base`),
the same events, in the same transactions. What differs is how concurrent writers are kept
apart. SQLite has one writer at a time; MariaDB runs transactions side by side, so each
mutation here first locks the rows its checks read (``SELECT ... FOR UPDATE``: a task before
its robot, orders in id order, so that lock orders never cross), then enforces each transition
again with a conditional UPDATE and its row count. Two servers, or many clients of one, can
therefore never put a dish on two trips or give a robot two trips: the loser waits for the
winner's COMMIT, re-reads, and gets the Conflict the SQLite store would give. Connections,
the pool, retries after deadlocks and lost connections, and migrations live in
:mod:`serveur.store.mariadb.db`; each method here is one unit of work, which that module may run
again when it surely did not commit. The trip methods are in :mod:`serveur.store.mariadb.tasks`
and the shared lookups in :mod:`serveur.store.mariadb.rows`.
"""

from __future__ import annotations

import asyncio
import contextlib
import os
import sqlite3
from collections.abc import Awaitable, Callable, Collection, Mapping, Sequence
from pathlib import Path
from typing import Any, TypeVar

from serveur.domain import EventRecord, Order, OrderStatus, Robot, WaypointRecord
from serveur.errors import Conflict, InvalidField, NotFound, StoreError
from serveur.status import RobotMode, RobotStatus
from serveur.store.base import (
    SqlTx,
    check_finite,
    check_new_order,
    check_text,
    link_json,
    status_values,
    to_json,
)
from serveur.store.mariadb.db import Database, MariaDBConfig, Tx
from serveur.store.mariadb.rows import (
    EVENT,
    FOREIGN_KEYS,
    MAX_NAME,
    ORDER,
    ROBOT,
    TABLES,
    WAYPOINT,
    check_name,
    event_record,
    sql_in,
)
from serveur.store.mariadb.tasks import MariaDBTasks
from serveur.store.site import REVIVE_ROBOT, REVIVE_WAYPOINT

__all__ = ["MAX_NAME", "MariaDBStore"]


T = TypeVar("T")


class _PortableTx:
    """:class:`~serveur.store.base.SqlTx` over a MariaDB transaction: ``?`` becomes ``%s``.

    Only for the portable account SQL, which has no ``?`` or ``%`` inside string literals.
    """

    def __init__(self, db: Tx) -> None:
        self._db = db

    @staticmethod
    def _sql(sql: str) -> str:
        return sql.replace("%", "%%").replace("?", "%s")

    async def all(self, sql: str, params: Sequence[Any] = ()) -> list[dict[str, Any]]:
        return await self._db.all(self._sql(sql), params)

    async def run(self, sql: str, params: Sequence[Any] = ()) -> int:
        return await self._db.run(self._sql(sql), params)

    async def insert(self, sql: str, params: Sequence[Any]) -> int:
        return await self._db.insert(self._sql(sql), params)


class MariaDBStore(MariaDBTasks):
    """The store in one MariaDB (or MySQL-compatible Galera) database."""

    def __init__(self, config: MariaDBConfig) -> None:
        self.config = config
        self._db = Database(config)

    @classmethod
    def from_url(cls, url: str, environ: Mapping[str, str] | None = None) -> MariaDBStore:
        """See :meth:`MariaDBConfig.from_url` for the URL and the environment variables."""
        return cls(MariaDBConfig.from_url(url, environ))

    def __repr__(self) -> str:
        return f"MariaDBStore({self.config.describe()!r})"

    @property
    def retries(self) -> int:
        """Transactions re-run so far after a surely-uncommitted failure."""
        return self._db.retries

    async def open(self) -> None:
        await self._db.open()

    async def close(self) -> None:
        await self._db.close()

    # -- robots -------------------------------------------------------------------------

    async def _portable(self, work: Callable[[SqlTx], Awaitable[T]], *, write: bool) -> T:
        async def run(db: Tx) -> T:
            return await work(_PortableTx(db))

        return await (self._db.write(run) if write else self._db.read(run))

    async def add_robot(
        self,
        name: str,
        url: str,
        *,
        home: str | None,
        kinematics: str = "omni",
        link: Mapping[str, str] | None = None,
        now: float,
    ) -> Robot:
        check_name(name, "name")
        check_text(url, "url")
        check_name(kinematics, "kinematics")

        async def work(db: Tx) -> Robot:
            row = await db.one(f"{ROBOT} AND name = %s FOR UPDATE", (name,))
            if row is not None:
                robot = Robot(**row)
                if (robot.url, robot.home, robot.kinematics, robot.link) == (
                    url,
                    home,
                    kinematics,
                    dict(link or {}),
                ):
                    return robot
                raise Conflict(
                    f"a robot named {name!r} exists with another url, home, kinematics or link",
                    robot=name,
                )
            if home is not None:
                await self._waypoint(db, home)
            revive = (url, home, kinematics, link_json(link), now, now, name)
            if not await db.run(REVIVE_ROBOT.replace("?", "%s"), revive):
                await db.run(
                    "INSERT INTO robot_info (name, url, home, kinematics, link, updated_at,"
                    " status_since) VALUES (%s, %s, %s, %s, %s, %s, %s)",
                    (name, url, home, kinematics, link_json(link), now, now),
                )
            data: dict[str, Any] = {"url": url, "home": home, "kinematics": kinematics}
            if link:
                data["link"] = dict(link)
            await self._event(db, "robot.added", now, robot=name, data=data)
            return await self._robot(db, name)

        return await self._db.write(work)

    async def update_robot(
        self,
        name: str,
        *,
        url: str | None = None,
        home: str | None = None,
        link: Mapping[str, str] | None = None,
        now: float | None = None,
    ) -> Robot:
        """Change url and/or home; ``now`` as in :meth:`SQLiteStore.update_robot`."""
        if url is not None:
            check_text(url, "url")
        if home is not None:
            check_text(home, "home")

        async def work(db: Tx) -> Robot:
            robot = await self._robot(db, name, lock=True)
            new_url = robot.url if url is None else url
            new_home = robot.home if home is None else home
            new_link = robot.link if link is None else dict(link)
            if (new_url, new_home, new_link) == (robot.url, robot.home, robot.link):
                return robot
            if new_home is not None and new_home != robot.home:
                await self._waypoint(db, new_home)
            stamp = now
            if stamp is None:
                latest = await db.one("SELECT coalesce(max(ts), 0) AS ts FROM events")
                stamp = float(latest["ts"]) if latest else 0.0
            await db.run(
                "UPDATE robot_info SET url = %s, home = %s, link = %s WHERE name = %s",
                (new_url, new_home, link_json(new_link), name),
            )
            data: dict[str, Any] = {"url": new_url, "home": new_home}
            if new_link != robot.link:
                data["link"] = new_link
            await self._event(db, "robot.updated", float(stamp or 0.0), robot=name, data=data)
            return await self._robot(db, name)

        return await self._db.write(work)

    async def get_robot(self, name: str) -> Robot:
        return await self._db.auto(lambda db: self._robot(db, name))

    async def list_robots(self) -> list[Robot]:
        rows = await self._db.auto(lambda db: db.all(f"{ROBOT} ORDER BY name"))
        return [Robot(**r) for r in rows]

    async def save_robot_state(
        self,
        name: str,
        *,
        status: RobotStatus,
        mode: RobotMode,
        resume: RobotStatus | None,
        last_error: str | None,
        now: float,
        event: str = "robot.status",
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        try:
            values = (
                RobotStatus(status).value,
                RobotMode(mode).value,
                None if resume is None else RobotStatus(resume).value,
            )
        except ValueError as exc:
            raise InvalidField(str(exc), field="status") from exc
        check_name(event, "event")
        payload: dict[str, Any] = {
            "status": values[0],
            "mode": values[1],
            "resume": values[2],
            "last_error": last_error,
        }
        payload.update(data or {})
        to_json(payload)  # refuse bad data before touching the database

        async def work(db: Tx) -> Robot:
            changed = await db.run(
                # status_since first: MariaDB assigns left to right, so it must still see
                # the old status (SQLite always does).
                "UPDATE robot_info SET"
                " status_since = CASE WHEN status = %s THEN status_since ELSE %s END,"
                " status = %s, mode = %s, resume = %s, last_error = %s,"
                " updated_at = %s WHERE name = %s",
                (values[0], now, *values, last_error, now, name),
            )
            if changed != 1:
                raise NotFound(f"no robot named {name!r}", robot=name)
            await self._event(db, event, now, robot=name, data=payload)
            return await self._robot(db, name)

        return await self._db.write(work)

    async def save_robot_pose(
        self, name: str, *, x: float, y: float, yaw: float, battery: float | None, now: float
    ) -> None:
        pose = (check_finite(x, "x"), check_finite(y, "y"), check_finite(yaw, "yaw"))
        if battery is not None and not 0.0 <= check_finite(battery, "battery") <= 1.0:
            raise InvalidField("battery must be between 0 and 1", field="battery")
        # One absolute UPDATE: running it twice is harmless, so even a lost COMMIT may retry.
        changed = await self._db.auto(
            lambda db: db.run(
                "UPDATE robot_info SET x = %s, y = %s, yaw = %s, battery = %s, updated_at = %s"
                " WHERE name = %s",
                (*pose, battery, now, name),
            )
        )
        if changed != 1:
            raise NotFound(f"no robot named {name!r}", robot=name)

    # -- waypoints ----------------------------------------------------------------------

    async def put_waypoint(
        self, wp: WaypointRecord, *, replace: bool = False, now: float
    ) -> WaypointRecord:
        check_name(wp.name, "name")
        for field in ("x", "y", "yaw"):
            check_finite(getattr(wp, field), field)

        async def work(db: Tx) -> WaypointRecord:
            row = await db.one(f"{WAYPOINT} AND name = %s FOR UPDATE", (wp.name,))
            values = (wp.x, wp.y, wp.yaw, wp.kind.value, wp.name)
            if row is None:
                if not await db.run(REVIVE_WAYPOINT.replace("?", "%s"), values):
                    await db.run(
                        "INSERT INTO waypoints (x, y, yaw, kind, name, created_at)"
                        " VALUES (%s, %s, %s, %s, %s, %s)",
                        (*values, now),
                    )
            else:
                existing = WaypointRecord(**row)
                if existing == wp:
                    return existing
                if not replace:
                    raise Conflict(
                        f"waypoint {wp.name!r} exists with another pose or kind",
                        waypoint=wp.name,
                    )
                await db.run(
                    "UPDATE waypoints SET x = %s, y = %s, yaw = %s, kind = %s WHERE name = %s",
                    values,
                )
            data: dict[str, Any] = {"x": wp.x, "y": wp.y, "yaw": wp.yaw, "kind": wp.kind.value}
            data["replaced"] = row is not None
            await self._event(db, "waypoint.saved", now, data={"name": wp.name, **data})
            return await self._waypoint(db, wp.name)

        return await self._db.write(work)

    async def get_waypoint(self, name: str) -> WaypointRecord:
        return await self._db.auto(lambda db: self._waypoint(db, name))

    async def list_waypoints(self) -> list[WaypointRecord]:
        rows = await self._db.auto(lambda db: db.all(f"{WAYPOINT} ORDER BY name"))
        return [WaypointRecord(**r) for r in rows]

    async def delete_waypoint(self, name: str, *, now: float) -> None:
        async def work(db: Tx) -> None:
            # Locked: an order or robot being added for it waits (its foreign key check needs
            # a shared lock on this row), so the counts below cannot miss it.
            await self._waypoint(db, name, lock=True)
            orders = await db.one("SELECT count(*) AS n FROM orders WHERE res_table = %s", (name,))
            n_orders = int(orders["n"]) if orders else 0
            robots = [
                r["name"]
                for r in await db.all("SELECT name FROM robot_info WHERE home = %s", (name,))
            ]
            if n_orders or robots:
                raise Conflict(
                    f"waypoint {name!r} is used by {n_orders} order(s) and as home of"
                    f" {len(robots)} robot(s)",
                    waypoint=name,
                    orders=n_orders,
                    robots=robots,
                )
            await db.run("DELETE FROM waypoints WHERE name = %s", (name,))
            await self._event(db, "waypoint.deleted", now, data={"name": name})

        await self._db.write(work)

    # -- orders -------------------------------------------------------------------------

    async def add_order(
        self,
        dish: str,
        table: str,
        *,
        ready_at: float | None,
        key: str | None = None,
        now: float,
        quantity: int = 1,
        note: str | None = None,
        status: OrderStatus = OrderStatus.PENDING,
    ) -> Order:
        note, ready_at, fingerprint = check_new_order(
            dish, table, ready_at=ready_at, quantity=quantity, note=note, status=status
        )
        if key is not None:
            check_name(key, "key")

        async def work(db: Tx) -> Order:
            if key is not None:
                done = await self._replayed(db, key, "order", fingerprint)
                if done is not None:
                    return await self._order(db, done["order_id"])
            await self._waypoint(db, table)
            order_id = await db.insert(
                "INSERT INTO orders (dish, res_table, `key`, ready_at, status, quantity, note,"
                " ordered_at) VALUES (%s, %s, %s, %s, %s, %s, %s, %s)",
                (dish, table, key, ready_at, status.value, quantity, note, now),
            )
            if key is not None:
                await self._remember(db, key, "order", fingerprint, {"order_id": order_id}, now)
            data = {
                "dish": dish,
                "table": table,
                "key": key,
                "ready_at": ready_at,
                "status": status.value,
                "quantity": quantity,
                "note": note,
            }
            await self._event(db, "order.created", now, order_id=order_id, data=data)
            return await self._order(db, order_id)

        return await self._db.write(work)

    async def get_order(self, order_id: int) -> Order:
        return await self._db.auto(lambda db: self._order(db, order_id))

    async def list_orders(
        self,
        *,
        status: OrderStatus | Collection[OrderStatus] | None = None,
        table: str | None = None,
        task_id: int | None = None,
    ) -> list[Order]:
        where: list[str] = ["1"]
        params: list[Any] = []
        statuses = status_values(status, OrderStatus)
        if statuses is not None:
            where.append(sql_in("status", statuses) if statuses else "0")
            params.extend(statuses)
        if table is not None:
            where.append("res_table = %s")
            params.append(table)
        if task_id is not None:
            where.append("task_num = %s")
            params.append(task_id)
        sql = f"{ORDER} WHERE {' AND '.join(where)} ORDER BY id"
        rows = await self._db.auto(lambda db: db.all(sql, params))
        return [Order(**r) for r in rows]

    async def cart(self, table: str) -> list[Order]:
        async def work(db: Tx) -> list[dict[str, Any]]:
            await self._waypoint(db, table)
            return await db.all(
                f"{ORDER} WHERE res_table = %s AND status IN ('assigned', 'delivered')"
                " ORDER BY ready_at, id",
                (table,),
            )

        return [Order(**r) for r in await self._db.read(work)]

    # -- events -------------------------------------------------------------------------

    async def add_event(
        self,
        kind: str,
        *,
        robot: str | None = None,
        task_id: int | None = None,
        order_id: int | None = None,
        data: Mapping[str, Any] | None = None,
        now: float,
    ) -> EventRecord:
        check_name(kind, "kind")
        to_json(dict(data or {}))

        async def work(db: Tx) -> EventRecord:
            event_id = await self._event(
                db, kind, now, robot=robot, task_id=task_id, order_id=order_id, data=data
            )
            row = await db.one(f"{EVENT} WHERE id = %s", (event_id,))
            assert row is not None
            return event_record(row)

        return await self._db.write(work)

    async def list_events(self, *, since_id: int = 0, limit: int = 1000) -> list[EventRecord]:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")
        rows = await self._db.auto(
            lambda db: db.all(f"{EVENT} WHERE id > %s ORDER BY id LIMIT %s", (since_id, limit))
        )
        return [event_record(r) for r in rows]

    # -- maintenance --------------------------------------------------------------------

    async def backup(self, path: str | Path) -> None:
        """Copy every row, read in one consistent snapshot, into a SQLite file at ``path``.

        The copy is a database the SQLite backend opens as it is (``serveur run --db
        copy.db``): the same schema history, so it can be inspected, served from, or checked
        with :meth:`integrity_check` without a MariaDB server. It is written to ``path.tmp``
        and renamed, so a crash never leaves half a backup where the last good one was. For
        backups of the server itself use ``mariadb-dump --single-transaction`` (docs/mariadb.md).
        """
        from serveur.store.sqlite.store import SQLiteStore

        target = Path(path)
        tmp = target.with_name(target.name + ".tmp")
        try:
            await asyncio.to_thread(tmp.unlink, missing_ok=True)
            async with SQLiteStore(tmp):  # the SQLite schema, from its own migrations
                pass
            columns = await asyncio.to_thread(_sqlite_columns, tmp)

            async def work(db: Tx) -> dict[str, list[dict[str, Any]]]:
                return {
                    table: await db.all(
                        f"SELECT {', '.join(f'`{c}`' for c in columns[table])} FROM {table}"
                    )
                    for table in TABLES
                }

            rows = await self._db.read(work)
            await asyncio.to_thread(_fill_sqlite, tmp, columns, rows)
            await asyncio.to_thread(os.replace, tmp, target)
        except (OSError, sqlite3.Error) as exc:
            raise StoreError(f"backup to {target} failed: {exc}") from exc

    async def integrity_check(self) -> str:
        """``CHECK TABLE`` on every table, and every foreign key checked row by row (they
        only hold while nobody ran with ``foreign_key_checks = 0``)."""

        async def work(db: Tx) -> list[str]:
            problems = [
                f"{r['Table']}: {r['Msg_text']}"
                for r in await db.all(f"CHECK TABLE {', '.join(TABLES)}")
                if (r["Msg_type"], r["Msg_text"]) != ("status", "OK")
            ]
            for table, key, column, parent, parent_key in FOREIGN_KEYS:
                orphans = await db.all(
                    f"SELECT c.{key} AS row_key FROM {table} AS c"
                    f" LEFT JOIN {parent} AS p ON p.{parent_key} = c.{column}"
                    f" WHERE c.{column} IS NOT NULL AND p.{parent_key} IS NULL"
                )
                problems += [
                    f"foreign key: {table} row {r['row_key']} refers to a missing {parent}"
                    for r in orphans
                ]
            return problems

        problems = await self._db.auto(work)
        return "\n".join(problems) if problems else "ok"


def _sqlite_columns(path: Path) -> dict[str, list[str]]:
    with contextlib.closing(sqlite3.connect(path)) as conn:
        return {t: [r[1] for r in conn.execute(f"PRAGMA table_info({t})")] for t in TABLES}


def _fill_sqlite(
    path: Path, columns: Mapping[str, list[str]], rows: Mapping[str, list[dict[str, Any]]]
) -> None:
    with contextlib.closing(sqlite3.connect(path, isolation_level=None)) as conn:
        conn.execute("PRAGMA foreign_keys = OFF")  # robot_info and task refer to each other
        conn.execute("BEGIN")
        for table in TABLES:
            conn.execute(f"DELETE FROM {table}")  # the menu a fresh schema is seeded with
            cols = columns[table]
            names = ", ".join(f'"{c}"' for c in cols)
            conn.executemany(
                f"INSERT INTO {table} ({names}) VALUES ({', '.join('?' * len(cols))})",
                [tuple(r[c] for c in cols) for r in rows[table]],
            )
        problems = conn.execute("PRAGMA foreign_key_check").fetchall()
        if problems:
            conn.execute("ROLLBACK")
            raise sqlite3.IntegrityError(f"the copy breaks foreign keys: {problems[:5]}")
        conn.execute("COMMIT")
        conn.execute("PRAGMA wal_checkpoint(TRUNCATE)")
