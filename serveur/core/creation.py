"""Creating orders, trips and waypoints: validation, planning, idempotency, publication.

``create`` is the one verb that does not act on a robot, so it needs none of the core's
per-robot locking or status machine — only the store, the floor plan
(:mod:`serveur.core.places`), publication (:mod:`serveur.core.publisher`) and a nudge to the
dispatcher. Keeping it here leaves :mod:`serveur.core.engine` about robots. (Creating a
*robot*, and a waypoint at a robot's current pose, do touch robots; the core does those parts.)

Idempotency: a keyed ``create task`` may be resent (a tablet that lost the reply). The
fingerprint is a digest of the request's order ids, not of the planned trips: by the resend
some orders are no longer pending and planning would give other trips, yet it is the same
request and must get the same answer — the store answers it from the key.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Callable, Iterable, Mapping
from typing import Any

from serveur.clock import Clock
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig
from serveur.domain import Order, OrderStatus, Task, WaypointRecord
from serveur.errors import Conflict, InvalidField
from serveur.scheduler import cart_order_trips, group_by_table, order_stops, plan_trips
from serveur.store.base import Store

__all__ = ["Creation"]


class Creation:
    """Creates orders, trips and waypoints for the ``create`` verb."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: CoreConfig,
        *,
        places: Places,
        publisher: Publisher,
        origin: Callable[[], str],
        kick: Callable[[], None],
        reachable: Callable[[Iterable[str]], None],
    ) -> None:
        """``origin`` names where trips start (:meth:`Places.origin` over the robots' homes);
        ``kick`` tells the dispatcher trips were queued."""
        self._store = store
        self._clock = clock
        self._config = config
        self._places = places
        self._publisher = publisher
        self._origin = origin
        self._kick = kick
        self._reachable = reachable

    async def order(
        self,
        dish: str,
        table: str,
        key: str | None,
        *,
        quantity: int = 1,
        note: str | None = None,
        status: OrderStatus = OrderStatus.PENDING,
        special: str | None = None,
    ) -> Order:
        """A dish for a table that must exist: ready at the pass now, or ordered."""
        now = self._clock.epoch()
        self._places.waypoint(table)
        order = await self._store.orders.add_order(
            dish,
            table,
            ready_at=now,
            key=key,
            now=now,
            quantity=quantity,
            note=note,
            status=status,
            special=special,
        )
        self._publisher.pub("orders", order)
        return order

    async def tasks(
        self, order_ids: list[int], key: str | None, *, trays: dict[int, int] | None = None
    ) -> list[Task]:
        """Queue the orders as trips (planned by the configured policy); the dispatcher runs.

        With ``trays`` (dish id -> the tray staff chose) the cart leaves as one trip, stops in
        the planned order: staff put dishes on trays for one robot, not for a split.

        Without a key every order must be pending. With a key, a resend is answered by the
        store from the key; only the orders still pending are planned otherwise.
        """
        fp = _fingerprint({"orders": sorted(order_ids)})
        if trays:
            fp = _fingerprint({"orders": sorted(order_ids), "trays": sorted(trays.items())})
        orders: list[Order] = [await self._store.orders.get_order(i) for i in order_ids]
        pending = [o for o in orders if o.status is OrderStatus.PENDING]
        if key is None and len(pending) != len(orders):
            bad = sorted(o.id for o in orders if o.status is not OrderStatus.PENDING)
            raise Conflict(f"orders not pending: {bad}", orders=bad)
        self._reachable({o.table for o in pending})
        if trays:
            trips = _one_trip(
                pending or orders, self._origin(), self._places, trays, self._config.capacity
            )
        elif self._config.policy == "baseline":
            trips = cart_order_trips(pending or orders, self._config.capacity)
        else:
            trips = plan_trips(
                pending or orders, self._origin(), self._places.distance, self._config.capacity
            )
        tasks = await self._store.tasks.create_tasks(
            trips, key=key, fingerprint=fp, now=self._clock.epoch(), trays=trays
        )
        for t in tasks:
            self._publisher.pub_task(t)
        await self._publisher.pub_orders(order_ids)
        self._kick()
        return tasks

    async def add(self, task_id: int, order_ids: list[int], key: str | None) -> Task:
        """Put pending dishes on trip ``task_id``, still at the pass, at their tables' stops.

        The caller holds the trip's robot's lock, so Go cannot land between the store's check
        that the robot is still Loading and the dishes going aboard.
        """
        fp = _fingerprint({"orders": sorted(order_ids), "task": task_id})
        task = await self._store.tasks.add_to_task(
            task_id, order_ids, key=key, fingerprint=fp, now=self._clock.epoch()
        )
        self._publisher.pub_task(task)
        await self._publisher.pub_orders(order_ids)
        return task

    async def waypoint(self, wp: WaypointRecord, *, replace: bool) -> WaypointRecord:
        """Store a waypoint (``replace`` to move one); its path distances are then planned."""
        wp = await self._store.waypoints.put_waypoint(wp, replace=replace, now=self._clock.epoch())
        self._places.put(wp)
        self._publisher.pub("waypoints", wp)
        return wp


def _one_trip(
    orders: list[Order],
    origin: str,
    places: Places,
    trays: Mapping[int, int],
    capacity: int,
) -> list[list[tuple[str, list[int]]]]:
    """The cart as one trip (staff chose trays): its tables in the shortest order. It must
    fit the site's trays: a trip of more tables would wait for a robot that does not come."""
    by_table = group_by_table(orders)
    if len(by_table) > capacity:
        raise InvalidField(
            f"{len(by_table)} tables do not fit on one robot's {capacity} trays: send fewer"
            " tables, or let the plan split the cart",
            field="trays",
            tables=len(by_table),
            trays=capacity,
        )
    high = sorted(oid for oid, tray in trays.items() if tray > capacity)
    if high:
        raise InvalidField(
            f"the robots have {capacity} trays: dish(es) {high} are on a tray beyond",
            field="trays",
            orders=high,
            trays=capacity,
        )
    tables = order_stops(origin, [t for t, _ in by_table], places.distance, end=origin)
    ids = dict(by_table)
    return [[(t, ids[t]) for t in tables]]


def _fingerprint(payload: Mapping[str, Any]) -> str:
    return hashlib.sha256(json.dumps(payload, sort_keys=True).encode()).hexdigest()
