"""The zones robots take turns through, stored (migration 007): one part of
:class:`~serveur.store.base.Store`, written once for every backend.

Zones are the owner's drawing, saved and removed whole; leases on them live in the server
(:mod:`serveur.core.leases`), not here. A zone removed is deleted outright: nothing refers to
it (the events keep what it was).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from serveur.domain import ZoneRecord
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store import rows
from serveur.store.live import WAYPOINT_NAMED
from serveur.store.sql import Db, Tx, one

__all__ = ["Zones", "check_zone", "load_zones_file"]

_ZONE = "SELECT name, points, capacity, wait_at, updated_at FROM zones"


def check_zone(points: Sequence[Sequence[float]], capacity: int) -> list[tuple[float, float]]:
    """A zone's points as stored: 3 to 32 finite (x, y) pairs enclosing some area."""
    if isinstance(capacity, bool) or not isinstance(capacity, int) or not 1 <= capacity <= 8:
        raise InvalidField("a zone's capacity is a whole number from 1 to 8", field="capacity")
    if not 3 <= len(points) <= 32:
        raise InvalidField("a zone has 3 to 32 points", field="points")
    out: list[tuple[float, float]] = []
    for p in points:
        if len(p) != 2 or not all(
            isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v) for v in p
        ):
            raise InvalidField("a zone's point is [x, y] in metres", field="points")
        out.append((float(p[0]), float(p[1])))
    area = sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(out, [*out[1:], out[0]], strict=True))
    if abs(area) / 2 < 0.01:
        raise InvalidField("a zone must enclose some floor (its points are in a line)")
    return out


def load_zones_file(path: str | Path) -> list[ZoneRecord]:
    """A zones file: ``{"zones": [{"name", "points": [[x, y], ...], "capacity"}, ...]}`` (the
    format the console imports and ``serveur run --zones`` reads); each zone checked."""
    try:
        doc = json.loads(Path(path).read_text("utf-8"))
        items = doc["zones"] if isinstance(doc, dict) else doc
        out = []
        for z in items:
            capacity = z.get("capacity", 1)
            points = check_zone(z["points"], capacity)
            wait_at = z.get("wait_at")
            out.append(
                ZoneRecord(
                    name=str(z["name"]),
                    points=points,
                    capacity=capacity,
                    wait_at=None if wait_at is None else str(wait_at),
                )
            )
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as exc:
        raise InvalidField(f"{path}: not a zones file: {exc}", file=str(path)) from None
    return out


class Zones:
    """Zone methods of the store (``store.zones``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def list_zones(self) -> list[ZoneRecord]:
        async def work(tx: Tx) -> list[ZoneRecord]:
            return [ZoneRecord(**r) for r in await tx.all(f"{_ZONE} ORDER BY name")]

        return await self._db.transact(work, "read")

    async def put_zone(
        self, zone: ZoneRecord, *, replace: bool, now: float, by: str | None = None
    ) -> ZoneRecord:
        """Save a zone; an existing one is changed only with ``replace`` (Conflict otherwise;
        an identical resend is a no-op)."""
        points = check_zone(zone.points, zone.capacity)
        body = json.dumps([list(p) for p in points])

        async def work(tx: Tx) -> ZoneRecord:
            row = await one(tx, f"{_ZONE} WHERE name = ?", (zone.name,))
            if zone.wait_at is not None and not await one(tx, WAYPOINT_NAMED, (zone.wait_at,)):
                raise NotFound(f"no waypoint named {zone.wait_at!r}", waypoint=zone.wait_at)
            if row is not None:
                old = ZoneRecord(**row)
                if (old.points, old.capacity, old.wait_at) == (
                    points,
                    zone.capacity,
                    zone.wait_at,
                ):
                    return old
                if not replace:
                    raise Conflict(f"a zone named {zone.name!r} exists", zone=zone.name)
                await tx.run(
                    "UPDATE zones SET points = ?, capacity = ?, wait_at = ?, updated_at = ?"
                    " WHERE name = ?",
                    (body, zone.capacity, zone.wait_at, now, zone.name),
                )
            else:
                await tx.run(
                    "INSERT INTO zones (name, points, capacity, wait_at, updated_at)"
                    " VALUES (?, ?, ?, ?, ?)",
                    (zone.name, body, zone.capacity, zone.wait_at, now),
                )
            data = {
                "name": zone.name,
                "points": points,
                "capacity": zone.capacity,
                "wait_at": zone.wait_at,
                "by": by,
            }
            await rows.add_event(tx, "zone.saved", now, data=data)
            saved = await one(tx, f"{_ZONE} WHERE name = ?", (zone.name,))
            assert saved is not None
            return ZoneRecord(**saved)

        return await self._db.transact(work, "write")

    async def delete_zone(self, name: str, *, now: float, by: str | None = None) -> ZoneRecord:
        async def work(tx: Tx) -> ZoneRecord:
            row = await one(tx, f"{_ZONE} WHERE name = ?", (name,))
            if row is None:
                raise NotFound(f"no zone named {name!r}", zone=name)
            await tx.run("DELETE FROM zones WHERE name = ?", (name,))
            await rows.add_event(tx, "zone.removed", now, data={"name": name, "by": by})
            return ZoneRecord(**row)

        return await self._db.transact(work, "write")
