"""Where a robot can go, how far it is, and what its lidar sees: planning on the restaurant map.

The fleet server needs distances between tables to batch deliveries, paths to send robots
along and to check that a waypoint someone clicked is reachable; the simulator needs laser
scans. All of it is pure, synchronous numpy on the :class:`~serveur.maps.mapio.OccupancyMap` the
robots localise on (no ROS needed), so it is deterministic and testable without an event loop.
Heavy calls (a new distance field: tens of milliseconds) should be run off the event loop by
the caller (``asyncio.to_thread``); repeated ones are cached.

Conventions: a robot is a disc of ``robot_radius``; anything not known free (occupied,
partially occupied or unknown, and everything off the map) is an obstacle for planning,
because bumping into a chair costs more than a detour. Paths are cheapest on the
8-connected inflated grid (length, plus a surcharge for hugging obstacles: see Planner),
then shortened by line-of-sight shortcuts into an any-angle polyline. Every failure is a
:class:`~serveur.errors.ServeurError` subclass.
"""

from __future__ import annotations

import itertools
import math
import threading
from collections import OrderedDict, deque
from collections.abc import Mapping, Sequence
from weakref import WeakKeyDictionary

import numpy as np

from serveur.errors import InvalidField, NavigationError, NotFound, Unreachable
from serveur.maps.mapio import (
    OccupancyMap,
    Waypoint,
    demo_map_path,
    demo_waypoints_path,
    load_demo,
    load_map,
    load_waypoints,
    save_map,
)

__all__ = [
    "HIT_THRESHOLD",
    "MARGIN_COST",
    "DistanceTable",
    "OccupancyMap",
    "Planner",
    "Waypoint",
    "demo_map_path",
    "demo_waypoints_path",
    "inflate",
    "load_demo",
    "load_map",
    "load_waypoints",
    "raycast",
    "save_map",
]

HIT_THRESHOLD = 65
"""Occupancy at which a laser ray stops (map_saver's own "occupied" threshold)."""

_SQRT2 = math.sqrt(2.0)
_FIELD_CACHE_BYTES = 256 * 2**20
MARGIN_COST = 3.0
"""What a metre driven right along the inflated obstacles costs the planner; the surcharge
falls off in steps to nothing at ``clearance`` further out (a costmap's inflation decay)."""
_BANDS = 3
_EPS = 1e-6  # cell units: how close to a grid line a point counts as touching both sides
# (d_row, d_col) of the 8 neighbours; diagonal moves also need both orthogonal cells free so
# that a path never squeezes between two blocked cells touching at a corner.
_MOVES = ((0, 1), (0, -1), (1, 0), (-1, 0), (1, 1), (1, -1), (-1, 1), (-1, -1))


def inflate(m: OccupancyMap, radius: float) -> np.ndarray:
    """Cells where a robot disc of ``radius`` (m) centred on the cell centre would collide.

    A cell collides when some obstacle cell (any value but 0, or off the map) comes strictly
    closer than ``radius`` to its centre, measured to the obstacle cell's nearest edge (to
    its centre would let a robot overlap an obstacle by up to half a cell). Vectorised: the
    disc is split into horizontal runs; each run is a sliding-window sum on row prefix sums
    shifted vertically, so the cost is O(radius) whole-array operations.
    """
    if not (math.isfinite(radius) and radius >= 0):
        raise InvalidField(f"radius must be a finite number >= 0, got {radius}", field="radius")
    obstacle = m.grid != 0
    r = radius / m.resolution
    reach = math.ceil(r + 0.5)
    h, w = obstacle.shape
    padded = np.pad(obstacle, reach, constant_values=True)  # off the map is an obstacle
    prefix = np.zeros((padded.shape[0], padded.shape[1] + 1), dtype=np.int32)
    np.cumsum(padded, axis=1, out=prefix[:, 1:])
    cols = np.arange(reach, reach + w)
    out: np.ndarray = obstacle.copy()
    runs: dict[int, np.ndarray] = {}
    for dy in range(-reach, reach + 1):
        gap_y = max(abs(dy) - 0.5, 0.0)
        if gap_y * gap_y >= r * r:
            continue
        half = 0  # widest |dx| with an obstacle edge strictly inside the disc
        while (half + 0.5) ** 2 + gap_y * gap_y < r * r:
            half += 1
        if half not in runs:
            runs[half] = (prefix[:, cols + half + 1] - prefix[:, cols - half]) > 0
        out |= runs[half][reach + dy : reach + dy + h]
    return out


def _pair_costs(weight: np.ndarray, step: float) -> tuple[np.ndarray, ...]:
    """Cost of each allowed move between neighbouring cells: its length times the mean weight
    of its two cells (inf where a cell is blocked or a diagonal would cut a blocked corner).
    Returns (vertical (k, k+1) rows, horizontal (k, k+1) cols, diagonal (k, c)-(k+1, c+1),
    anti-diagonal (k, c+1)-(k+1, c))."""
    w = weight
    vertical = step * (w[1:] + w[:-1]) / 2
    horizontal = step * (w[:, 1:] + w[:, :-1]) / 2
    corners = np.isfinite(w[1:, 1:] + w[:-1, :-1] + w[:-1, 1:] + w[1:, :-1])
    diag = step * _SQRT2 / 2
    d1 = np.where(corners, diag * (w[:-1, :-1] + w[1:, 1:]), np.inf)
    d2 = np.where(corners, diag * (w[:-1, 1:] + w[1:, :-1]), np.inf)
    return vertical, horizontal, d1, d2


def _sweep_field(weight: np.ndarray, goal: tuple[int, int], step: float) -> np.ndarray:
    """Least cost to ``goal`` over 8-connected cells (see _pair_costs; inf weight = blocked).

    Gauss-Seidel sweeps (up, right, down, left) repeated until nothing improves: each row (or
    column) is relaxed in one vectorised step from its already-updated neighbour row, so a
    sweep carries costs across the whole map and a dozen or so sweeps converge on a dining
    room. Measured on the demo map (2-core VM, 57k free cells, bounding box cropped): 20-30 ms
    a field, against 100-170 ms for a heapq Dijkstra and 230-300 ms for whole-array Jacobi
    relaxation with array shifts (~270 iterations: one per cell of path length). The results
    are the same (the tests check them against a plain Dijkstra).
    """
    h, w = weight.shape
    dist = np.full((h, w), np.inf)
    dist[goal] = 0.0
    vertical, horizontal, d1, d2 = _pair_costs(weight, step)

    def sweep(
        d: np.ndarray, pair: np.ndarray, left: np.ndarray, right: np.ndarray, fwd: bool
    ) -> None:
        # Row r takes its candidates from row r-1 (forward) or r+1 (backward); ``left`` costs
        # the move from column c-1 of that row, ``right`` from column c+1.
        n = d.shape[0]
        for r in range(1, n) if fwd else range(n - 2, -1, -1):
            k = r - 1 if fwd else r  # index of the (k, k+1) pair between r and its source
            prev = d[r - 1] if fwd else d[r + 1]
            cand = prev + pair[k]
            np.minimum(cand[1:], prev[:-1] + left[k], out=cand[1:])
            np.minimum(cand[:-1], prev[1:] + right[k], out=cand[:-1])
            np.minimum(d[r], cand, out=d[r])

    sweeps = itertools.cycle(
        [
            (dist, vertical, d1, d2, True),  # up
            (dist.T, horizontal.T, d1.T, d2.T, True),  # right
            (dist, vertical, d2, d1, False),  # down
            (dist.T, horizontal.T, d2.T, d1.T, False),  # left
        ]
    )
    quiet = 0  # consecutive sweeps that changed nothing
    # Converged once the other three directions change nothing after the last change (a
    # sweep repeated on its own output is a no-op). Each round of four sweeps that changes
    # something fixes at least one more cell of every cheapest path, hence the bound.
    for _ in range(4 * h * w):
        before = dist.copy()
        sweep(*next(sweeps))
        quiet = quiet + 1 if np.array_equal(before, dist) else 0
        if quiet == 3:
            break
    return dist


def _next_cells(dist: np.ndarray, weight: np.ndarray, step: float) -> np.ndarray:
    """For each cell, the flat index of the neighbour its cheapest path to the goal goes
    through (-1: none). Precomputed per goal, so that a path from any start is a pointer walk."""
    h, w = dist.shape
    pad_d = np.pad(dist, 1, constant_values=np.inf)
    pad_w = np.pad(weight, 1, constant_values=np.inf)
    cand = np.empty((len(_MOVES), h, w))
    for i, (dr, dc) in enumerate(_MOVES):
        nb_w = pad_w[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w]
        cost = (weight + nb_w) / 2 * step
        if dr and dc:  # no corner cutting: both orthogonal cells must be free too
            side = pad_w[1 + dr : 1 + dr + h, 1 : 1 + w] + pad_w[1 : 1 + h, 1 + dc : 1 + dc + w]
            cost = np.where(np.isfinite(side), cost * _SQRT2, np.inf)
        cand[i] = pad_d[1 + dr : 1 + dr + h, 1 + dc : 1 + dc + w] + cost
    best = cand.argmin(axis=0)
    d_row = np.array([dr for dr, _ in _MOVES])[best]
    d_col = np.array([dc for _, dc in _MOVES])[best]
    rows, cols = np.indices((h, w))
    nxt: np.ndarray = (rows + d_row) * w + (cols + d_col)
    nxt[~np.isfinite(dist) | (dist == 0.0)] = -1
    return nxt.astype(np.int32) if h * w < 2**31 else nxt


def _segment_clear(ok: np.ndarray, a: tuple[float, float], b: tuple[float, float]) -> bool:
    """Whether the straight segment a->b (in cell units, (u, v) = (col, row) + fraction)
    touches only ``ok`` cells. Exact, not sampled: it visits every cell the segment enters
    (cuts at each grid line crossing) and, at a crossing, every cell touching that point."""
    u0, v0 = a
    du, dv = b[0] - u0, b[1] - v0
    cuts = [np.array([0.0, 1.0])]
    for p0, dp in ((u0, du), (v0, dv)):
        if dp != 0.0:
            lines = np.arange(math.ceil(min(p0, p0 + dp)), math.floor(max(p0, p0 + dp)) + 1)
            cuts.append((lines - p0) / dp)
    t = np.unique(np.concatenate(cuts))
    t = np.concatenate((t, (t[:-1] + t[1:]) / 2))
    u = u0 + t * du
    v = v0 + t * dv
    cols = np.concatenate((np.floor(u - _EPS), np.floor(u + _EPS))).astype(np.intp)
    rows = np.concatenate((np.floor(v - _EPS), np.floor(v + _EPS))).astype(np.intp)
    cols, rows = np.tile(cols, 2), np.repeat(rows.reshape(2, -1), 2, axis=0).ravel()
    h, w = ok.shape
    if cols.min() < 0 or rows.min() < 0 or cols.max() >= w or rows.max() >= h:
        return False
    return bool(ok[rows, cols].all())


def _shortcut(points: list[tuple[float, float]], ok: np.ndarray) -> list[tuple[float, float]]:
    """Drop every vertex that line of sight can skip (greedy, farthest visible vertex found by
    exponential then binary search, so O(k log n) segment checks for k output vertices).
    Consecutive input points must already be connected by a clear segment."""
    n = len(points)
    keep = [0]
    a = 0
    while a < n - 1:
        good, bad, jump = a + 1, n, 2
        while good < n - 1:
            j = min(a + jump, n - 1)
            if not _segment_clear(ok, points[a], points[j]):
                bad = j
                break
            good, jump = j, jump * 2
        while bad - good > 1:
            mid = (good + bad) // 2
            if _segment_clear(ok, points[a], points[mid]):
                good = mid
            else:
                bad = mid
        keep.append(good)
        a = good
    # The binary search can stop short on non-monotone visibility: one cleanup pass.
    i = 1
    while i < len(keep) - 1:
        if _segment_clear(ok, points[keep[i - 1]], points[keep[i + 1]]):
            del keep[i]
        else:
            i += 1
    return [points[i] for i in keep]


class Planner:
    """Collision-free paths for a disc robot on one map: shortest, but keeping clear of
    obstacles when that costs little.

    A path that is strictly shortest grazes the inflated obstacles at every corner, and a
    real path follower (a carrot ``lookahead`` ahead, acceleration limits) cuts those corners
    into the table. So, as move_base's costmap inflation does, a metre within ``clearance``
    of the inflation costs up to MARGIN_COST metres: paths keep ~``clearance`` off tables
    where the room allows, run down the middle of narrow aisles, and still go wherever the
    robot fits (spots next to tables, the narrowest aisle). ``clearance=0`` gives the plain
    shortest path on the inflated grid. Line-of-sight smoothing may not cut back into the
    margin except along the path's own cells.

    Distance fields (one per goal cell, the expensive part) are cached in an LRU of
    ``cache_size`` entries (1.1 MB each on the demo map, at most 256 MB in all): robots keep
    going to the same tables, the pass and their homes, so most plans after warm-up are a
    pointer walk plus line-of-sight smoothing (a millisecond or two). Thread-safe, so that
    callers can run plans in worker threads (``asyncio.to_thread``) and keep the event loop
    responsive.
    """

    def __init__(
        self,
        m: OccupancyMap,
        robot_radius: float = 0.2,
        *,
        clearance: float = 0.3,
        cache_size: int = 32,
    ) -> None:
        if not (math.isfinite(clearance) and clearance >= 0):
            raise InvalidField(f"clearance must be >= 0, got {clearance}", field="clearance")
        self.map = m
        self.robot_radius = float(robot_radius)
        self.clearance = float(clearance)
        self._blocked = inflate(m, self.robot_radius)
        self._ok: np.ndarray = ~self._blocked
        self._ok.flags.writeable = False
        self._raw_free: np.ndarray = m.grid == 0
        self._metric = np.where(self._ok, 1.0, np.inf)  # cell weights for distance_field()
        self._comfy: np.ndarray
        if self.clearance > 0:
            # How many of the nested clearance bands (outermost at ``clearance`` beyond the
            # inflation) cover each cell: the cost per metre rises towards obstacles.
            level = np.zeros(m.grid.shape)
            for k in range(1, _BANDS + 1):
                level += inflate(m, self.robot_radius + self.clearance * k / _BANDS)
            self._comfy = level == 0
            self._weight = np.where(self._ok, 1.0 + (MARGIN_COST - 1.0) * level / _BANDS, np.inf)
        else:
            self._comfy, self._weight = self._ok, self._metric
        # Bounded by count and by memory (a field is 12 bytes a cell: float64 + int32), so a
        # 200 m SLAM map cannot eat gigabytes.
        per_field = 12 * m.width * m.height
        self._cache_size = max(1, min(cache_size, _FIELD_CACHE_BYTES // per_field))
        self._fields: OrderedDict[tuple[int, int, bool], tuple[np.ndarray, np.ndarray]]
        self._fields = OrderedDict()
        self.fields_computed = 0  # how many distance fields were built (cache misses)
        self._lock = threading.Lock()
        rows, cols = np.nonzero(self._ok)
        self._box = (
            (int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1)
            if rows.size
            else (0, 0, 0, 0)
        )

    # -- cells and checks ------------------------------------------------------------------

    def _uv(self, x: float, y: float) -> tuple[float, float]:
        """World point in cell units: (col, row) with fractions."""
        ox, oy, _ = self.map.origin
        return (x - ox) / self.map.resolution, (y - oy) / self.map.resolution

    def _check(self, which: str, x: float, y: float) -> tuple[int, int]:
        """The cell of a start/goal, or Unreachable saying what is wrong with it. A start is
        only required to be raw-free (plan() lets it escape the inflation zone)."""
        where = f"{which} ({x:.2f}, {y:.2f})"
        if not (math.isfinite(x) and math.isfinite(y)):
            raise Unreachable(f"{where} is not a finite point", which=which, reason="invalid")
        row, col = self.map.world_to_cell(x, y)
        if not self.map.in_bounds(row, col):
            raise Unreachable(f"{where} is outside the map", which=which, reason="outside_map")
        value = int(self.map.grid[row, col])
        if value < 0:
            raise Unreachable(f"{where} is in unknown space", which=which, reason="unknown")
        if value > 0:
            raise Unreachable(f"{where} is inside an obstacle", which=which, reason="occupied")
        if which == "goal" and self._blocked[row, col]:
            raise Unreachable(
                f"{where} is too close to an obstacle for a robot of radius "
                f"{self.robot_radius:.2f} m",
                which=which,
                reason="too_close",
            )
        return row, col

    def is_traversable(self, x: float, y: float) -> bool:
        """Whether a robot can stand centred at (x, y) without touching anything."""
        if not (math.isfinite(x) and math.isfinite(y)):
            return False
        row, col = self.map.world_to_cell(x, y)
        return self.map.in_bounds(row, col) and bool(self._ok[row, col])

    # -- distance fields -------------------------------------------------------------------

    def clear_cache(self) -> None:
        """Forget the cached distance fields (1.1 MB each on the demo map).

        A server needs them only while it fills its DistanceTable; a simulator keeps them
        because its robots plan to the same tables again and again.
        """
        with self._lock:
            self._fields.clear()

    def _field(self, goal_cell: tuple[int, int], *, metric: bool) -> tuple[np.ndarray, np.ndarray]:
        """(cost to the goal, next cell towards it) for every cell; ``metric`` in metres, else
        with the clearance margin's surcharge (what plan() follows)."""
        metric = metric or self._weight is self._metric
        key = (goal_cell[0], goal_cell[1], metric)
        with self._lock:
            cached = self._fields.get(key)
            if cached is not None:
                self._fields.move_to_end(key)
                return cached
        # Computed outside the lock: two threads may race to build the same field, which only
        # wastes time, while holding the lock would serialise every plan behind it.
        weight = self._metric if metric else self._weight
        r0, r1, c0, c1 = self._box  # sweep only the bounding box of traversable cells
        dist = np.full(self._ok.shape, np.inf)
        dist[r0:r1, c0:c1] = _sweep_field(
            weight[r0:r1, c0:c1], (goal_cell[0] - r0, goal_cell[1] - c0), self.map.resolution
        )
        nxt = _next_cells(dist, weight, self.map.resolution)
        dist.flags.writeable = False
        nxt.flags.writeable = False
        with self._lock:
            self.fields_computed += 1
            self._fields[key] = (dist, nxt)
            if len(self._fields) > self._cache_size:
                self._fields.popitem(last=False)
        return dist, nxt

    def has_field(self, goal: tuple[float, float]) -> bool:
        """Whether :meth:`plan` to ``goal`` finds its distance field cached (a plan of a
        millisecond or two, cheap enough to run on an event loop)."""
        try:
            row, col = self._check("goal", *goal)
        except Unreachable:
            return False
        key = (row, col, self._weight is self._metric)
        with self._lock:
            return key in self._fields

    def distance_field(self, goal: tuple[float, float]) -> np.ndarray:
        """Geodesic distance (m, 8-connected grid metric, no clearance surcharge) from every
        cell to the goal's cell; np.inf where unreachable. Read-only, cached per goal cell."""
        return self._field(self._check("goal", *goal), metric=True)[0]

    def _corridor(self, cells: list[tuple[int, int]]) -> np.ndarray:
        """Where shortcuts may go: comfortable cells, plus the path's own cells and their
        neighbours. Smoothing must not cut back into the clearance margin that the path
        only enters where it has to (a narrow aisle, a spot next to a table)."""
        if self._comfy is self._ok:
            return self._ok
        near = np.zeros(self._ok.shape, dtype=bool)
        rows, cols = zip(*cells, strict=True)
        near[rows, cols] = True
        near[1:] |= near[:-1].copy()
        near[:-1] |= near[1:].copy()
        near[:, 1:] |= near[:, :-1].copy()
        near[:, :-1] |= near[:, 1:].copy()
        allowed: np.ndarray = (near & self._ok) | self._comfy
        return allowed

    # -- paths -----------------------------------------------------------------------------

    def _escape(self, start: tuple[int, int], dist: np.ndarray) -> list[tuple[int, int]]:
        """Cells from a raw-free but inflation-blocked start to the nearest traversable cell
        connected to the goal (breadth-first over raw-free cells, within one robot diameter
        plus a cell). A robot pushed against a wall must be able to drive away from it."""
        limit = (2 * self.robot_radius + self.map.resolution) / self.map.resolution
        parent: dict[tuple[int, int], tuple[int, int] | None] = {start: None}
        queue = deque([start])
        raw = self._raw_free
        while queue:
            cell = queue.popleft()
            if math.isfinite(dist[cell]):
                path = []
                node: tuple[int, int] | None = cell
                while node is not None:
                    path.append(node)
                    node = parent[node]
                return path[::-1]
            r, c = cell
            for dr, dc in _MOVES:
                nb = (r + dr, c + dc)
                if nb in parent or not self.map.in_bounds(*nb) or not raw[nb]:
                    continue
                if dr and dc and not (raw[r + dr, c] and raw[r, c + dc]):
                    continue
                if math.hypot(nb[0] - start[0], nb[1] - start[1]) > limit:
                    continue
                parent[nb] = cell
                queue.append(nb)
        raise Unreachable(
            "start is wedged against obstacles: no free spot for a robot of radius "
            f"{self.robot_radius:.2f} m connected to the goal nearby",
            which="start",
            reason="wedged",
        )

    def plan(
        self, start: tuple[float, float], goal: tuple[float, float]
    ) -> list[tuple[float, float]]:
        """World points from ``start`` to ``goal`` inclusive; every segment is collision-free
        on the inflated grid, except the legs of an escape (below), which are on raw-free cells.

        Raises Unreachable when the goal is off the map, in or too close to an obstacle, in
        unknown space or not connected to the start, or the start is off the map or inside an
        obstacle. A start that is raw-free but within the inflation (a robot nudged against a
        table) first escapes to the nearest traversable cell over raw-free cells.
        """
        goal_cell = self._check("goal", *goal)
        start_cell = self._check("start", *start)
        dist, nxt = self._field(goal_cell, metric=False)
        res = self.map.resolution
        lead: list[tuple[int, int]] = []
        if not math.isfinite(dist[start_cell]):
            if self._ok[start_cell]:
                raise Unreachable(
                    f"no path from ({start[0]:.2f}, {start[1]:.2f}) to "
                    f"({goal[0]:.2f}, {goal[1]:.2f}): not connected for a robot of radius "
                    f"{self.robot_radius:.2f} m",
                    reason="not_connected",
                )
            lead = self._escape(start_cell, dist)
        entry = lead[-1] if lead else start_cell
        w = self.map.width
        cells = [entry]
        flat = entry[0] * w + entry[1]
        for _ in range(dist.size):  # dist strictly decreases along next pointers
            flat = int(nxt.flat[flat])
            if flat < 0:
                break
            cells.append(divmod(flat, w))
        if cells[-1] != goal_cell:
            raise NavigationError("internal error: path extraction did not reach the goal")

        def centre(cell: tuple[int, int]) -> tuple[float, float]:
            return cell[1] + 0.5, cell[0] + 0.5

        s_uv, g_uv = self._uv(*start), self._uv(*goal)
        ok = self._corridor(cells)
        if lead:
            escape = _shortcut([s_uv] + [centre(c) for c in lead[1:]], self._raw_free)
            main = _shortcut([centre(c) for c in cells[:-1]] + [g_uv], ok)
            main = main if len(main) > 1 else [centre(entry), g_uv]
            pts = escape + main[1:]
        else:
            pts = _shortcut([s_uv] + [centre(c) for c in cells[1:-1]] + [g_uv], ok)
        ox, oy, _ = self.map.origin
        out = [(ox + u * res, oy + v * res) for u, v in pts]
        out[0], out[-1] = (float(start[0]), float(start[1])), (float(goal[0]), float(goal[1]))
        return out

    def path_length(self, start: tuple[float, float], goal: tuple[float, float]) -> float:
        """Metres along :meth:`plan`'s smoothed path; raises Unreachable like plan()."""
        pts = self.plan(start, goal)
        return float(sum(math.dist(p, q) for p, q in itertools.pairwise(pts)))


class DistanceTable:
    """Distances between named waypoints for the scheduler ("how far is T7 from T3"), cached.

    A distance is the length of the planned path between the two spots, computed once per
    unordered pair (so it is symmetric by construction) and kept, as is "unreachable", until
    one of the two waypoints moves. A waypoint that is not a valid goal (too close to an
    obstacle, say) is unreachable in both directions, which keeps the table symmetric.
    """

    def __init__(self, planner: Planner, waypoints: Mapping[str, Waypoint]) -> None:
        self.planner = planner
        self._waypoints: dict[str, Waypoint] = dict(waypoints)
        self._cache: dict[tuple[str, str], float | str] = {}  # metres, or why unreachable
        self._paths: dict[tuple[str, str], list[tuple[float, float]]] = {}  # as planned
        # Guards the dicts, not the planning: matrix() typically runs in a worker thread while
        # the event loop asks for single distances and adds waypoints.
        self._lock = threading.Lock()

    def _get(self, name: str) -> Waypoint:
        with self._lock:
            wp = self._waypoints.get(name)
        if wp is None:
            raise NotFound(f"unknown waypoint {name!r}", waypoint=name)
        return wp

    def distance(self, a: str, b: str) -> float:
        """Metres between waypoints ``a`` and ``b``; NotFound / Unreachable otherwise."""
        wa, wb = self._get(a), self._get(b)
        if a == b:
            return 0.0
        key = (a, b) if a < b else (b, a)
        with self._lock:
            value = self._cache.get(key)
        if value is None:
            value = self._compute(wa, wb) if a < b else self._compute(wb, wa)
            with self._lock:  # unless add() moved one of them meanwhile: that would be stale
                if self._waypoints.get(a) == wa and self._waypoints.get(b) == wb:
                    self._cache[key] = value
        if isinstance(value, str):
            raise Unreachable(value, waypoints=[key[0], key[1]])
        return value

    def _compute(self, start: Waypoint, goal: Waypoint) -> float | str:
        for wp in (start, goal):
            try:
                self.planner._check("goal", wp.x, wp.y)
            except Unreachable as exc:
                return f"waypoint {wp.name!r}: {exc.message}"
        try:
            pts = self.planner.plan((start.x, start.y), (goal.x, goal.y))
        except Unreachable as exc:
            return f"{start.name} -> {goal.name}: {exc.message}"
        with self._lock:
            self._paths[(start.name, goal.name)] = pts
        return float(sum(math.dist(p, q) for p, q in itertools.pairwise(pts)))

    def path(self, a: str, b: str) -> list[tuple[float, float]] | None:
        """The planned path from ``a`` to ``b`` (after :meth:`distance` computed the pair),
        None if unreachable or not planned."""
        with self._lock:
            if (a, b) in self._paths:
                return list(self._paths[(a, b)])
            back = self._paths.get((b, a))
        return None if back is None else back[::-1]

    def matrix(self, names: Sequence[str]) -> np.ndarray:
        """(n, n) distances in metres for ``names`` in order; np.inf for unreachable pairs
        (a scheduler wants the whole table even if one spot is blocked). NotFound as distance()."""
        for name in names:
            self._get(name)
        n = len(names)
        out = np.zeros((n, n))
        # Goal by goal (a pair plans towards its later name when ``names`` is sorted): each
        # goal's distance field is built once and used for every start. Row by row, with more
        # waypoints than the planner's field cache holds (37 > 32), the LRU missed on every
        # pair: 666 fields (~10 s) instead of 37 on a 30-table room.
        for j in range(n):
            for i in range(j):
                try:
                    out[i, j] = out[j, i] = self.distance(names[i], names[j])
                except Unreachable:
                    out[i, j] = out[j, i] = np.inf
        return out

    def add(self, wp: Waypoint) -> None:
        """Add or move a waypoint; forgets only the distances that involve it."""
        with self._lock:
            old = self._waypoints.get(wp.name)
            self._waypoints[wp.name] = wp
            if old is not None and (old.x, old.y) != (wp.x, wp.y):
                for key in [k for k in self._cache if wp.name in k]:
                    del self._cache[key]
                for key in [k for k in self._paths if wp.name in k]:
                    del self._paths[key]

    def __contains__(self, name: object) -> bool:
        with self._lock:
            return name in self._waypoints


_HIT_CELLS: WeakKeyDictionary[OccupancyMap, np.ndarray] = WeakKeyDictionary()


def _hit_cells(m: OccupancyMap) -> np.ndarray:
    """Ray-stopping cells of ``m``, flattened with a one-cell False border; cached per map
    (maps are immutable) because the simulator casts a scan per robot several times a second."""
    cells = _HIT_CELLS.get(m)
    if cells is None:
        cells = np.pad(m.grid >= HIT_THRESHOLD, 1, constant_values=False).ravel()
        _HIT_CELLS[m] = cells
    return cells


def raycast(
    m: OccupancyMap, x: float, y: float, angles: np.ndarray, max_range: float
) -> np.ndarray:
    """Simulated laser: distance (m) from (x, y) along each map-frame angle to the first
    occupied cell (value >= HIT_THRESHOLD), np.inf if none within ``max_range``.

    Unknown cells and the space off the map do not stop rays: in a SLAM map unknown is what
    the laser never saw, usually beyond a wall that already stopped the ray. All rays are
    sampled at once every half cell, in chunks so that rays that already hit stop costing;
    the hit range is then refined to the exact entry into the hit cell. So ranges are exact
    except where a ray clips a cell corner for less than half a cell between two samples: that
    cell is missed (the range is then that of the next hit, usually a few mm further).
    """
    if not (math.isfinite(x) and math.isfinite(y) and max_range >= 0):
        raise InvalidField(f"raycast from ({x}, {y}) up to {max_range} m", field="position")
    ang = np.asarray(angles, dtype=np.float64)
    out = np.full(ang.shape, np.inf)
    flat_ang = ang.ravel()
    ranges = out.reshape(-1)
    if flat_ang.size == 0 or not max_range > 0:
        return out
    res = m.resolution
    hit = _hit_cells(m)  # flat, with a never-hit border so indices just get clipped into it
    h, w = m.height, m.width
    u0, v0 = (x - m.origin[0]) / res, (y - m.origin[1]) / res
    cos, sin = np.cos(flat_ang), np.sin(flat_ang)
    step = 0.5  # cells
    n_samples = math.ceil(max_range / res / step)
    active = np.arange(flat_ang.size)
    chunk = 48
    for first in range(0, n_samples + 1, chunk):  # sample 0 is the origin: inside a wall is 0 m
        t = np.arange(first, min(first + chunk, n_samples + 1)) * step  # cells along the ray
        u = u0 + cos[active, None] * t
        v = v0 + sin[active, None] * t
        cols = np.clip(np.floor(u), -1, w).astype(np.intp)
        rows = np.clip(np.floor(v), -1, h).astype(np.intp)
        hits = hit[(rows + 1) * (w + 2) + (cols + 1)]
        any_hit = hits.any(axis=1)
        k = hits.argmax(axis=1)[any_hit]
        idx = active[any_hit]
        r_hit, c_hit = rows[any_hit, k], cols[any_hit, k]
        # Entry into the hit cell's square (slab method), clamped to the sampled bracket. An
        # axis-parallel ray is inside that axis' slab all along (a sample is in the cell).
        with np.errstate(divide="ignore", invalid="ignore"):
            cx, sy = cos[idx], sin[idx]
            tx = np.minimum((c_hit - u0) / cx, (c_hit + 1 - u0) / cx)
            ty = np.minimum((r_hit - v0) / sy, (r_hit + 1 - v0) / sy)
        enter = np.maximum(np.where(cx == 0, -np.inf, tx), np.where(sy == 0, -np.inf, ty))
        ranges[idx] = np.clip(enter, np.maximum(t[k] - step, 0.0), t[k]) * res
        # A ray beyond an edge of the (rectangular) map and heading away never comes back.
        u_end, v_end, ca, sa = u[:, -1], v[:, -1], cos[active], sin[active]
        gone = (
            ((u_end < 0) & (ca <= 0))
            | ((u_end >= w) & (ca >= 0))
            | ((v_end < 0) & (sa <= 0))
            | ((v_end >= h) & (sa >= 0))
        )
        active = active[~any_hit & ~gone]
        if active.size == 0:
            break
    ranges[ranges > max_range] = np.inf
    return out
