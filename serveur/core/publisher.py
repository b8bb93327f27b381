"""What the core shows screens: records published on hub topics and the ``events`` feed.

Every change the core makes is published the same few ways — a record on its topic if anyone
watches it, a trip with the robot doing it, the orders a change touched, and the event rows the
store wrote with the change. Gathering them here keeps the core's instruction handling about
robots and trips, and gives the creation side (:mod:`serveur.core.creation`) one small thing to
publish through.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable, Sequence
from typing import Any

from serveur import protocol as P
from serveur.core.hub import Hub
from serveur.domain import EventRecord, Task
from serveur.store.base import Store

__all__ = ["Publisher"]

#: Task -> robot entries kept for screens' views; a night has hundreds, bound it anyway.
_TASK_ROBOTS_MAX = 10_000
#: Events read back per query when flushing the feed.
_EVENTS_BATCH = 500


class Publisher:
    """Publishes records on hub topics and forwards the store's events, each exactly once."""

    def __init__(self, hub: Hub, store: Store) -> None:
        self._hub = hub
        self._store = store
        self._task_robots: dict[int, str] = {}  # task id -> robot, for screens' views
        self._last_event = 0
        self._events_lock = asyncio.Lock()
        #: Called when a flush found new events (the chain's shipper: ship them now rather
        #: than at its next look).
        self.on_events: Callable[[], None] | None = None

    async def skip_stored_events(self) -> None:
        """Start the feed after the events already stored (those of earlier runs)."""
        while batch := await self._store.events.list_events(since_id=self._last_event, limit=1000):
            self._last_event = batch[-1].id

    def pub(self, topic: str, record: Any) -> None:
        """Publish ``record`` on ``topic`` if anyone watches it (serialised only then)."""
        if self._hub.watched(topic):
            self._hub.publish(topic, P.dump(record), record)

    def pub_task(self, task: Task) -> None:
        """Publish a trip, remembering which robot does it."""
        if task.robot is not None:
            self._task_robots[task.id] = task.robot
            while len(self._task_robots) > _TASK_ROBOTS_MAX:
                del self._task_robots[next(iter(self._task_robots))]
        self.pub("tasks", task)

    def task_robot(self, task_id: int) -> str | None:
        """The robot a published trip was given to, if this server published it."""
        return self._task_robots.get(task_id)

    async def pub_orders(self, ids: Sequence[int]) -> None:
        """Publish the orders ``ids`` as stored now (read only if anyone watches orders)."""
        if self._hub.watched("orders"):
            for oid in ids:
                self.pub("orders", await self._store.orders.get_order(oid))

    async def flush_events(self) -> None:
        """Push the events recorded since the last flush to ``events`` subscribers.

        The store writes an event row in the same transaction as every state change; reading
        them back here (by id, so nothing is missed or repeated) keeps that one source of truth.
        """
        async with self._events_lock:
            while batch := await self._store.events.list_events(
                since_id=self._last_event, limit=_EVENTS_BATCH
            ):
                self._last_event = batch[-1].id
                if self.on_events is not None:
                    self.on_events()
                if self._hub.watched("events"):
                    for ev in batch:
                        self._hub.publish("events", P.dump(ev))
                if len(batch) < _EVENTS_BATCH:
                    # All of them: asking again would only find none (a query per request).
                    break

    async def events_snapshot(self) -> list[EventRecord]:
        """The ``events`` topic's snapshot: the last hundred or so events, flushed first."""
        await self.flush_events()
        return await self._store.events.list_events(since_id=max(0, self._last_event - 100))
