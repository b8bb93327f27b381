"""A simulated robot's front camera: a first-person JPEG of the map from the robot's pose.

Real robots publish ``sensor_msgs/CompressedImage`` (``format: "jpeg"``, the JPEG bytes in
``data``) from their camera driver's ``image_transport`` compressed plugin, typically 640x480 at
10-30 fps, 20-50 kB a frame at the default quality (../shared/notes/video.md). The simulator
publishes the same message, rendered as the robot would see the room: one ray per image column
cast on the occupancy grid (walls and tables are what the map marks occupied), each hit drawn
as a vertical strip whose height falls with distance (a pinhole camera at ``CAMERA_HEIGHT``
looking level), shaded by distance, above a floor and below a ceiling. It is only rendered
while someone subscribes (the outbox builds a message only for a subscriber that takes it),
so an unwatched camera costs nothing.

What it does not model: lens distortion, exposure, motion blur, people. Enough for the relay
to be tested and demoed with real JPEG bytes of a realistic size.
"""

from __future__ import annotations

import io
import math
from typing import Final

import numpy as np
import numpy.typing as npt
from PIL import Image

from serveur.maps.navigation import OccupancyMap, raycast

__all__ = ["CAMERA_FOV", "CAMERA_SIZE", "CameraView"]

#: Horizontal field of view (radians): a typical robot front camera (RealSense D435 colour:
#: 69 degrees).
CAMERA_FOV: Final = math.radians(69.0)
#: Image size (width, height): the common 640x480.
CAMERA_SIZE: Final = (640, 480)
#: How high the camera sits and how tall walls are drawn (metres).
CAMERA_HEIGHT: Final = 1.0
_WALL_HEIGHT: Final = 2.2
_MAX_RANGE: Final = 12.0
_QUALITY: Final = 80  # image_transport's default JPEG quality

_CEILING = np.array([214, 219, 224], dtype=np.uint8)
_FLOOR = np.array([150, 120, 90], dtype=np.uint8)
_WALL = np.array([236, 232, 220], dtype=np.float64)
_FAR = np.array([120, 124, 130], dtype=np.float64)


class CameraView:
    """Renders the robot's view of one map (the column geometry is computed once)."""

    def __init__(
        self,
        grid: OccupancyMap,
        size: tuple[int, int] = CAMERA_SIZE,
        fov: float = CAMERA_FOV,
        quality: int = _QUALITY,
    ) -> None:
        self._grid = grid
        self.width, self.height = size
        self._quality = quality
        # Column c looks along yaw + offset[c] (left of the image is left of the robot).
        focal = (self.width / 2) / math.tan(fov / 2)
        cols = np.arange(self.width) + 0.5 - self.width / 2
        self._offsets: npt.NDArray[np.float64] = -np.arctan2(cols, focal)
        self._cos = np.cos(self._offsets)
        self._focal = focal
        self._rows = np.arange(self.height)[:, None]
        self._room = np.empty((self.height, self.width, 3), dtype=np.uint8)
        self._room[: self.height // 2] = _CEILING
        self._room[self.height // 2 :] = _FLOOR
        self.rendered = 0

    def jpeg(self, x: float, y: float, yaw: float) -> bytes:
        """The view from (x, y) facing ``yaw``, as JPEG bytes."""
        ranges = raycast(self._grid, x, y, self._offsets + yaw, _MAX_RANGE)
        depth = np.where(np.isfinite(ranges), ranges, _MAX_RANGE) * self._cos  # no fish-eye
        depth = np.maximum(depth, 0.05)
        horizon = self.height / 2
        top = horizon - (_WALL_HEIGHT - CAMERA_HEIGHT) * self._focal / depth
        bottom = horizon + CAMERA_HEIGHT * self._focal / depth
        near = np.clip(depth / _MAX_RANGE, 0.0, 1.0)[:, None]
        shade = (_WALL * (1.0 - near) + _FAR * near).astype(np.uint8)  # (width, 3)
        # Darker every metre of wall, so turning shows: a stripe where depth crosses a metre.
        edge = np.abs(np.diff(np.floor(depth), prepend=np.floor(depth[0]))) > 0
        shade[edge] = (shade[edge] * 0.7).astype(np.uint8)
        wall = (self._rows >= top[None, :]) & (self._rows < bottom[None, :])
        img = np.where(wall[:, :, None], shade[None, :, :], self._room)
        out = io.BytesIO()
        Image.fromarray(img, "RGB").save(out, "JPEG", quality=self._quality)
        self.rendered += 1
        return out.getvalue()
