"""rosbridge v2 protocol pieces shared by the simulator and the server's robot link (pure, no I/O).

Both ends of a robot link build and read the same frames, so the shapes live here once: if the
simulator and the link each had their own idea of a ``MoveBaseActionGoal``, the simulator would
only prove that it agrees with itself. Every shape follows the ROS1 message definitions with their
exact field names (see ``shared/notes/rosbridge.md``), because real rosbridge clients (roslibpy,
roslibjs) index into them by name.

Value rules that differ from "just ``json.dumps``" and why:

* NaN and ±Inf become ``null``: that is what rosbridge_server sends (Python's ``NaN`` token is not
  JSON and breaks browsers' ``JSON.parse``). A ``LaserScan`` ray with no return is ``+Inf`` in ROS.
* ``uint8[]`` becomes a base64 string, ``int8[]`` (``OccupancyGrid.data``) stays a list; so the big
  array fields of the message builders below are numpy arrays carrying their ROS element type, and
  :func:`encode` / :func:`encode_cbor` turn them into the right JSON or CBOR form. Python ``bytes``
  are treated as ``uint8[]``.
* :func:`encode_cbor` implements rosbridge's ``"cbor"`` compression: numeric arrays become
  little-endian typed-array tags (RFC 8746) instead of one CBOR item per element.
"""

from __future__ import annotations

import base64
import json
import math
import sys
from array import array
from collections.abc import Mapping, Sequence
from enum import IntEnum
from typing import TYPE_CHECKING, Any, Final

import cbor2

from serveur.errors import RosbridgeError

if TYPE_CHECKING:
    import numpy.typing as npt

__all__ = [
    "FIXED_ARRAY_TYPES",
    "MALFORMED",
    "STATUS_LEVELS",
    "TERMINAL_STATUSES",
    "TOPIC_TYPES",
    "BatteryStatus",
    "GoalStatus",
    "amcl_pose_from_msg",
    "battery_fraction",
    "battery_state",
    "compressed_image",
    "decode",
    "encode",
    "encode_cbor",
    "fragment_ops",
    "from_ros_time",
    "goal_id",
    "goal_id_from_msg",
    "goal_status_array",
    "header",
    "laser_scan",
    "move_base_action_goal",
    "move_base_feedback",
    "move_base_result",
    "normalize_type",
    "occupancy_grid",
    "odometry",
    "op_advertise",
    "op_call_service",
    "op_publish",
    "op_service_response",
    "op_set_level",
    "op_status",
    "op_subscribe",
    "op_unadvertise",
    "op_unsubscribe",
    "point_from_msg",
    "pose_from_msg",
    "pose_msg",
    "pose_stamped",
    "pose_with_covariance_stamped",
    "quaternion_from_msg",
    "quaternion_from_yaw",
    "ros_time",
    "transform_stamped",
    "twist",
    "twist_from_msg",
    "yaw_from_quaternion",
]


class GoalStatus(IntEnum):
    """actionlib_msgs/GoalStatus codes (the numbers are on the wire, never renumber)."""

    PENDING = 0
    ACTIVE = 1
    PREEMPTED = 2
    SUCCEEDED = 3
    ABORTED = 4
    REJECTED = 5
    PREEMPTING = 6
    RECALLING = 7
    RECALLED = 8
    LOST = 9


#: Statuses after which a goal never changes again (LOST is the client's "it vanished").
TERMINAL_STATUSES: Final[frozenset[GoalStatus]] = frozenset(
    {
        GoalStatus.PREEMPTED,
        GoalStatus.SUCCEEDED,
        GoalStatus.ABORTED,
        GoalStatus.REJECTED,
        GoalStatus.RECALLED,
        GoalStatus.LOST,
    }
)


class BatteryStatus(IntEnum):
    """sensor_msgs/BatteryState ``power_supply_status`` constants."""

    UNKNOWN = 0
    CHARGING = 1
    DISCHARGING = 2
    NOT_CHARGING = 3
    FULL = 4


#: The ROS graph of one waiter robot: every topic the robot publishes or subscribes, with its type.
TOPIC_TYPES: Final[dict[str, str]] = {
    "/amcl_pose": "geometry_msgs/PoseWithCovarianceStamped",
    "/odom": "nav_msgs/Odometry",
    "/map": "nav_msgs/OccupancyGrid",
    "/scan": "sensor_msgs/LaserScan",
    "/move_base/status": "actionlib_msgs/GoalStatusArray",
    "/move_base/feedback": "move_base_msgs/MoveBaseActionFeedback",
    "/move_base/result": "move_base_msgs/MoveBaseActionResult",
    "/move_base/goal": "move_base_msgs/MoveBaseActionGoal",
    "/move_base_simple/goal": "geometry_msgs/PoseStamped",
    "/move_base/cancel": "actionlib_msgs/GoalID",
    "/cmd_vel": "geometry_msgs/Twist",
    "/initialpose": "geometry_msgs/PoseWithCovarianceStamped",
    "/battery_state": "sensor_msgs/BatteryState",
    # image_transport's compressed plugin: the camera's JPEG as the driver encoded it.
    "/camera/image/compressed": "sensor_msgs/CompressedImage",
    # amcl's particle cloud, and tf (for robots whose pose comes from it)
    "/particlecloud": "geometry_msgs/PoseArray",
    "/tf": "tf2_msgs/TFMessage",
    "/tf_static": "tf2_msgs/TFMessage",
}


#: Message types of :data:`TOPIC_TYPES` holding a fixed-size array (``float64[36] covariance``).
#: rosbridge 0.11's CBOR encoder cannot encode those: with ``compression: "cbor"`` it logs an
#: exception for each message and sends nothing (shared/notes/rosbridge.md, "What the real
#: ROS1 stack does"). Every other type here has only variable-length arrays.
FIXED_ARRAY_TYPES: Final[frozenset[str]] = frozenset(
    {"geometry_msgs/PoseWithCovarianceStamped", "nav_msgs/Odometry"}
)

#: rosbridge v2 ``status``/``set_level`` levels, by verbosity (ROSBRIDGE_PROTOCOL.md, ROS1).
STATUS_LEVELS: Final[dict[str, int]] = {"none": 0, "error": 1, "warning": 2, "info": 3}


def normalize_type(type_name: str) -> str:
    """``pkg/msg/Type`` (ROS2 spelling, accepted by rosbridge's loader) -> ``pkg/Type``."""
    parts = type_name.strip("/").split("/")
    if len(parts) == 3 and parts[1] == "msg":
        return f"{parts[0]}/{parts[2]}"
    return type_name


# --------------------------------------------------------------------------------------------
# Encoding
# --------------------------------------------------------------------------------------------

_SEPARATORS: Final = (",", ":")


def _numpy() -> Any:
    """numpy if this process has imported it, else None.

    The server's own process never imports numpy (its robot links only move JSON; see
    serveur.maps.distances), so the encoders test for numpy values only where numpy is loaded:
    without it there can be no numpy value to encode.
    """
    return sys.modules.get("numpy")


def _float_array_to_list(a: npt.NDArray[Any]) -> list[float | None]:
    import numpy as np

    values: list[float | None] = a.tolist()
    finite = np.isfinite(a)
    if not finite.all():
        for i in np.flatnonzero(~finite).tolist():
            values[i] = None
    return values


def _json_default(o: object) -> object:
    """Called by ``json`` for what it cannot encode: numpy arrays/scalars and bytes."""
    np = _numpy()
    if np is not None and isinstance(o, np.ndarray):
        if o.dtype == np.uint8:
            return base64.b64encode(o.tobytes()).decode("ascii")
        if o.dtype.kind == "f":
            return _float_array_to_list(o.ravel())
        return o.ravel().tolist()
    if isinstance(o, bytes | bytearray | memoryview):
        return base64.b64encode(o).decode("ascii")
    if np is not None and isinstance(o, np.generic):
        value = o.item()
        if isinstance(value, float) and not math.isfinite(value):
            return None
        return value
    raise TypeError(f"{type(o).__name__} is not JSON serialisable")


def _finite_or_none(v: object) -> object:
    """Rebuild a JSON tree with non-finite floats replaced by None (slow path of :func:`encode`)."""
    t = type(v)
    if t is float:
        return v if math.isfinite(v) else None  # type: ignore[arg-type]
    if t is dict:
        return {k: _finite_or_none(x) for k, x in v.items()}  # type: ignore[attr-defined]
    if t is list or t is tuple:
        seq: Sequence[Any] = v  # type: ignore[assignment]
        if len(seq) > 8 and all(type(x) is float for x in seq):
            isfinite = math.isfinite
            return [x if isfinite(x) else None for x in seq]
        return [_finite_or_none(x) for x in seq]
    if isinstance(v, Mapping):
        return {k: _finite_or_none(x) for k, x in v.items()}
    if isinstance(v, float):  # float subclasses such as numpy.float64
        return float(v) if math.isfinite(v) else None
    return v


def encode(op: Mapping[str, Any]) -> str:
    """Compact JSON text of a rosbridge op; NaN/±Inf become ``null`` as rosbridge_server does.

    The common case (no non-finite float outside numpy arrays) is one pass of the C encoder;
    only a frame that really holds a NaN/Inf in plain Python floats pays for a rebuild.
    """
    try:
        return json.dumps(op, separators=_SEPARATORS, allow_nan=False, default=_json_default)
    except ValueError:
        return json.dumps(
            _finite_or_none(op), separators=_SEPARATORS, allow_nan=False, default=_json_default
        )


def decode(frame: str | bytes) -> dict[str, Any]:
    """Parse one rosbridge frame; RosbridgeError unless it is a JSON object with a string ``op``.

    The error's ``details`` carry the frame's ``id`` when there is one, so that the endpoint can
    echo it in its ``status`` reply.
    """
    if isinstance(frame, bytes | bytearray | memoryview):
        try:
            frame = bytes(frame).decode("utf-8")
        except UnicodeDecodeError as exc:
            raise RosbridgeError("frame is not UTF-8 text") from exc
    try:
        obj = json.loads(frame)
    except (ValueError, RecursionError) as exc:
        raise RosbridgeError(f"frame is not JSON: {exc}") from exc
    if not isinstance(obj, dict):
        raise RosbridgeError("frame is not a JSON object")
    op = obj.get("op")
    if not isinstance(op, str):
        details = {"id": obj["id"]} if _valid_id(obj.get("id")) else {}
        raise RosbridgeError("frame has no string 'op'", **details)
    return obj


def _valid_id(v: object) -> bool:
    return isinstance(v, str | int) and not isinstance(v, bool)


# CBOR typed-array tags (RFC 8746), little-endian variants: what rosbridge's cbor encoder emits.
_CBOR_TAGS: Final[dict[str, int]] = {
    "i1": 72,
    "u2": 69,
    "u4": 70,
    "u8": 71,
    "i2": 77,
    "i4": 78,
    "i8": 79,
    "f4": 85,
    "f8": 86,
}


def _cbor_tree(v: object) -> object:
    t = type(v)
    if t is dict:
        return {k: _cbor_tree(x) for k, x in v.items()}  # type: ignore[attr-defined]
    if t is list or t is tuple:
        seq: Sequence[Any] = v  # type: ignore[assignment]
        if seq and all(type(x) is float for x in seq):
            # Plain Python floats are float64 (covariances): one float64 typed array.
            packed = array("d", seq)
            if sys.byteorder != "little":
                packed.byteswap()
            return cbor2.CBORTag(86, packed.tobytes())
        return [_cbor_tree(x) for x in seq]
    np = _numpy()
    if np is not None and isinstance(v, np.ndarray):
        a = v.ravel()
        if a.dtype == np.uint8:
            return a.tobytes()
        if a.dtype == np.bool_:
            return a.tolist()
        key = f"{a.dtype.kind}{a.dtype.itemsize}"
        tag = _CBOR_TAGS.get(key)
        if tag is None:
            return a.tolist()
        return cbor2.CBORTag(tag, a.astype(a.dtype.newbyteorder("<"), copy=False).tobytes())
    if np is not None and isinstance(v, np.generic):
        return v.item()
    if isinstance(v, bytearray | memoryview):
        return bytes(v)
    if isinstance(v, Mapping):
        return {k: _cbor_tree(x) for k, x in v.items()}
    return v


def encode_cbor(op: Mapping[str, Any]) -> bytes:
    """rosbridge ``cbor`` compression: the op as CBOR, numeric arrays as typed-array tags.

    uint8 arrays and ``bytes`` become CBOR byte strings; numpy arrays become the little-endian
    typed-array tag of their dtype (float32 -> 85, int8 -> 72...); lists of Python floats become
    float64 arrays (tag 86). NaN stays NaN: CBOR can carry it, and rosbridge does not null it here.
    """
    return cbor2.dumps(_cbor_tree(op))


def fragment_ops(text: str, size: int, id: str | int) -> list[dict[str, Any]]:
    """``text`` (one encoded op) cut into ``fragment`` ops of ``size`` characters, as rosbridge
    0.11 sends it (rosbridge_library/capabilities/fragmentation.py, ``_fragment_generator``).

    Its ``total`` is ``((len(text) - 1) / size) + 1``, written for Python 2's integer division:
    on Python 3 it is a float, fractional unless ``size`` divides ``len(text) - 1`` (250
    characters in fragments of 100 give ``total`` 3.49 for 3 fragments). The number of
    fragments is ``int(total)``; a client comparing its count with ``total`` never completes
    a message. ``num`` counts from 0.
    """
    if size < 1:
        raise ValueError("fragment size must be at least 1")
    total = ((len(text) - 1) / size) + 1
    return [
        {"op": "fragment", "id": id, "data": text[i : i + size], "num": n, "total": total}
        for n, i in enumerate(range(0, len(text), size))
    ]


# --------------------------------------------------------------------------------------------
# Ops
# --------------------------------------------------------------------------------------------


def _with_id(d: dict[str, Any], id: str | int | None) -> dict[str, Any]:
    if id is not None:
        d["id"] = id
    return d


def op_advertise(topic: str, type: str, id: str | int | None = None) -> dict[str, Any]:
    """Tell the bridge this client will publish ``topic``."""
    return _with_id({"op": "advertise", "topic": topic, "type": type}, id)


def op_unadvertise(topic: str, id: str | int | None = None) -> dict[str, Any]:
    """Stop advertising ``topic``."""
    return _with_id({"op": "unadvertise", "topic": topic}, id)


def op_publish(topic: str, msg: Mapping[str, Any]) -> dict[str, Any]:
    """A publish op, exactly the keys rosbridge_server sends to subscribers."""
    return {"op": "publish", "topic": topic, "msg": msg}


def op_subscribe(
    topic: str,
    type: str | None = None,
    *,
    throttle_rate: int = 0,
    queue_length: int = 0,
    compression: str | None = None,
    id: str | int | None = None,
    fragment_size: int | None = None,
) -> dict[str, Any]:
    """Subscribe; ``throttle_rate`` is the minimum gap in ms between two messages.

    ``fragment_size`` (characters) makes rosbridge cut every longer frame it sends this
    client from then on into ``fragment`` ops (see :func:`fragment_ops`).
    """
    d: dict[str, Any] = {"op": "subscribe", "topic": topic}
    if type is not None:
        d["type"] = type
    d["throttle_rate"] = throttle_rate
    d["queue_length"] = queue_length
    if compression is not None:
        d["compression"] = compression
    if fragment_size is not None:
        d["fragment_size"] = fragment_size
    return _with_id(d, id)


def op_unsubscribe(topic: str, id: str | int | None = None) -> dict[str, Any]:
    """Drop one subscription (by ``id``) or all of this client's on ``topic``."""
    return _with_id({"op": "unsubscribe", "topic": topic}, id)


def op_call_service(
    service: str, args: Mapping[str, Any] | Sequence[Any] | None = None, id: str | int | None = None
) -> dict[str, Any]:
    """Call a service; ``id`` is echoed by the ``service_response`` (roslibpy needs one)."""
    d: dict[str, Any] = {"op": "call_service", "service": service}
    if args is not None:
        d["args"] = args
    return _with_id(d, id)


def op_service_response(
    service: str, id: str | int | None, values: Any, result: bool = True
) -> dict[str, Any]:
    """Answer a call; on failure ``result`` is False and ``values`` is the error text."""
    return _with_id(
        {"op": "service_response", "service": service, "values": values, "result": result}, id
    )


def op_status(level: str, msg: str, id: str | int | None = None) -> dict[str, Any]:
    """A rosbridge log line for the client (level: info, warning, error)."""
    return _with_id({"op": "status", "level": level, "msg": msg}, id)


def op_set_level(level: str, id: str | int | None = None) -> dict[str, Any]:
    """Ask for ``status`` ops at ``level`` (one of :data:`STATUS_LEVELS`) and more severe."""
    return _with_id({"op": "set_level", "level": level}, id)


# --------------------------------------------------------------------------------------------
# Field readers (raise RosbridgeError on wrong shapes; missing fields take ROS defaults)
# --------------------------------------------------------------------------------------------


def _mapping(v: object, what: str) -> Mapping[str, Any]:
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise RosbridgeError(f"{what} must be an object, not {type(v).__name__}")
    return v


def _float(m: Mapping[str, Any], key: str, what: str) -> float:
    """A float64 field: missing -> 0.0 (rosbridge fills defaults), null -> NaN (how NaN travels)."""
    v = m.get(key, 0.0)
    if v is None:
        return math.nan
    if isinstance(v, bool) or not isinstance(v, int | float):
        raise RosbridgeError(f"{what}.{key} must be a number, not {type(v).__name__}")
    return float(v)


def _int(m: Mapping[str, Any], key: str, what: str) -> int:
    v = m.get(key, 0)
    if isinstance(v, bool) or not isinstance(v, int):
        if isinstance(v, float) and v.is_integer():
            return int(v)
        raise RosbridgeError(f"{what}.{key} must be an integer, not {type(v).__name__}")
    return v


def _str(m: Mapping[str, Any], key: str, what: str) -> str:
    v = m.get(key, "")
    if not isinstance(v, str):
        raise RosbridgeError(f"{what}.{key} must be a string, not {type(v).__name__}")
    return v


# --------------------------------------------------------------------------------------------
# Time, header, geometry
# --------------------------------------------------------------------------------------------


def ros_time(t: float) -> dict[str, int]:
    """Seconds (Unix time) -> ROS1 ``time`` ``{secs, nsecs}``, nsecs always in [0, 1e9)."""
    secs = math.floor(t)
    nsecs = round((t - secs) * 1e9)
    if nsecs >= 1_000_000_000:
        secs += 1
        nsecs -= 1_000_000_000
    return {"secs": int(secs), "nsecs": int(nsecs)}


def from_ros_time(d: Mapping[str, Any]) -> float:
    """ROS ``time`` -> seconds; also reads ROS2's ``{sec, nanosec}``."""
    m = _mapping(d, "time")
    if "sec" in m and "secs" not in m:
        return _int(m, "sec", "time") + _int(m, "nanosec", "time") * 1e-9
    return _int(m, "secs", "time") + _int(m, "nsecs", "time") * 1e-9


def header(seq: int, stamp: float, frame_id: str) -> dict[str, Any]:
    """std_msgs/Header."""
    return {"seq": seq, "stamp": ros_time(stamp), "frame_id": frame_id}


def quaternion_from_yaw(yaw: float) -> dict[str, float]:
    """A rotation of ``yaw`` radians about z, as geometry_msgs/Quaternion."""
    half = 0.5 * yaw
    return {"x": 0.0, "y": 0.0, "z": math.sin(half), "w": math.cos(half)}


def yaw_from_quaternion(q: Mapping[str, Any]) -> float:
    """Heading (rotation about z) of a quaternion, in (-pi, pi]; tolerates a non-unit one."""
    x, y, z, w = quaternion_from_msg(q)
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def quaternion_from_msg(q: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """(x, y, z, w) of a geometry_msgs/Quaternion (missing fields are 0 as in ROS)."""
    m = _mapping(q, "orientation")
    return (
        _float(m, "x", "orientation"),
        _float(m, "y", "orientation"),
        _float(m, "z", "orientation"),
        _float(m, "w", "orientation"),
    )


def point_from_msg(p: Mapping[str, Any]) -> tuple[float, float, float]:
    """(x, y, z) of a geometry_msgs/Point."""
    m = _mapping(p, "position")
    return (_float(m, "x", "position"), _float(m, "y", "position"), _float(m, "z", "position"))


def pose_msg(x: float, y: float, yaw: float) -> dict[str, Any]:
    """geometry_msgs/Pose of a planar pose."""
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": quaternion_from_yaw(yaw)}


#: What parsing a robot's frame raises when the frame is malformed: a driver drops the frame
#: (1e999 is inf and int(inf) overflows, 10**400 overflows float(), deep nesting recurses).
MALFORMED: Final = (
    RosbridgeError,
    KeyError,
    TypeError,
    ValueError,
    AttributeError,
    ArithmeticError,
    RecursionError,
)


def amcl_pose_from_msg(msg: Mapping[str, Any]) -> tuple[float, float, float, float]:
    """(x, y, yaw, stamp) of a PoseWithCovarianceStamped (``/amcl_pose``, ROS1 or ROS 2
    time); RosbridgeError on a non-finite pose."""
    x, y, yaw = pose_from_msg(msg["pose"]["pose"])
    if not all(math.isfinite(v) for v in (x, y, yaw)):
        raise RosbridgeError("non-finite pose")
    return x, y, yaw, from_ros_time(msg["header"]["stamp"])


def battery_fraction(msg: Mapping[str, Any]) -> float | None:
    """A BatteryState's ``percentage`` clamped to 0..1; None when not measured (NaN, null)."""
    pct = msg.get("percentage")
    if isinstance(pct, int | float) and math.isfinite(pct):
        return max(0.0, min(1.0, float(pct)))
    return None


def pose_from_msg(pose: Mapping[str, Any]) -> tuple[float, float, float]:
    """(x, y, yaw) of a geometry_msgs/Pose; RosbridgeError on wrong shapes."""
    m = _mapping(pose, "pose")
    x, y, _ = point_from_msg(m.get("position"))  # type: ignore[arg-type]
    yaw = yaw_from_quaternion(m.get("orientation"))  # type: ignore[arg-type]
    return x, y, yaw


def pose_stamped(
    x: float, y: float, yaw: float, *, stamp: float, frame_id: str = "map", seq: int = 0
) -> dict[str, Any]:
    """geometry_msgs/PoseStamped (what RViz's "2D Nav Goal" publishes)."""
    return {"header": header(seq, stamp, frame_id), "pose": pose_msg(x, y, yaw)}


def _covariance(values: Sequence[float] | None, default: list[float]) -> list[float]:
    if values is None:
        return default.copy()  # a copy: a caller may edit its message in place
    c = [float(v) for v in values]
    if len(c) != 36:
        raise ValueError("a covariance has 36 entries")
    return c


def _diag_covariance(*diag: float) -> list[float]:
    c = [0.0] * 36
    for i, v in enumerate(diag):
        c[7 * i] = v
    return c


#: AMCL's default initial covariance (0.25 m², 0.25 m², 0.068 rad² on x, y, yaw).
_AMCL_COVARIANCE: Final = _diag_covariance(0.25, 0.25, 0.0, 0.0, 0.0, 0.06853891945200942)


def pose_with_covariance_stamped(
    x: float,
    y: float,
    yaw: float,
    *,
    stamp: float,
    seq: int = 0,
    covariance: Sequence[float] | None = None,
    frame_id: str = "map",
) -> dict[str, Any]:
    """geometry_msgs/PoseWithCovarianceStamped (``/amcl_pose``, ``/initialpose``)."""
    return {
        "header": header(seq, stamp, frame_id),
        "pose": {
            "pose": pose_msg(x, y, yaw),
            "covariance": _covariance(covariance, _AMCL_COVARIANCE),
        },
    }


def twist(vx: float, vy: float, wz: float) -> dict[str, Any]:
    """geometry_msgs/Twist of a planar velocity (body frame)."""
    return {"linear": {"x": vx, "y": vy, "z": 0.0}, "angular": {"x": 0.0, "y": 0.0, "z": wz}}


def twist_from_msg(msg: Mapping[str, Any]) -> tuple[float, float, float]:
    """(vx, vy, wz) of a geometry_msgs/Twist; RosbridgeError on wrong shapes."""
    m = _mapping(msg, "twist")
    lin = _mapping(m.get("linear"), "linear")
    ang = _mapping(m.get("angular"), "angular")
    for part, name in ((lin, "linear"), (ang, "angular")):
        for key in ("x", "y", "z"):
            _float(part, key, name)  # validate every component, even those a planar robot ignores
    return _float(lin, "x", "linear"), _float(lin, "y", "linear"), _float(ang, "z", "angular")


# --------------------------------------------------------------------------------------------
# actionlib / move_base
# --------------------------------------------------------------------------------------------


def goal_id(id: str, stamp: float) -> dict[str, Any]:
    """actionlib_msgs/GoalID."""
    return {"stamp": ros_time(stamp), "id": id}


def goal_id_from_msg(d: Mapping[str, Any]) -> tuple[str, float]:
    """(id, stamp) of a GoalID; roslibpy's cancel-all ``{}`` reads as ``("", 0.0)``."""
    m = _mapping(d, "goal_id")
    gid = _str(m, "id", "goal_id")
    stamp = from_ros_time(m["stamp"]) if m.get("stamp") is not None else 0.0
    return gid, stamp


def move_base_action_goal(
    goal_id: str,
    x: float,
    y: float,
    yaw: float,
    *,
    stamp: float,
    goal_stamp: float | None = None,
    frame_id: str = "map",
) -> dict[str, Any]:
    """move_base_msgs/MoveBaseActionGoal: what the robot link publishes on ``/move_base/goal``.

    ``goal_id.stamp`` is ``goal_stamp`` when given, else ``stamp``; 0.0 is the zero stamp that
    roslibpy and roslibjs send, which the robot's action server replaces with its own clock.
    ``frame_id``: the frame of the target pose (the robot's map frame).
    """
    gstamp = stamp if goal_stamp is None else goal_stamp
    return {
        "header": header(0, stamp, ""),
        "goal_id": {"stamp": ros_time(gstamp), "id": goal_id},
        "goal": {"target_pose": pose_stamped(x, y, yaw, stamp=stamp, frame_id=frame_id)},
    }


StatusEntry = tuple[str, GoalStatus, str] | tuple[str, GoalStatus, str, float]


def _goal_status(entry: StatusEntry) -> dict[str, Any]:
    gid, status, text = entry[0], entry[1], entry[2]
    goal_stamp = entry[3] if len(entry) == 4 else 0.0
    return {"goal_id": goal_id(gid, goal_stamp), "status": int(status), "text": text}


def goal_status_array(statuses: Sequence[StatusEntry], *, stamp: float, seq: int) -> dict[str, Any]:
    """actionlib_msgs/GoalStatusArray from (goal id, status, text[, goal stamp]) entries."""
    return {"header": header(seq, stamp, ""), "status_list": [_goal_status(s) for s in statuses]}


def move_base_result(
    goal_id: str,
    status: GoalStatus,
    text: str,
    *,
    stamp: float,
    seq: int,
    goal_stamp: float = 0.0,
) -> dict[str, Any]:
    """move_base_msgs/MoveBaseActionResult (MoveBaseResult itself is empty)."""
    return {
        "header": header(seq, stamp, ""),
        "status": _goal_status((goal_id, status, text, goal_stamp)),
        "result": {},
    }


def move_base_feedback(
    goal_id: str,
    status: GoalStatus,
    x: float,
    y: float,
    yaw: float,
    *,
    stamp: float,
    seq: int,
    goal_stamp: float = 0.0,
    text: str = "",
) -> dict[str, Any]:
    """move_base_msgs/MoveBaseActionFeedback: the robot's pose while it drives."""
    return {
        "header": header(seq, stamp, ""),
        "status": _goal_status((goal_id, status, text, goal_stamp)),
        "feedback": {"base_position": pose_stamped(x, y, yaw, stamp=stamp, frame_id="map")},
    }


# --------------------------------------------------------------------------------------------
# Sensors and maps
# --------------------------------------------------------------------------------------------

_ODOM_POSE_COVARIANCE: Final = _diag_covariance(1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-3)
_ODOM_TWIST_COVARIANCE: Final = _diag_covariance(1e-3, 1e-3, 1e6, 1e6, 1e6, 1e-3)


def transform_stamped(
    parent: str, child: str, x: float, y: float, yaw: float, *, stamp: float, seq: int = 0
) -> dict[str, Any]:
    """geometry_msgs/TransformStamped: ``child``'s pose in ``parent`` (one entry of /tf)."""
    return {
        "header": header(seq, stamp, parent),
        "child_frame_id": child,
        "transform": {
            "translation": {"x": x, "y": y, "z": 0.0},
            "rotation": quaternion_from_yaw(yaw),
        },
    }


def odometry(
    x: float,
    y: float,
    yaw: float,
    vx: float,
    vy: float,
    wz: float,
    *,
    stamp: float,
    seq: int,
    frame_id: str = "odom",
    child_frame_id: str = "base_footprint",
    pose_covariance: Sequence[float] | None = None,
    twist_covariance: Sequence[float] | None = None,
) -> dict[str, Any]:
    """nav_msgs/Odometry: pose in ``frame_id``, twist in the body frame ``child_frame_id``."""
    return {
        "header": header(seq, stamp, frame_id),
        "child_frame_id": child_frame_id,
        "pose": {
            "pose": pose_msg(x, y, yaw),
            "covariance": _covariance(pose_covariance, _ODOM_POSE_COVARIANCE),
        },
        "twist": {
            "twist": twist(vx, vy, wz),
            "covariance": _covariance(twist_covariance, _ODOM_TWIST_COVARIANCE),
        },
    }


def occupancy_grid(m: Any, *, stamp: float, seq: int, frame_id: str = "map") -> dict[str, Any]:
    """nav_msgs/OccupancyGrid of an OccupancyMap (``grid`` row 0 = lowest y, like ROS).

    ``data`` is an int8 numpy array: a JSON list after :func:`encode`, an int8 typed array
    (tag 72) after :func:`encode_cbor`.
    """
    ox, oy, oyaw = (float(v) for v in m.origin)
    import numpy as np

    data = np.ascontiguousarray(m.grid, dtype=np.int8).ravel()
    return {
        "header": header(seq, stamp, frame_id),
        "info": {
            "map_load_time": ros_time(stamp),
            "resolution": float(m.resolution),
            "width": int(m.width),
            "height": int(m.height),
            "origin": pose_msg(ox, oy, oyaw),
        },
        "data": data,
    }


def compressed_image(
    jpeg: bytes, *, stamp: float, seq: int = 0, frame_id: str = "camera_link"
) -> dict[str, Any]:
    """sensor_msgs/CompressedImage ``{header, format, data}``: ``data`` stays bytes here (JSON
    encodes it as base64, CBOR as a byte string, as rosbridge does for ``uint8[]``)."""
    return {"header": header(seq, stamp, frame_id), "format": "jpeg", "data": jpeg}


def laser_scan(
    ranges: Sequence[float] | npt.NDArray[Any],
    *,
    stamp: float,
    seq: int,
    angle_min: float,
    angle_increment: float,
    range_min: float,
    range_max: float,
    scan_time: float,
    time_increment: float = 0.0,
    frame_id: str = "base_scan",
    intensities: Sequence[float] | npt.NDArray[Any] | None = None,
) -> dict[str, Any]:
    """sensor_msgs/LaserScan; ``ranges`` become float32 (no return = +Inf -> ``null`` in JSON)."""
    import numpy as np

    r = np.asarray(ranges, dtype=np.float32)
    n = int(r.shape[0])
    return {
        "header": header(seq, stamp, frame_id),
        "angle_min": angle_min,
        "angle_max": angle_min + angle_increment * max(0, n - 1),
        "angle_increment": angle_increment,
        "time_increment": time_increment,
        "scan_time": scan_time,
        "range_min": range_min,
        "range_max": range_max,
        "ranges": r,
        "intensities": np.asarray(intensities if intensities is not None else (), dtype=np.float32),
    }


def battery_state(
    percentage: float,
    *,
    stamp: float,
    seq: int,
    voltage: float,
    current: float,
    status: BatteryStatus,
    capacity: float = 20.0,
    design_capacity: float = 20.0,
    temperature: float = 30.0,
    frame_id: str = "",
    location: str = "base",
    serial_number: str = "",
) -> dict[str, Any]:
    """sensor_msgs/BatteryState (Noetic fields); ``percentage`` is 0..1 as in ROS, not 0..100."""
    return {
        "header": header(seq, stamp, frame_id),
        "voltage": voltage,
        "temperature": temperature,
        "current": current,
        "charge": capacity * percentage,
        "capacity": capacity,
        "design_capacity": design_capacity,
        "percentage": percentage,
        "power_supply_status": int(status),
        "power_supply_health": 1,  # GOOD
        "power_supply_technology": 2,  # LION
        "present": True,
        "cell_voltage": [],
        "cell_temperature": [],
        "location": location,
        "serial_number": serial_number,
    }
