"""Restaurant maps and waypoints: the data model and the files they live in.

Robots localise on a ROS ``map_server`` map (YAML metadata + a PGM/PNG image), usually saved
from a SLAM run with ``map_saver``. The fleet server must read exactly the grid the robots
read, otherwise a path the server thinks is free is a wall for the robot; so this module
follows map_server's pixel semantics to the letter and writes files map_server reads back
cell-for-cell. Everything malformed becomes :class:`~serveur.errors.MapError` at this boundary,
so a bad file on disk is one clear error code instead of a PIL, YAML or OS traceback.

Planning on the map lives in :mod:`serveur.maps.navigation`, which re-exports everything here.
"""

from __future__ import annotations

import io
import json
import math
import os
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from serveur.errors import InvalidField, MapError

if TYPE_CHECKING:
    import numpy as np

# numpy, PyYAML and Pillow are imported by the functions that use them: the server process
# reads waypoint files through this module but never a map (serveur.maps.distances plans in a child
# process), and must not carry those libraries' ~20 MB for nothing.

__all__ = [
    "WAYPOINT_KINDS",
    "OccupancyMap",
    "Waypoint",
    "demo_map_path",
    "demo_waypoints_path",
    "load_demo",
    "load_map",
    "load_waypoints",
    "save_map",
    "save_map_cells",
    "save_waypoints",
]

WAYPOINT_KINDS = frozenset({"table", "home", "pass", "other", "dish_return", "dock"})

_DATA = Path(__file__).resolve().parent.parent / "data"  # serveur/data/: the demo room
_MODES = ("trinary", "scale", "raw")
# map_saver's pixel values and the thresholds it writes: 254 -> p=0.004 (free), 0 -> p=1.0
# (occupied), 205 -> p=0.196078..., which is neither < 0.196 nor > 0.65, hence unknown.
_FREE_PX, _OCC_PX, _UNKNOWN_PX = 254, 0, 205
_SAVE_OCC_THRESH, _SAVE_FREE_THRESH = 0.65, 0.196
# map_saver (noetic) thresholds for grids holding graded values 1..99.
_SAVER_FREE_MAX, _SAVER_OCC_MIN = 25, 65


@dataclass(frozen=True)
class Waypoint:
    """A named pose on the map: a table's serving spot, a robot's home, the kitchen pass.

    Validated on construction because waypoints are also created at run time from client
    requests; a NaN coordinate would otherwise surface much later as a planner failure.
    """

    name: str
    x: float
    y: float
    yaw: float
    kind: str

    def __post_init__(self) -> None:
        if not isinstance(self.name, str) or not self.name:
            raise InvalidField("waypoint name must be a non-empty string", field="name")
        for field in ("x", "y", "yaw"):
            value = getattr(self, field)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise InvalidField(f"waypoint {self.name!r}: {field} must be a number", field=field)
            if not math.isfinite(value):
                raise InvalidField(f"waypoint {self.name!r}: {field} must be finite", field=field)
            object.__setattr__(self, field, float(value))
        if not isinstance(self.kind, str) or self.kind not in WAYPOINT_KINDS:
            raise InvalidField(
                f"waypoint {self.name!r}: kind must be one of {sorted(WAYPOINT_KINDS)}, "
                f"not {self.kind!r}",
                field="kind",
            )
        object.__setattr__(self, "kind", str(self.kind))  # a StrEnum member becomes plain str


@dataclass(frozen=True, eq=False)
class OccupancyMap:
    """An occupancy grid in ROS ``nav_msgs/OccupancyGrid`` layout.

    ``grid[row, col]``: row 0 is the lowest y, so ``grid.ravel()`` is exactly the ROS ``data``
    array. Values: -1 unknown, 0 free, 1..100 occupancy. The grid is stored as a read-only
    copy because planners cache what they derive from it; build a new map to change it.

    ``origin`` is the pose of the lower-left corner of cell (0, 0). Only yaw == 0 is
    supported (a rotated map is rejected with MapError): map_saver never writes another yaw,
    and most of the ROS navigation stack ignores it anyway.
    """

    grid: np.ndarray
    resolution: float
    origin: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        import numpy as np

        grid = np.asarray(self.grid)
        if grid.ndim != 2 or grid.shape[0] == 0 or grid.shape[1] == 0:
            raise MapError(f"occupancy grid must be a non-empty 2-D array, got shape {grid.shape}")
        if not np.issubdtype(grid.dtype, np.integer):
            raise MapError(f"occupancy grid must hold integers, got {grid.dtype}")
        if grid.size and (int(grid.min()) < -1 or int(grid.max()) > 100):
            raise MapError("occupancy grid values must be -1 (unknown) or 0..100")
        res = float(self.resolution)
        if not (math.isfinite(res) and res > 0):
            raise MapError(f"map resolution must be a positive number, got {self.resolution!r}")
        if len(self.origin) != 3:
            raise MapError(f"map origin must be [x, y, yaw], got {self.origin!r}")
        ox, oy, oyaw = (float(v) for v in self.origin)
        if not all(math.isfinite(v) for v in (ox, oy, oyaw)):
            raise MapError(f"map origin must be finite, got {self.origin!r}")
        if abs(oyaw) > 1e-9:
            raise MapError(
                f"rotated maps are not supported (origin yaw {oyaw}); re-save with yaw 0"
            )
        frozen = np.array(grid, dtype=np.int8)  # always a private copy
        frozen.flags.writeable = False
        object.__setattr__(self, "grid", frozen)
        object.__setattr__(self, "resolution", res)
        object.__setattr__(self, "origin", (ox, oy, 0.0))

    @property
    def width(self) -> int:
        """Number of columns (cells along x)."""
        return int(self.grid.shape[1])

    @property
    def height(self) -> int:
        """Number of rows (cells along y)."""
        return int(self.grid.shape[0])

    def world_to_cell(self, x: float, y: float) -> tuple[int, int]:
        """The (row, col) containing world point (x, y); may be out of bounds (see in_bounds)."""
        if not (math.isfinite(x) and math.isfinite(y)):
            raise InvalidField(f"not a finite point: ({x}, {y})", field="position")
        return (
            math.floor((y - self.origin[1]) / self.resolution),
            math.floor((x - self.origin[0]) / self.resolution),
        )

    def cell_to_world(self, row: int, col: int) -> tuple[float, float]:
        """World coordinates of the centre of cell (row, col)."""
        return (
            self.origin[0] + (col + 0.5) * self.resolution,
            self.origin[1] + (row + 0.5) * self.resolution,
        )

    def in_bounds(self, row: int, col: int) -> bool:
        """Whether (row, col) is a cell of the grid."""
        return 0 <= row < self.height and 0 <= col < self.width

    def is_free(self, x: float, y: float) -> bool:
        """Whether the raw (not inflated) cell under (x, y) is known free; False off the map."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        row, col = self.world_to_cell(x, y)
        return self.in_bounds(row, col) and int(self.grid[row, col]) == 0


# --- reading ------------------------------------------------------------------------------


def _number(meta: dict[str, Any], key: str, where: Path) -> float:
    """A finite float from the YAML. Strings are accepted: PyYAML (YAML 1.1) reads ``1e-05``
    as a string while ROS's yaml-cpp reads it as a number, and such files exist."""
    if key not in meta:
        raise MapError(f"{where}: missing required key {key!r}", path=str(where))
    value = meta[key]
    try:
        if isinstance(value, bool):
            raise ValueError
        out = float(value)
    except (TypeError, ValueError):
        raise MapError(f"{where}: {key} must be a number, got {value!r}", path=str(where)) from None
    if not math.isfinite(out):
        raise MapError(f"{where}: {key} must be finite, got {value!r}", path=str(where))
    return out


def _read_meta(yaml_path: Path) -> dict[str, Any]:
    import yaml

    try:
        text = yaml_path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise MapError(f"cannot read map file {yaml_path}: {exc}", path=str(yaml_path)) from exc
    try:
        meta = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise MapError(f"{yaml_path}: invalid YAML: {exc}", path=str(yaml_path)) from exc
    if not isinstance(meta, dict):
        raise MapError(f"{yaml_path}: expected a YAML mapping of map metadata", path=str(yaml_path))
    return meta


def _read_image(image_path: Path) -> tuple[np.ndarray, np.ndarray | None]:
    """Grey level (float, 0..255, mean of the colour channels as map_server computes it) and
    the alpha channel if the image has one."""
    import numpy as np
    from PIL import Image, UnidentifiedImageError

    try:
        with Image.open(image_path) as img:
            img.load()
            if img.mode in ("I", "I;16", "I;16B", "I;16L", "F"):
                raise MapError(
                    f"{image_path}: {img.mode} images (16-bit/float) are not supported; "
                    "save the map as 8-bit grey",
                    path=str(image_path),
                )
            if img.mode in ("L", "LA", "RGB", "RGBA"):
                arr = np.asarray(img)
            else:  # palette, 1-bit, CMYK...: let Pillow expand it to colour
                has_alpha = img.mode in ("PA", "La") or "transparency" in img.info
                arr = np.asarray(img.convert("RGBA" if has_alpha else "RGB"))
    except MapError:
        raise
    except (OSError, UnidentifiedImageError, ValueError, SyntaxError) as exc:
        # Pillow reports bad headers as ValueError/SyntaxError and truncation as OSError.
        raise MapError(f"cannot read map image {image_path}: {exc}", path=str(image_path)) from exc
    if arr.ndim == 2:
        return arr.astype(np.float64), None
    if arr.shape[2] in (2, 4):
        return arr[:, :, :-1].mean(axis=2), arr[:, :, -1]
    return arr.mean(axis=2), None


def load_map(yaml_path: str | Path) -> OccupancyMap:
    """Read a ROS map_server map (YAML + PGM P5/P2 or PNG) into the grid map_server builds.

    Pixel rules (ROS 1 map_server): ``p = (255 - grey) / 255``, or ``grey / 255`` with
    ``negate``; grey is the mean of the colour channels. ``trinary`` (default): p >
    occupied_thresh is 100, p < free_thresh is 0, anything else -1. ``scale``: the same ends,
    in between ``1 + 98 * (p - free) / (occ - free)``, and any transparent pixel is unknown
    (as the ROS wiki and Nav2 say; ROS 1's code only applies alpha to in-between greys).
    ``raw``: the grey value itself when it is 0..100, else unknown (as Nav2 does; ROS 1 would
    wrap it into a negative int8). The image's top row is the map's highest y, so it is flipped.
    Deviation: in trinary mode ROS 1 averages alpha into the grey level (a quirk that turns
    opaque unknown grey into free); here alpha never changes the grey level.
    """
    import numpy as np

    yaml_path = Path(yaml_path)
    meta = _read_meta(yaml_path)
    if not isinstance(meta.get("image"), str) or not meta["image"]:
        raise MapError(f"{yaml_path}: missing or empty 'image'", path=str(yaml_path))
    resolution = _number(meta, "resolution", yaml_path)
    occ_th = _number(meta, "occupied_thresh", yaml_path)
    free_th = _number(meta, "free_thresh", yaml_path)
    if "negate" not in meta or meta["negate"] not in (0, 1):  # True/False compare equal to 1/0
        raise MapError(f"{yaml_path}: negate must be 0 or 1", path=str(yaml_path))
    negate = bool(meta["negate"])
    origin = meta.get("origin")
    if not isinstance(origin, list | tuple) or len(origin) != 3:
        raise MapError(f"{yaml_path}: origin must be [x, y, yaw], got {origin!r}")
    origin_xyz = tuple(_number({"origin": v}, "origin", yaml_path) for v in origin)
    mode = meta.get("mode", "trinary")
    if mode not in _MODES:
        raise MapError(f"{yaml_path}: mode must be one of {_MODES}, got {mode!r}")
    if not (0.0 <= free_th <= occ_th <= 1.0):
        raise MapError(
            f"{yaml_path}: need 0 <= free_thresh <= occupied_thresh <= 1, "
            f"got free_thresh={free_th} occupied_thresh={occ_th}"
        )

    grey, alpha = _read_image(yaml_path.parent / meta["image"])  # absolute image paths win
    if negate:
        grey = 255.0 - grey
    occ = (255.0 - grey) / 255.0
    if mode == "raw":
        value = np.rint(grey)
        cells = np.where((value >= 0) & (value <= 100), value, -1)
    else:
        cells = np.full(grey.shape, -1, dtype=np.int16)
        if mode == "scale" and occ_th > free_th:
            between = 1 + 98 * (occ - free_th) / (occ_th - free_th)
            cells = between.astype(np.int16)  # C++ double -> int truncation, as map_server
        cells[occ > occ_th] = 100
        cells[occ < free_th] = 0
        if mode == "scale" and alpha is not None:
            cells[alpha < 255] = -1
    # The map's y axis points up, the image's rows go down.
    grid = np.flipud(cells).astype(np.int8)
    return OccupancyMap(grid, resolution, (origin_xyz[0], origin_xyz[1], origin_xyz[2]))


# --- writing ------------------------------------------------------------------------------


def _write_atomic(path: Path, data: bytes) -> None:
    """Write via a temporary file and rename, so a reader never sees half a map."""
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            fh.write(data)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def _saver_pixel(cell: int) -> int:
    """One cell (-1 unknown, 0..100 occupancy) as map_saver writes it (see :func:`save_map`)."""
    if 0 <= cell <= _SAVER_FREE_MAX:
        return _FREE_PX
    if cell >= _SAVER_OCC_MIN:
        return _OCC_PX
    return _UNKNOWN_PX


#: The signed byte of a cell (as the ``map`` topic carries it) -> its PGM pixel.
_PIXELS = bytes(_saver_pixel(b - 256 if b >= 128 else b) for b in range(256))


def save_map_cells(
    cells: bytes,
    width: int,
    height: int,
    resolution: float,
    origin: tuple[float, float, float],
    yaml_path: str | Path,
) -> None:
    """:func:`save_map` as PGM from the cells' bytes (int8, row 0 at the map's bottom), without
    numpy: the server writes the site for a forecast's replay in its own process, which must
    not load numpy (a child or a CLI reads it back with :func:`load_map`)."""
    if len(cells) != width * height:
        raise MapError(f"map data has {len(cells)} cells, expected {width}x{height}")
    pixels = cells.translate(_PIXELS)
    rows = [pixels[r * width : (r + 1) * width] for r in range(height - 1, -1, -1)]
    header = f"P5\n# CREATOR: serveur {resolution:.3f} m/pix\n{width} {height}\n255\n"
    _write_map(Path(yaml_path), "pgm", header.encode("ascii") + b"".join(rows), resolution, origin)


def save_map(m: OccupancyMap, yaml_path: str | Path, image_format: str = "pgm") -> None:
    """Write ``m`` as map_saver does: YAML + image (``<yaml stem>.pgm`` or ``.png``).

    Free is 254, occupied 0, unknown 205, thresholds 0.65/0.196, trinary: map_server and
    :func:`load_map` read a trinary grid (-1/0/100) back identically. Graded cells (1..99)
    are thresholded like map_saver: <= 25 free, >= 65 occupied, else unknown.
    """
    import numpy as np
    from PIL import Image

    yaml_path = Path(yaml_path)
    fmt = image_format.lower()
    if fmt not in ("pgm", "png"):
        raise MapError(f"image_format must be 'pgm' or 'png', got {image_format!r}")
    g = m.grid
    # The same byte table as save_map_cells: one rule for what each cell is written as.
    cells = np.ascontiguousarray(g, dtype=np.int8).tobytes()
    pixels = np.frombuffer(cells.translate(_PIXELS), dtype=np.uint8).reshape(g.shape)
    pixels = np.ascontiguousarray(np.flipud(pixels))
    if fmt == "pgm":
        header = f"P5\n# CREATOR: serveur {m.resolution:.3f} m/pix\n{m.width} {m.height}\n255\n"
        image_bytes = header.encode("ascii") + pixels.tobytes()
    else:
        buf = io.BytesIO()
        Image.fromarray(pixels, mode="L").save(buf, format="PNG")
        image_bytes = buf.getvalue()
    _write_map(yaml_path, fmt, image_bytes, m.resolution, m.origin)


def _write_map(
    yaml_path: Path,
    fmt: str,
    image_bytes: bytes,
    resolution: float,
    origin: tuple[float, float, float],
) -> None:
    """The image beside its YAML, each written whole (a reader never sees half a map)."""
    import yaml

    image_path = yaml_path.with_suffix(f".{fmt}")
    meta = {
        "image": image_path.name,
        "resolution": resolution,
        "origin": [origin[0], origin[1], origin[2]],
        "negate": 0,
        "occupied_thresh": _SAVE_OCC_THRESH,
        "free_thresh": _SAVE_FREE_THRESH,
        "mode": "trinary",
    }
    text = yaml.safe_dump(meta, default_flow_style=None, sort_keys=False)
    try:
        _write_atomic(image_path, image_bytes)
        _write_atomic(yaml_path, text.encode("utf-8"))
    except OSError as exc:
        raise MapError(f"cannot write map {yaml_path}: {exc}", path=str(yaml_path)) from exc


# --- waypoints ----------------------------------------------------------------------------


def load_waypoints(path: str | Path) -> dict[str, Waypoint]:
    """Read ``{"waypoints": [{"name", "x", "y", "yaw", "kind"}, ...]}`` keyed by name.

    ``yaw`` defaults to 0 and ``kind`` to "other"; duplicate names are an error rather than
    a silent overwrite, because two different "T7" spots would send food to the wrong table.
    """
    path = Path(path)
    try:
        doc = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise MapError(f"cannot read waypoints {path}: {exc}", path=str(path)) from exc
    items = doc.get("waypoints") if isinstance(doc, dict) else None
    if not isinstance(items, list):
        raise MapError(f"{path}: expected an object with a 'waypoints' list", path=str(path))
    out: dict[str, Waypoint] = {}
    for i, item in enumerate(items):
        if not isinstance(item, dict) or "name" not in item or "x" not in item or "y" not in item:
            raise MapError(f"{path}: waypoint #{i} needs at least name, x and y", path=str(path))
        try:
            wp = Waypoint(
                item["name"], item["x"], item["y"], item.get("yaw", 0.0), item.get("kind", "other")
            )
        except InvalidField as exc:
            raise MapError(f"{path}: waypoint #{i}: {exc.message}", path=str(path)) from exc
        if wp.name in out:
            raise MapError(f"{path}: duplicate waypoint name {wp.name!r}", path=str(path))
        out[wp.name] = wp
    return out


def save_waypoints(waypoints: dict[str, Waypoint], path: str | Path) -> None:
    """Write waypoints in the format :func:`load_waypoints` reads (coordinates to the mm)."""
    lines = [
        json.dumps(
            {"name": w.name, "x": round(w.x, 3), "y": round(w.y, 3), "yaw": round(w.yaw, 6)}
            | {"kind": w.kind}
        )
        for w in waypoints.values()
    ]
    text = '{"waypoints": [\n  ' + ",\n  ".join(lines) + "\n]}\n"  # one waypoint a line
    try:
        _write_atomic(Path(path), text.encode("utf-8"))
    except OSError as exc:
        raise MapError(f"cannot write waypoints {path}: {exc}", path=str(path)) from exc


# --- the packaged demo restaurant -----------------------------------------------------------


def demo_map_path() -> Path:
    """The demo dining room's map YAML shipped in the package (see bench/make_demo_map.py)."""
    return _DATA / "demo_restaurant.yaml"


def demo_waypoints_path() -> Path:
    """The demo dining room's waypoints: tables T1.., home1..home6 and the kitchen pass."""
    return _DATA / "demo_waypoints.json"


def load_demo() -> tuple[OccupancyMap, dict[str, Waypoint]]:
    """The demo map and its waypoints, ready for a Planner or the simulator."""
    return load_map(demo_map_path()), load_waypoints(demo_waypoints_path())
