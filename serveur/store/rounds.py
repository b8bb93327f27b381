"""Trips that carry no dishes from the pass: bussing rounds and cruises. One part of
:class:`~serveur.store.base.Store`, written once for every backend.

A bussing trip's stops are the tables whose used dishes it collects, then the dish return
where staff empty it; a cruise's are the places of its round, visited again and again (its
stops go back to ``pending`` at the end of each round, :meth:`Rounds.restart`). Both are
``task`` rows like a delivery's, told apart by ``task.kind`` and each stop's ``purpose``, so a
robot on one runs through the same statuses, locks and stale checks as on a delivery.
"""

from __future__ import annotations

from collections.abc import Sequence

from serveur.domain import StopPurpose, Task, TaskKind, TaskStatus
from serveur.errors import Conflict, InvalidField
from serveur.store import rows
from serveur.store.checks import check_text, digest
from serveur.store.sql import Db, Tx

__all__ = ["Rounds"]


class Rounds:
    """Bussing trips and cruises in the store."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def create_bussing(
        self, tables: Sequence[str], dish_return: str, *, key: str | None = None, now: float
    ) -> Task:
        """Queue a bussing trip: collect at ``tables`` (each once), then unload at
        ``dish_return``. ``key`` makes a resend return the same trip."""
        if not tables or len(set(tables)) != len(tables):
            raise InvalidField("name each table once", field="tables", tables=list(tables))
        for t in tables:
            check_text(t, "table")
        if dish_return in tables:
            raise InvalidField("the dish return is not a table", field="tables")
        fingerprint = digest(["bussing", sorted(tables)])
        if key is not None:
            self._db.dialect.check_name(key, "key")

        async def work(tx: Tx) -> Task:
            if key is not None:
                # The idempotency table's kinds are order and tasks (001): a bussing trip is
                # one of the tasks a key may answer with.
                done = await rows.replayed(tx, key, "tasks", fingerprint)
                if done is not None:
                    return await rows.get_task(tx, done["task_ids"][0])
            stops = [(t, StopPurpose.COLLECT) for t in tables]
            stops.append((dish_return, StopPurpose.UNLOAD))
            task_id = await _insert(tx, TaskKind.BUSSING, stops, now)
            if key is not None:
                await rows.remember(tx, key, "tasks", fingerprint, {"task_ids": [task_id]}, now)
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def create_cruise(self, robot: str, route: Sequence[str], *, now: float) -> Task:
        """A cruise round of ``route`` (each place once), queued for the caller to give to
        ``robot`` at once (the dispatcher never hands cruises out)."""
        if not route or len(set(route)) != len(route):
            raise InvalidField("name each place of the round once", field="route")

        async def work(tx: Tx) -> Task:
            task_id = await _insert(
                tx, TaskKind.CRUISE, [(p, StopPurpose.VISIT) for p in route], now
            )
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")

    async def restart(self, task_id: int, *, now: float) -> Task:
        """A cruise's round is over: its places are to visit again, from the first."""

        async def work(tx: Tx) -> Task:
            task = await rows.get_task(tx, task_id, lock=True)
            if task.kind is not TaskKind.CRUISE or task.status is not TaskStatus.ACTIVE:
                raise Conflict(
                    f"task {task_id} is not a cruise under way", task=task_id, kind=task.kind.value
                )
            await tx.run(
                "UPDATE task_stop SET status = 'pending', arrived_at = NULL, done_at = NULL"
                " WHERE task_id = ?",
                (task_id,),
            )
            await tx.run("UPDATE task SET current_stop = 0 WHERE id = ?", (task_id,))
            await rows.add_event(tx, "cruise.round", now, robot=task.robot, task_id=task_id)
            return await rows.get_task(tx, task_id)

        return await self._db.transact(work, "write")


async def _insert(
    tx: Tx, kind: TaskKind, stops: Sequence[tuple[str, StopPurpose]], now: float
) -> int:
    for place, _ in stops:
        await rows.get_waypoint(tx, place)  # NotFound names it
    task_id = await tx.insert(
        "INSERT INTO task (created_at, kind) VALUES (?, ?)", (now, kind.value)
    )
    await tx.many(
        "INSERT INTO task_stop (task_id, seq, waypoint, purpose) VALUES (?, ?, ?, ?)",
        [(task_id, seq, place, purpose.value) for seq, (place, purpose) in enumerate(stops)],
    )
    data = {"kind": kind.value, "stops": [{"table": p, "purpose": u.value} for p, u in stops]}
    await rows.add_event(tx, "task.created", now, task_id=task_id, data=data)
    return task_id
