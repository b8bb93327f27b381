"""A restaurant floor plan of known dimensions, drawn for the tests (as an owner's scan would
look): outer walls, a partition with a door, tables drawn as outlines, text, a dimension line.

The room is ``ROOM`` metres inside, walls ``WALL`` m thick, drawn at ``px_per_m`` pixels a metre
across and ``px_per_m * stretch`` along (a stretched scan when ``stretch`` is not 1), with a
white margin. :func:`plan` returns the PNG (or JPEG) bytes and where the inner wall faces are in
pixels, so a test can mark the measures an owner would.
"""

from __future__ import annotations

import io
from dataclasses import dataclass

from PIL import Image, ImageDraw

ROOM = (15.6, 11.6)  # inside the outer walls, m
WALL = 0.2
MARGIN = 30  # px


@dataclass(frozen=True)
class Plan:
    data: bytes
    #: Inner faces of the outer walls, in pixels: left, right (x) and top, bottom (y).
    left: float
    right: float
    top: float
    bottom: float
    partition_x: float  # the partition wall's left face, px


def plan(px_per_m: float = 40.0, stretch: float = 1.0, fmt: str = "PNG") -> Plan:
    sx, sy = px_per_m, px_per_m * stretch
    w = round(2 * MARGIN + (ROOM[0] + 2 * WALL) * sx)
    h = round(2 * MARGIN + (ROOM[1] + 2 * WALL) * sy)
    img = Image.new("L", (w, h), 255)
    d = ImageDraw.Draw(img)
    ox, oy = MARGIN, MARGIN
    outer = (ox, oy, ox + (ROOM[0] + 2 * WALL) * sx, oy + (ROOM[1] + 2 * WALL) * sy)
    d.rectangle(outer, fill=20)
    inner = (ox + WALL * sx, oy + WALL * sy, outer[2] - WALL * sx, outer[3] - WALL * sy)
    d.rectangle(inner, fill=250)
    # A partition 10 m from the left inner face with a 1 m door: a kitchen behind it.
    px = inner[0] + 10.0 * sx
    d.rectangle((px, inner[1], px + 0.1 * sx, inner[1] + 7.0 * sy), fill=30)
    d.rectangle((px, inner[1] + 8.0 * sy, px + 0.1 * sx, inner[3]), fill=30)
    # Tables as thin outlines, labels, a dimension line with arrows: the owner erases those.
    for i in range(3):
        cx, cy = inner[0] + (2.0 + 3.0 * i) * sx, inner[1] + 3.0 * sy
        d.ellipse((cx - 0.5 * sx, cy - 0.5 * sy, cx + 0.5 * sx, cy + 0.5 * sy), outline=60, width=2)
        d.text((cx - 6, cy - 5), f"T{i + 1}", fill=60)
    d.line((inner[0], inner[3] - 1.0 * sy, inner[2], inner[3] - 1.0 * sy), fill=90, width=1)
    buf = io.BytesIO()
    img.save(buf, format=fmt)
    return Plan(buf.getvalue(), inner[0], inner[2], inner[1], inner[3], px)
