"""The restaurant's map as the owner set it in the console, stored (migration 009), and the floor
plan drawn under it (migration 010): parts of :class:`~serveur.store.base.Store`, written once
for every backend.

One row at most, replaced whole. It is in the database so that a backup holds it and a restore
brings it back; at start it wins over ``serveur run --map`` (serveur.core.engine).
"""

from __future__ import annotations

from dataclasses import dataclass

from serveur.store.sql import Db, Tx, one

__all__ = ["SiteBackdrop", "SiteMap", "StoredBackdrop", "StoredMap"]


@dataclass(frozen=True, slots=True)
class StoredMap:
    """The stored grid: int8 cells row-major, row 0 at the lowest y (OccupancyGrid's data)."""

    resolution: float
    origin: tuple[float, float]
    width: int
    height: int
    cells: bytes
    source: str


_MAP = (
    "SELECT resolution, origin_x, origin_y, width, height, cells, source, updated_at"
    " FROM site_map WHERE id = 1"
)


class SiteMap:
    """``store.site_map``: the map the owner gave, or None."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def get(self) -> StoredMap | None:
        """The stored map, or None (the server uses ``--map``, or a robot's)."""

        async def work(tx: Tx) -> StoredMap | None:
            row = await one(tx, _MAP, ())
            if row is None:
                return None
            return StoredMap(
                float(row["resolution"]),
                (float(row["origin_x"]), float(row["origin_y"])),
                int(row["width"]),
                int(row["height"]),
                bytes(row["cells"]),
                str(row["source"]),
            )

        return await self._db.transact(work, "read")

    async def put(self, m: StoredMap, *, now: float, by: str | None = None) -> None:
        """Make ``m`` the restaurant's map (replacing any)."""

        async def work(tx: Tx) -> None:
            await tx.run("DELETE FROM site_map WHERE id = 1", ())
            await tx.run(
                "INSERT INTO site_map (id, resolution, origin_x, origin_y, width, height, cells,"
                " source, updated_at, updated_by) VALUES (1, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    m.resolution,
                    m.origin[0],
                    m.origin[1],
                    m.width,
                    m.height,
                    m.cells,
                    m.source[:255],
                    now,
                    by,
                ),
            )

        await self._db.transact(work, "write")


@dataclass(frozen=True, slots=True)
class StoredBackdrop:
    """The floor plan's image and where its pixels land on the map: metres =
    ``scale * R(rotation) * (column, -row) + (tx, ty)``."""

    image: bytes
    mime: str
    digest: str
    scale: float
    rotation: float
    tx: float
    ty: float
    rms: float
    points: int


_BACKDROP = "SELECT image, mime, digest, scale, rotation, tx, ty, rms, points FROM site_backdrop"


class SiteBackdrop:
    """``store.site_backdrop``: the floor plan under the map, or None."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def get(self) -> StoredBackdrop | None:
        async def work(tx: Tx) -> StoredBackdrop | None:
            row = await one(tx, _BACKDROP + " WHERE id = 1", ())
            if row is None:
                return None
            return StoredBackdrop(
                bytes(row["image"]),
                str(row["mime"]),
                str(row["digest"]),
                float(row["scale"]),
                float(row["rotation"]),
                float(row["tx"]),
                float(row["ty"]),
                float(row["rms"]),
                int(row["points"]),
            )

        return await self._db.transact(work, "read")

    async def put(self, b: StoredBackdrop, *, now: float, by: str | None = None) -> None:
        async def work(tx: Tx) -> None:
            await tx.run("DELETE FROM site_backdrop WHERE id = 1", ())
            await tx.run(
                "INSERT INTO site_backdrop (id, image, mime, digest, scale, rotation, tx, ty,"
                " rms, points, updated_at, updated_by) VALUES (1, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    b.image,
                    b.mime,
                    b.digest,
                    b.scale,
                    b.rotation,
                    b.tx,
                    b.ty,
                    b.rms,
                    b.points,
                    now,
                    by,
                ),
            )

        await self._db.transact(work, "write")

    async def clear(self) -> bool:
        """No floor plan under the map any more (a new map: another frame); True if one was."""

        async def work(tx: Tx) -> int:
            return await tx.run("DELETE FROM site_backdrop WHERE id = 1", ())

        return bool(await self._db.transact(work, "write"))
