"""Path distances between waypoints for the scheduler, planned outside the server's heap.

The scheduler asks "how far is T7 from T3" on every cart; the answer is the length of the path
a robot would drive, planned on the occupancy map (:mod:`serveur.maps.navigation`). Planning needs
numpy and, while it runs, ~35 MB of distance fields on the demo map. On a Raspberry Pi the server
is a process that runs for months, so it keeps only the answers (a dict of floats) and plans in
a short-lived child process, ``python -m serveur.maps.distances``, that reads a :class:`PlanRequest`
as JSON on stdin and writes the distances as JSON on stdout. The child's memory goes back to the
OS when it exits, and numpy never loads in the server (docs/performance.md, footprint).

The child is also what keeps the event loop free: planning is numpy and pure-Python loops that
hold the GIL for hundreds of milliseconds, so in a worker thread it starved the loop (requests
at 87-128 ms, robot links dropped at ``--time-scale 10``). Only the replay, whose virtual clock
does not see the loop's stalls and must not see a child's wall time, plans in a worker thread
(``in_child=False``). Both paths run the same :func:`plan` function, and an identical request
already being planned is waited for, not planned twice.

The map itself lives in the server as :class:`MapData`: the bytes of the grid and its geometry,
which is all the ``map`` topic sends to the UI. It is built without numpy from a map file (in
the child), from a robot's ``/map`` message or from an in-process ``OccupancyMap``.
"""

from __future__ import annotations

import asyncio
import base64
import hashlib
import json
import logging
import math
import sys
from array import array
from collections import OrderedDict
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from serveur.errors import MapError, NavigationError
from serveur.maps import plancache

__all__ = ["Distances", "MapData", "PlanRequest", "plan", "plan_async"]

log = logging.getLogger(__name__)

#: Waypoint as the planner needs it: name, x, y.
Spot = tuple[str, float, float]


@dataclass(frozen=True)
class MapData:
    """An occupancy grid as the server keeps it: int8 cells, row 0 = lowest y (as ROS)."""

    resolution: float
    origin: tuple[float, float, float]
    width: int
    height: int
    data: bytes = field(repr=False)

    def __post_init__(self) -> None:
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise MapError(f"map resolution must be a positive number, got {self.resolution!r}")
        if self.width <= 0 or self.height <= 0:
            raise MapError(f"map must be non-empty, got {self.width} x {self.height}")
        if len(self.data) != self.width * self.height:
            raise MapError("map data size does not match width x height")
        if not all(math.isfinite(v) for v in self.origin):
            raise MapError("map origin must be finite")

    def snapshot(self) -> dict[str, Any]:
        """The ``map`` topic's payload (docs/protocol.md)."""
        return {
            "resolution": self.resolution,
            "origin": list(self.origin),
            "width": self.width,
            "height": self.height,
            "encoding": "int8-base64",
            "data": base64.b64encode(self.data).decode("ascii"),
        }

    @classmethod
    def from_snapshot(cls, snap: Mapping[str, Any]) -> MapData:
        try:
            x, y, yaw = (float(v) for v in snap["origin"])
            return cls(
                float(snap["resolution"]),
                (x, y, yaw),
                int(snap["width"]),
                int(snap["height"]),
                base64.b64decode(snap["data"], validate=True),
            )
        except (KeyError, TypeError, ValueError) as exc:
            raise MapError(f"bad map snapshot: {exc}") from exc

    @classmethod
    def from_grid_msg(cls, msg: Mapping[str, Any]) -> MapData:
        """A ``nav_msgs/OccupancyGrid`` as rosbridge delivers it (``data``: list of int8)."""
        from serveur.robots import rosbridge as rb

        try:
            info = msg["info"]
            raw = msg["data"]
            cells = bytes(raw) if isinstance(raw, bytes | bytearray) else array("b", raw).tobytes()
            return cls(
                float(info["resolution"]),
                rb.pose_from_msg(info["origin"]),
                int(info["width"]),
                int(info["height"]),
                cells,
            )
        except (KeyError, TypeError, ValueError, OverflowError) as exc:
            raise MapError(f"unusable OccupancyGrid: {exc}") from exc

    @classmethod
    def from_occupancy(cls, m: Any) -> MapData:
        """From a :class:`serveur.maps.mapio.OccupancyMap` (numpy grid) held in this process."""
        import numpy as np

        x, y, yaw = (float(v) for v in m.origin)
        grid = np.ascontiguousarray(m.grid, dtype=np.int8)
        return cls(float(m.resolution), (x, y, yaw), int(m.width), int(m.height), grid.tobytes())

    def goal_problem(self, x: float, y: float) -> tuple[str, str] | None:
        """Why a robot cannot be sent to (x, y): ``(reason, message)``, or None if it may.

        The planner's own first checks, without numpy (the server does not load it): outside
        the map, in unknown space, inside an obstacle. A free cell too close to a wall is left
        to the robot's planner, which knows its footprint.
        """
        where = f"({x:.2f}, {y:.2f})"
        row = math.floor((y - self.origin[1]) / self.resolution)
        col = math.floor((x - self.origin[0]) / self.resolution)
        if not (0 <= row < self.height and 0 <= col < self.width):
            return "outside_map", f"{where} is outside the map"
        value = int.from_bytes(
            self.data[row * self.width + col : row * self.width + col + 1], "little", signed=True
        )
        if value < 0:
            return "unknown", f"{where} is in unknown space"
        if value > 0:
            return "occupied", f"{where} is inside an obstacle"
        return None

    def to_occupancy(self) -> Any:
        import numpy as np

        from serveur.maps.mapio import OccupancyMap

        grid = np.frombuffer(self.data, dtype=np.int8).reshape(self.height, self.width)
        return OccupancyMap(grid, self.resolution, self.origin)


@dataclass(frozen=True)
class PlanRequest:
    """What to plan: a map (file or data), the spots, and which rows (``sources``) to fill.

    ``sources`` None means every pair; otherwise the pairs with at least one end in
    ``sources`` (a waypoint just added or moved).
    """

    spots: Sequence[Spot]
    robot_radius: float
    map: MapData | None = None
    map_path: str | None = None
    sources: Sequence[str] | None = None

    def to_json(self) -> str:
        return json.dumps(
            {
                "spots": [list(s) for s in self.spots],
                "robot_radius": self.robot_radius,
                "map": self.map.snapshot() if self.map is not None else None,
                "map_path": self.map_path,
                "sources": list(self.sources) if self.sources is not None else None,
            }
        )

    @classmethod
    def from_json(cls, text: str) -> PlanRequest:
        d = json.loads(text)
        return cls(
            spots=[(str(n), float(x), float(y)) for n, x, y in d["spots"]],
            robot_radius=float(d["robot_radius"]),
            map=MapData.from_snapshot(d["map"]) if d.get("map") else None,
            map_path=d.get("map_path"),
            sources=d.get("sources"),
        )


@dataclass
class PlanResult:
    """The map that was planned on and the distances: metres, or None if unreachable."""

    map: MapData
    pairs: dict[tuple[str, str], float | None]
    #: The planned path of each reachable pair, from its first name to its second (the zones
    #: a leg crosses are read off it: serveur.core.leases).
    paths: dict[tuple[str, str], list[tuple[float, float]]] = field(default_factory=dict)
    #: Read from the plan cache on disk rather than planned by this run (not serialised).
    cached: bool = False

    def to_json(self) -> str:
        return json.dumps(
            {
                "map": self.map.snapshot(),
                "pairs": [[a, b, d] for (a, b), d in self.pairs.items()],
                "paths": [[a, b, [list(p) for p in pts]] for (a, b), pts in self.paths.items()],
            }
        )

    @classmethod
    def from_json(cls, text: str) -> PlanResult:
        d = json.loads(text)
        pairs = {(str(a), str(b)): (None if v is None else float(v)) for a, b, v in d["pairs"]}
        paths = {
            (str(a), str(b)): [(float(x), float(y)) for x, y in pts]
            for a, b, pts in d.get("paths", [])
        }
        return cls(MapData.from_snapshot(d["map"]), pairs, paths)


def plan(req: PlanRequest) -> PlanResult:
    """Plan the requested pairs (imports numpy: call it in a child or a worker thread)."""
    from serveur.maps import navigation as nav

    if req.map is not None:
        grid = req.map.to_occupancy()
        data = req.map
    elif req.map_path is not None:
        grid = nav.load_map(req.map_path)
        data = MapData.from_occupancy(grid)
    else:
        raise MapError("nothing to plan on: no map and no map file")
    planner = nav.Planner(grid, robot_radius=req.robot_radius)
    spots = {n: nav.Waypoint(n, x, y, 0.0, "other") for n, x, y in req.spots}
    table = nav.DistanceTable(planner, spots)
    names = sorted(spots)
    wanted = set(req.sources) if req.sources is not None else None
    pairs: dict[tuple[str, str], float | None] = {}
    paths: dict[tuple[str, str], list[tuple[float, float]]] = {}
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            if wanted is not None and a not in wanted and b not in wanted:
                continue
            try:
                pairs[(a, b)] = table.distance(a, b)
            except NavigationError:
                pairs[(a, b)] = None
                continue
            pts = table.path(a, b)
            if pts is not None:
                paths[(a, b)] = [(round(x, 3), round(y, 3)) for x, y in pts]
    return PlanResult(data, pairs, paths)


#: The last few plans made in this process, by request: the demo, the replay (one server per
#: policy) and the tests start servers on the same map and waypoints again and again, and each
#: plan costs ~0.75 s of CPU on the demo map. Results are immutable once made.
_RECENT: OrderedDict[str, PlanResult] = OrderedDict()
_RECENT_MAX = 8
#: Requests being planned now, by the same key: an identical request waits for that plan.
_INFLIGHT: dict[str, asyncio.Future[PlanResult]] = {}


async def plan_async(req: PlanRequest, *, in_child: bool, reuse: bool = True) -> PlanResult:
    """:func:`plan` off the event loop: in a child process, or in a worker thread.

    A failure in the child (a bad map file, say) comes back as the ServeurError the child
    raised, with its code and message; anything else the child dies of is a NavigationError.
    With ``reuse``, an identical request planned earlier in this process is answered from
    memory (a map file is read again each time: it may have changed on disk), and one planned
    by an earlier run from the plan cache on disk (:mod:`serveur.maps.plancache`, keyed by the
    request and the map file's bytes).
    """
    key = hashlib.sha256(req.to_json().encode()).hexdigest() if req.map is not None else ""
    if reuse and key and (hit := _RECENT.get(key)) is not None:
        _RECENT.move_to_end(key)
        return hit
    loop = asyncio.get_running_loop()
    running = _INFLIGHT.get(key) if reuse and key else None
    if running is not None and running.get_loop() is loop:
        try:
            return await asyncio.shield(running)
        except asyncio.CancelledError:
            if not running.cancelled():
                raise  # this caller was cancelled
            # The planner it waited for was cancelled (its server stopping): plan here.
    fut: asyncio.Future[PlanResult] = loop.create_future()
    if key:
        _INFLIGHT[key] = fut
    try:
        # Read, hashed and parsed off the loop: a cached plan is a few hundred kB of JSON.
        result = await asyncio.to_thread(_from_disk, req) if reuse else None
        if result is None:
            result = await (asyncio.to_thread(plan, req) if not in_child else _plan_in_child(req))
            await asyncio.to_thread(_to_disk, req, result)
    except Exception as exc:
        fut.set_exception(exc)
        fut.exception()  # retrieved: nobody else may be waiting
        raise
    except BaseException:
        fut.cancel()
        raise
    finally:
        if key and _INFLIGHT.get(key) is fut:
            del _INFLIGHT[key]
    fut.set_result(result)
    if key:
        _RECENT[key] = result
        while len(_RECENT) > _RECENT_MAX:
            _RECENT.popitem(last=False)
    return result


def _disk_key(req: PlanRequest) -> str | None:
    """The plan cache's key of ``req``: its JSON, and the map file's bytes when it names one
    (so an edited map is another key). None when the map file cannot be read (planning then
    reports why)."""
    parts = [req.to_json().encode()]
    if req.map is None and req.map_path is not None:
        import yaml

        try:
            meta_bytes = Path(req.map_path).read_bytes()
            image = yaml.safe_load(meta_bytes).get("image")
            parts += [meta_bytes, (Path(req.map_path).parent / str(image)).read_bytes()]
        except (OSError, ValueError, AttributeError, yaml.YAMLError):
            return None
    return plancache.digest(*parts)


def _from_disk(req: PlanRequest) -> PlanResult | None:
    key = _disk_key(req)
    text = plancache.load(key) if key is not None else None
    if text is None:
        return None
    try:
        result = PlanResult.from_json(text)
        result.cached = True
        return result
    except (ValueError, KeyError, TypeError, MapError) as exc:
        log.warning("plan cache entry %s unreadable (planning again): %s", key, exc)
        return None


def _to_disk(req: PlanRequest, result: PlanResult) -> None:
    key = _disk_key(req)
    if key is not None:
        plancache.store(key, result.to_json())


async def _plan_in_child(req: PlanRequest) -> PlanResult:
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.maps.distances",
        stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        out, err = await proc.communicate(req.to_json().encode())
    finally:
        if proc.returncode is None:  # cancelled (server stopping): do not leave it behind
            proc.kill()
            await proc.wait()
    if proc.returncode == 0:
        return PlanResult.from_json(out.decode())
    try:
        e = json.loads(out.decode())["error"]
    except (ValueError, KeyError, TypeError):
        tail = err.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
        raise NavigationError(
            f"distance planner exited with {proc.returncode}: {tail[0]}"
        ) from None
    cls = MapError if e.get("code") == MapError.code else NavigationError
    raise cls(str(e.get("message")))


class Distances:
    """The scheduler's table of path distances; straight lines until a pair is planned.

    Entries remember the coordinates they were planned for, so a result that arrives after
    its waypoint moved is dropped rather than trusted.
    """

    def __init__(self) -> None:
        self._spots: dict[str, tuple[float, float]] = {}
        self._pairs: dict[tuple[str, str], float | None] = {}
        self._planned_at: dict[str, tuple[float, float]] = {}
        self._paths: dict[tuple[str, str], list[tuple[float, float]]] = {}

    def set_spots(self, spots: Iterable[Spot]) -> None:
        for name, x, y in spots:
            old = self._spots.get(name)
            self._spots[name] = (x, y)
            if old is not None and old != (x, y):
                self._pairs = {k: v for k, v in self._pairs.items() if name not in k}
                self._paths = {k: v for k, v in self._paths.items() if name not in k}

    def merge(self, req: PlanRequest, result: PlanResult) -> None:
        """Keep the planned pairs whose two ends are still where they were planned."""
        at = {n: (x, y) for n, x, y in req.spots}
        for (a, b), d in result.pairs.items():
            if self._spots.get(a) == at.get(a) and self._spots.get(b) == at.get(b):
                self._pairs[(a, b)] = d
                if (a, b) in result.paths:
                    self._paths[(a, b)] = result.paths[(a, b)]

    def path(self, a: str, b: str) -> list[tuple[float, float]] | None:
        """The planned path from ``a`` to ``b``, None until planned (or unreachable)."""
        if (a, b) in self._paths:
            return list(self._paths[(a, b)])
        back = self._paths.get((b, a))
        return None if back is None else back[::-1]

    def planned(self, a: str, b: str) -> float | None:
        """Metres of path if planned and reachable, else None."""
        key = (a, b) if a < b else (b, a)
        return self._pairs.get(key)

    def __len__(self) -> int:
        return len(self._pairs)


def _main() -> int:
    """Child process: a PlanRequest on stdin, a PlanResult (or an error) on stdout."""
    from serveur.errors import ServeurError

    try:
        result = plan(PlanRequest.from_json(sys.stdin.read()))
    except ServeurError as exc:
        print(json.dumps({"error": {"code": exc.code, "message": exc.message}}))
        return 1
    sys.stdout.write(result.to_json())
    return 0


if __name__ == "__main__":
    sys.exit(_main())
