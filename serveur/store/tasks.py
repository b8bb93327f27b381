"""Trips: creating, starting, serving, skipping, finishing, cancelling and requeueing tasks. One
part of :class:`~serveur.store.base.Store`, written once for every backend.

Each writer here is one ``write`` unit of work that reads the task with ``lock=True`` first
(then the robot, then the orders in id order: one lock order for all, so concurrent trips
queue on MariaDB instead of deadlocking; SQLite's write transaction holds the whole file), so
what it read about a task's stops and orders stays true until it commits; the conditional
UPDATEs whose row counts are checked say so again. A dish is on at most one trip, a robot has
at most one trip, "food collected" counts once.
"""

from __future__ import annotations

import json
from collections.abc import Collection, Mapping, Sequence
from typing import Any

from serveur.domain import Stop, StopStatus, Task, TaskStatus
from serveur.errors import Conflict, InvalidField, NotFound, Stale
from serveur.status import RobotStatus
from serveur.store import rows
from serveur.store.checks import (
    check_trips,
    plan_stop_order,
    returned_rows,
    status_values,
    trips_fingerprint,
)
from serveur.store.sql import Db, Tx, one, sql_in

__all__ = ["Tasks"]


async def _lock_orders(tx: Tx, wanted: Sequence[int]) -> dict[int, dict[str, Any]]:
    """The orders' rows (id, res_table, status) by id, locked; NotFound names the missing.

    Locked in id order: a concurrent caller wanting some of these dishes waits here for our
    COMMIT, then finds them assigned (and two callers never lock crosswise).
    """
    locked = await tx.all(
        f"SELECT id, res_table, status FROM orders WHERE {sql_in('id', wanted)}"
        " ORDER BY id" + tx.dialect.for_update,
        list(wanted),
    )
    found = {r["id"]: r for r in locked}
    missing = sorted(set(wanted) - set(found))
    if missing:
        raise NotFound(f"no order(s) {missing}", orders=missing)
    return found


class Tasks:
    """Trip methods of the store (``store.tasks``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def create_tasks(
        self,
        trips: Sequence[Sequence[tuple[str, Sequence[int]]]],
        *,
        key: str | None = None,
        fingerprint: str = "",
        now: float,
        trays: Mapping[int, int] | None = None,
    ) -> list[Task]:
        """Queue trips (each: stops in visiting order as ``(table, order ids)``) atomically;
        ``trays`` puts dishes (by id) on the trays staff chose.

        All or nothing: one missing, non-pending, repeated or misplaced order and no trip is
        created. With ``key``, a resend with the same ``fingerprint`` (the caller's digest of
        the request; the trips' own digest when empty) returns the tasks it created, in their
        current state, without looking at ``trips``: on a resend the dishes are no longer
        pending, so the scheduler's new split cannot be compared with the first one.
        """
        if key is not None:
            self._db.dialect.check_name(key, "key")
        plan_digest = (fingerprint or trips_fingerprint(trips)) if key is not None else ""

        async def work(tx: Tx) -> list[Task]:
            if key is not None:
                done = await rows.replayed(tx, key, "tasks", plan_digest)
                if done is not None:
                    ids = done["task_ids"]
                    return await rows.get_tasks(tx, sql_in("id", ids), ids)
            plan = check_trips(trips)
            wanted = [oid for trip in plan for _, ids in trip for oid in ids]
            found = await _lock_orders(tx, wanted)
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
            task_ids = [await self._queue_trip(tx, trip, now) for trip in plan]
            if trays:
                # The request's trays name only its own dishes (checked with the message): one
                # not planned was left out as no longer pending (a cart resent under a new key).
                gone = sorted(set(trays) - set(wanted))
                if gone:
                    raise Conflict(f"order(s) {gone} are not pending", orders=gone)
                await tx.many(
                    "UPDATE orders SET tray = ? WHERE id = ?",
                    [(tray, oid) for oid, tray in sorted(trays.items())],
                )
            if key is not None:
                await rows.remember(tx, key, "tasks", plan_digest, {"task_ids": task_ids}, now)
            return await rows.get_tasks(tx, sql_in("id", task_ids), task_ids)

        return await self._db.transact(work, "write")

    async def _queue_trip(self, tx: Tx, trip: list[tuple[str, list[int]]], now: float) -> int:
        task_id = await tx.insert("INSERT INTO task (created_at) VALUES (?)", (now,))
        await tx.many(
            "INSERT INTO task_stop (task_id, seq, waypoint) VALUES (?, ?, ?)",
            [(task_id, seq, table) for seq, (table, _) in enumerate(trip)],
        )
        ids = [oid for _, stop_ids in trip for oid in stop_ids]
        changed = await tx.run(
            f"UPDATE orders SET status = 'assigned', task_num = ?"
            f" WHERE {sql_in('id', ids)} AND status = 'pending'",
            (task_id, *ids),
        )
        if changed != len(ids):  # pragma: no cover - locked and checked in this transaction
            raise Conflict("an order was assigned concurrently", orders=ids)
        stops = [{"table": table, "orders": stop_ids} for table, stop_ids in trip]
        await rows.add_event(tx, "task.created", now, task_id=task_id, data={"stops": stops})
        return task_id

    async def add_to_task(
        self,
        task_id: int,
        orders: Sequence[int],
        *,
        key: str | None = None,
        fingerprint: str,
        now: float,
    ) -> Task:
        """Put pending dishes on a trip still at the pass, each at its table's stop.

        The plate that comes out while its table's robot is being loaded goes on that robot,
        as a waiter would put it: otherwise it waits for the robot to come back, since two
        robots cannot stand at one table. The trip must not have left: ``queued``, or taken by
        a robot still ``Loading`` (the caller holds that robot's lock; its persisted status is
        checked again here) — else :class:`Stale`, with the trip and where it is. Every dish
        must be pending (``Conflict``) and for a table the trip already serves
        (``InvalidField``): stops, trays and their order do not change. All or nothing; a
        keyed resend gets the trip as it is now.
        """
        if key is not None:
            self._db.dialect.check_name(key, "key")

        async def work(tx: Tx) -> Task:
            if key is not None:
                done = await rows.replayed(tx, key, "tasks", fingerprint)
                if done is not None:
                    return await rows.get_task(tx, done["task_ids"][0])
            task = await rows.get_task(tx, task_id, lock=True)
            where = task.status.value
            at_pass = task.status is TaskStatus.QUEUED
            if task.status is TaskStatus.ACTIVE and task.robot is not None:
                robot = await rows.get_robot(tx, task.robot, lock=True)
                where = robot.status.value
                first = task.stops[0].status if task.stops else None
                at_pass = robot.status is RobotStatus.LOADING and first is StopStatus.PENDING
            if not at_pass:
                raise Stale(
                    f"trip {task_id} has left the pass ({where})",
                    task=task_id,
                    robot=task.robot,
                    status=where,
                )
            wanted = sorted(set(orders))
            found = await _lock_orders(tx, wanted)
            tables = sorted({s.table for s in task.stops})
            elsewhere = [oid for oid in wanted if found[oid]["res_table"] not in tables]
            if elsewhere:
                raise InvalidField(
                    f"order(s) {elsewhere} are for a table trip {task_id} does not serve",
                    field="orders",
                    orders=elsewhere,
                    tables=tables,
                )
            taken = [oid for oid in wanted if found[oid]["status"] != "pending"]
            if taken:
                raise Conflict(f"order(s) {taken} are not pending", orders=taken)
            started = now if task.status is TaskStatus.ACTIVE else None
            changed = await tx.run(
                f"UPDATE orders SET status = 'assigned', task_num = ?, dispatched_at = ?"
                f" WHERE {sql_in('id', wanted)} AND status = 'pending'",
                (task_id, started, *wanted),
            )
            if changed != len(wanted):  # pragma: no cover - locked and checked in this tx
                raise Conflict("an order was assigned concurrently", orders=wanted)
            data = {"orders": wanted}
            await rows.add_event(
                tx, "task.dishes_added", now, robot=task.robot, task_id=task_id, data=data
            )
            if key is not None:
                await rows.remember(tx, key, "tasks", fingerprint, {"task_ids": [task_id]}, now)
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def get_task(self, task_id: int) -> Task:
        """A task with its stops and each stop's order ids."""
        return await self._db.transact(lambda tx: rows.get_task(tx, task_id), "read")

    async def list_tasks(
        self,
        *,
        status: TaskStatus | Collection[TaskStatus] | None = None,
        robot: str | None = None,
    ) -> list[Task]:
        """Tasks matching every given filter, by id."""
        where: list[str] = ["1"]
        params: list[Any] = []
        statuses = status_values(status, TaskStatus)
        if statuses is not None:
            where.append(sql_in("status", statuses) if statuses else "0")
            params.extend(statuses)
        if robot is not None:
            where.append("robot_name = ?")
            params.append(robot)
        return await self._db.transact(
            lambda tx: rows.get_tasks(tx, " AND ".join(where), params), "read"
        )

    async def start_task(
        self, task_id: int, robot: str, *, stop_order: Sequence[str] | None = None, now: float
    ) -> Task:
        """Give a queued task to an idle robot; exactly one of concurrent callers wins.

        ``stop_order`` reorders the stops still to serve (the planner's shortest tour): the
        tables of those stops, or of all stops (stops already done keep their place).
        """

        async def work(tx: Tx) -> Task:
            task = await rows.get_task(tx, task_id, lock=True)
            rob = await rows.get_robot(tx, robot, lock=True)
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
                await self._reorder(tx, task, stop_order)
            changed = await tx.run(
                "UPDATE task SET status = 'active', robot_name = ?, started_at = ?"
                " WHERE id = ? AND status = 'queued'",
                (robot, now, task_id),
            )
            if changed == 1:
                changed = await tx.run(
                    "UPDATE robot_info SET current_task = ?, updated_at = ?"
                    " WHERE name = ? AND current_task IS NULL",
                    (task_id, now, robot),
                )
            if changed != 1:  # pragma: no cover - locked and checked in this transaction
                raise Conflict(f"task {task_id} or robot {robot!r} was taken concurrently")
            await tx.run(
                "UPDATE orders SET dispatched_at = ? WHERE task_num = ? AND status = 'assigned'",
                (now, task_id),
            )
            started = await rows.get_task(tx, task_id)
            data = {"robot": robot, "stops": [s.table for s in started.stops]}
            await rows.add_event(tx, "task.started", now, robot=robot, task_id=task_id, data=data)
            return started

        return await self._db.transact(work, "write")

    @staticmethod
    async def _reorder(tx: Tx, task: Task, stop_order: Sequence[str]) -> None:
        """Renumber the stops still to serve in ``stop_order``; done stops keep 0..k-1."""
        wanted = plan_stop_order(task, stop_order)
        if wanted is None:
            return
        first, n = task.current_stop, len(task.stops)
        # Out of the way first: (task_id, seq) is the key, so swapping in place would collide.
        await tx.run(
            "UPDATE task_stop SET seq = seq + ? WHERE task_id = ? AND seq >= ?",
            (n, task.id, first),
        )
        await tx.many(
            "UPDATE task_stop SET seq = ? WHERE task_id = ? AND waypoint = ?",
            [(first + i, task.id, table) for i, table in enumerate(wanted)],
        )

    async def _active_stop(self, tx: Tx, task_id: int, seq: int, action: str) -> tuple[Task, Stop]:
        task = await rows.get_task(tx, task_id, lock=True)
        if not 0 <= seq < len(task.stops):
            raise NotFound(f"task {task_id} has no stop {seq}", task=task_id, seq=seq)
        if task.status is not TaskStatus.ACTIVE:
            raise Conflict(
                f"cannot {action}: task {task_id} is {task.status.value}",
                task=task_id,
                status=task.status.value,
            )
        return task, task.stops[seq]

    async def arrive_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        """The robot reached the current stop (pending -> arrived; a repeat is a no-op)."""

        async def work(tx: Tx) -> Task:
            task, stop = await self._active_stop(tx, task_id, seq, "arrive")
            if stop.status is StopStatus.ARRIVED:
                return task
            changed = await tx.run(
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
            await rows.add_event(
                tx, "stop.arrived", now, robot=task.robot, task_id=task_id, data=data
            )
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def complete_stop(
        self, task_id: int, seq: int, *, now: float, timed_out: bool = False
    ) -> Task:
        """Food collected at the current stop: its orders are delivered, the trip moves on.
        ``timed_out``: nobody pressed Done, the stop's own wait ran out (collecting plates, a
        cruise's pause): the event says so."""

        async def work(tx: Tx) -> Task:
            task, stop = await self._active_stop(tx, task_id, seq, "complete a stop")
            changed = await tx.run(
                "UPDATE task SET current_stop = current_stop + 1"
                " WHERE id = ? AND status = 'active' AND current_stop = ?",
                (task_id, seq),
            )
            if changed == 1:
                changed = await tx.run(
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
            await tx.run(
                "UPDATE orders SET status = 'delivered', delivered_at = ?"
                " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                (now, task_id, stop.table),
            )
            data: dict[str, Any] = {"seq": seq, "table": stop.table, "orders": stop.orders}
            if timed_out:
                data["timed_out"] = True
            await rows.add_event(tx, "stop.done", now, robot=task.robot, task_id=task_id, data=data)
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def skip_stop(
        self, task_id: int, seq: int, *, now: float, reason: str, by: str | None = None
    ) -> Task:
        """The robot leaves the current stop unserved (staff's skip, or the table's timeout):
        the stop is ``skipped``, its dishes ``returned`` (they go back to the pass, off the
        trip, for staff to send again or void), and the trip moves on to its next stop."""

        async def work(tx: Tx) -> None:
            task = await one(
                tx, "SELECT robot_name, status, current_stop FROM task WHERE id = ?", (task_id,)
            )
            if task is None:
                raise NotFound(f"no task {task_id}", task=task_id)
            stop = await one(
                tx,
                "SELECT waypoint, status FROM task_stop WHERE task_id = ? AND seq = ?",
                (task_id, seq),
            )
            if (
                task["status"] != "active"
                or task["current_stop"] != seq
                or stop is None
                or stop["status"] not in ("pending", "arrived")
            ):
                raise Conflict(
                    f"stop {seq} of task {task_id} is not the one being served",
                    task=task_id,
                    seq=seq,
                    status=None if stop is None else stop["status"],
                )
            moved = await tx.run(
                "UPDATE task SET current_stop = current_stop + 1"
                " WHERE id = ? AND status = 'active' AND current_stop = ?",
                (task_id, seq),
            )
            if moved != 1:
                raise Conflict(f"task {task_id} moved on meanwhile", task=task_id, seq=seq)
            table = stop["waypoint"]
            returned = [
                r["id"]
                for r in await tx.all(
                    "SELECT id FROM orders WHERE task_num = ? AND res_table = ?"
                    " AND status = 'assigned' ORDER BY id",
                    (task_id, table),
                )
            ]
            # The stop keeps the ids of what it carried (migration 008), the dishes leave.
            await tx.run(
                "UPDATE task_stop SET status = 'skipped', done_at = ?, returned = ?"
                " WHERE task_id = ? AND seq = ?",
                (now, json.dumps(returned), task_id, seq),
            )
            await tx.run(
                "UPDATE orders SET status = 'returned', task_num = NULL, returned_at = ?"
                " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                (now, task_id, table),
            )
            data = {"seq": seq, "table": table, "orders": returned, "reason": reason, "by": by}
            await rows.add_event(
                tx, "stop.skipped", now, robot=task["robot_name"], task_id=task_id, data=data
            )

        await self._db.transact(work, "write")
        return await self.get_task(task_id)

    async def finish_task(self, task_id: int, *, now: float) -> Task:
        """Close an active task whose stops are all done and free its robot."""

        async def work(tx: Tx) -> Task:
            task = await rows.get_task(tx, task_id, lock=True)
            changed = await tx.run(
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
            await rows.free_robot(tx, task_id, now)
            await rows.add_event(tx, "task.finished", now, robot=task.robot, task_id=task_id)
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def cancel_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        """Cancel a queued or active task: undelivered orders go back to pending."""

        async def work(tx: Tx) -> Task:
            task = await rows.get_task(tx, task_id, lock=True)
            returned = [
                r["id"]
                for r in await tx.all(
                    "SELECT id FROM orders WHERE task_num = ? AND status = 'assigned'"
                    " ORDER BY id" + tx.dialect.for_update,
                    (task_id,),
                )
            ]
            changed = await tx.run(
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
            await tx.run(
                "UPDATE orders SET status = 'pending', task_num = NULL, dispatched_at = NULL"
                " WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await tx.run(
                "UPDATE task_stop SET status = 'skipped'"
                " WHERE task_id = ? AND status IN ('pending', 'arrived')",
                (task_id,),
            )
            for row in returned_rows(task):
                await tx.run("UPDATE task_stop SET returned = ? WHERE task_id = ? AND seq = ?", row)
            await rows.free_robot(tx, task_id, now)
            data = {"reason": reason, "orders_returned": returned}
            await rows.add_event(
                tx, "task.cancelled", now, robot=task.robot, task_id=task_id, data=data
            )
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def requeue_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        """Take an active task off its robot (gone too long) so another robot can take it."""

        async def work(tx: Tx) -> Task:
            task = await rows.get_task(tx, task_id, lock=True)
            if task.status is TaskStatus.ACTIVE and task.current_stop >= len(task.stops):
                raise Conflict(
                    f"task {task_id} has every stop done: finish it instead", task=task_id
                )
            changed = await tx.run(
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
            await tx.run(
                "UPDATE task_stop SET status = 'pending', arrived_at = NULL"
                " WHERE task_id = ? AND status = 'arrived'",
                (task_id,),
            )
            await tx.run(
                "UPDATE orders SET dispatched_at = NULL WHERE task_num = ? AND status = 'assigned'",
                (task_id,),
            )
            await rows.free_robot(tx, task_id, now)
            data = {"reason": reason, "robot": task.robot}
            await rows.add_event(
                tx, "task.requeued", now, robot=task.robot, task_id=task_id, data=data
            )
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def drop_stops(self, task_id: int, tables: Sequence[str], *, now: float) -> Task:
        """Take ``tables`` off a queued trip (blocked since it was planned): their dishes go
        back to ``pending``; a trip left with no stop is cancelled."""

        async def work(tx: Tx) -> None:
            task = await one(tx, "SELECT status FROM task WHERE id = ?", (task_id,))
            if task is None:
                raise NotFound(f"no task {task_id}", task=task_id)
            if task["status"] != "queued":
                raise Conflict(f"task {task_id} is {task['status']}, not queued", task=task_id)
            dropped: list[int] = []
            for table in tables:
                dropped += [
                    r["id"]
                    for r in await tx.all(
                        "SELECT id FROM orders WHERE task_num = ? AND res_table = ?",
                        (task_id, table),
                    )
                ]
                await tx.run(
                    "UPDATE orders SET status = 'pending', task_num = NULL, dispatched_at = NULL"
                    " WHERE task_num = ? AND res_table = ? AND status = 'assigned'",
                    (task_id, table),
                )
                await tx.run(
                    "DELETE FROM task_stop WHERE task_id = ? AND waypoint = ?", (task_id, table)
                )
            left = await tx.all(
                "SELECT seq FROM task_stop WHERE task_id = ? ORDER BY seq", (task_id,)
            )
            # Renumber 0..n-1 (``current_stop`` indexes them), through numbers no stop has,
            # so that no two stops share one on the way.
            for i, row in enumerate(left):
                await tx.run(
                    "UPDATE task_stop SET seq = ? WHERE task_id = ? AND seq = ?",
                    (_RENUMBER + i, task_id, row["seq"]),
                )
            await tx.run(
                "UPDATE task_stop SET seq = seq - ? WHERE task_id = ?", (_RENUMBER, task_id)
            )
            data = {"tables": list(tables), "orders": dropped, "reason": "table blocked"}
            await rows.add_event(tx, "task.stops_dropped", now, task_id=task_id, data=data)
            if not left:
                await tx.run(
                    "UPDATE task SET status = 'cancelled', finished_at = ? WHERE id = ?",
                    (now, task_id),
                )
                await rows.add_event(
                    tx, "task.cancelled", now, task_id=task_id, data={"reason": "table blocked"}
                )

        await self._db.transact(work, "write")
        return await self.get_task(task_id)


_RENUMBER = 1_000_000  # above any stop number (a trip has at most a few hundred stops)
