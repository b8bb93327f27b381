"""The restaurant's map as the owner sets it in the console: stored, used, and what it changes.

A map given in the console (a robot's map files now; a floor plan next) is checked in a child
process (:func:`serveur.maps.mapfiles.read_map_files_in_child`), stored in the database
(``store.site_map``: a backup holds it, and at start it wins over ``--map``), shown to every
screen at once, and path distances are planned again in the background. Places are kept where
they are; those that are no longer on free floor are named to the owner, who moves them.
"""

from __future__ import annotations

import base64
import hashlib
import json
import logging
from typing import Any

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.places import Places
from serveur.core.uploads import Uploads
from serveur.errors import Conflict, InvalidField
from serveur.maps.align import Similarity, fit, matches_nothing
from serveur.maps.child import run_child
from serveur.maps.distances import MapData
from serveur.maps.mapfiles import read_map_files_in_child
from serveur.store.base import Store, StoredBackdrop, StoredMap

__all__ = ["BACKDROP_PATH", "SiteMaps", "stored_backdrop", "stored_map"]

#: Where the floor plan under the map is served: ``/site/backdrop/<digest>`` (the image's
#: SHA-256: a new plan is a new address, and an address nobody was shown is not guessed).
BACKDROP_PATH = "/site/backdrop/"
#: The plausible scales of a floor plan (metres per pixel): a 0.1 mm scan to a 1 m sketch.
MIN_SCALE = 1e-4
MAX_SCALE = 1.0
_MIMES = {b"\x89PNG\r\n\x1a\n": "image/png", b"\xff\xd8\xff": "image/jpeg"}

log = logging.getLogger(__name__)


async def stored_map(store: Store) -> MapData | None:
    """The map the owner set, as the core keeps maps, or None."""
    got = await store.site_map.get()
    if got is None:
        return None
    log.info("using the restaurant's map set in the console (%s)", got.source)
    return MapData(got.resolution, (*got.origin, 0.0), got.width, got.height, got.cells)


def _info(m: MapData, source: str) -> dict[str, Any]:
    return {
        "width": m.width,
        "height": m.height,
        "resolution": m.resolution,
        "origin": list(m.origin),
        "source": source,
    }


def _backdrop_info(b: StoredBackdrop) -> dict[str, Any]:
    return {
        "url": f"{BACKDROP_PATH}{b.digest}",
        "scale": b.scale,
        "rotation": b.rotation,
        "tx": b.tx,
        "ty": b.ty,
    }


async def stored_backdrop(store: Store) -> dict[str, Any] | None:
    """The floor plan under the map, as the ``map`` snapshot says it, or None."""
    got = await store.site_backdrop.get()
    return None if got is None else _backdrop_info(got)


def _fit_info(t: Similarity) -> dict[str, Any]:
    return {
        "scale": t.scale,
        "rotation": t.rotation,
        "tx": t.tx,
        "ty": t.ty,
        "residuals": [round(r, 4) for r in t.residuals],
        "rms": round(t.rms, 4),
    }


class SiteMaps:
    """The owner's map actions over ``/ws``, on the files a connection sent in parts
    (``uploads``): a robot's map files, a floor plan made a map, the plan fitted under the map.
    A refused action keeps its uploads for another try; one that is done uses them up."""

    def __init__(self, store: Store, places: Places, clock: Clock) -> None:
        self._store = store
        self._places = places
        self._clock = clock
        self._image: tuple[str, bytes, str] | None = None  # the backdrop's (digest, bytes, type)

    async def set_map(
        self, uploads: Uploads, msg: P.SiteSetMap, actor: str | None
    ) -> dict[str, Any]:
        """Check, store and use a robot's map files (read in a child process); the reply:
        the map's size and the places no longer on free floor."""
        yaml_file = uploads.take(msg.yaml, "map_yaml")
        image = uploads.take(msg.image, "map_image")
        m = await read_map_files_in_child(bytes(yaml_file.data), bytes(image.data), image.name)
        source = f"robot map files ({image.name})"
        outside = await self._use(m, source, actor)
        uploads.done(msg.yaml, msg.image)
        return {"map": _info(m, source), "outside": outside}

    async def plan_map(
        self, uploads: Uploads, msg: P.SitePlanMap, actor: str | None
    ) -> dict[str, Any]:
        """A floor plan made a map in a child process (:mod:`serveur.maps.floorplan`): the
        preview (the map's cells, the scale, whether the plan is stretched) and, with
        ``apply``, the restaurant's map from now on."""
        plan = uploads.take(msg.upload, "plan")
        request = {
            "plan": base64.b64encode(bytes(plan.data)).decode(),
            "threshold": msg.threshold,
            "strokes": [s.model_dump() for s in msg.strokes],
            "across": msg.across.model_dump(),
            "along": msg.along.model_dump(),
            "resolution": msg.resolution,
        }
        reply = await run_child("serveur.maps.floorplan", json.dumps(request).encode())
        m = MapData.from_snapshot(reply["map"])
        scale = reply["scale"]
        source = f"floor plan ({plan.name})"
        out: dict[str, Any] = {
            "plan": {
                "map": reply["map"],
                "scale_x": scale["x"],
                "scale_y": scale["y"],
                "disagreement": scale["disagreement"],
                "stretched": bool(scale["stretched"]),
            },
            "map": _info(m, source),
        }
        if msg.apply:
            out["outside"] = await self._use(m, source, actor)
            uploads.done(msg.upload)  # a preview keeps it for the next try
        return out

    async def align_map(
        self, uploads: Uploads, msg: P.SiteAlignMap, actor: str | None
    ) -> dict[str, Any]:
        """Fit the floor plan onto the map from the owner's matched spots; with ``apply``,
        store the plan (its bytes as given: browsers decode it) and draw it under the map
        everywhere.

        A plan pixel (column, row) counts rows downwards and the map's y goes up, so the fit
        carries (column, -row): a similarity has no mirror."""
        plan = None if msg.upload is None else bytes(uploads.take(msg.upload, "plan").data)
        if self._places.map is None:
            raise Conflict("there is no map yet to fit the floor plan onto")
        src = [(p.plan[0], -p.plan[1]) for p in msg.points]
        dst = [(p.map[0], p.map[1]) for p in msg.points]
        # Spots bunched together are refused by their spread on the map (metres): the same
        # spots on the plan are bunched too.
        t = fit(src, dst)
        if not MIN_SCALE <= t.scale <= MAX_SCALE or matches_nothing(t, dst):
            # Spots in another order on the two pictures, or a plan mirrored.
            raise InvalidField(
                "the spots do not match: mark them in the same order on the plan and the map",
                field="points",
                reason="mismatch",
            )
        out: dict[str, Any] = {"alignment": _fit_info(t)}
        if not msg.apply:
            return out
        if msg.upload is None or plan is None:
            raise InvalidField(
                "give the floor plan's upload to draw it under the map", field="upload"
            )
        mime = next((m for magic, m in _MIMES.items() if plan.startswith(magic)), None)
        if mime is None:
            raise InvalidField("the floor plan is not a PNG or JPEG picture", field="upload")
        digest = hashlib.sha256(plan).hexdigest()[:32]
        stored = StoredBackdrop(
            plan, mime, digest, t.scale, t.rotation, t.tx, t.ty, t.rms, len(msg.points)
        )
        await self._store.site_backdrop.put(stored, now=self._clock.epoch(), by=actor)
        self._places.use_backdrop(_backdrop_info(stored))
        uploads.done(msg.upload)
        log.info("the floor plan fitted onto the map (%d points, rms %.3f m)", len(src), t.rms)
        return out

    async def backdrop_image(self, digest: str) -> tuple[bytes, str] | None:
        """The floor plan's image and its type, if ``digest`` names the one under the map.

        Asked without a login (an image element's GET): another digest is answered from
        memory, and the image is read from the database once, not once per request."""
        shown = self._places.backdrop
        if shown is None or shown["url"] != f"{BACKDROP_PATH}{digest}":
            return None
        if self._image is None or self._image[0] != digest:
            got = await self._store.site_backdrop.get()
            if got is None or got.digest != digest:
                return None
            self._image = (digest, got.image, got.mime)
        return self._image[1], self._image[2]

    async def _use(self, m: MapData, source: str, actor: str | None) -> list[str]:
        """Store ``m`` as the restaurant's map and use it; the places now off free floor."""
        stored = StoredMap(m.resolution, m.origin[:2], m.width, m.height, m.data, source)
        await self._store.site_map.put(stored, now=self._clock.epoch(), by=actor)
        # A floor plan fitted onto the old map would sit wrong on this one (another frame).
        if await self._store.site_backdrop.clear():
            self._places.backdrop = None
        self._places.use_map(m)
        outside = self._places.outside(m)
        log.info("the owner set the map from %s; places off free floor: %s", source, outside)
        return outside
