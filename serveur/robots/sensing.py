"""How sure a robot is of where it is, its particle cloud, and its pose from tf (pure).

Three things a robot's localisation says beyond ``/amcl_pose``'s x, y and yaw, read here from
the messages as rosbridge delivers them (ROS1 and ROS 2 shapes alike), with no I/O:

* **How spread its estimate is** (:func:`pose_spread`): AMCL publishes the covariance of its
  particles with every pose (``geometry_msgs/PoseWithCovarianceStamped``, row-major 6x6, x y z
  roll pitch yaw). The spread in metres is the standard deviation along the worst direction
  on the floor (the square root of the larger eigenvalue of the x-y block), in radians the
  standard deviation of the heading. AMCL's own initial pose has 0.5 m and 0.26 rad (its
  default 0.25 m², 0.068 rad²); a converged robot a few centimetres; a robot AMCL has lost,
  metres (its particles spread over the room after a recovery or a global localisation).
* **Its particle cloud** (:class:`Cloud`): ROS1 amcl publishes ``particlecloud``
  (``geometry_msgs/PoseArray``), Nav2's amcl ``particle_cloud`` (``nav2_msgs/ParticleCloud``:
  ``particles[]`` of ``{pose, weight}``, published best effort, SensorDataQoS; read in
  nav2_amcl's amcl_node.cpp). Its weighted spread says the same as the covariance, measured
  on the particles themselves.
* **The pose from tf** (:class:`TfTree`): robots that localise with slam_toolbox or
  cartographer publish no ``/amcl_pose``; their pose is the transform from the map frame to
  the robot's base frame, composed along ``/tf`` (``map`` -> ``odom`` from the localiser,
  ``odom`` -> ``base_link`` from odometry, each in its own ``tf2_msgs/TFMessage``) and
  ``/tf_static``. Robots drive on a floor, so transforms are kept in 2-D (x, y, yaw).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from typing import Any, Final

from serveur.errors import RosbridgeError
from serveur.robots import rosbridge as rb

__all__ = ["CLOUD_SHOWN", "Cloud", "TfTree", "cloud_of", "pose_spread", "spread_of"]

#: The most particles sent to a screen: AMCL runs 500-2000 (5000 in Nav2's defaults); a
#: phone draws a few hundred dots as well and the stream stays small.
CLOUD_SHOWN: Final = 300


def _worst(xx: float, xy: float, yy: float) -> float:
    """The standard deviation along the worst floor direction of the x-y covariance
    ``[[xx, xy], [xy, yy]]`` (the square root of its larger eigenvalue); infinite when an
    entry is not a number."""
    if not all(math.isfinite(v) for v in (xx, xy, yy)):
        return math.inf
    half = (xx + yy) / 2.0
    largest = half + math.sqrt(((xx - yy) / 2.0) ** 2 + xy * xy)
    return math.sqrt(max(0.0, largest))


def spread_of(cov: Sequence[float]) -> tuple[float, float]:
    """(metres, radians): a 6x6 row-major pose covariance's standard deviation along the worst
    floor direction, and of the heading. NaN or negative entries count as unknown (infinite)."""
    if len(cov) != 36:
        raise RosbridgeError("a pose covariance has 36 entries")
    xx, xy, yy, aa = (float(cov[i]) for i in (0, 1, 7, 35))
    if not all(math.isfinite(v) for v in (xx, xy, yy, aa)) or min(xx, yy, aa) < 0.0:
        return (math.inf, math.inf)
    return (_worst(xx, xy, yy), math.sqrt(aa))


def pose_spread(msg: Mapping[str, Any]) -> tuple[float, float] | None:
    """:func:`spread_of` a PoseWithCovarianceStamped (``/amcl_pose``), ROS1 or ROS 2; None
    when it carries no 6x6 covariance (a hand-made message: the pose still counts)."""
    pose = msg.get("pose")
    cov = pose.get("covariance") if isinstance(pose, Mapping) else None
    if cov is None or isinstance(cov, str | bytes) or not hasattr(cov, "__len__"):
        return None
    if len(cov) != 36:
        return None
    try:
        return spread_of([float(v) for v in cov])
    except (TypeError, ValueError):
        return None


@dataclass(frozen=True, slots=True)
class Cloud:
    """A particle cloud in the map frame: positions, headings and normalised weights.

    Plain lists, not numpy: the server process reads clouds (while someone shows one) and must
    not load numpy's ~20 MB for it (tests/maps/test_distances.py checks it never does); one
    pass over a few thousand particles costs less than decoding their JSON did.
    """

    xs: list[float]
    ys: list[float]
    yaws: list[float]
    weights: list[float]
    stamp: float

    def __len__(self) -> int:
        return len(self.xs)

    def spread(self) -> float:
        """The weighted standard deviation (m) along the cloud's worst floor direction."""
        if not self.xs:
            return math.inf
        w, xs, ys = self.weights, self.xs, self.ys
        mx = math.fsum(wi * x for wi, x in zip(w, xs, strict=True))
        my = math.fsum(wi * y for wi, y in zip(w, ys, strict=True))
        xx = yy = xy = 0.0
        for wi, x, y in zip(w, xs, ys, strict=True):
            dx, dy = x - mx, y - my
            xx += wi * dx * dx
            yy += wi * dy * dy
            xy += wi * dx * dy
        return _worst(xx, xy, yy)

    def shown(self, most: int = CLOUD_SHOWN) -> list[list[float]]:
        """At most ``most`` particles as ``[x, y, yaw]`` rounded to cm and centiradians, the
        heaviest first (a thinned cloud keeps where the robot probably is)."""
        order = sorted(range(len(self.xs)), key=lambda i: -self.weights[i])[:most]
        xs, ys, yaws = self.xs, self.ys, self.yaws
        return [[round(xs[i], 2), round(ys[i], 2), round(yaws[i], 2)] for i in order]


def _yaw(q: Mapping[str, Any]) -> float:
    x, y, z, w = rb.quaternion_from_msg(q)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def cloud_of(msg: Mapping[str, Any]) -> Cloud:
    """A ``geometry_msgs/PoseArray`` (ROS1 ``particlecloud``, equal weights) or a
    ``nav2_msgs/ParticleCloud`` (Nav2 ``particle_cloud``, weighted) as a :class:`Cloud`."""
    poses: Iterable[Any]
    weighted: list[float] | None = None
    if isinstance(msg.get("particles"), list):
        parts = msg["particles"]
        poses = [p.get("pose") if isinstance(p, Mapping) else None for p in parts]
        weighted = [float(p.get("weight", 0.0)) if isinstance(p, Mapping) else 0.0 for p in parts]
    elif isinstance(msg.get("poses"), list):
        poses = msg["poses"]
    else:
        raise RosbridgeError("a particle cloud has poses (PoseArray) or particles (ParticleCloud)")
    xs: list[float] = []
    ys: list[float] = []
    yaws: list[float] = []
    for p in poses:
        if not isinstance(p, Mapping):
            raise RosbridgeError("a particle's pose is not an object")
        x, y, _ = rb.point_from_msg(p.get("position") or {})
        xs.append(x)
        ys.append(y)
        yaws.append(_yaw(p.get("orientation") or {}))
    n = len(xs)
    w = weighted if weighted is not None else [1.0] * n
    total = math.fsum(w) if all(math.isfinite(v) and v >= 0.0 for v in w) else 0.0
    if n and total <= 0.0:
        w, total = [1.0] * n, float(n)  # weights that cannot be weights: count them alike
    if n:
        w = [v / total for v in w]
    header = msg.get("header")
    stamp = 0.0
    if isinstance(header, Mapping) and isinstance(header.get("stamp"), Mapping):
        stamp = rb.from_ros_time(header["stamp"])
    return Cloud(xs, ys, yaws, w, stamp)


_Transform = tuple[float, float, float]  # x, y, yaw of a child frame in its parent


def _compose(a: _Transform, b: _Transform) -> _Transform:
    """``b`` (in ``a``'s child frame) expressed in ``a``'s parent frame."""
    c, s = math.cos(a[2]), math.sin(a[2])
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def _frame(name: object) -> str:
    # tf2 names have no leading slash; tf (ROS1) often had one ("/odom"): the same frame.
    return str(name).lstrip("/")


class TfTree:
    """The latest transform of each frame in its parent, from ``/tf`` and ``/tf_static``."""

    #: A chain longer than this is a loop in a broken tree, not a robot's frames.
    MAX_DEPTH: Final = 16

    def __init__(self) -> None:
        self._parent: dict[str, tuple[str, _Transform, float]] = {}

    def update(self, msg: Mapping[str, Any]) -> set[str]:
        """Take a ``tf2_msgs/TFMessage``; the child frames it moved."""
        transforms = msg.get("transforms")
        if not isinstance(transforms, list):
            raise RosbridgeError("a tf message has transforms[]")
        moved: set[str] = set()
        for t in transforms:
            if not isinstance(t, Mapping) or not isinstance(t.get("transform"), Mapping):
                raise RosbridgeError("a transform has header, child_frame_id and transform")
            header: Mapping[str, Any] = t["header"] if isinstance(t.get("header"), Mapping) else {}
            parent, child = _frame(header.get("frame_id", "")), _frame(t.get("child_frame_id"))
            tr = t["transform"]
            x, y, _ = rb.point_from_msg(tr.get("translation") or {})
            st = header.get("stamp")
            stamp = rb.from_ros_time(st) if isinstance(st, Mapping) else 0.0
            if not parent or not child or parent == child:
                continue
            self._parent[child] = (parent, (x, y, _yaw(tr.get("rotation") or {})), stamp)
            moved.add(child)
        return moved

    def lookup(self, target: str, source: str) -> tuple[float, float, float, float] | None:
        """The pose (x, y, yaw, stamp) of frame ``source`` in frame ``target``, walking up
        from ``source``; None while the chain is incomplete. The stamp is the
        chain's newest transform (when the composed pose last changed)."""
        target, source = _frame(target), _frame(source)
        pose: _Transform = (0.0, 0.0, 0.0)
        stamp = 0.0
        frame = source
        for _ in range(self.MAX_DEPTH):
            if frame == target:
                return (pose[0], pose[1], math.remainder(pose[2], math.tau), stamp)
            link = self._parent.get(frame)
            if link is None:
                return None
            frame, tr, st = link
            pose = _compose(tr, pose)
            stamp = max(stamp, st)
        return None

    def reaches(self, frame: str) -> bool:
        """Has a transform for this frame (as a child) arrived?"""
        return _frame(frame) in self._parent
