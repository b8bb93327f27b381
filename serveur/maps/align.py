"""Fit one map onto another from matched points: scale, rotation, translation (pure).

A restaurant's places and zones are drawn on its floor plan, but the robot drives in the frame
of the map it made itself (SLAM): its origin, its heading and even its scale (a floor plan's
scale is measured by hand) differ. Staff mark the same spots on both — a pillar's corner, a
door — and :func:`fit` finds the similarity transform (uniform scale, rotation, translation)
that carries the floor plan's points onto the robot's, in the least-squares sense (Umeyama's
method, 1991: closed form, no iteration), with each point's residual shown so a mis-clicked
pair stands out. Two pairs determine the transform exactly; three or more say how well it fits.
Open-RMF's traffic-editor aligns its layers with such fiducials (../shared/notes/field.md).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

from serveur.errors import InvalidField

__all__ = ["MIN_SPREAD", "MISMATCH", "Similarity", "fit", "matches_nothing"]

Point = tuple[float, float]

#: Matched points closer together than this (m, in either map) cannot fix a rotation.
MIN_SPREAD = 0.5
#: A fit whose points are off by this share of their spread on the average matched nothing.
MISMATCH = 0.3


@dataclass(frozen=True, slots=True)
class Similarity:
    """``dst = scale * R(rotation) * src + (tx, ty)``, and how well it fits the points."""

    scale: float
    rotation: float  # radians, (-pi, pi]
    tx: float
    ty: float
    #: Each pair's distance (m, in the destination frame) between its matched point and where
    #: the transform puts its source point; and their root mean square.
    residuals: tuple[float, ...] = ()
    rms: float = 0.0

    def apply(self, x: float, y: float) -> Point:
        c, s = math.cos(self.rotation), math.sin(self.rotation)
        return (
            self.scale * (c * x - s * y) + self.tx,
            self.scale * (s * x + c * y) + self.ty,
        )

    def apply_yaw(self, yaw: float) -> float:
        """A heading in the source frame, in the destination frame."""
        return math.remainder(yaw + self.rotation, math.tau)

    def inverse(self) -> Similarity:
        inv_scale = 1.0 / self.scale
        c, s = math.cos(-self.rotation), math.sin(-self.rotation)
        tx = -inv_scale * (c * self.tx - s * self.ty)
        ty = -inv_scale * (s * self.tx + c * self.ty)
        return Similarity(inv_scale, -self.rotation, tx, ty)


def _from_centre(points: Sequence[Point]) -> list[float]:
    cx = sum(p[0] for p in points) / len(points)
    cy = sum(p[1] for p in points) / len(points)
    return [math.hypot(p[0] - cx, p[1] - cy) for p in points]


def _spread(points: Sequence[Point]) -> float:
    return max(_from_centre(points))


def matches_nothing(t: Similarity, dst: Sequence[Point]) -> bool:
    """Whether the fit's points are off by about their own spread (by :data:`MISMATCH` of their
    mean distance from their centre): points marked in another order on the two maps, or a
    mirrored map — no turn and shift carries one onto the other. One point marked wrong is not
    this: its residual names it."""
    return t.rms > MISMATCH * (sum(_from_centre(dst)) / len(dst))


def fit(src: Sequence[Point], dst: Sequence[Point]) -> Similarity:
    """The similarity carrying ``src[i]`` onto ``dst[i]`` best (least squares).

    Refused (:class:`~serveur.errors.InvalidField`) with fewer than two pairs, unequal lists, a
    non-finite coordinate, or points bunched together (all within :data:`MIN_SPREAD` of their
    centre in either map: the rotation would be noise).
    """
    if len(src) != len(dst):
        raise InvalidField("each point on one map needs its match on the other", field="points")
    if len(src) < 2:
        raise InvalidField("mark at least two matching points on both maps", field="points")
    if not all(math.isfinite(v) for p in (*src, *dst) for v in p):
        raise InvalidField("a point is not a number", field="points")
    if _spread(src) < MIN_SPREAD / 2 or _spread(dst) < MIN_SPREAD / 2:
        raise InvalidField(
            "the points are too close together: mark spots at least a metre apart",
            field="points",
        )
    n = len(src)
    sx = sum(p[0] for p in src) / n
    sy = sum(p[1] for p in src) / n
    dx = sum(p[0] for p in dst) / n
    dy = sum(p[1] for p in dst) / n
    # Centred coordinates; in 2-D Umeyama reduces to two sums (the complex-number form).
    a = b = var = 0.0
    for (x, y), (u, v) in zip(src, dst, strict=True):
        x, y, u, v = x - sx, y - sy, u - dx, v - dy
        a += x * u + y * v
        b += x * v - y * u
        var += x * x + y * y
    rotation = math.atan2(b, a)
    scale = math.hypot(a, b) / var
    c, s = math.cos(rotation), math.sin(rotation)
    tx = dx - scale * (c * sx - s * sy)
    ty = dy - scale * (s * sx + c * sy)
    t = Similarity(scale, rotation, tx, ty)
    residuals = tuple(
        math.hypot(t.apply(*p)[0] - q[0], t.apply(*p)[1] - q[1])
        for p, q in zip(src, dst, strict=True)
    )
    rms = math.sqrt(sum(r * r for r in residuals) / n)
    return Similarity(scale, rotation, tx, ty, residuals, rms)
