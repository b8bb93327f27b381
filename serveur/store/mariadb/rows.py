"""Rows of the MariaDB store: the SELECTs, the lookups every unit of work starts from, the
event and idempotency-key writes. Shared by :mod:`serveur.store.mariadb.store` (robots, waypoints,
orders, events, maintenance) and :mod:`serveur.store.mariadb.tasks` (trips), which are split
only to keep each module readable; :class:`MariaDBRows` is their common base.

Every lookup takes the unit of work's :class:`~serveur.store.mariadb.db.Tx`; ``lock=True`` reads
with ``FOR UPDATE``, which is how a writer makes what it checked stay true until COMMIT.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any

from serveur.domain import EventRecord, Order, Robot, Stop, Task, WaypointRecord
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.base import Store, check_text, to_json
from serveur.store.live import ROBOT, WAYPOINT
from serveur.store.mariadb.db import Database, Tx

__all__ = [
    "EVENT",
    "FOREIGN_KEYS",
    "MAX_NAME",
    "ORDER",
    "ROBOT",
    "TABLES",
    "TASK",
    "WAYPOINT",
    "MariaDBRows",
    "check_name",
    "event_record",
    "sql_in",
]

#: Names, tables, keys and event kinds are VARCHAR(255): longer ones are refused up front.
MAX_NAME = 255

ORDER = (
    "SELECT id, dish, res_table AS `table`, status, task_num AS task_id, `key`, ready_at,"
    " dispatched_at, delivered_at, quantity, note, ordered_at, returned_at, voided_at FROM orders"
)
EVENT = "SELECT id, ts, kind, robot, task_id, order_id, data FROM events"
TASK = (
    "SELECT id, robot_name AS robot, status, current_stop, created_at, started_at, finished_at"
    " FROM task"
)
# Tables in parent-before-child order, as the SQLite schema has them (for backups).
TABLES = (
    "waypoints",
    "robot_info",
    "task",
    "task_stop",
    "idempotency",
    "orders",
    "events",
    "menu",
    "table_block",
    "settings",
    "zones",
)
# Every foreign key, as (table, its key, column, parent table, parent key), for the check.
FOREIGN_KEYS = (
    ("robot_info", "name", "home", "waypoints", "name"),
    ("robot_info", "name", "current_task", "task", "id"),
    ("task", "id", "robot_name", "robot_info", "name"),
    ("task_stop", "task_id", "task_id", "task", "id"),
    ("task_stop", "task_id", "waypoint", "waypoints", "name"),
    ("orders", "id", "res_table", "waypoints", "name"),
    ("orders", "id", "task_num", "task", "id"),
    ("table_block", "waypoint", "waypoint", "waypoints", "name"),
)


def sql_in(column: str, values: Sequence[object]) -> str:
    return f"{column} IN ({', '.join(['%s'] * len(values))})"


def check_name(value: object, field: str) -> str:
    text = check_text(value, field)
    if len(text) > MAX_NAME:
        raise InvalidField(f"{field} is longer than {MAX_NAME} characters", field=field)
    return text


def event_record(row: Mapping[str, Any]) -> EventRecord:
    fields = dict(row)
    fields["data"] = json.loads(fields["data"])
    return EventRecord(**fields)


class MariaDBRows(Store):
    """The lookups and row writes shared by the MariaDB store's modules (abstract)."""

    _db: Database

    async def _event(
        self,
        db: Tx,
        kind: str,
        now: float,
        *,
        robot: str | None = None,
        task_id: int | None = None,
        order_id: int | None = None,
        data: Mapping[str, Any] | None = None,
    ) -> int:
        return await db.insert(
            "INSERT INTO events (ts, kind, robot, task_id, order_id, data)"
            " VALUES (%s, %s, %s, %s, %s, %s)",
            (now, kind, robot, task_id, order_id, to_json(dict(data or {}))),
        )

    # -- lookups used inside transactions ------------------------------------------------

    @staticmethod
    async def _robot(db: Tx, name: str, *, lock: bool = False) -> Robot:
        row = await db.one(f"{ROBOT} AND name = %s{' FOR UPDATE' if lock else ''}", (name,))
        if row is None:
            raise NotFound(f"no robot named {name!r}", robot=name)
        return Robot(**row)

    @staticmethod
    async def _waypoint(db: Tx, name: str, *, lock: bool = False) -> WaypointRecord:
        sql = f"{WAYPOINT} AND name = %s{' FOR UPDATE' if lock else ''}"
        row = await db.one(sql, (name,))
        if row is None:
            raise NotFound(f"no waypoint named {name!r}", waypoint=name)
        return WaypointRecord(**row)

    @staticmethod
    async def _order(db: Tx, order_id: int, *, lock: bool = False) -> Order:
        row = await db.one(f"{ORDER} WHERE id = %s{' FOR UPDATE' if lock else ''}", (order_id,))
        if row is None:
            raise NotFound(f"no order {order_id}", order=order_id)
        return Order(**row)

    @staticmethod
    async def _tasks(db: Tx, where: str, params: Sequence[Any] = ()) -> list[Task]:
        """Tasks with their stops and each stop's order ids (those it carried before it was
        skipped included, migration 008): three statements in all."""
        tasks = await db.all(f"{TASK} WHERE {where} ORDER BY id", params)
        if not tasks:
            return []
        ids = [t["id"] for t in tasks]
        stops = await db.all(
            "SELECT task_id, seq, waypoint AS `table`, status, arrived_at, done_at, returned"
            f" FROM task_stop WHERE {sql_in('task_id', ids)} ORDER BY task_id, seq",
            ids,
        )
        dishes: dict[tuple[int, str], list[int]] = {}
        in_tasks = sql_in("task_num", ids)
        for row in await db.all(
            f"SELECT task_num, res_table, id FROM orders WHERE {in_tasks} ORDER BY id", ids
        ):
            dishes.setdefault((row["task_num"], row["res_table"]), []).append(row["id"])
        by_task: dict[int, list[Stop]] = {}
        for stop in stops:
            task_id = stop.pop("task_id")
            carried = {*dishes.get((task_id, stop["table"]), []), *json.loads(stop.pop("returned"))}
            stop["orders"] = sorted(carried)
            by_task.setdefault(task_id, []).append(Stop(**stop))
        return [Task(**t, stops=by_task.get(t["id"], [])) for t in tasks]

    async def _task(self, db: Tx, task_id: int, *, lock: bool = False) -> Task:
        """The task; with ``lock``, its row is locked first, which every writer of a task's
        stops and orders does, so what is read next stays true until COMMIT."""
        if lock and not await db.one("SELECT id FROM task WHERE id = %s FOR UPDATE", (task_id,)):
            raise NotFound(f"no task {task_id}", task=task_id)
        found = await self._tasks(db, "id = %s", (task_id,))
        if not found:
            raise NotFound(f"no task {task_id}", task=task_id)
        return found[0]

    @staticmethod
    async def _replayed(db: Tx, key: str, kind: str, fingerprint: str) -> dict[str, Any] | None:
        """The stored result of an earlier request with ``key``; Conflict if it differed.

        Two first sends racing both find no row; the loser's INSERT of the key then hits the
        primary key, and its re-run finds the winner's result here.
        """
        row = await db.one(
            "SELECT kind, fingerprint, result FROM idempotency WHERE `key` = %s FOR UPDATE",
            (key,),
        )
        if row is None:
            return None
        if row["kind"] != kind or row["fingerprint"] != fingerprint:
            raise Conflict(f"key {key!r} was already used for another request", key=key)
        result: dict[str, Any] = json.loads(row["result"])
        return result

    @staticmethod
    async def _remember(
        db: Tx, key: str, kind: str, fingerprint: str, result: Mapping[str, Any], now: float
    ) -> None:
        await db.run(
            "INSERT INTO idempotency (`key`, kind, fingerprint, result, created_at)"
            " VALUES (%s, %s, %s, %s, %s)",
            (key, kind, fingerprint, to_json(dict(result)), now),
        )

    @staticmethod
    async def _free_robot(db: Tx, task_id: int, now: float) -> None:
        await db.run(
            "UPDATE robot_info SET current_task = NULL, updated_at = %s WHERE current_task = %s",
            (now, task_id),
        )
