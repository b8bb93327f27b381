"""The ROS 2 dialect of a simulated robot: Nav2's ``navigate_to_pose`` and ROS 2 message shapes.

Split from :mod:`serveur.sim.robot` (the robot's graph, which uses these when it runs ``ros=2``)
and :mod:`serveur.sim.bridge` (rosbridge 2.x's action ops) because both need the same names,
types and shapes, and because a ROS 2 robot differs from a ROS1 one mostly in its wire forms.
Sources (shared/notes/ros2.md, researched from rosbridge_suite's ROSBRIDGE_PROTOCOL.md and its
``send_action_goal`` capability, nav2_msgs, ros2/common_interfaces and Nav2's amcl_node):

* Time is ``builtin_interfaces/Time {sec, nanosec}``; ``std_msgs/Header`` has no ``seq``;
  type names are spelled ``pkg/msg/Type`` (rosapi answers them that way).
* ``nav2_msgs/action/NavigateToPose``: goal ``{pose: PoseStamped, behavior_tree}``; feedback
  ``{current_pose, navigation_time, estimated_time_remaining, number_of_recoveries,
  distance_remaining}``; result Humble ``{result: std_msgs/Empty}``, Jazzy and later
  ``{error_code, error_msg}`` with the failing BT node's code (ComputePathToPose's 2xx,
  FollowPath's 1xx).
* action_msgs/GoalStatus codes on ``action_result``: 4 SUCCEEDED, 5 CANCELED, 6 ABORTED.
* Nav2's AMCL publishes ``/amcl_pose`` after ``update_min_d`` 0.25 m / ``update_min_a`` 0.2 rad
  of motion (ROS1 amcl: 0.2 m / 30 degrees).
* Nav2 Jazzy's and Kilted's ``/cmd_vel`` may be ``TwistStamped`` (Kilted's default; Jazzy's
  diff_drive_controller requires it).
* Nav2's lifecycle: ``/bt_navigator/get_state`` (lifecycle_msgs/srv/GetState) answers
  ``{current_state: {id: 3, label: "active"}}`` when the navigator can take goals
  (:func:`lifecycle_state`).
* rosbridge stopped with SIGTERM or SIGINT answers every call with ``result: false`` and
  :data:`ROS_SIDE_DEAD` ("Liveness, measured on the same stack").
* opennav_docking's docking server (a robot made with ``docking``; its behaviour is
  :mod:`serveur.sim.docking`): actions ``dock_robot`` and ``undock_robot`` of types
  ``nav2_msgs/action/DockRobot`` / ``UndockRobot`` from Jazzy on (docking ships with Nav2; the
  types are there whether or not a docking server runs), ``opennav_docking_msgs/action/...``
  on Humble (the standalone package, installed only with the server). Goal, result and
  feedback fields from ros-navigation/navigation2's ``nav2_msgs/action/DockRobot.action`` and
  ``UndockRobot.action``: :func:`dock_goal_from_args`, :func:`dock_result`,
  :func:`undock_result`, :func:`dock_feedback`.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final

from serveur.errors import RosbridgeError
from serveur.robots import rosbridge as rb

__all__ = [
    "ABORTED",
    "ACTION_TYPES",
    "CANCELED",
    "DOCK_NOT_IN_DB",
    "DOCK_NOT_VALID",
    "DOCK_ROBOT",
    "DOCK_UNKNOWN",
    "FAILED_TO_CHARGE",
    "FAILED_TO_CONTROL",
    "FAILED_TO_DETECT_DOCK",
    "FAILED_TO_MAKE_PROGRESS",
    "FAILED_TO_STAGE",
    "GET_STATE",
    "LIFECYCLE_STATES",
    "NAVIGATE_TO_POSE",
    "NAVIGATE_TO_POSE_TYPE",
    "NO_VALID_PATH",
    "RELEASES",
    "ROS_SIDE_DEAD",
    "SUCCEEDED",
    "UNDOCK_ROBOT",
    "UNKNOWN",
    "DockGoal",
    "action_of",
    "dock_feedback",
    "dock_goal_from_args",
    "dock_result",
    "docking_types",
    "duration",
    "goal_from_args",
    "importable",
    "lifecycle_state",
    "nav2_feedback",
    "nav2_result",
    "time",
    "to_ros2",
    "topic_types",
    "undock_goal_from_args",
    "undock_result",
]

#: ROS 2 releases whose Nav2 / rosbridge differences the simulator models.
RELEASES: Final = ("humble", "jazzy", "kilted")
#: The navigator's action name (under the robot's namespace) and its type.
NAVIGATE_TO_POSE: Final = "/navigate_to_pose"
NAVIGATE_TO_POSE_TYPE: Final = "nav2_msgs/action/NavigateToPose"
#: Spellings rosbridge's ros_loader resolves to the navigator's action type.
ACTION_TYPES: Final = frozenset({NAVIGATE_TO_POSE_TYPE, "nav2_msgs/NavigateToPose"})
#: The navigator's lifecycle state service (lifecycle_msgs/srv/GetState).
GET_STATE: Final = "/bt_navigator/get_state"
#: lifecycle_msgs/msg/State ids of the primary states, by label.
LIFECYCLE_STATES: Final = {"unconfigured": 1, "inactive": 2, "active": 3, "finalized": 4}
#: What rosbridge 2.1.0 answers every ``call_service`` with once SIGTERM or SIGINT shut its
#: ROS side (``result: false``; shared/notes/ros2.md, "Liveness, measured on the same stack").
ROS_SIDE_DEAD: Final = "rcl node's context is invalid"

#: action_msgs/msg/GoalStatus codes an ``action_result`` carries.
SUCCEEDED: Final = 4
CANCELED: Final = 5
ABORTED: Final = 6

#: Error codes (Jazzy+): ComputePathToPose NO_VALID_PATH, FollowPath FAILED_TO_MAKE_PROGRESS,
#: NavigateToPose UNKNOWN.
NO_VALID_PATH: Final = 208
FAILED_TO_MAKE_PROGRESS: Final = 105
UNKNOWN: Final = 9000

#: The docking server's actions (under the robot's namespace).
DOCK_ROBOT: Final = "/dock_robot"
UNDOCK_ROBOT: Final = "/undock_robot"
#: DockRobot / UndockRobot result error codes (nav2_msgs/action/DockRobot.action).
DOCK_NOT_IN_DB: Final = 901
DOCK_NOT_VALID: Final = 902
FAILED_TO_STAGE: Final = 903
FAILED_TO_DETECT_DOCK: Final = 904
FAILED_TO_CONTROL: Final = 905
FAILED_TO_CHARGE: Final = 906
DOCK_UNKNOWN: Final = 999
#: DockRobot's goal fields, in order (a list of ``args`` is zipped with them, as rosbridge does),
#: with their defaults; UndockRobot's.
_DOCK_FIELDS: Final[dict[str, object]] = {
    "use_dock_id": True,
    "dock_id": "",
    "dock_pose": None,
    "dock_type": "",
    "max_staging_time": 1000.0,
    "navigate_to_staging_pose": True,
}
_UNDOCK_FIELDS: Final[dict[str, object]] = {"dock_type": "", "max_undocking_time": 30.0}


def docking_types(release: str) -> tuple[frozenset[str], frozenset[str]]:
    """The spellings of DockRobot's and UndockRobot's types on this release: Nav2's own
    (``nav2_msgs``) from Jazzy on, the standalone package's (``opennav_docking_msgs``) on
    Humble."""
    pkg = "opennav_docking_msgs" if release == "humble" else "nav2_msgs"
    return (
        frozenset({f"{pkg}/action/DockRobot", f"{pkg}/DockRobot"}),
        frozenset({f"{pkg}/action/UndockRobot", f"{pkg}/UndockRobot"}),
    )


def importable(action_type: str, release: str, docking: bool) -> bool:
    """Can rosbridge load this action type on the robot? NavigateToPose always; Nav2's
    docking types from Jazzy on (nav2_msgs has them), Humble's standalone ones only where
    the docking server is installed."""
    if action_type in ACTION_TYPES:
        return True
    if release == "humble" and not docking:
        return False
    dock, undock = docking_types(release)
    return action_type in dock or action_type in undock


def action_of(local: str | None, action_type: str, release: str, docking: bool) -> str | None:
    """Which of the robot's action servers takes a goal of ``action_type`` on the action
    named ``local`` (without the namespace): "navigate", "dock", "undock", or None (nobody
    serves that name with that type: rosbridge waits for a server for ever)."""
    if local == NAVIGATE_TO_POSE and action_type in ACTION_TYPES:
        return "navigate"
    if not docking:
        return None
    dock, undock = docking_types(release)
    if local == DOCK_ROBOT and action_type in dock:
        return "dock"
    if local == UNDOCK_ROBOT and action_type in undock:
        return "undock"
    return None


def topic_types(twist_stamped: bool) -> dict[str, str]:
    """A ROS 2 waiter robot's topics and their types (``pkg/msg/Type``, as rosapi says them)."""
    return {
        "/amcl_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/odom": "nav_msgs/msg/Odometry",
        "/map": "nav_msgs/msg/OccupancyGrid",
        "/scan": "sensor_msgs/msg/LaserScan",
        "/cmd_vel": "geometry_msgs/msg/TwistStamped"
        if twist_stamped
        else "geometry_msgs/msg/Twist",
        "/initialpose": "geometry_msgs/msg/PoseWithCovarianceStamped",
        "/goal_pose": "geometry_msgs/msg/PoseStamped",  # RViz2's "Nav2 Goal"
        "/battery_state": "sensor_msgs/msg/BatteryState",
        "/camera/image/compressed": "sensor_msgs/msg/CompressedImage",
        # Nav2 amcl's particle cloud (best effort, SensorDataQoS), and tf
        "/particle_cloud": "nav2_msgs/msg/ParticleCloud",
        "/tf": "tf2_msgs/msg/TFMessage",
        "/tf_static": "tf2_msgs/msg/TFMessage",
    }


def lifecycle_state(label: str) -> dict[str, Any]:
    """A lifecycle_msgs/srv/GetState response: ``{current_state: {id, label}}``."""
    return {"current_state": {"id": LIFECYCLE_STATES.get(label, 0), "label": label}}


def time(t: float) -> dict[str, int]:
    """Seconds -> builtin_interfaces/Time ``{sec, nanosec}``."""
    r = rb.ros_time(t)
    return {"sec": r["secs"], "nanosec": r["nsecs"]}


def duration(s: float) -> dict[str, int]:
    """Seconds (>= 0) -> builtin_interfaces/Duration ``{sec, nanosec}``."""
    return time(max(0.0, s))


def to_ros2(msg: Any) -> Any:
    """A message built by :mod:`serveur.robots.rosbridge` (ROS1 shapes) in its ROS 2 shape.

    Every ``{secs, nsecs}`` becomes ``{sec, nanosec}`` and every ``header`` loses ``seq``;
    arrays of numbers (lists, numpy) are left alone; arrays of messages (tf's ``transforms``)
    are converted each.
    """
    if not isinstance(msg, dict):
        return msg
    if len(msg) == 2 and "secs" in msg and "nsecs" in msg:
        return {"sec": msg["secs"], "nanosec": msg["nsecs"]}
    out: dict[str, Any] = {}
    for k, v in msg.items():
        if isinstance(v, dict):
            v = to_ros2(v)
            if k == "header":
                v.pop("seq", None)
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            v = [to_ros2(x) for x in v]  # tf's transforms[], each with its own header
        out[k] = v
    return out


def _mapping(v: object, what: str) -> Mapping[str, Any]:
    """A nested message field; missing takes ROS 2 defaults (as rosbridge's populate_instance)."""
    if v is None:
        return {}
    if not isinstance(v, Mapping):
        raise RosbridgeError(f"{what} must be an object, not {type(v).__name__}")
    return v


def goal_from_args(args: object) -> tuple[str, float, float, tuple[float, float, float, float]]:
    """(frame_id, x, y, quaternion) of a NavigateToPose goal's ``args``; RosbridgeError when
    rosbridge could not populate the goal message (wrong field types).

    Missing fields take ROS 2 defaults, including the quaternion's ``w = 1``.
    """
    if isinstance(args, list):  # rosbridge zips a list with the goal's fields in order
        args = dict(zip(("pose", "behavior_tree"), args, strict=False))
    a = _mapping(args, "args")
    bt = a.get("behavior_tree", "")
    if not isinstance(bt, str):
        raise RosbridgeError("args.behavior_tree must be a string")
    ps = _mapping(a.get("pose"), "args.pose")
    frame = _mapping(ps.get("header"), "args.pose.header").get("frame_id", "")
    if not isinstance(frame, str):
        raise RosbridgeError("args.pose.header.frame_id must be a string")
    pose = _mapping(ps.get("pose"), "args.pose.pose")
    x, y, _ = rb.point_from_msg(_mapping(pose.get("position"), "position"))
    o = dict(_mapping(pose.get("orientation"), "orientation"))
    o.setdefault("w", 1.0)
    return frame, x, y, rb.quaternion_from_msg(o)


def nav2_feedback(
    x: float,
    y: float,
    yaw: float,
    *,
    stamp: float,
    navigation_time: float,
    distance_remaining: float,
    speed: float,
    recoveries: int = 0,
) -> dict[str, Any]:
    """NavigateToPose feedback; the time left is distance / current speed (0 when stopped),
    as Nav2's navigator estimates it."""
    eta = distance_remaining / speed if speed > 0.01 else 0.0
    return {
        "current_pose": {
            "header": {"stamp": time(stamp), "frame_id": "map"},
            "pose": rb.pose_msg(x, y, yaw),
        },
        "navigation_time": duration(navigation_time),
        "estimated_time_remaining": duration(eta if math.isfinite(eta) else 0.0),
        "number_of_recoveries": recoveries,
        "distance_remaining": distance_remaining,
    }


def nav2_result(release: str, error_code: int = 0, error_msg: str = "") -> dict[str, Any]:
    """NavigateToPose result: Humble's holds an empty ``result``; Jazzy's an error code."""
    if release == "humble":
        return {"result": {}}
    return {"error_code": error_code, "error_msg": error_msg}


@dataclass(frozen=True, slots=True)
class DockGoal:
    """A DockRobot goal as the docking server reads it."""

    use_dock_id: bool
    dock_id: str
    frame: str
    x: float
    y: float
    q: tuple[float, float, float, float]
    dock_type: str
    max_staging_time: float
    navigate_to_staging_pose: bool


def _fields(args: object, fields: Mapping[str, object], typ: str) -> dict[str, Any]:
    """A goal's ``args`` filled as rosbridge's populate_instance does: a list is zipped with
    the fields in order, a missing field takes its default, a field the type does not have
    is an error."""
    if isinstance(args, list):
        args = dict(zip(fields, args, strict=False))
    a = _mapping(args, "args")
    extra = sorted(set(a) - set(fields))
    if extra:
        raise RosbridgeError(f"message type {typ} does not have a field {extra[0]!r}")
    return {k: a.get(k, default) for k, default in fields.items()}


def _typed(v: object, kind: type, what: str) -> Any:
    if kind is float and isinstance(v, int) and not isinstance(v, bool):
        v = float(v)
    if not isinstance(v, kind) or (kind is not bool and isinstance(v, bool)):
        raise RosbridgeError(f"args.{what} must be a {kind.__name__}")
    return v


def dock_goal_from_args(args: object) -> DockGoal:
    """A DockRobot goal's ``args``; RosbridgeError where rosbridge could not populate it."""
    a = _fields(args, _DOCK_FIELDS, "DockRobot_Goal")
    ps = _mapping(a["dock_pose"], "args.dock_pose")
    frame = _mapping(ps.get("header"), "args.dock_pose.header").get("frame_id", "")
    if not isinstance(frame, str):
        raise RosbridgeError("args.dock_pose.header.frame_id must be a string")
    pose = _mapping(ps.get("pose"), "args.dock_pose.pose")
    x, y, _ = rb.point_from_msg(_mapping(pose.get("position"), "position"))
    o = dict(_mapping(pose.get("orientation"), "orientation"))
    o.setdefault("w", 1.0)
    return DockGoal(
        use_dock_id=_typed(a["use_dock_id"], bool, "use_dock_id"),
        dock_id=_typed(a["dock_id"], str, "dock_id"),
        frame=frame,
        x=x,
        y=y,
        q=rb.quaternion_from_msg(o),
        dock_type=_typed(a["dock_type"], str, "dock_type"),
        max_staging_time=_typed(a["max_staging_time"], float, "max_staging_time"),
        navigate_to_staging_pose=_typed(
            a["navigate_to_staging_pose"], bool, "navigate_to_staging_pose"
        ),
    )


def undock_goal_from_args(args: object) -> tuple[str, float]:
    """(dock_type, max_undocking_time) of an UndockRobot goal's ``args``."""
    a = _fields(args, _UNDOCK_FIELDS, "UndockRobot_Goal")
    return (
        _typed(a["dock_type"], str, "dock_type"),
        _typed(a["max_undocking_time"], float, "max_undocking_time"),
    )


def dock_feedback(state: int, docking_time: float, num_retries: int = 0) -> dict[str, Any]:
    """DockRobot feedback: the docking state (1 NAV_TO_STAGING_POSE, 2 INITIAL_PERCEPTION,
    3 CONTROLLING, 4 WAIT_FOR_CHARGE, 5 RETRY) and the time since the goal began."""
    return {"state": state, "docking_time": duration(docking_time), "num_retries": num_retries}


def dock_result(
    release: str, success: bool, error_code: int = 0, error_msg: str = ""
) -> dict[str, Any]:
    """DockRobot's result: Humble's standalone package has no ``error_msg``."""
    out: dict[str, Any] = {"success": success, "error_code": error_code, "num_retries": 0}
    if release != "humble":
        out["error_msg"] = error_msg
    return out


def undock_result(success: bool, error_code: int = 0) -> dict[str, Any]:
    """UndockRobot's result."""
    return {"success": success, "error_code": error_code}
