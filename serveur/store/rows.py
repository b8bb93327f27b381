"""The rows every part of the store reads and writes: the records' SELECTs, the lookups a unit
of work starts from, the ``events`` row each change appends, idempotency keys.

Written once for every backend (:mod:`serveur.store.sql`). A lookup with ``lock=True`` reads
``FOR UPDATE`` where the dialect has row locks: that is how a MariaDB writer keeps what it
checked true until COMMIT (parents before children: task, then robot, then orders, so lock
orders never cross). On SQLite the write transaction already holds the whole database.
"""

from __future__ import annotations

import json
from collections.abc import Mapping, Sequence
from typing import Any, Final

from serveur.domain import EventRecord, Order, Robot, Stop, Task, WaypointRecord
from serveur.errors import Conflict, NotFound
from serveur.store.checks import to_json
from serveur.store.live import ROBOT, ROBOT_NAMED, WAYPOINT, WAYPOINT_NAMED
from serveur.store.sql import Tx, one

__all__ = [
    "EVENT",
    "ORDER",
    "ROBOT",
    "TASK",
    "WAYPOINT",
    "add_event",
    "event_record",
    "free_robot",
    "get_order",
    "get_robot",
    "get_settings",
    "get_task",
    "get_tasks",
    "get_waypoint",
    "put_setting",
    "remember",
    "replayed",
    "revoke_where",
]

ORDER: Final = (
    "SELECT id, dish, res_table AS `table`, status, task_num AS task_id, `key`, ready_at,"
    " dispatched_at, delivered_at, quantity, note, ordered_at, returned_at, voided_at, special,"
    " tray, ticket_id AS ticket FROM orders"
)
EVENT: Final = "SELECT id, ts, kind, robot, task_id, order_id, data FROM events"
TASK: Final = (
    "SELECT id, robot_name AS robot, kind, status, current_stop, created_at, started_at,"
    " finished_at FROM task"
)
# A stop's dishes are the trip's orders for its table (see 001_init), and those it carried
# before it was skipped (returned, 008): gathered per stop in the same query, so a task list
# costs two statements whatever its size.
_STOPS = (
    "SELECT s.task_id, s.seq, s.waypoint AS `table`, s.status, s.purpose, s.arrived_at,"
    " s.done_at,"
    " s.returned, (SELECT {ids}(o.id) FROM orders AS o"
    "   WHERE o.task_num = s.task_id AND o.res_table = s.waypoint) AS orders"
    " FROM task_stop AS s WHERE s.task_id IN (SELECT id FROM task WHERE {where})"
    " ORDER BY s.task_id, s.seq"
)


def event_record(row: Mapping[str, Any]) -> EventRecord:
    fields = dict(row)
    fields["data"] = json.loads(fields["data"])
    return EventRecord(**fields)


async def add_event(
    tx: Tx,
    kind: str,
    now: float,
    *,
    robot: str | None = None,
    task_id: int | None = None,
    order_id: int | None = None,
    data: Mapping[str, Any] | None = None,
) -> int:
    """Append the ``events`` row of a change, in the change's own transaction; its id.

    The event also takes the site's next outbox number here (migration 013), in the same
    transaction: committed together or not at all, so the chain's centre receives every
    event and can tell a missing one by the gap. Bumping ``outbox_state.head`` first locks
    its row (MariaDB) or holds the write lock (SQLite): numbers follow commit order.
    """
    event_id = await tx.insert(
        "INSERT INTO events (ts, kind, robot, task_id, order_id, data) VALUES (?, ?, ?, ?, ?, ?)",
        (now, kind, robot, task_id, order_id, to_json(dict(data or {}))),
    )
    await tx.run("UPDATE outbox_state SET head = head + 1 WHERE id = 1")
    head = await one(tx, "SELECT head FROM outbox_state WHERE id = 1")
    assert head is not None, "migration 013 writes outbox_state's row"
    await tx.run(
        "INSERT INTO outbox (seq, event_id, at) VALUES (?, ?, ?)", (head["head"], event_id, now)
    )
    return event_id


async def get_robot(tx: Tx, name: str, *, lock: bool = False) -> Robot:
    row = await one(tx, f"{ROBOT_NAMED}{tx.dialect.for_update if lock else ''}", (name,))
    if row is None:
        raise NotFound(f"no robot named {name!r}", robot=name)
    return Robot(**row)


async def get_waypoint(tx: Tx, name: str, *, lock: bool = False) -> WaypointRecord:
    row = await one(tx, f"{WAYPOINT_NAMED}{tx.dialect.for_update if lock else ''}", (name,))
    if row is None:
        raise NotFound(f"no waypoint named {name!r}", waypoint=name)
    return WaypointRecord(**row)


async def get_order(tx: Tx, order_id: int) -> Order:
    row = await one(tx, f"{ORDER} WHERE id = ?", (order_id,))
    if row is None:
        raise NotFound(f"no order {order_id}", order=order_id)
    return Order(**row)


async def get_tasks(tx: Tx, where: str, params: Sequence[Any] = ()) -> list[Task]:
    """Tasks matching ``where`` (on ``task``), by id, with their stops and each stop's order
    ids (those it carried before it was skipped included, migration 008)."""
    tasks = await tx.all(f"{TASK} WHERE {where} ORDER BY id", params)
    if not tasks:
        return []
    stops: dict[int, list[Stop]] = {}
    for stop in await tx.all(_STOPS.format(ids=tx.dialect.json_ids, where=where), params):
        carried = {*json.loads(stop.pop("orders") or "[]"), *json.loads(stop.pop("returned"))}
        stops.setdefault(stop.pop("task_id"), []).append(Stop(**stop, orders=sorted(carried)))
    return [Task(**t, stops=stops.get(t["id"], [])) for t in tasks]


async def get_task(tx: Tx, task_id: int, *, lock: bool = False) -> Task:
    """The task; with ``lock``, its row is locked first, which every writer of a task's
    stops and orders does, so what is read next stays true until COMMIT."""
    if lock and tx.dialect.row_locks:
        await tx.all("SELECT id FROM task WHERE id = ? FOR UPDATE", (task_id,))
    found = await get_tasks(tx, "id = ?", (task_id,))
    if not found:
        raise NotFound(f"no task {task_id}", task=task_id)
    return found[0]


async def replayed(tx: Tx, key: str, kind: str, fingerprint: str) -> dict[str, Any] | None:
    """The stored result of an earlier request with ``key``; Conflict if it differed.

    Two first sends racing on MariaDB both find no row; the loser's INSERT of the key then
    hits the primary key, and its re-run finds the winner's result here.
    """
    row = await one(
        tx,
        "SELECT kind, fingerprint, result FROM idempotency WHERE `key` = ?" + tx.dialect.for_update,
        (key,),
    )
    if row is None:
        return None
    if row["kind"] != kind or row["fingerprint"] != fingerprint:
        raise Conflict(f"key {key!r} was already used for another request", key=key)
    result: dict[str, Any] = json.loads(row["result"])
    return result


async def remember(
    tx: Tx, key: str, kind: str, fingerprint: str, result: Mapping[str, Any], now: float
) -> None:
    await tx.run(
        "INSERT INTO idempotency (`key`, kind, fingerprint, result, created_at)"
        " VALUES (?, ?, ?, ?, ?)",
        (key, kind, fingerprint, to_json(dict(result)), now),
    )


async def get_settings(tx: Tx, table: str) -> dict[str, Any]:
    """Every named setting of ``table`` (``settings``, ``till_setting``): name -> value."""
    saved = await tx.all(f"SELECT name, value FROM {table} ORDER BY name")
    return {str(r["name"]): json.loads(r["value"]) for r in saved}


async def put_setting(
    tx: Tx, table: str, name: str, value: Any, now: float, by: str | None
) -> None:
    """One named setting of ``table`` (``settings``, ``till_setting``: name, value as JSON,
    updated_at, updated_by) written, whether it had a row or not."""
    body = json.dumps(value, separators=(",", ":"), ensure_ascii=False)
    if not await tx.run(
        f"UPDATE {table} SET value = ?, updated_at = ?, updated_by = ? WHERE name = ?",
        (body, now, by, name),
    ):
        await tx.run(
            f"INSERT INTO {table} (name, value, updated_at, updated_by) VALUES (?, ?, ?, ?)",
            (name, body, now, by),
        )


async def free_robot(tx: Tx, task_id: int, now: float) -> None:
    await tx.run(
        "UPDATE robot_info SET current_task = NULL, updated_at = ? WHERE current_task = ?",
        (now, task_id),
    )


async def revoke_where(tx: Tx, where: str, params: Sequence[Any], now: float) -> list[int]:
    """Revoke the live tokens matching ``where``; their ids."""
    rows = await tx.all(f"SELECT id FROM tokens WHERE revoked_at IS NULL AND {where}", params)
    ids = [int(r["id"]) for r in rows]
    if ids:
        await tx.run(
            f"UPDATE tokens SET revoked_at = ? WHERE revoked_at IS NULL AND {where}",
            (now, *params),
        )
    return ids
