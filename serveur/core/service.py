"""The dinner service around the robots: dishes' steps, the menu, blocked tables, alerts, timeouts.

The core (:mod:`serveur.core.engine`) drives robots; this module keeps what staff see of the
service as a whole. It owns:

* the kitchen's side of a dish (``dish``: cooking, ready, void, edit) and the menu
  (``create dish``), each step stored with who asked;
* the tables robots could not reach (``blocks``), cached here so the dispatcher can keep them
  out of trips without a query, and cleared by staff (``clear``);
* the alert book and its watch loop: once a second of the service clock it gathers the
  robots' and dishes' facts, raises and clears alerts (:mod:`serveur.core.alerts`), and tells
  the core about robots waiting at a table past the site's timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Iterable
from typing import Any, Protocol

from serveur.clock import Clock
from serveur.core.alerts import (
    Alert,
    AlertBook,
    DishFact,
    RobotFact,
    Thresholds,
    TillFacts,
    conditions,
)
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.domain import Call, DishAction, MenuItem, Order, OrderStatus, TableBlock
from serveur.errors import InvalidField, ServeurError, Stale, Unreachable
from serveur.store.base import Store

__all__ = ["Service", "ServiceHost"]

log = logging.getLogger(__name__)

_NO_TILL = TillFacts()
#: How often the watch loop looks (service-clock seconds).
TICK = 1.0


class ServiceHost(Protocol):
    """What the service needs from the core."""

    def robot_facts(self) -> list[RobotFact]: ...

    def timers(self) -> None:
        """Post each robot what its waiting has come to (a stop's wait over, charging)."""
        ...

    async def escalate_calls(self) -> list[Call]:
        """Escalate the calls nobody answered in time; the escalated calls still open."""
        ...

    def till_facts(self) -> TillFacts:
        """The till's unread tickets and whether its kitchen printer answers."""
        ...


class Service:
    """Dishes, menu, blocked tables and alerts; the watch loop."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        *,
        places: Places,
        publisher: Publisher,
        kick: Callable[[], None],
        limits: Thresholds,
    ) -> None:
        self._store = store
        self._clock = clock
        self._places = places
        self._publisher = publisher
        self._kick = kick
        self._limits = limits
        self.alerts = AlertBook()
        self.blocks: dict[str, TableBlock] = {}
        self._task: asyncio.Task[None] | None = None

    async def start(self, host: ServiceHost) -> None:
        self.blocks = {b.table: b for b in await self._store.service.list_blocks()}
        self._task = asyncio.create_task(self._watch(host), name="service-watch")

    async def stop(self) -> None:
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._task
            self._task = None

    # -- dishes and the menu -------------------------------------------------------------

    async def dish(
        self,
        order_id: int,
        action: DishAction,
        *,
        seen: OrderStatus | None,
        by: str | None,
        quantity: int | None = None,
        note: str | None = None,
        table: str | None = None,
    ) -> Order:
        """One step of a dish. ``seen``: the status the client showed (stale if it moved)."""
        if action is not DishAction.EDIT and (quantity, note, table) != (None, None, None):
            raise InvalidField(
                f"{action.value} takes no quantity, note or table (edit does)", field="action"
            )
        if seen is not None:
            now_is = (await self._store.orders.get_order(order_id)).status
            if now_is is not seen:
                raise Stale(
                    f"order {order_id} is {now_is.value} now, not {seen.value}",
                    order=order_id,
                    status=now_is.value,
                )
        if table is not None:
            self._places.waypoint(table)
        order = await self._store.orders.step_order(
            order_id,
            action,
            now=self._clock.epoch(),
            by=by,
            quantity=quantity,
            note=note,
            table=table,
        )
        self._publisher.pub("orders", order)
        return order

    async def put_dish(self, item: MenuItem, by: str | None) -> MenuItem:
        item = await self._store.service.put_dish(item, now=self._clock.epoch(), by=by)
        self._publisher.pub("menu", item)
        return item

    # -- blocked tables ------------------------------------------------------------------

    def check_reachable(self, tables: Iterable[str]) -> None:
        """Refuse a cart with a blocked table: its dishes wait, with the reason."""
        for t in tables:
            block = self.blocks.get(t)
            if block is not None:
                raise Unreachable(
                    f"{t} is blocked: {block.reason}. Clear it once the way is free.",
                    table=t,
                    reason=block.reason,
                )

    async def block(self, table: str, reason: str, robot: str | None) -> None:
        """A robot could not reach ``table``: no robot is sent there until staff clear it."""
        if table in self.blocks:
            return
        block = await self._store.service.block_table(
            table, reason, robot=robot, now=self._clock.epoch()
        )
        self.blocks[table] = block
        self._publisher.pub("blocks", block)
        log.warning("table %s blocked: %s", table, reason)

    async def clear(self, table: str, by: str | None) -> dict[str, Any]:
        self._places.waypoint(table)
        cleared = await self._store.service.unblock_table(table, now=self._clock.epoch(), by=by)
        block = self.blocks.pop(table, None)
        if block is not None:
            # Screens drop a block whose reason is gone (the record with an empty reason).
            self._publisher.pub("blocks", block.model_copy(update={"reason": ""}))
            self._kick()
        return {"table": table, "cleared": cleared}

    # -- alerts --------------------------------------------------------------------------

    async def ack(self, alert_id: int, by: str) -> Alert:
        alert = self.alerts.ack(alert_id, by, self._clock.epoch())
        await self._store.events.add_event(
            "alert.acked",
            data={"alert": alert.id, "kind": alert.kind.value, "subject": alert.subject, "by": by},
            now=self._clock.epoch(),
        )
        self._publisher.pub("alerts", alert)
        return alert

    async def evaluate(
        self, host: ServiceHost, calls: Iterable[Call] = (), till: TillFacts = _NO_TILL
    ) -> list[Alert]:
        """Raise and clear alerts from the restaurant as it is now (``calls``: the escalated
        calls still open; ``till``: the till's tickets and printer)."""
        now = self._clock.epoch()
        pending = await self._store.orders.list_orders(status=OrderStatus.PENDING)
        dishes = [DishFact(o.table, o.ready_at) for o in pending if o.ready_at is not None]
        holding = conditions(
            host.robot_facts(),
            dishes,
            {t: b.reason for t, b in self.blocks.items()},
            calls=calls,
            till=till,
            now=now,
            active=self.alerts.keys(),
            limits=self._limits,
        )
        changed = self.alerts.update(holding, now)
        for alert in changed:
            kind = "alert.cleared" if alert.cleared_at is not None else "alert.raised"
            data = {"alert": alert.id, "kind": alert.kind.value, "subject": alert.subject}
            if alert.cleared_at is None:
                data["message"] = alert.message
            await self._store.events.add_event(kind, data=data, now=now)
            self._publisher.pub("alerts", alert)
        return changed

    async def _watch(self, host: ServiceHost) -> None:
        while True:
            try:
                host.timers()
                await self.evaluate(host, await host.escalate_calls(), host.till_facts())
                await self._publisher.flush_events()
            except ServeurError as exc:  # a busy or full disk: try again next tick
                log.warning("service watch: %s", exc)
            except Exception:
                log.exception("service watch failed")
            await self._clock.sleep(TICK)
