"""A floor-plan image turned into the map robots and serveur use (pure: numpy and Pillow).

The design report made its map from the site's fire-escape plan with a script (MakeROSMap.py,
../shared/notes/field.md) that fixed 0.05 m a pixel and origin [-1, -1], resized with cubic
interpolation — grey edges a map reads as unknown — and left its red click markers in the map
as walls. Here, step by step, each a function the owner's page calls with a live preview:

1. :func:`read_plan`: the uploaded image, refused with a clear reason when it is not an image
   or is too large (bytes or pixels), as grey levels;
2. :func:`walls`: dark is wall, light is floor, split at a threshold the owner moves;
3. :func:`edit`: strokes that erase (a table drawn on the plan, text, a dimension line) or draw
   walls (a glass wall the plan shows faintly), on the mask only, never on the plan;
4. :func:`scale_from`: the scale from two distances measured on the floor, one across and one
   along the room; a plan stretched when it was scanned or exported gives two scales that
   disagree, which :attr:`Scale.stretched` reports (more than :data:`STRETCH_WARN`);
5. :func:`to_map`: the mask resampled to the map's cells with no interpolation — a cell is a
   wall if any plan pixel it covers is (a thin wall line never vanishes between two cells), a
   plan pixel larger than a cell is copied to each cell it covers — so the map is trinary like
   map_saver's, with its resolution and origin stated.

The result is an :class:`~serveur.maps.mapio.OccupancyMap`, saved as map_server's YAML + PGM
(:func:`serveur.maps.mapio.save_map`) for the robot and used by serveur itself.
"""

from __future__ import annotations

import base64
import io
import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from serveur.errors import InvalidField, MapError
from serveur.maps.child import serve_child
from serveur.maps.mapio import OccupancyMap

__all__ = [
    "MAX_PLAN_BYTES",
    "MAX_PLAN_PIXELS",
    "STRETCH_WARN",
    "Measure",
    "Scale",
    "Stroke",
    "edit",
    "read_plan",
    "scale_from",
    "to_map",
    "walls",
]

#: The largest plan accepted: an A3 scan at 300 dpi is ~4960x3500 (17 Mpx), a few MB as PNG.
MAX_PLAN_BYTES: Final = 25 * 1024 * 1024
MAX_PLAN_PIXELS: Final = 40_000_000
#: Two scales disagreeing by more than this (relative) mean a stretched plan: said to the owner.
STRETCH_WARN: Final = 0.03
_FORMATS: Final = ("PNG", "JPEG")

Pixel = tuple[float, float]  # (column, row) from the image's top-left corner
Mask = npt.NDArray[np.bool_]


def read_plan(data: bytes) -> npt.NDArray[np.uint8]:
    """The plan's grey levels (rows from the top), or :class:`MapError` saying why not."""
    from PIL import Image, UnidentifiedImageError

    if len(data) > MAX_PLAN_BYTES:
        raise MapError(
            f"the plan is {len(data) / 1e6:.0f} MB: at most {MAX_PLAN_BYTES // 2**20} MB",
            reason="too_large",
        )
    try:
        with Image.open(io.BytesIO(data)) as img:
            if img.format not in _FORMATS:
                raise MapError(
                    f"the plan must be a PNG or JPEG image, not {img.format or 'this file'}",
                    reason="not_an_image",
                )
            w, h = img.size
            if w * h > MAX_PLAN_PIXELS:
                raise MapError(
                    f"the plan is {w}x{h} pixels: at most {MAX_PLAN_PIXELS // 1_000_000} million",
                    reason="too_large",
                )
            grey = img.convert("L")  # decoded only now, once its size is known to be sane
            return np.asarray(grey, dtype=np.uint8).copy()
    except UnidentifiedImageError as exc:
        raise MapError("the file is not an image (PNG or JPEG)", reason="not_an_image") from exc
    except (OSError, ValueError, Image.DecompressionBombError) as exc:
        raise MapError(f"the image cannot be read: {exc}", reason="not_an_image") from exc


def walls(grey: npt.NDArray[np.uint8], threshold: int) -> Mask:
    """Wall where the plan is darker than ``threshold`` (0-255)."""
    if not 0 <= threshold <= 255:
        raise InvalidField("the threshold is a grey level from 0 to 255", field="threshold")
    return np.asarray(grey < threshold)


@dataclass(frozen=True, slots=True)
class Stroke:
    """A line drawn by the owner on the plan: ``wall`` adds wall, ``erase`` makes floor."""

    kind: str
    points: tuple[Pixel, ...]
    width: float  # pixels

    def __post_init__(self) -> None:
        if self.kind not in ("wall", "erase"):
            raise InvalidField("a stroke draws a wall or erases", field="kind")
        if not self.points or not 0 < self.width <= 500:
            raise InvalidField("a stroke has points and a width of 1-500 pixels", field="stroke")


def edit(mask: Mask, strokes: Sequence[Stroke]) -> Mask:
    """``mask`` with the strokes drawn on it, in order (a copy)."""
    from PIL import Image, ImageDraw

    h, w = mask.shape
    out = mask.copy()
    for stroke in strokes:
        layer = Image.new("1", (w, h), 0)
        draw = ImageDraw.Draw(layer)
        pts = [(float(x), float(y)) for x, y in stroke.points]
        width = max(1, round(stroke.width))
        if len(pts) > 1:
            draw.line(pts, fill=1, width=width, joint="curve")
        r = width / 2
        for x, y in pts:  # round ends, and a single tap
            draw.ellipse((x - r, y - r, x + r, y + r), fill=1)
        touched = np.asarray(layer, dtype=bool)
        out[touched] = stroke.kind == "wall"
    return out


@dataclass(frozen=True, slots=True)
class Measure:
    """Two points on the plan and the distance measured between them on the floor (m)."""

    a: Pixel
    b: Pixel
    metres: float

    def pixels(self) -> float:
        return math.hypot(self.b[0] - self.a[0], self.b[1] - self.a[1])


@dataclass(frozen=True, slots=True)
class Scale:
    """Metres a plan pixel spans across (x) and along (y), and whether they disagree."""

    x: float
    y: float

    @property
    def disagreement(self) -> float:
        """|x - y| relative to their mean: 0 for an undistorted plan."""
        return abs(self.x - self.y) / ((self.x + self.y) / 2)

    @property
    def stretched(self) -> bool:
        return self.disagreement > STRETCH_WARN


def scale_from(across: Measure, along: Measure) -> Scale:
    """The plan's scale from a distance measured across the room (mostly horizontal on the
    plan) and one along it (mostly vertical). Each gives metres per pixel on its own axis; a
    measure at an angle counts for the axis it leans to most."""
    for m in (across, along):
        if not (math.isfinite(m.metres) and m.metres > 0):
            raise InvalidField("a measured distance is a positive number of metres", field="metres")
        if m.pixels() < 10:
            raise InvalidField("mark the two ends of a measure further apart", field="points")
    dx = abs(across.b[0] - across.a[0])
    dy = abs(along.b[1] - along.a[1])
    if dx < abs(across.b[1] - across.a[1]) or dy < abs(along.b[0] - along.a[0]):
        raise InvalidField(
            "measure one distance across the plan and one along it", field="measures"
        )
    return Scale(across.metres / across.pixels(), along.metres / along.pixels())


def to_map(
    mask: Mask,
    scale: Scale,
    *,
    resolution: float = 0.05,
    origin: tuple[float, float] = (0.0, 0.0),
) -> OccupancyMap:
    """The wall mask as an occupancy map of ``resolution`` m cells, the plan's bottom-left
    corner at ``origin``: 100 wall, 0 floor (see the module's docstring for the sampling)."""
    if not (math.isfinite(resolution) and 0.01 <= resolution <= 1.0):
        raise InvalidField("the map's cells are 0.01-1 m", field="resolution")
    h_px, w_px = mask.shape
    width = math.ceil(w_px * scale.x / resolution)
    height = math.ceil(h_px * scale.y / resolution)
    if width * height > MAX_PLAN_PIXELS:
        raise MapError("the map would be too large: check the scale", reason="too_large")
    # Plan pixels [lo, hi) each cell covers, along x (columns) and y (rows counted from the
    # bottom, as a map's rows are); at least one pixel when a pixel is larger than a cell.
    cols = _spans(width, resolution / scale.x, w_px)
    rows = _spans(height, resolution / scale.y, h_px)
    # Rows of the plan go down; rows of the map go up.
    flipped = mask[::-1, :]
    integral = np.zeros((h_px + 1, w_px + 1), dtype=np.int64)
    integral[1:, 1:] = flipped.astype(np.int64).cumsum(0).cumsum(1)
    r0, r1 = rows[:, 0][:, None], rows[:, 1][:, None]
    c0, c1 = cols[:, 0][None, :], cols[:, 1][None, :]
    covered = integral[r1, c1] - integral[r0, c1] - integral[r1, c0] + integral[r0, c0]
    grid = np.where(covered > 0, 100, 0).astype(np.int8)
    return OccupancyMap(grid, resolution, (float(origin[0]), float(origin[1]), 0.0))


def _spans(cells: int, px_per_cell: float, limit: int) -> npt.NDArray[np.int64]:
    starts = np.floor(np.arange(cells) * px_per_cell).astype(np.int64)
    ends = np.ceil((np.arange(cells) + 1) * px_per_cell).astype(np.int64)
    starts = np.clip(starts, 0, limit - 1)
    ends = np.clip(np.maximum(ends, starts + 1), 1, limit)
    return np.stack([starts, ends], axis=1)


# -- in a child process: the server never decodes images itself --------------------------------


def plan_to_map(
    data: bytes,
    threshold: int,
    strokes: Sequence[Stroke],
    across: Measure,
    along: Measure,
    resolution: float,
) -> tuple[OccupancyMap, Scale]:
    """The whole pipeline: read, walls, edits, scale, resample (origin at the plan's
    bottom-left corner, as map_saver's maps start at their lower-left cell)."""
    grey = read_plan(data)
    mask = edit(walls(grey, threshold), strokes)
    scale = scale_from(across, along)
    return to_map(mask, scale, resolution=resolution), scale


def _answer(req: dict[str, Any]) -> dict[str, Any]:
    """The child's work (``site plan_map``, serveur.core.site_map): the map and the scale."""
    from serveur.maps.distances import MapData

    def measure(m: dict[str, Any]) -> Measure:
        return Measure(tuple(m["a"]), tuple(m["b"]), float(m["metres"]))

    m, scale = plan_to_map(
        base64.b64decode(req["plan"]),
        int(req["threshold"]),
        [
            Stroke(s["kind"], tuple(map(tuple, s["points"])), float(s["width"]))
            for s in req["strokes"]
        ],
        measure(req["across"]),
        measure(req["along"]),
        float(req["resolution"]),
    )
    return {
        "map": MapData.from_occupancy(m).snapshot(),
        "scale": {
            "x": scale.x,
            "y": scale.y,
            "disagreement": scale.disagreement,
            "stretched": scale.stretched,
        },
    }


if __name__ == "__main__":
    sys.exit(serve_child(_answer))
