"""Persistence: the abstract :class:`Store`, the migration history and :func:`open_store`.

Every SQL statement of serveur lives in the store modules, behind :class:`Store`, so that the
server, the scheduler and the tests speak in domain records (``serveur.domain``) and the
database can change (SQLite on the robot's Raspberry Pi today, MariaDB for a bigger site
later) without touching them.

The store, not the server, owns the invariants that money and food depend on: a dish is on at
most one trip, a robot has at most one trip, "food collected" counts once. Each mutation is one
transaction that re-checks its preconditions with conditional UPDATEs and their row counts, so
they hold even with several server processes on one database file (or later on MariaDB with
row locks), not only within one asyncio loop. Each mutation also appends an ``events`` row in
the same transaction: the audit trail never disagrees with the state.

Times are floats given by the caller (``now``, simulated epoch seconds from the clock), never
read here, so that replays and tests are deterministic.

Migrations are ``migrations/NNN_name.<dialect>.sql`` (or ``NNN_name.sql`` when the SQL
is the same for every dialect): one numbered history shared by all backends, shipped in the
wheel and applied in order at :meth:`Store.open`, each in its own transaction, recorded in
``schema_migrations`` so that re-opening applies nothing twice.
"""

from __future__ import annotations

import hashlib
import json
import math
from abc import ABC, abstractmethod
from collections.abc import Collection, Iterable, Mapping, Sequence
from enum import StrEnum
from pathlib import Path
from types import TracebackType
from typing import Any, Self, TypeVar

from serveur.domain import (
    DishAction,
    EventRecord,
    Order,
    OrderStatus,
    Robot,
    StopStatus,
    Task,
    TaskStatus,
    WaypointRecord,
)
from serveur.errors import InvalidField
from serveur.status import RobotMode, RobotStatus
from serveur.store.accounts import SqlTx, TokenRecord, UserRecord
from serveur.store.service import check_note, check_quantity
from serveur.store.zones import ZonesMixin

__all__ = [
    "SqlTx",
    "Store",
    "TokenRecord",
    "UserRecord",
    "check_finite",
    "check_new_order",
    "check_text",
    "check_trips",
    "digest",
    "link_json",
    "plan_stop_order",
    "returned_rows",
    "status_values",
    "to_json",
    "trips_fingerprint",
]

_E = TypeVar("_E", bound=StrEnum)


class Store(ZonesMixin, ABC):
    """The restaurant's persistent state. Use as ``async with open_store(url) as store:``.

    Errors: :class:`~serveur.errors.NotFound` for a missing robot/waypoint/order/task,
    :class:`~serveur.errors.Conflict` when the state forbids the change (an order already
    assigned, a robot already busy, a key reused for other content),
    :class:`~serveur.errors.InvalidField` for a malformed request, and
    :class:`~serveur.errors.StoreError` when the database itself fails. A method that raises
    has changed nothing.
    """

    async def __aenter__(self) -> Self:
        await self.open()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()

    @abstractmethod
    async def open(self) -> None:
        """Connect and apply the migrations not applied yet."""

    def busy(self) -> bool:
        """True while a query may be running outside the event loop (in a worker thread).

        A virtual-time loop (serveur.replay.vtime) must not let time jump meanwhile: the query's
        result would arrive "later" than it did. False for a backend that cannot tell.
        """
        return False

    @abstractmethod
    async def close(self) -> None:
        """Close the connection; safe to call twice."""

    # -- robots -------------------------------------------------------------------------

    @abstractmethod
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
        """Register a robot (Offline, mode off). A resend with the same fields returns it.

        ``link``: the robot's ROS name options (:class:`~serveur.robots.names.RosNames`,
        checked by the caller), kept as given.
        """

    @abstractmethod
    async def update_robot(
        self,
        name: str,
        *,
        url: str | None = None,
        home: str | None = None,
        link: Mapping[str, str] | None = None,
    ) -> Robot:
        """Change a robot's url, home and/or link options (``None`` keeps the current value)."""

    @abstractmethod
    async def get_robot(self, name: str) -> Robot: ...

    @abstractmethod
    async def list_robots(self) -> list[Robot]:
        """All robots, by name."""

    @abstractmethod
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
        """Persist a status change and its event together (one transaction)."""

    @abstractmethod
    async def save_robot_pose(
        self, name: str, *, x: float, y: float, yaw: float, battery: float | None, now: float
    ) -> None:
        """Persist the last pose (no event: it is called often, throttled by the caller)."""

    # -- waypoints ----------------------------------------------------------------------

    @abstractmethod
    async def put_waypoint(
        self, wp: WaypointRecord, *, replace: bool = False, now: float
    ) -> WaypointRecord:
        """Create a waypoint, or overwrite it with ``replace``; an identical resend is a no-op."""

    @abstractmethod
    async def get_waypoint(self, name: str) -> WaypointRecord: ...

    @abstractmethod
    async def list_waypoints(self) -> list[WaypointRecord]:
        """All waypoints, by name."""

    @abstractmethod
    async def delete_waypoint(self, name: str, *, now: float) -> None:
        """Delete a waypoint no order and no robot's home refers to."""

    # -- orders -------------------------------------------------------------------------

    @abstractmethod
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
        """A dish for ``table``: ready at the pass (``pending``, at ``ready_at``) or just
        ``ordered`` (the kitchen marks it ready later); ``key`` makes a resend return the same
        order."""

    @abstractmethod
    async def get_order(self, order_id: int) -> Order: ...

    @abstractmethod
    async def list_orders(
        self,
        *,
        status: OrderStatus | Collection[OrderStatus] | None = None,
        table: str | None = None,
        task_id: int | None = None,
    ) -> list[Order]:
        """Orders matching every given filter, by id."""

    async def cancel_order(self, order_id: int, *, now: float) -> Order:
        """Void a dish that has not left the pass (an order on a trip is a Conflict)."""
        return await self.step_order(order_id, DishAction.VOID, now=now)

    # -- tasks --------------------------------------------------------------------------

    @abstractmethod
    async def create_tasks(
        self,
        trips: Sequence[Sequence[tuple[str, Sequence[int]]]],
        *,
        key: str | None = None,
        fingerprint: str = "",
        now: float,
    ) -> list[Task]:
        """Queue trips (each: stops in visiting order as ``(table, order ids)``) atomically.

        All or nothing: one missing, non-pending, repeated or misplaced order and no trip is
        created. With ``key``, a resend with the same ``fingerprint`` (the caller's digest of
        the request; the trips' own digest when empty) returns the tasks it created, in their
        current state, without looking at ``trips``: on a resend the dishes are no longer
        pending, so the scheduler's new split cannot be compared with the first one.
        """

    @abstractmethod
    async def get_task(self, task_id: int) -> Task:
        """A task with its stops and each stop's order ids."""

    @abstractmethod
    async def list_tasks(
        self,
        *,
        status: TaskStatus | Collection[TaskStatus] | None = None,
        robot: str | None = None,
    ) -> list[Task]:
        """Tasks matching every given filter, by id."""

    @abstractmethod
    async def start_task(
        self, task_id: int, robot: str, *, stop_order: Sequence[str] | None = None, now: float
    ) -> Task:
        """Give a queued task to an idle robot; exactly one of concurrent callers wins.

        ``stop_order`` reorders the stops still to serve (the planner's shortest tour): the
        tables of those stops, or of all stops (stops already done keep their place).
        """

    @abstractmethod
    async def arrive_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        """The robot reached the current stop (pending -> arrived; a repeat is a no-op)."""

    @abstractmethod
    async def complete_stop(self, task_id: int, seq: int, *, now: float) -> Task:
        """Food collected at the current stop: its orders are delivered, the trip moves on."""

    @abstractmethod
    async def finish_task(self, task_id: int, *, now: float) -> Task:
        """Close an active task whose stops are all done and free its robot."""

    @abstractmethod
    async def cancel_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        """Cancel a queued or active task: undelivered orders go back to pending."""

    @abstractmethod
    async def requeue_task(self, task_id: int, *, now: float, reason: str = "") -> Task:
        """Take an active task off its robot (gone too long) so another robot can take it."""

    @abstractmethod
    async def cart(self, table: str) -> list[Order]:
        """The table's assigned and delivered orders, oldest first (the guest's cart)."""

    # -- events -------------------------------------------------------------------------

    @abstractmethod
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
        """Append an event that goes with no state change of the store (a robot's report)."""

    @abstractmethod
    async def list_events(self, *, since_id: int = 0, limit: int = 1000) -> list[EventRecord]:
        """Events with ``id > since_id``, oldest first: poll with the last id seen."""

    # -- maintenance --------------------------------------------------------------------

    @abstractmethod
    async def backup(self, path: str | Path) -> None:
        """Write a consistent copy of the live database to ``path`` (replaced atomically)."""

    @abstractmethod
    async def integrity_check(self) -> str:
        """``"ok"`` when the database is sound, else the problems found, one per line."""


# -- helpers shared by the backends ----------------------------------------------------------
# Every backend validates with these, so that the same request gets the same answer (and the
# same error) from SQLite and MariaDB: the shared test suite holds them to it.


def check_text(value: object, field: str) -> str:
    """``value`` if it is a non-blank string (names, urls, dishes are shown to staff)."""
    if not isinstance(value, str) or not value.strip():
        raise InvalidField(f"{field} must be a non-empty string", field=field)
    return value


def link_json(link: Mapping[str, str] | None) -> str:
    """A robot's link options as the ``link`` column keeps them (sorted keys, compact)."""
    return json.dumps(dict(sorted((link or {}).items())), separators=(",", ":"))


def check_new_order(
    dish: str,
    table: str,
    *,
    ready_at: float | None,
    quantity: int,
    note: str | None,
    status: OrderStatus,
) -> tuple[str | None, float | None, str]:
    """A new order's fields checked, as every backend's ``add_order`` needs them: the note
    (stripped, None if empty), ``ready_at`` (None while only ordered) and the fingerprint a
    resend under the same key must match."""
    check_text(dish, "dish")
    check_text(table, "table")
    check_quantity(quantity)
    note = check_note(note)
    if status not in (OrderStatus.ORDERED, OrderStatus.PENDING):
        raise InvalidField("a new order is ordered or pending", field="status")
    ready_at = check_finite(ready_at, "ready_at") if status is OrderStatus.PENDING else None
    # The first fields alone for a plain dish ready at the pass: keys stored before quantity,
    # note and status existed still match their resends.
    plain = (quantity, note, status) == (1, None, OrderStatus.PENDING)
    extra = [] if plain else [quantity, note, status.value]
    return note, ready_at, digest(["order", dish, table, *extra])


def check_finite(value: object, field: str) -> float:
    """``value`` as a float; NaN and infinities are refused before they reach a REAL column
    (SQLite would store them, then every distance computed from them would be NaN)."""
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise InvalidField(f"{field} must be a finite number", field=field)
    return float(value)


def to_json(data: Any) -> str:
    """Strict, canonical JSON (sorted keys, no NaN) so that digests of equal data are equal."""
    try:
        return json.dumps(data, allow_nan=False, separators=(",", ":"), sort_keys=True)
    except (TypeError, ValueError) as exc:
        raise InvalidField(f"event data is not JSON: {exc}", field="data") from exc


def digest(data: Any) -> str:
    """The idempotency fingerprint of a request's content."""
    return hashlib.sha256(to_json(data).encode()).hexdigest()


def status_values(value: _E | Collection[_E] | None, enum: type[_E]) -> list[str] | None:
    """A status filter as a list of values; a single enum is a str, hence a Collection too."""
    if value is None:
        return None
    items = [value] if isinstance(value, str) else list(value)
    try:
        return [enum(v).value for v in items]
    except ValueError as exc:
        raise InvalidField(str(exc), field="status") from exc


def returned_rows(task: Task) -> list[tuple[str, int, int]]:
    """``(returned, task_id, seq)`` for each stop of ``task`` not served yet that holds dishes:
    what a cancelled trip's stops keep of what they carried (``task_stop.returned``, migration
    008), read before the dishes leave the trip."""
    return [
        (to_json(stop.orders), task.id, stop.seq)
        for stop in task.stops
        if stop.status in (StopStatus.PENDING, StopStatus.ARRIVED) and stop.orders
    ]


def trips_fingerprint(trips: Iterable[Iterable[tuple[str, Iterable[int]]]]) -> str:
    """A digest of the trips, the idempotency fingerprint when the caller gives none.

    Tolerant of any shape: it runs before validation, because a keyed resend is answered
    from the key without looking at the trips at all.
    """
    try:
        return digest([[[table, list(ids)] for table, ids in trip] for trip in trips])
    except (TypeError, ValueError) as exc:
        raise InvalidField(f"trips are malformed: {exc}", field="trips") from exc


def check_trips(
    trips: Sequence[Sequence[tuple[str, Sequence[int]]]],
) -> list[list[tuple[str, list[int]]]]:
    """Validate the shape of ``trips`` (no database needed); InvalidField on any defect."""
    if isinstance(trips, str | bytes) or not trips:
        raise InvalidField("at least one trip is needed", field="trips")
    plan: list[list[tuple[str, list[int]]]] = []
    seen: set[int] = set()
    for t, trip in enumerate(trips):
        if isinstance(trip, str | bytes) or not trip:
            raise InvalidField(f"trip {t} has no stops", field="trips")
        stops: list[tuple[str, list[int]]] = []
        for stop in trip:
            try:
                table, ids = stop
                ids = list(ids)
            except (TypeError, ValueError) as exc:
                raise InvalidField(
                    f"trip {t}: a stop is (table, order ids)", field="trips"
                ) from exc
            check_text(table, "table")
            if not ids or not all(isinstance(i, int) and not isinstance(i, bool) for i in ids):
                raise InvalidField(f"trip {t}: stop {table!r} needs order ids", field="trips")
            if table in (s[0] for s in stops):
                raise InvalidField(f"trip {t} visits {table!r} twice", field="trips")
            repeated = sorted(seen.intersection(ids) | {i for i in ids if ids.count(i) > 1})
            if repeated:
                raise InvalidField(
                    f"order(s) {repeated} appear more than once", field="trips", orders=repeated
                )
            seen.update(ids)
            stops.append((table, ids))
        plan.append(stops)
    return plan


def plan_stop_order(task: Task, stop_order: Sequence[str]) -> list[str] | None:
    """The new visiting order of the stops not done yet, or None if it is unchanged.

    ``stop_order`` lists the tables still to serve, or every table of the task (the planner's
    full tour); stops already done stay first, in their order, since they are history.
    InvalidField if it is not a permutation of either.
    """
    done = [s.table for s in task.stops if s.status is StopStatus.DONE]
    rest = [s.table for s in task.stops if s.status is not StopStatus.DONE]
    wanted = list(stop_order)
    if sorted(wanted) == sorted(done + rest):
        wanted = [t for t in wanted if t not in done]
    if sorted(wanted) != sorted(rest):
        raise InvalidField(
            f"stop_order must be a permutation of the task's tables {rest}",
            field="stop_order",
            tables=rest,
        )
    return None if wanted == rest else wanted
