"""Trips on SQLite: creating, starting, serving, finishing, cancelling and requeueing tasks.

Part of :class:`~serveur.store.sqlite.store.SQLiteStore` (split out to keep modules short). Every
writer here runs in one ``BEGIN IMMEDIATE`` transaction (``_tx("write")``), so what it read
about a task's stops and orders stays true until it commits; the conditional UPDATEs whose row
counts are checked say so again.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from typing import Any

import aiosqlite

from serveur.domain import StopStatus, Task, TaskStatus
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.base import (
    check_text,
    check_trips,
    plan_stop_order,
    returned_rows,
    status_values,
    trips_fingerprint,
)
from serveur.store.sqlite.rows import SQLiteRows, sql_all, sql_in, sql_insert, sql_run

__all__ = ["SQLiteTasks"]


class SQLiteTasks(SQLiteRows):
    """The task methods of :class:`~serveur.store.sqlite.store.SQLiteStore`."""

    # -- tasks --------------------------------------------------------------------------

    async def create_tasks(
        self,
        trips: Sequence[Sequence[tuple[str, Sequence[int]]]],
        *,
        key: str | None = None,
        fingerprint: str = "",
        now: float,
    ) -> list[Task]:
        if key is not None:
            check_text(key, "key")
        async with self._tx("write") as db:
            if key is not None:
                plan_digest = fingerprint or trips_fingerprint(trips)
                done = await self._replayed(db, key, "tasks", plan_digest)
                if done is not None:
                    ids = done["task_ids"]
                    return await self._tasks(db, sql_in("id", ids), ids)
            plan = check_trips(trips)
            wanted = [oid for trip in plan for _, ids in trip for oid in ids]
            rows = await sql_all(
                db, f"SELECT id, res_table, status FROM orders WHERE {sql_in('id', wanted)}", wanted
            )
            found = {r["id"]: r for r in rows}
            missing = sorted(set(wanted) - set(found))
            if missing:
                raise NotFound(f"no order(s) {missing}", orders=missing)
            misplaced = sorted(
                oid
                for trip in plan
                for table, ids in trip
                for oid in ids
                if found[oid]["res_table"] != table
            )
            if misplaced:
                raise InvalidField(
                    f"order(s) {misplaced} are for another table than their stop",
                    field="trips",
                    orders=misplaced,
                )
            taken = sorted(oid for oid in wanted if found[oid]["status"] != "pending")
            if taken:
                raise Conflict(f"order(s) {taken} are not pending", orders=taken)
            task_ids = [await self._queue_trip(db, trip, now) for trip in plan]
            if key is not None:
                result = {"task_ids": task_ids}
                await self._remember(db, key, "tasks", plan_digest, result, now)
            return await self._tasks(db, sql_in("id", task_ids), task_ids)

    async def _queue_trip(
        self, db: aiosqlite.Connection, trip: list[tuple[str, list[int]]], now: float
    ) -> int:
        task_id = await sql_insert(db, "INSERT INTO task (created_at) VALUES (?)", (now,))
        await db.executemany(
            "INSERT INTO task_stop (task_id, seq, waypoint) VALUES (?, ?, ?)",
            [(task_id, seq, table) for seq, (table, _) in enumerate(trip)],
        )
        ids = [oid for _, stop_ids in trip for oid in stop_ids]
        changed = await sql_run(
            db,
            f"UPDATE orders SET status = 'assigned', task_num = ?"
            f" WHERE {sql_in('id', ids)} AND status = 'pending'",
            (task_id, *ids),
        )
        if changed != len(ids):  # pragma: no cover - checked above in this transaction
            raise Conflict("an order was assigned concurrently", orders=ids)
        stops = [{"table": table, "orders": stop_ids} for table, stop_ids in trip]
        await self._event(db, "task.created", now, task_id=task_id, data={"stops": stops})
        return task_id

    async def get_task(self, task_id: int) -> Task:
        async with self._tx("read") as db:
            return await self._task(db, task_id)

    async def list_tasks(
        self,
        *,
        status: TaskStatus | Collection[TaskStatus] | None = None,
        robot: str | None = None,
    ) -> list[Task]:
        where: list[str] = ["1"]
        params: list[Any] = []
        statuses = status_values(status, TaskStatus)
        if statuses is not None:
            where.append(sql_in("status", statuses))
            params.extend(statuses)
        if robot is not None:
            where.append("robot_name = ?")
            params.append(robot)
        async with self._tx("read") as db:
            return await self._tasks(db, " AND ".join(where), params)

    async def start_task(
        self, task_id: int, robot: str, *, stop_order: Sequence[str] | None = None, now: float
    ) -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            rob = await self._robot(db, robot)
            if task.status is not TaskStatus.QUEUED:
                raise Conflict(
                    f"task {task_id} is {task.status.value}, not queued",
                    task=task_id,
                    status=task.status.value,
                )
            if rob.current_task is not None:
                raise Conflict(
                    f"robot {robot!r} is busy with task {rob.current_task}",
                    robot=robot,
                    task=rob.current_task,
                )
            if stop_order is not None:
                await self._reorder(db, task, stop_order)
            changed = await sql_run(
                db,
                "UPDATE task SET status = 'active', robot_name = ?, started_at = ?"
                " WHERE id = ? AND status = 'queued'",
                (robot, now, task_id),
            )
            if changed == 1:
                changed = await sql_run(
                    db,
                    "UPDATE robot_info SET current_task = ?, updated_at = ?"
                    " WHERE name = ? AND current_task IS NULL",
                    (task_id, now, robot),
                )
            if changed != 1:  # pragma: no cover - checked above in this transaction
                raise Conflict(f"task {task_id} or robot {robot!r} was taken concurrently")
            await sql_run(
                db,
                "UPDATE orders SET dispatched_at = ? WHERE task_num = ? AND status = 'assigned'",
                (now, task_id),
            )
            started = await self._task(db, task_id)
            tables = [s.table for s in started.stops]
            data = {"robot": robot, "stops": tables}
            await self._event(db, "task.started", now, robot=robot, task_id=task_id, data=data)
            return started

    @staticmethod
    async def _reorder(db: aiosqlite.Connection, task: Task, stop_order: Sequence[str]) -> None:
        """Renumber the stops still to serve in ``stop_order``; done stops keep 0..k-1."""
        wanted = plan_stop_order(task, stop_order)
        if wanted is None:
            return
        first, n = task.current_stop, len(task.stops)
        # Out of the way first: (task_id, seq) is the key, so swapping in place would collide.
        await sql_run(
            db,
            "UPDATE task_stop SET seq = seq + ? WHERE task_id = ? AND seq >= ?",
            (n, task.id, first),
        )
        await db.executemany(
            "UPDATE task_stop SET seq = ? WHERE task_id = ? AND waypoint = ?",
            [(first + i, task.id, table) for i, table in enumerate(wanted)],
        )

    async def _active_stop(
        self, db: aiosqlite.Connection, task_id: int, seq: int, action: str
    ) -> tuple[Task, Any]:
        task = await self._task(db, task_id)
        if not 0 <= seq < len(task.stops):
            raise NotFound(f"task {task_id} has no stop {seq}", task=task_id, seq=seq)
        stop = task.stops[seq]
        if task.status is not TaskStatus.ACTIVE:
            raise Conflict(
                f"cannot {action}: task {task_id} is {task.status.value}",
                task=task_id,
                status=task.status.value,
            )
        return task, stop

    async def arrive_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task, stop = await self._active_stop(db, task_id, seq, "arrive")
            if stop.status is StopStatus.ARRIVED:
                return task
            changed = await sql_run(
                db,
                "UPDATE task_stop SET status = 'arrived', arrived_at = ?"
                " WHERE task_id = ? AND seq = ? AND status = 'pending' AND EXISTS"
                " (SELECT 1 FROM task WHERE id = ? AND status = 'active' AND current_stop = ?)",
                (now, task_id, seq, task_id, seq),
            )
            if changed != 1:
                raise Conflict(
                    f"stop {seq} of task {task_id} is {stop.status.value}, and the current stop"
                    f" is {task.current_stop}",
                    task=task_id,
                    seq=seq,
                    status=stop.status.value,
                )
            data = {"seq": seq, "table": stop.table}
            await self._event(db, "stop.arrived", now, robot=task.robot, task_id=task_id, data=data)
            return await self._task(db, task_id)

    async def complete_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task, stop = await self._active_stop(db, task_id, seq, "complete a stop")
            changed = await sql_run(
                db,
                "UPDATE task SET current_stop = current_stop + 1"
                " WHERE id = ? AND status = 'active' AND current_stop = ?",
                (task_id, seq),
            )
            if changed == 1:
                changed = await sql_run(
                    db,
                    "UPDATE task_stop SET status = 'done', done_at = ?"
                    " WHERE task_id = ? AND seq = ? AND status IN ('pending', 'arrived')",
                    (now, task_id, seq),
                )
            if changed != 1:
                raise Conflict(
                    f"stop {seq} of task {task_id} is {stop.status.value}, and the current stop"
                    f" is {task.current_stop}",
                    task=task_id,
                    seq=seq,
                    status=stop.status.value,
                )
            await sql_run(
                db,
                "UPDATE orders SET status = 'delivered', delivered_at = ?"
                " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                (now, task_id, stop.table),
            )
            data = {"seq": seq, "table": stop.table, "orders": stop.orders}
            await self._event(db, "stop.done", now, robot=task.robot, task_id=task_id, data=data)
            return await self._task(db, task_id)

    async def finish_task(self, task_id: int, *, now: float) -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            changed = await sql_run(
                db,
                "UPDATE task SET status = 'done', finished_at = ?"
                " WHERE id = ? AND status = 'active' AND NOT EXISTS"
                " (SELECT 1 FROM task_stop WHERE task_id = ?"
                "  AND status NOT IN ('done', 'skipped'))",
                (now, task_id, task_id),
            )
            if changed != 1:
                left = sum(s.status is not StopStatus.DONE for s in task.stops)
                raise Conflict(
                    f"task {task_id} is {task.status.value} with {left} stop(s) not done",
                    task=task_id,
                    status=task.status.value,
                )
            await self._free_robot(db, task_id, now)
            await self._event(db, "task.finished", now, robot=task.robot, task_id=task_id)
            return await self._task(db, task_id)

    async def cancel_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            returned = [
                r[0]
                for r in await sql_all(
                    db,
                    "SELECT id FROM orders WHERE task_num = ? AND status = 'assigned' ORDER BY id",
                    (task_id,),
                )
            ]
            changed = await sql_run(
                db,
                "UPDATE task SET status = 'cancelled', finished_at = ?"
                " WHERE id = ? AND status IN ('queued', 'active')",
                (now, task_id),
            )
            if changed != 1:
                raise Conflict(
                    f"task {task_id} is {task.status.value}: only a queued or active task can"
                    " be cancelled",
                    task=task_id,
                    status=task.status.value,
                )
            await sql_run(
                db,
                "UPDATE orders SET status = 'pending', task_num = NULL, dispatched_at = NULL"
                " WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await sql_run(
                db,
                "UPDATE task_stop SET status = 'skipped'"
                " WHERE task_id = ? AND status IN ('pending', 'arrived')",
                (task_id,),
            )
            for row in returned_rows(task):
                await sql_run(
                    db, "UPDATE task_stop SET returned = ? WHERE task_id = ? AND seq = ?", row
                )
            await self._free_robot(db, task_id, now)
            data = {"reason": reason, "orders_returned": returned}
            await self._event(
                db, "task.cancelled", now, robot=task.robot, task_id=task_id, data=data
            )
            return await self._task(db, task_id)

    async def requeue_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        async with self._tx("write") as db:
            task = await self._task(db, task_id)
            if task.status is TaskStatus.ACTIVE and task.current_stop >= len(task.stops):
                raise Conflict(
                    f"task {task_id} has every stop done: finish it instead", task=task_id
                )
            changed = await sql_run(
                db,
                "UPDATE task SET status = 'queued', robot_name = NULL, started_at = NULL"
                " WHERE id = ? AND status = 'active'",
                (task_id,),
            )
            if changed != 1:
                raise Conflict(
                    f"task {task_id} is {task.status.value}: only an active task can be requeued",
                    task=task_id,
                    status=task.status.value,
                )
            await sql_run(
                db,
                "UPDATE task_stop SET status = 'pending', arrived_at = NULL"
                " WHERE task_id = ? AND status = 'arrived'",
                (task_id,),
            )
            await sql_run(
                db,
                "UPDATE orders SET dispatched_at = NULL WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await self._free_robot(db, task_id, now)
            data = {"reason": reason, "robot": task.robot}
            await self._event(
                db, "task.requeued", now, robot=task.robot, task_id=task_id, data=data
            )
            return await self._task(db, task_id)
