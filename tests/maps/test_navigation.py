"""Maps, inflation, planning, distances and ray casting (pure, no event loop, a few seconds).

The reference implementations here (brute-force inflation, heapq Dijkstra) are deliberately
naive: they are what the vectorised code must agree with.
"""

from __future__ import annotations

import heapq
import itertools
import math
import time
from collections import deque
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from serveur.errors import InvalidField, MapError, NotFound, ServeurError, Unreachable
from serveur.maps.navigation import (
    DistanceTable,
    OccupancyMap,
    Planner,
    Waypoint,
    demo_map_path,
    inflate,
    load_demo,
    load_map,
    load_waypoints,
    raycast,
    save_map,
)

RES = 0.05


def room(
    width_m: float,
    height_m: float,
    boxes: Sequence[tuple[float, float, float, float]] = (),
    *,
    res: float = RES,
    origin: tuple[float, float] = (0.0, 0.0),
) -> OccupancyMap:
    """A free rectangle with occupied boxes (x0, y0, x1, y1) in world metres."""
    w, h = round(width_m / res), round(height_m / res)
    grid = np.zeros((h, w), dtype=np.int8)
    xs = origin[0] + (np.arange(w) + 0.5) * res
    ys = origin[1] + (np.arange(h) + 0.5) * res
    x, y = np.meshgrid(xs, ys)
    for x0, y0, x1, y1 in boxes:
        grid[(x >= x0) & (x <= x1) & (y >= y0) & (y <= y1)] = 100
    return OccupancyMap(grid, res, (origin[0], origin[1], 0.0))


def assert_path_clear(planner: Planner, path: list[tuple[float, float]], skip: int = 0) -> None:
    """Sample every segment (from index ``skip``) every 2 mm: all samples traversable."""
    for (x0, y0), (x1, y1) in itertools.pairwise(path[skip:]):
        n = max(2, math.ceil(math.hypot(x1 - x0, y1 - y0) / 0.002))
        for t in np.linspace(0.0, 1.0, n):
            x, y = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
            assert planner.is_traversable(x, y), f"({x:.3f}, {y:.3f}) on {path}"


def length(path: list[tuple[float, float]]) -> float:
    return sum(math.dist(p, q) for p, q in itertools.pairwise(path))


# --- map files ------------------------------------------------------------------------------


def asymmetric_grid() -> np.ndarray:
    """7 x 5, every row and column different, all three cell states."""
    grid = np.zeros((5, 7), dtype=np.int8)
    grid[0, :] = 100  # bottom row (lowest y) occupied
    grid[4, 0] = -1  # top-left unknown
    grid[2, 5] = 100
    grid[3, 1:3] = -1
    return grid


@pytest.mark.parametrize("fmt", ["pgm", "png"])
def test_save_load_round_trip(tmp_path: Path, fmt: str) -> None:
    m = OccupancyMap(asymmetric_grid(), 0.1, (-1.5, 2.25, 0.0))
    save_map(m, tmp_path / "room.yaml", fmt)
    back = load_map(tmp_path / "room.yaml")
    assert np.array_equal(back.grid, m.grid)
    assert back.resolution == m.resolution and back.origin == m.origin
    # The image itself is map_saver's: top image row = highest y, 254 free / 0 occ / 205 unknown.
    pixels = np.asarray(Image.open(tmp_path / f"room.{fmt}"))
    assert pixels.shape == (5, 7)
    assert pixels[0, 0] == 205 and pixels[0, 1] == 254  # grid row 4 (top)
    assert (pixels[-1] == 0).all()  # grid row 0 (bottom)
    assert set(np.unique(pixels)) == {0, 205, 254}


def write_map(tmp_path: Path, data: bytes, name: str = "m.pgm", **meta: object) -> Path:
    """Image bytes plus a YAML; ``meta`` overrides keys (None drops one)."""
    (tmp_path / name).write_bytes(data)
    fields = {
        "image": name,
        "resolution": 0.5,
        "origin": "[1.0, -2.0, 0.0]",
        "negate": 0,
        "occupied_thresh": 0.65,
        "free_thresh": 0.196,
    } | meta
    text = "".join(f"{k}: {v}\n" for k, v in fields.items() if v is not None)
    (tmp_path / "m.yaml").write_text(text)
    return tmp_path / "m.yaml"


def test_hand_written_p5_orientation(tmp_path: Path) -> None:
    # Independent of save_map: the TOP-LEFT pixel is black, so the top-left cell of the map
    # (highest y, lowest x) must be occupied and it is grid[height - 1, 0].
    px = bytes([0, 254, 254, 254, 254, 254])  # 3 wide, 2 high
    m = load_map(write_map(tmp_path, b"P5\n# a comment\n3 2\n255\n" + px))
    assert m.grid.tolist() == [[0, 0, 0], [100, 0, 0]]
    assert m.cell_to_world(1, 0) == (1.25, -1.25)  # origin (1, -2), 0.5 m cells
    assert not m.is_free(1.1, -1.1) and m.is_free(1.1, -1.9)


def test_p2_ascii_with_comments_matches_p5(tmp_path: Path) -> None:
    values = [0, 128, 205, 254, 255, 60]
    p2 = "P2\n# CREATOR: hand\n3 2\n# maxval next\n255\n" + " ".join(map(str, values)) + "\n"
    a = load_map(write_map(tmp_path, p2.encode()))
    b = load_map(write_map(tmp_path, b"P5\n3 2\n255\n" + bytes(values)))
    assert np.array_equal(a.grid, b.grid)
    assert a.grid.tolist() == [[0, 0, 100], [100, -1, -1]]  # bottom image row is grid row 0


def test_thresholds_are_strict_and_negate_flips(tmp_path: Path) -> None:
    # p = (255 - px) / 255 ; occupied_thresh 0.6 -> px 102 is exactly p = 0.6 (not > 0.6).
    px = bytes([101, 102, 103, 204, 205, 206])  # p: .604 .6 .596 .2 .196 .192
    m = load_map(write_map(tmp_path, b"P5\n6 1\n255\n" + px, occupied_thresh=0.6, free_thresh=0.2))
    assert m.grid.tolist() == [[100, -1, -1, -1, 0, 0]]
    # negate: p = px / 255, so white is occupied and black free.
    m = load_map(write_map(tmp_path, b"P5\n3 1\n255\n" + bytes([0, 255, 128]), negate=1))
    assert m.grid.tolist() == [[0, 100, -1]]


def test_scale_and_raw_modes(tmp_path: Path) -> None:
    rgba = np.array([[[255, 255, 255, 255], [0, 0, 0, 255], [128, 128, 128, 255], [0, 0, 0, 0]]])
    Image.fromarray(rgba.astype(np.uint8), mode="RGBA").save(tmp_path / "s.png")
    m = load_map(write_map(tmp_path, (tmp_path / "s.png").read_bytes(), "s.png", mode="scale"))
    # grey 128: p = 127/255 = 0.498 -> 1 + 98 * (0.498 - 0.196) / (0.65 - 0.196) = 66.2 -> 66;
    # a transparent pixel is unknown whatever its colour (here black).
    assert m.grid.tolist() == [[0, 100, 66, -1]]
    raw = load_map(write_map(tmp_path, b"P5\n4 1\n255\n" + bytes([0, 42, 100, 200]), mode="raw"))
    assert raw.grid.tolist() == [[0, 42, 100, -1]]


@pytest.mark.parametrize(
    ("image", "meta", "needle"),
    [
        (b"P5\n3 2\n255\n" + bytes(6), {"resolution": None}, "resolution"),
        (b"P5\n3 2\n255\n" + bytes(6), {"resolution": "-0.1"}, "resolution"),
        (b"P5\n3 2\n255\n" + bytes(6), {"negate": 2}, "negate"),
        (b"P5\n3 2\n255\n" + bytes(6), {"mode": "fancy"}, "mode"),
        (b"P5\n3 2\n255\n" + bytes(6), {"origin": "[0, 0, 0.5]"}, "rotated"),
        (b"P5\n3 2\n255\n" + bytes(6), {"origin": "[0, 0]"}, "origin"),
        (b"P5\n3 2\n255\n" + bytes(6), {"free_thresh": 0.9}, "free_thresh"),
        (b"P5\n3 2\n255\n" + bytes(6), {"image": "missing.pgm"}, "missing.pgm"),
        (b"P5\n3 x\n255\n", {}, "m.pgm"),  # bad header
        (b"P5\n3 2\n255\n\x00\x01", {}, "m.pgm"),  # truncated pixels
        (b"not an image at all", {}, "m.pgm"),
        (b"P5\n3 2\n65535\n" + bytes(12), {}, "16-bit"),
    ],
)
def test_malformed_maps_raise_map_error(
    tmp_path: Path, image: bytes, meta: dict[str, Any], needle: str
) -> None:
    with pytest.raises(MapError, match=needle):
        load_map(write_map(tmp_path, image, **meta))


@pytest.mark.parametrize("text", ["image: [unclosed\n", "- just\n- a list\n", ""])
def test_bad_yaml_raises_map_error(tmp_path: Path, text: str) -> None:
    (tmp_path / "m.yaml").write_text(text)
    with pytest.raises(MapError):
        load_map(tmp_path / "m.yaml")
    with pytest.raises(MapError, match="cannot read"):
        load_map(tmp_path / "nope.yaml")


def test_save_errors(tmp_path: Path) -> None:
    m = OccupancyMap(asymmetric_grid(), 0.1)
    with pytest.raises(MapError, match="image_format"):
        save_map(m, tmp_path / "m.yaml", "bmp")
    with pytest.raises(MapError, match="cannot write"):
        save_map(m, tmp_path / "no" / "such" / "dir.yaml")


def test_waypoints_file(tmp_path: Path) -> None:
    path = tmp_path / "w.json"
    path.write_text(
        '{"waypoints": [{"name": "T1", "x": 1, "y": 2.5, "yaw": 0.5, "kind": "table"}]}'
    )
    assert load_waypoints(path) == {"T1": Waypoint("T1", 1.0, 2.5, 0.5, "table")}
    for bad in (
        "{not json",
        '{"points": []}',
        '{"waypoints": [{"name": "A", "x": 0, "y": 0}, {"name": "A", "x": 1, "y": 1}]}',
        '{"waypoints": [{"name": "A", "x": 0, "y": 0, "kind": "bar"}]}',
        '{"waypoints": [{"name": "A", "x": "left", "y": 0}]}',
    ):
        path.write_text(bad)
        with pytest.raises(MapError):
            load_waypoints(path)
    with pytest.raises(InvalidField):
        Waypoint("A", math.nan, 0.0, 0.0, "table")


# --- geometry -------------------------------------------------------------------------------


def test_world_cell_conversions_with_origin_offset() -> None:
    m = OccupancyMap(np.zeros((4, 6), dtype=np.int8), 0.25, (-2.0, 3.0, 0.0))
    assert (m.width, m.height) == (6, 4)
    assert m.world_to_cell(-2.0, 3.0) == (0, 0)
    assert m.world_to_cell(-1.76, 3.26) == (1, 0)
    assert m.world_to_cell(-0.51, 3.99) == (3, 5)
    assert m.world_to_cell(-2.01, 3.5) == (2, -1) and not m.in_bounds(2, -1)
    assert not m.in_bounds(4, 0) and m.in_bounds(3, 5)
    assert m.cell_to_world(1, 0) == (-1.875, 3.375)
    for row, col in itertools.product(range(4), range(6)):
        assert m.world_to_cell(*m.cell_to_world(row, col)) == (row, col)
    assert m.is_free(-1.9, 3.1) and not m.is_free(-2.1, 3.1) and not m.is_free(math.nan, 3.1)
    with pytest.raises(InvalidField):
        m.world_to_cell(math.inf, 0.0)


def test_map_validation_and_immutability() -> None:
    with pytest.raises(MapError):
        OccupancyMap(np.full((2, 2), 101), 0.1)
    with pytest.raises(MapError):
        OccupancyMap(np.zeros((2, 2)), 0.1)  # float grid
    with pytest.raises(MapError):
        OccupancyMap(np.zeros((2, 2), dtype=np.int8), 0.0)
    m = OccupancyMap(np.zeros((2, 2), dtype=np.int8), 0.1)
    with pytest.raises(ValueError):
        m.grid[0, 0] = 100


def brute_inflate(m: OccupancyMap, radius: float) -> np.ndarray:
    """Per cell: is any obstacle (or off-map) cell's square strictly closer than radius?"""
    r = radius / m.resolution
    reach = math.ceil(r) + 1
    out = np.zeros(m.grid.shape, dtype=bool)
    for row, col in itertools.product(range(m.height), range(m.width)):
        for dr, dc in itertools.product(range(-reach, reach + 1), repeat=2):
            rr, cc = row + dr, col + dc
            obstacle = not m.in_bounds(rr, cc) or m.grid[rr, cc] != 0
            gap = math.hypot(max(abs(dr) - 0.5, 0), max(abs(dc) - 0.5, 0))
            if obstacle and (gap < r or (dr, dc) == (0, 0)):
                out[row, col] = True
                break
    return out


def test_inflation_single_cell() -> None:
    grid = np.zeros((21, 21), dtype=np.int8)
    grid[10, 10] = 100
    m = OccupancyMap(grid, RES)
    assert np.array_equal(inflate(m, 0.0), grid != 0)
    blocked = inflate(m, 0.2)  # 4 cells: edge at 3.5 cells = 0.175 m < 0.2, 4.5 cells is not
    assert blocked[10, 6:15].all() and not blocked[10, 5] and not blocked[10, 15]
    assert blocked[13, 13] and not blocked[13, 14]  # 2.5, 2.5 -> 3.54 cells; 2.5, 3.5 -> 4.3
    assert np.array_equal(blocked, brute_inflate(m, 0.2))
    assert (inflate(m, 0.3) >= blocked).all() and inflate(m, 0.3).sum() > blocked.sum()


def test_inflation_matches_brute_force_with_unknown_and_edges() -> None:
    rng = np.random.default_rng(7)
    grid = rng.choice(np.array([0, 0, 0, 0, 0, 0, 0, 0, 100, -1], dtype=np.int8), size=(18, 23))
    m = OccupancyMap(grid, 0.1, (3.0, -1.0, 0.0))
    for radius in (0.0, 0.05, 0.12, 0.2, 0.31):
        assert np.array_equal(inflate(m, radius), brute_inflate(m, radius)), radius


# --- planning -------------------------------------------------------------------------------


def wall_room() -> OccupancyMap:
    """x in [-1, 5], y in [0.5, 4.5]; a wall x in [2.9, 3.1] from the bottom up to y = 3."""
    return room(6.0, 4.0, [(2.9, 0.0, 3.1, 3.0)], origin=(-1.0, 0.5))


def wall_gap(x: float, y: float) -> float:
    """Distance from (x, y) to wall_room's wall."""
    return math.hypot(max(2.9 - x, 0.0, x - 3.1), max(0.5 - y, 0.0, y - 3.0))


def test_shortest_plan_around_wall() -> None:
    p = Planner(wall_room(), robot_radius=0.2, clearance=0.0)
    start, goal = (0.0, 1.5), (4.0, 1.5)
    path = p.plan(start, goal)
    assert path[0] == start and path[-1] == goal
    assert_path_clear(p, path)
    assert max(y for _, y in path) > 3.0 + 0.2  # over the wall's top with clearance
    assert len(path) <= 5  # any-angle, not a staircase
    # Lower bound: to the inflated wall's top-left corner, across, down to the goal; a robot
    # centre may pass up to half a cell diagonal closer than the radius, hence 0.98.
    around = math.hypot(2.9, 1.7) + 0.2 + math.hypot(0.9, 1.7)
    assert 0.98 * around < p.path_length(start, goal) < 1.05 * around
    assert p.path_length(start, goal) > math.dist(start, goal)
    assert min(wall_gap(x, y) for x, y in path) < 0.2 + 0.05  # hugs the inflated wall


def test_clearance_keeps_paths_off_obstacles() -> None:
    # Above the wall there is room to pass 0.5 m off it; the default planner takes it, and
    # pays only a little length for it.
    p = Planner(wall_room(), robot_radius=0.2)
    tight = Planner(wall_room(), robot_radius=0.2, clearance=0.0)
    start, goal = (0.0, 1.5), (4.0, 1.5)
    path = p.plan(start, goal)
    assert_path_clear(p, path)
    for (x0, y0), (x1, y1) in itertools.pairwise(path):
        for t in np.linspace(0.0, 1.0, 200):
            assert wall_gap(x0 + t * (x1 - x0), y0 + t * (y1 - y0)) > 0.2 + 0.3 - 0.05
    assert p.path_length(start, goal) < 1.15 * tight.path_length(start, goal)
    # ...but it still squeezes through where only the robot fits: a 0.5 m gap.
    gap = room(4.0, 3.0, [(1.9, 0.0, 2.1, 1.25), (1.9, 1.75, 2.1, 3.0)])
    squeeze = Planner(gap, robot_radius=0.2).plan((0.5, 1.5), (3.5, 1.5))
    assert squeeze == [(0.5, 1.5), (3.5, 1.5)]
    with pytest.raises(InvalidField):
        Planner(gap, clearance=-1.0)


def test_open_space_is_one_straight_segment() -> None:
    p = Planner(room(5.0, 4.0, [(4.0, 0.0, 5.0, 0.5)]), robot_radius=0.2)
    start, goal = (0.4, 0.4), (3.7, 3.55)
    path = p.plan(start, goal)
    assert path == [start, goal]
    assert p.path_length(start, goal) == pytest.approx(math.dist(start, goal), abs=1e-12)
    assert p.plan(start, start) == [start, start] and p.path_length(start, start) == 0.0


def test_unreachable_goals_fail_fast_with_reasons() -> None:
    # A closed box (walls all round) in the middle of a room, with free space inside.
    m = room(
        8.0,
        8.0,
        [(3.0, 3.0, 5.0, 3.2), (3.0, 4.8, 5.0, 5.0), (3.0, 3.0, 3.2, 5.0), (4.8, 3.0, 5.0, 5.0)],
    )
    p = Planner(m)
    start = (1.0, 1.0)
    cases = {
        (4.0, 4.0): "not_connected",  # inside the box
        (3.1, 4.0): "occupied",  # in the box wall
        (3.35, 4.0): "too_close",  # free but hugging the wall
        (9.0, 1.0): "outside_map",
        (1.0, -0.1): "outside_map",
    }
    for goal, reason in cases.items():
        t0 = time.perf_counter()
        with pytest.raises(Unreachable) as info:
            p.plan(start, goal)
        assert time.perf_counter() - t0 < 1.0
        assert info.value.details["reason"] == reason, goal
        assert isinstance(info.value, ServeurError) and info.value.code == "unreachable"
    with pytest.raises(Unreachable, match=r"start .* inside an obstacle"):
        p.plan((3.1, 3.5), (1.0, 1.0))
    unknown = np.zeros((40, 40), dtype=np.int8)
    unknown[:, 30:] = -1
    with pytest.raises(Unreachable, match="unknown"):
        Planner(OccupancyMap(unknown, RES)).plan((0.5, 0.5), (1.8, 1.0))


def test_start_inside_inflation_escapes() -> None:
    m = wall_room()
    p = Planner(m, robot_radius=0.2)
    start = (2.8, 1.5)  # raw free, 0.1 m from the wall: inside the inflation
    assert m.is_free(*start) and not p.is_traversable(*start)
    path = p.plan(start, (0.0, 1.5))
    assert path[0] == start and p.is_traversable(*path[1])
    assert_path_clear(p, path, skip=1)
    assert all(m.is_free(2.8 + t * (path[1][0] - 2.8), 1.5) for t in np.linspace(0, 1, 50))


def test_wedged_start_is_unreachable() -> None:
    # A 0.15 m slot between two walls: raw free, but no spot a 0.2 m robot fits near it.
    m = room(4.0, 4.0, [(1.0, 0.0, 1.9, 4.0), (2.05, 0.0, 3.0, 4.0)])
    with pytest.raises(Unreachable) as info:
        Planner(m).plan((1.97, 2.0), (0.4, 2.0))
    assert info.value.details["reason"] == "wedged"


def dijkstra(ok: np.ndarray, goal: tuple[int, int], step: float) -> np.ndarray:
    """Textbook 8-connected Dijkstra with the no-corner-cutting rule."""
    h, w = ok.shape
    dist = np.full((h, w), np.inf)
    dist[goal] = 0.0
    heap = [(0.0, goal)]
    while heap:
        d, (r, c) = heapq.heappop(heap)
        if d > dist[r, c]:
            continue
        for dr, dc in itertools.product((-1, 0, 1), repeat=2):
            rr, cc = r + dr, c + dc
            if (dr, dc) == (0, 0) or not (0 <= rr < h and 0 <= cc < w) or not ok[rr, cc]:
                continue
            if dr and dc and not (ok[r + dr, c] and ok[r, c + dc]):
                continue
            nd = d + step * (math.sqrt(2) if dr and dc else 1)
            if nd < dist[rr, cc]:
                dist[rr, cc] = nd
                heapq.heappush(heap, (nd, (rr, cc)))
    return dist


def test_distance_field_matches_dijkstra_and_is_cached() -> None:
    rng = np.random.default_rng(3)
    grid = np.where(rng.random((60, 70)) < 0.02, 100, 0).astype(np.int8)
    grid[20:45, 30] = 100  # a long wall to force detours
    grid[50:, 50:] = -1
    m = OccupancyMap(grid, 0.1, (1.0, 2.0, 0.0))
    p = Planner(m, robot_radius=0.1)
    goal = m.cell_to_world(25, 35)
    assert p.is_traversable(*goal)
    field = p.distance_field(goal)
    expected = dijkstra(p._ok, m.world_to_cell(*goal), m.resolution)
    assert np.array_equal(np.isinf(field), np.isinf(expected))
    assert np.allclose(
        field[np.isfinite(field)], expected[np.isfinite(expected)], rtol=0, atol=1e-9
    )
    assert np.isinf(field).any() and np.isfinite(field).sum() > 1000
    assert p.distance_field(goal) is field and p.fields_computed == 1
    with pytest.raises(ValueError):
        field[0, 0] = 1.0


def test_distance_field_converges_in_a_serpentine() -> None:
    # Walls alternately open on the right and on the left: the path zig-zags, so the sweeps
    # must keep going in all four directions many times before nothing changes.
    grid = np.zeros((61, 40), dtype=np.int8)
    for i, row in enumerate(range(4, 60, 4)):
        if i % 2 == 0:
            grid[row, 5:] = 100  # gap on the left
        else:
            grid[row, :35] = 100  # gap on the right
    m = OccupancyMap(grid, 0.1)
    p = Planner(m, robot_radius=0.0)
    field = p.distance_field(m.cell_to_world(0, 0))
    expected = dijkstra(p._ok, (0, 0), m.resolution)
    assert np.array_equal(np.isinf(field), np.isinf(expected))
    assert np.allclose(field[np.isfinite(field)], expected[np.isfinite(expected)], atol=1e-9)
    top = p.plan(m.cell_to_world(0, 0), m.cell_to_world(60, 0))
    assert p.path_length(m.cell_to_world(0, 0), m.cell_to_world(60, 0)) > 14 * 3.0
    assert len(top) > 14  # one turn per wall at least


# --- distance table -------------------------------------------------------------------------


def test_distance_table_symmetric_cached_and_invalidated() -> None:
    p = Planner(wall_room())
    calls: list[tuple[object, object]] = []
    real, real_plan = Planner(wall_room()).path_length, p.plan  # the reference: a 2nd planner

    def counting(
        start: tuple[float, float], goal: tuple[float, float]
    ) -> list[tuple[float, float]]:
        calls.append((start, goal))
        return real_plan(start, goal)

    p.plan = counting  # type: ignore[method-assign]
    wps = {
        "A": Waypoint("A", 0.0, 1.5, 0.0, "table"),
        "B": Waypoint("B", 4.0, 1.5, 0.0, "table"),
        "C": Waypoint("C", 0.0, 3.8, 0.0, "home"),
        "W": Waypoint("W", 3.0, 1.0, 0.0, "other"),  # inside the wall
    }
    table = DistanceTable(p, wps)
    ab = table.distance("A", "B")
    assert ab == table.distance("B", "A") == pytest.approx(real((0.0, 1.5), (4.0, 1.5)))
    assert len(calls) == 1
    # The planned path is kept, either way round.
    path = table.path("A", "B")
    assert path is not None and path[0] == (0.0, 1.5) and path[-1] == (4.0, 1.5)
    assert table.path("B", "A") == path[::-1]
    assert table.distance("A", "A") == 0.0
    with pytest.raises(NotFound):
        table.distance("A", "Z")
    with pytest.raises(Unreachable, match="'W'"):
        table.distance("W", "A")
    with pytest.raises(Unreachable):
        table.distance("A", "W")
    calls.clear()
    mat = table.matrix(["A", "B", "C", "W"])
    assert np.array_equal(mat, mat.T) and (np.diag(mat) == 0).all()
    assert mat[0, 1] == ab and np.isinf(mat[0, 3]) and np.isfinite(mat[:3, :3]).all()
    assert len(calls) == 2  # only A-C and B-C were new
    calls.clear()
    table.add(Waypoint("C", 4.0, 3.8, 0.0, "home"))  # C moved: only C's distances go
    table.add(Waypoint("D", 1.0, 1.0, 0.0, "table"))
    assert table.distance("A", "B") == ab and not calls
    assert table.distance("A", "C") < table.distance("B", "C") + 10 and len(calls) == 2
    with pytest.raises(NotFound):
        table.matrix(["A", "nope"])


# --- ray casting ----------------------------------------------------------------------------


def test_raycast_hand_computed() -> None:
    # 10 x 4 m at 0.1 m, a wall filling x in [7.0, 7.1]; a far wall x in [9.5, 9.6] behind it.
    m = room(10.0, 4.0, [(7.0, 0.0, 7.1, 4.0), (9.5, 0.0, 9.6, 4.0)], res=0.1)
    angles = np.array([0.0, math.pi / 4, -math.pi / 4, math.pi, math.pi / 2])
    r = raycast(m, 2.05, 2.0, angles, 20.0)
    assert r[0] == pytest.approx(4.95, abs=1e-9)
    # At 45 deg the ray would cross y = 4 (the map top) before x = 7: leaves the map, no hit.
    assert np.isinf(r[1]) and np.isinf(r[2])
    assert np.isinf(r[3]) and np.isinf(r[4])  # off the map is not an obstacle
    diag = raycast(m, 5.0, 2.0, np.array([math.atan2(1.0, 2.0)]), 20.0)[0]
    assert diag == pytest.approx(math.hypot(2.0, 1.0), abs=1e-9)  # enters at (7.0, 3.0)
    assert np.isinf(raycast(m, 2.05, 2.0, np.array([0.0]), 4.9))[0]  # beyond max_range
    assert raycast(m, 7.05, 2.0, np.array([0.0]), 5.0)[0] == 0.0  # inside the wall
    # Unknown cells do not stop rays; graded cells stop them from 65 up.
    grid = m.grid.copy()
    grid[:, 50:55] = -1
    grid[:, 60] = 64
    r2 = raycast(OccupancyMap(grid, 0.1), 2.05, 2.0, np.array([0.0]), 20.0)
    assert r2[0] == pytest.approx(4.95, abs=1e-9)
    grid[:, 60] = 65
    r3 = raycast(OccupancyMap(grid, 0.1), 2.05, 2.0, np.array([0.0]), 20.0)
    assert r3[0] == pytest.approx(3.95, abs=1e-9)


def test_raycast_matches_dense_sampling_on_demo(demo: tuple[OccupancyMap, Planner]) -> None:
    m, _ = demo
    angles = np.linspace(-math.pi, math.pi, 360, endpoint=False)
    ranges = raycast(m, 8.03, 6.71, angles, 8.0)
    assert ranges.shape == (360,)
    ts = np.arange(0.0, 8.0, 0.001)
    for a, r in zip(angles[::3], ranges[::3], strict=True):
        cols = np.floor((8.03 + ts * math.cos(a) - m.origin[0]) / m.resolution).astype(int)
        rows = np.floor((6.71 + ts * math.sin(a) - m.origin[1]) / m.resolution).astype(int)
        inside = (rows >= 0) & (rows < m.height) & (cols >= 0) & (cols < m.width)
        hit = np.zeros(ts.shape, dtype=bool)
        hit[inside] = m.grid[rows[inside], cols[inside]] >= 65
        expected = ts[hit.argmax()] if hit.any() else math.inf
        # Exact but for a cell corner clipped between two half-cell samples.
        assert r == pytest.approx(expected, abs=0.5 * m.resolution) or (
            math.isinf(r) and math.isinf(expected)
        )


# --- the demo restaurant --------------------------------------------------------------------


@pytest.fixture(scope="module")
def demo() -> tuple[OccupancyMap, Planner]:
    m, _ = load_demo()
    return m, Planner(m, robot_radius=0.2)


def components(mask: np.ndarray) -> list[np.ndarray]:
    """8-connected components of ``mask`` as boolean masks (plain BFS)."""
    seen = np.zeros(mask.shape, dtype=bool)
    out = []
    for start in zip(*np.nonzero(mask), strict=True):
        if seen[start]:
            continue
        comp = np.zeros(mask.shape, dtype=bool)
        queue = deque([start])
        seen[start] = True
        while queue:
            r, c = queue.popleft()
            comp[r, c] = True
            for dr, dc in itertools.product((-1, 0, 1), repeat=2):
                nb = (r + dr, c + dc)
                inside = 0 <= nb[0] < mask.shape[0] and 0 <= nb[1] < mask.shape[1]
                if inside and mask[nb] and not seen[nb]:
                    seen[nb] = True
                    queue.append(nb)
        out.append(comp)
    return out


def test_demo_map_shape() -> None:
    m, wps = load_demo()
    assert demo_map_path().name == "demo_restaurant.yaml" and m.resolution == 0.05
    free_rows, free_cols = np.nonzero(m.grid == 0)
    width = (free_cols.max() - free_cols.min() + 1) * m.resolution
    height = (free_rows.max() - free_rows.min() + 1) * m.resolution
    assert width == pytest.approx(16.0, abs=0.06) and height == pytest.approx(12.0, abs=0.06)
    assert m.grid[0, 0] == -1 and m.grid[-1, -1] == -1  # unknown outside the walls
    tables = [w for w in wps.values() if w.kind == "table"]
    homes = [wps[f"home{i}"] for i in range(1, 7)]
    assert len(tables) >= 14 and {f"T{i}" for i in range(1, 15)} <= wps.keys()
    assert all(h.kind == "home" for h in homes) and wps["pass"].kind == "pass"
    assert len({h.y for h in homes}) == 1  # one row
    assert (
        min(math.dist((a.x, a.y), (b.x, b.y)) for a, b in itertools.combinations(homes, 2)) >= 0.8
    )


def test_demo_waypoints_face_their_target(demo: tuple[OccupancyMap, Planner]) -> None:
    m, planner = demo
    _, wps = load_demo()
    for w in wps.values():
        assert planner.is_traversable(w.x, w.y), w.name
        ahead = raycast(m, w.x, w.y, np.array([w.yaw]), 1.0)[0]
        assert ahead < 0.8, w.name  # facing its table, or the pass counter for home/pass
        if w.kind in ("home", "pass"):  # ...and that obstacle is the counter along the north wall
            north = raycast(m, w.x, w.y, np.array([math.pi / 2]), 1.0)[0]
            assert north == pytest.approx(ahead, abs=1e-9)


def test_demo_every_table_reachable_from_every_home(demo: tuple[OccupancyMap, Planner]) -> None:
    _, planner = demo
    _, wps = load_demo()
    table = DistanceTable(planner, wps)
    names = list(wps)
    mat = table.matrix(names)
    assert np.isfinite(mat).all() and (mat[~np.eye(len(names), dtype=bool)] > 0).all()
    # Path lengths are at least the straight line, and not absurdly longer in a dining room.
    for i, j in itertools.combinations(range(len(names)), 2):
        a, b = wps[names[i]], wps[names[j]]
        assert (
            math.dist((a.x, a.y), (b.x, b.y)) - 1e-9
            <= mat[i, j]
            < 2 * math.dist((a.x, a.y), (b.x, b.y)) + 1.0
        )
    path = planner.plan((wps["home1"].x, wps["home1"].y), (wps["T16"].x, wps["T16"].y))
    assert_path_clear(planner, path)


def test_demo_narrowest_aisle_is_at_least_70cm(demo: tuple[OccupancyMap, Planner]) -> None:
    """No free cell is closer than 0.35 m to two different obstacles, i.e. every gap between
    two obstacles (tables, pillars, walls) is >= 0.7 m, measured on the raw grid."""
    m, _ = demo
    margin = 20  # keep inflate()'s "off the map is an obstacle" rule away from the room
    count = np.zeros(m.grid.shape, dtype=np.int32)
    comps = components(m.grid >= 65)
    assert len(comps) >= 14 + 2 + 1  # tables, pillars, walls with what stands against them
    for comp in comps:
        grid = np.zeros((m.height + 2 * margin, m.width + 2 * margin), dtype=np.int8)
        grid[margin:-margin, margin:-margin][comp] = 100
        near = inflate(OccupancyMap(grid, m.resolution), 0.35)[margin:-margin, margin:-margin]
        count += near & (m.grid == 0)
    assert count.max() == 1


def test_demo_paths_keep_clear_of_tables(demo: tuple[OccupancyMap, Planner]) -> None:
    """Home -> table paths stay >= half the clearance beyond the inflation (0.35 m from any
    obstacle) except in their first and last 0.6 m, so a follower cutting corners does not
    touch a table; the demo aisles leave room for that everywhere."""
    m, planner = demo
    _, wps = load_demo()
    roomy = ~inflate(m, 0.2 + 0.3 / 2)  # the default clearance is 0.3 m
    for home, table in itertools.product(
        [w for w in wps.values() if w.kind == "home"],
        [w for w in wps.values() if w.kind == "table"],
    ):
        path = np.array(planner.plan((home.x, home.y), (table.x, table.y)))
        seg = np.diff(path, axis=0)
        seg_len = np.hypot(seg[:, 0], seg[:, 1])
        total = seg_len.sum()
        along = np.arange(0.6, total - 0.6, 0.01)
        i = np.minimum(np.searchsorted(np.cumsum(seg_len), along), len(seg) - 1)
        before = np.concatenate(([0.0], np.cumsum(seg_len)))[i]
        pts = path[i] + seg[i] * ((along - before) / seg_len[i])[:, None]
        rows = np.floor((pts[:, 1] - m.origin[1]) / m.resolution).astype(int)
        cols = np.floor((pts[:, 0] - m.origin[0]) / m.resolution).astype(int)
        assert roomy[rows, cols].all(), (home.name, table.name)
