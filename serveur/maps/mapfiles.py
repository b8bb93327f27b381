"""A robot's map as the owner uploads it: map_server's YAML and its image, checked (pure files).

The console takes the two files a robot's ``map_saver`` wrote and makes them the restaurant's
map. What is uploaded is checked before anything changes: the YAML is map_server metadata
whose ``image`` names the uploaded image — a bare file name, never a path (a YAML pointing
outside its folder, ``../../etc/x.pgm`` or ``/var/...``, is refused, as is one naming another
file); the image is a PNG or PGM of sane size. The map is then read exactly as
:func:`serveur.maps.mapio.load_map` reads one from disk (map_server's semantics), from a
private temporary folder holding only those two files.
"""

from __future__ import annotations

import base64
import io
import json
import sys
import tempfile
from pathlib import Path
from typing import Any, Final

from serveur.errors import MapError
from serveur.maps.child import run_child, serve_child
from serveur.maps.distances import MapData
from serveur.maps.mapio import OccupancyMap, load_map, save_map

__all__ = [
    "MAX_MAP_IMAGE_BYTES",
    "MAX_MAP_PIXELS",
    "MAX_YAML_BYTES",
    "map_files",
    "read_map_files",
    "read_map_files_in_child",
]

MAX_YAML_BYTES: Final = 16 * 1024
#: A 100 m x 100 m floor at 0.025 m a cell is 16 million cells: more is not a restaurant.
MAX_MAP_PIXELS: Final = 16_000_000
MAX_MAP_IMAGE_BYTES: Final = 20 * 1024 * 1024
_IMAGE_FORMATS: Final = ("PNG", "PPM")  # Pillow calls PGM "PPM"


def _image_name(yaml_bytes: bytes) -> str:
    import yaml

    if len(yaml_bytes) > MAX_YAML_BYTES:
        raise MapError("the map's YAML is too large to be map_server's", reason="too_large")
    try:
        meta = yaml.safe_load(yaml_bytes.decode("utf-8"))
    except (UnicodeDecodeError, yaml.YAMLError) as exc:
        raise MapError(f"the map's YAML cannot be read: {exc}", reason="not_a_map") from exc
    if not isinstance(meta, dict) or not isinstance(meta.get("image"), str):
        raise MapError("the YAML is not map_server's: it names no image", reason="not_a_map")
    name = meta["image"]
    if "/" in name or "\\" in name or name in ("", ".", "..") or name.startswith("."):
        raise MapError(
            f"the YAML's image {name!r} points outside its folder: it must be the image's"
            " file name only",
            reason="outside",
        )
    return str(name)


def _check_image(image: bytes) -> None:
    from PIL import Image, UnidentifiedImageError

    if len(image) > MAX_MAP_IMAGE_BYTES:
        raise MapError("the map image is too large", reason="too_large")
    try:
        with Image.open(io.BytesIO(image)) as img:
            if img.format not in _IMAGE_FORMATS:
                raise MapError(
                    f"the map image must be a PGM or PNG, not {img.format}", reason="not_a_map"
                )
            w, h = img.size
    except UnidentifiedImageError as exc:
        raise MapError("the map image is not an image", reason="not_a_map") from exc
    except (OSError, ValueError) as exc:
        raise MapError(f"the map image cannot be read: {exc}", reason="not_a_map") from exc
    if w * h > MAX_MAP_PIXELS:
        raise MapError(f"the map image is {w}x{h}: too large for a restaurant", reason="too_large")


def read_map_files(yaml_bytes: bytes, image: bytes, image_name: str) -> OccupancyMap:
    """The map the two uploaded files describe; :class:`MapError` (with a ``reason``:
    not_a_map, outside, mismatch, too_large) and nothing read otherwise."""
    named = _image_name(yaml_bytes)
    uploaded = Path(image_name).name
    if named != uploaded:
        raise MapError(
            f"the YAML names the image {named!r} but the image uploaded is {uploaded!r}",
            reason="mismatch",
        )
    _check_image(image)
    with tempfile.TemporaryDirectory(prefix="serveur-map-") as folder:
        (Path(folder) / named).write_bytes(image)
        yaml_path = Path(folder) / "map.yaml"
        yaml_path.write_bytes(yaml_bytes)
        try:
            return load_map(yaml_path)
        except MapError as exc:
            # The temporary folder's path means nothing to the owner: the reason is enough.
            raise MapError(str(exc).replace(folder + "/", ""), reason="not_a_map") from None


def map_files(m: OccupancyMap, stem: str = "restaurant") -> tuple[bytes, bytes]:
    """``m`` as map_server's two files (YAML, PGM), for the owner to give the robot."""
    with tempfile.TemporaryDirectory(prefix="serveur-map-") as folder:
        yaml_path = Path(folder) / f"{stem}.yaml"
        save_map(m, yaml_path)
        return yaml_path.read_bytes(), yaml_path.with_suffix(".pgm").read_bytes()


async def read_map_files_in_child(yaml_bytes: bytes, image: bytes, image_name: str) -> MapData:
    """:func:`read_map_files` in a child process (:mod:`serveur.maps.child`): a refusal comes
    back as the child's MapError, reason and all."""
    request = json.dumps(
        {
            "yaml": base64.b64encode(yaml_bytes).decode(),
            "image": base64.b64encode(image).decode(),
            "name": image_name,
        }
    ).encode()
    reply = await run_child("serveur.maps.mapfiles", request)
    return MapData.from_snapshot(reply["map"])


def _answer(req: dict[str, Any]) -> dict[str, Any]:
    """The child's work (:func:`read_map_files_in_child`)."""
    m = read_map_files(
        base64.b64decode(req["yaml"]), base64.b64decode(req["image"]), str(req["name"])
    )
    return {"map": MapData.from_occupancy(m).snapshot()}


if __name__ == "__main__":
    sys.exit(serve_child(_answer))
