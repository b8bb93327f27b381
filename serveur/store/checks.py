"""The checks every store method applies before it touches the database, and the pure helpers
of its records: the same request gets the same answer (and the same error) on every backend,
because there is one copy of each.
"""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Collection, Iterable, Mapping, Sequence
from enum import StrEnum
from typing import Any, TypeVar

from serveur.domain import OrderStatus, StopStatus, Task
from serveur.errors import InvalidField

__all__ = [
    "check_finite",
    "check_new_order",
    "check_note",
    "check_quantity",
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


def check_quantity(value: object) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= 99:
        raise InvalidField("quantity must be a whole number from 1 to 99", field="quantity")
    return value


def check_note(value: object) -> str | None:
    if value is None:
        return None
    if not isinstance(value, str) or len(value) > 200:
        raise InvalidField("note must be text of at most 200 characters", field="note")
    return value.strip() or None


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
    special: str | None = None,
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
    extra: list[object] = [] if plain else [quantity, note, status.value]
    if special is not None:
        check_text(special, "special")
        if len(special) > 120:
            raise InvalidField("a special message is at most 120 characters", field="special")
        extra.append(["special", special])
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
