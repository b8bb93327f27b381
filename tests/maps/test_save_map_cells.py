"""The site written for a forecast's replay without numpy (the server process must never load
numpy or Pillow: a forecast started from the console loaded numpy into the server to write the
map). save_map_cells writes the bytes save_map writes, and a child process writing the site
from the map's cells never imports numpy."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np

from serveur.maps.mapio import OccupancyMap, load_map, save_map, save_map_cells


def test_the_cells_are_written_as_save_map_writes_them(tmp_path: Path) -> None:
    rng = np.random.default_rng(7)
    grid = rng.choice(np.array([-1, 0, 10, 25, 26, 50, 64, 65, 99, 100], np.int8), (13, 17))
    m = OccupancyMap(grid, 0.05, (-1.5, 2.25, 0.0))
    save_map(m, tmp_path / "a.yaml")
    save_map_cells(grid.tobytes(), 17, 13, 0.05, (-1.5, 2.25, 0.0), tmp_path / "b.yaml")
    assert (tmp_path / "a.pgm").read_bytes() == (tmp_path / "b.pgm").read_bytes()
    a = (tmp_path / "a.yaml").read_text().replace("a.pgm", "b.pgm")
    assert a == (tmp_path / "b.yaml").read_text()
    back = load_map(tmp_path / "b.yaml")
    assert back.grid.shape == (13, 17)


def test_writing_the_cells_loads_no_numpy(tmp_path: Path) -> None:
    code = (
        "import sys\n"
        "from serveur.maps.mapio import save_map_cells\n"
        "save_map_cells(bytes([0, 100, 255, 0]), 2, 2, 0.05, (0.0, 0.0, 0.0),"
        f" {str(tmp_path / 's.yaml')!r})\n"
        "print(sorted(m for m in ('numpy', 'PIL') if m in sys.modules))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
    # Row 0 (free, occupied) is the map's bottom: written last, under (unknown, free).
    assert (tmp_path / "s.pgm").read_bytes().endswith(bytes([205, 254, 254, 0]))
