"""ROS 2 over rosbridge 2.x: action ops and message JSON (pure; no I/O).

What differs from ROS1 on the wire (rosbridge_suite's ROSBRIDGE_PROTOCOL.md, sections on
actions, and ../shared/notes/ros2.md): actions are ops of their own (``send_action_goal``,
``cancel_action_goal``, ``action_feedback``, ``action_result``) instead of five topics; time
is ``{sec, nanosec}``; a Header has no ``seq``; type names carry ``/msg/`` or ``/action/``.
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum
from typing import Any, Final

from serveur.robots import rosbridge as rb
from serveur.robots.liveness import DownCause

__all__ = [
    "ACTION_STATUS",
    "NAVIGATE_TO_POSE",
    "STACK",
    "TOPIC_TYPES",
    "ActionStatus",
    "header",
    "heartbeat_verdict",
    "op_cancel_action_goal",
    "op_send_action_goal",
    "outcome",
    "pose_with_covariance_stamped",
    "time",
    "twist_stamped",
]

NAVIGATE_TO_POSE: Final = "nav2_msgs/action/NavigateToPose"
#: The goal's server, in every goal report (the core shows it as it is).
STACK: Final = "Nav2 navigate_to_pose"

TOPIC_TYPES: Final[dict[str, str]] = {
    "/amcl_pose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/initialpose": "geometry_msgs/msg/PoseWithCovarianceStamped",
    "/cmd_vel": "geometry_msgs/msg/Twist",
    "/battery_state": "sensor_msgs/msg/BatteryState",
    "/scan": "sensor_msgs/msg/LaserScan",
    "/map": "nav_msgs/msg/OccupancyGrid",
    # Nav2 amcl's particle_cloud (named /particlecloud in RosNames), and tf
    "/particlecloud": "nav2_msgs/msg/ParticleCloud",
    "/tf": "tf2_msgs/msg/TFMessage",
    "/tf_static": "tf2_msgs/msg/TFMessage",
}


class ActionStatus(IntEnum):
    """action_msgs/GoalStatus."""

    UNKNOWN = 0
    ACCEPTED = 1
    EXECUTING = 2
    CANCELING = 3
    SUCCEEDED = 4
    CANCELED = 5
    ABORTED = 6


#: A ROS 2 goal's end in the one outcome vocabulary of the robot-driver interface.
ACTION_STATUS: Final[dict[ActionStatus, rb.GoalStatus]] = {
    ActionStatus.SUCCEEDED: rb.GoalStatus.SUCCEEDED,
    ActionStatus.CANCELED: rb.GoalStatus.PREEMPTED,
    ActionStatus.ABORTED: rb.GoalStatus.ABORTED,
}


def time(t: float) -> dict[str, int]:
    """Seconds -> builtin_interfaces/Time ``{sec, nanosec}``."""
    ros1 = rb.ros_time(t)
    return {"sec": ros1["secs"], "nanosec": ros1["nsecs"]}


def header(stamp: float, frame_id: str) -> dict[str, Any]:
    """std_msgs/Header (ROS 2 has no ``seq``)."""
    return {"stamp": time(stamp), "frame_id": frame_id}


def pose_with_covariance_stamped(
    x: float, y: float, yaw: float, *, stamp: float, frame_id: str
) -> dict[str, Any]:
    msg = rb.pose_with_covariance_stamped(x, y, yaw, stamp=stamp, frame_id=frame_id)
    msg["header"] = header(stamp, frame_id)
    return msg


def twist_stamped(vx: float, vy: float, wz: float, *, frame_id: str = "") -> dict[str, Any]:
    """geometry_msgs/TwistStamped with a zero stamp (the controller's own time)."""
    return {"header": header(0.0, frame_id), "twist": rb.twist(vx, vy, wz)}


def op_send_action_goal(
    action: str, goal_id: str, x: float, y: float, yaw: float, *, frame_id: str
) -> dict[str, Any]:
    """A NavigateToPose goal with feedback: the feedback is how the driver learns the goal
    was accepted (rosbridge sends no frame for a goal nobody takes)."""
    return {
        "op": "send_action_goal",
        "id": goal_id,
        "action": action,
        "action_type": NAVIGATE_TO_POSE,
        "args": {
            "pose": {"header": header(0.0, frame_id), "pose": rb.pose_msg(x, y, yaw)},
            "behavior_tree": "",
        },
        "feedback": True,
    }


def op_cancel_action_goal(action: str, goal_id: str) -> dict[str, Any]:
    return {"op": "cancel_action_goal", "id": goal_id, "action": action}


def outcome(op: Mapping[str, Any]) -> tuple[rb.GoalStatus, str]:
    """An ``action_result`` frame's outcome and the words for it.

    ``result`` is true for every normal end — succeeded, canceled *or* aborted — and the
    outcome is ``status``; older bridges put ``status`` inside ``values``. ``result`` false
    is an exception on the bridge (``values`` is its text). Jazzy's NavigateToPose result has
    ``error_code``/``error_msg``; Humble's is empty.
    """
    values = op.get("values")
    if op.get("result") is False:
        return rb.GoalStatus.ABORTED, f"{STACK} failed on the bridge: {values}"
    raw = op.get("status")
    if raw is None and isinstance(values, Mapping):
        raw = values.get("status")
    try:
        status = ActionStatus(int(raw))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return rb.GoalStatus.ABORTED, f"{STACK} ended with status {raw!r}"
    mapped = ACTION_STATUS.get(status, rb.GoalStatus.ABORTED)
    text = f"{STACK} {status.name}"
    if isinstance(values, Mapping):
        inner = values.get("result", values)
        if isinstance(inner, Mapping) and inner.get("error_msg"):
            text += f": {inner['error_msg']} (error {inner.get('error_code')})"
    return mapped, text


def heartbeat_verdict(op: Mapping[str, Any]) -> tuple[bool, str, DownCause]:
    """Does this ``service_response`` of the robot's heartbeat service prove it alive?

    (True, "", ...) for a lifecycle_msgs/srv/GetState answer ``{current_state: {id: 3,
    label: "active"}}`` (Nav2's navigator can take goals) or a std_srvs/srv/Trigger answer
    with ``success`` true. Otherwise (False, why, cause): ``result: false`` is the bridge
    failing the call — after SIGTERM/SIGINT rosbridge answers every call so ("rcl node's
    context is invalid", shared/notes/ros2.md) — and is *not* life; a state other than
    active (or ``success`` false) is a robot that cannot take goals.
    """
    values = op.get("values")
    if op.get("result") is False:
        return False, str(values), DownCause.ROS_STOPPED
    if isinstance(values, Mapping):
        state = values.get("current_state")
        if isinstance(state, Mapping):
            label = str(state.get("label", ""))
            if label == "active":
                return True, "", DownCause.NOT_READY
            return (
                False,
                f"Nav2's navigator is {label or 'in no state'}, not active",
                (DownCause.NOT_READY),
            )
        if "success" in values:
            if values.get("success") is True:
                return True, "", DownCause.NOT_READY
            why = values.get("message") or "not ready"
            return False, f"the robot's heartbeat says: {why}", DownCause.NOT_READY
    return False, f"the heartbeat's answer is not understood: {values!r}", DownCause.NOT_READY
