"""A floor-plan image turned into a map (serveur.maps.floorplan, pure): distances on the map
within 2 % of the plan's truth, thin walls kept, markup erased, stretched plans caught, bad
files refused with the reason."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from serveur.errors import InvalidField, MapError
from serveur.maps.floorplan import (
    Measure,
    Scale,
    Stroke,
    edit,
    read_plan,
    scale_from,
    to_map,
    walls,
)
from serveur.maps.mapio import load_map, save_map
from tests.maps.plans import ROOM, plan


def measures(p: object, y_mid: float, x_mid: float) -> tuple[Measure, Measure]:
    """What an owner does: tape-measure the room inside, wall to wall, across and along."""
    across = Measure((p.left, y_mid), (p.right, y_mid), ROOM[0])  # type: ignore[attr-defined]
    along = Measure((x_mid, p.top), (x_mid, p.bottom), ROOM[1])  # type: ignore[attr-defined]
    return across, along


def free_run(line: np.ndarray, start: int) -> int:
    """Cells of floor on both sides of ``start`` along a row or column of the grid."""
    lo = hi = start
    while lo > 0 and line[lo - 1] == 0:
        lo -= 1
    while hi < len(line) - 1 and line[hi + 1] == 0:
        hi += 1
    return hi - lo + 1


@pytest.mark.parametrize("fmt", ["PNG", "JPEG"])
def test_measured_distances_on_the_map_are_within_two_percent(fmt: str) -> None:
    p = plan(px_per_m=37.0, fmt=fmt)
    grey = read_plan(p.data)
    x_mid, y_mid = (p.left + p.partition_x) / 2, (p.top + p.bottom) / 2
    across, along = measures(p, y_mid + 40, x_mid)
    scale = scale_from(across, along)
    assert not scale.stretched
    # The threshold the owner settles on in the preview: the walls (drawn near black) stay,
    # the tables, labels and dimension line (mid grey) go.
    mask = walls(grey, 50)
    m = to_map(mask, scale, resolution=0.05)
    row = m.grid[m.height // 2]
    col = int(((x_mid - 30) / 37.0) / 0.05)
    width_m = free_run(row, col) * 0.05
    assert width_m == pytest.approx(10.0, rel=0.02)  # left wall to the partition
    column = m.grid[:, col]
    depth_m = free_run(column, m.height // 2) * 0.05
    assert depth_m == pytest.approx(ROOM[1], rel=0.02)
    assert set(np.unique(m.grid).tolist()) <= {0, 100}  # trinary, no grey edges


def test_a_thin_wall_line_survives_cells_larger_than_it() -> None:
    img = np.full((200, 400), 255, dtype=np.uint8)
    img[:, 200] = 0  # a 1 px line: 2.5 cm at 40 px/m, half a 5 cm cell (off its centre)
    m = to_map(walls(img, 128), Scale(1 / 40, 1 / 40), resolution=0.05)
    assert all(100 in row for row in m.grid)  # the wall is continuous on the map


def test_markup_is_erased_and_a_faint_wall_drawn() -> None:
    p = plan(px_per_m=40.0)
    mask = walls(read_plan(p.data), 128)
    table = (p.left + 2.0 * 40.0, p.top + 3.0 * 40.0)
    ring = (int(table[1]), int(table[0] + 0.5 * 40.0))  # on the table's outline
    assert mask[ring[0], ring[1] - 1 : ring[1] + 2].any()
    cleaned = edit(mask, [Stroke("erase", (table,), width=1.2 * 40.0)])
    assert not cleaned[ring[0], ring[1] - 1 : ring[1] + 2].any()
    glass = (p.left + 12.0 * 40, p.top + 5.0 * 40)
    drawn = edit(cleaned, [Stroke("wall", (glass, (glass[0], glass[1] + 80)), width=4)])
    assert (
        drawn[int(glass[1]) + 40, int(glass[0])] and not cleaned[int(glass[1]) + 40, int(glass[0])]
    )
    assert mask is not cleaned and mask[ring[0], ring[1] - 1 : ring[1] + 2].any()  # a copy


def test_a_stretched_plan_is_caught() -> None:
    p = plan(px_per_m=40.0, stretch=1.05)  # a scan 5 % taller than it should be
    across, along = measures(p, (p.top + p.bottom) / 2, (p.left + p.partition_x) / 2)
    scale = scale_from(across, along)
    assert scale.stretched and scale.disagreement == pytest.approx(0.05, abs=0.005)
    m = to_map(walls(read_plan(p.data), 50), scale)  # each axis its own scale: still true
    col = int(((p.left + p.partition_x) / 2 - 30) / 40.0 / 0.05)
    assert free_run(m.grid[:, col], m.height // 2) * 0.05 == pytest.approx(ROOM[1], rel=0.02)


def test_the_map_is_what_map_server_reads_back(tmp_path: Path) -> None:
    p = plan(px_per_m=30.0)
    across, along = measures(p, (p.top + p.bottom) / 2, (p.left + p.partition_x) / 2)
    m = to_map(walls(read_plan(p.data), 128), scale_from(across, along), origin=(-1.0, -2.0))
    save_map(m, tmp_path / "plan.yaml")
    back = load_map(tmp_path / "plan.yaml")
    assert back.resolution == 0.05 and back.origin == (-1.0, -2.0, 0.0)
    assert np.array_equal(back.grid, m.grid)


def _png(size: tuple[int, int], fmt: str = "PNG") -> bytes:
    buf = io.BytesIO()
    Image.new("L", size, 255).save(buf, format=fmt)
    return buf.getvalue()


@pytest.mark.parametrize(
    ("data", "reason"),
    [
        (b"restaurant plan.txt, not a picture", "not_an_image"),
        (b"\x89PNG\r\n\x1a\n" + b"\x00" * 64, "not_an_image"),  # a PNG cut short
        (_png((40, 40), "GIF"), "not_an_image"),
        (_png((8000, 6000)), "too_large"),  # 48 million pixels
        (b"\x00" * (26 * 1024 * 1024), "too_large"),
    ],
)
def test_a_file_that_is_not_a_plan_is_refused_with_why(data: bytes, reason: str) -> None:
    with pytest.raises(MapError) as err:
        read_plan(data)
    assert err.value.details["reason"] == reason


def test_measures_that_cannot_give_a_scale_are_refused() -> None:
    across = Measure((0.0, 0.0), (400.0, 0.0), 10.0)
    with pytest.raises(InvalidField, match="across"):
        scale_from(across, Measure((0.0, 0.0), (300.0, 20.0), 8.0))  # both across
    with pytest.raises(InvalidField, match="metres"):
        scale_from(across, Measure((0.0, 0.0), (0.0, 300.0), 0.0))
    with pytest.raises(InvalidField, match="further apart"):
        scale_from(across, Measure((0.0, 0.0), (0.0, 3.0), 1.0))
