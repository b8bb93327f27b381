"""A robot's map files as the owner uploads them (serveur.maps.mapfiles, pure): read exactly as
map_server reads them, and every bad upload refused with its reason."""

from __future__ import annotations

import io

import numpy as np
import pytest
from PIL import Image

from serveur.errors import MapError
from serveur.maps.mapfiles import map_files, read_map_files
from serveur.maps.navigation import demo_map_path, load_demo


def demo_files() -> tuple[bytes, bytes, str]:
    yaml_path = demo_map_path()
    text = yaml_path.read_bytes()
    import yaml

    name = yaml.safe_load(text)["image"]
    return text, (yaml_path.parent / name).read_bytes(), name


def test_the_demo_files_read_as_map_server_reads_them() -> None:
    text, image, name = demo_files()
    m = read_map_files(text, image, name)
    demo = load_demo()[0]
    assert np.array_equal(m.grid, demo.grid)
    assert (m.resolution, m.origin) == (demo.resolution, demo.origin)


def test_the_map_goes_back_out_as_yaml_and_pgm() -> None:
    demo = load_demo()[0]
    text, pgm = map_files(demo)
    assert b"image: restaurant.pgm" in text and pgm.startswith(b"P5")
    assert np.array_equal(read_map_files(text, pgm, "restaurant.pgm").grid, demo.grid)


def _png(size: tuple[int, int]) -> bytes:
    buf = io.BytesIO()
    Image.new("L", size, 254).save(buf, format="PNG")
    return buf.getvalue()


YAML = b"image: room.png\nresolution: 0.05\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n"
YAML += b"occupied_thresh: 0.65\nfree_thresh: 0.196\n"


@pytest.mark.parametrize(
    ("text", "image", "name", "reason"),
    [
        (YAML.replace(b"room.png", b"../../etc/room.png"), _png((10, 10)), "room.png", "outside"),
        (YAML.replace(b"room.png", b"/var/lib/room.png"), _png((10, 10)), "room.png", "outside"),
        (YAML, _png((10, 10)), "other.png", "mismatch"),
        (b"just: words\n", _png((10, 10)), "room.png", "not_a_map"),
        (b"image: [unclosed\n", _png((10, 10)), "room.png", "not_a_map"),
        (b"\xff\xfe not text", _png((10, 10)), "room.png", "not_a_map"),
        (YAML, b"GIF89a not a map image", "room.png", "not_a_map"),
        (YAML, _png((5000, 4000)), "room.png", "too_large"),
        (
            YAML.replace(b"resolution: 0.05", b"resolution: -1"),
            _png((10, 10)),
            "room.png",
            "not_a_map",
        ),
        (YAML + b"#" * 20000, _png((10, 10)), "room.png", "too_large"),
    ],
)
def test_a_bad_upload_is_refused_with_its_reason(
    text: bytes, image: bytes, name: str, reason: str
) -> None:
    with pytest.raises(MapError) as err:
        read_map_files(text, image, name)
    assert err.value.details["reason"] == reason
    assert "serveur-map-" not in str(err.value)  # no temporary path in what the owner reads
