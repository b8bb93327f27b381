"""ROS 2 over rosbridge 2.x: action ops and message JSON (pure; no I/O).

What differs from ROS1 on the wire (rosbridge_suite's ROSBRIDGE_PROTOCOL.md, sections on
actions, and ../shared/notes/ros2.md): actions are ops of their own (``send_action_goal``,
``cancel_action_goal``, ``action_feedback``, ``action_result``) instead of five topics; time
is ``{sec, nanosec}``; a Header has no ``seq``; type names carry ``/msg/`` or ``/action/``.

**Docking** (opennav_docking's docking server, read in ros-navigation/navigation2's
``nav2_msgs/action/DockRobot.action`` and ``UndockRobot.action`` and
``nav2_docking/opennav_docking/src/docking_server.cpp``, and open-navigation/opennav_docking's
README and ``opennav_docking_msgs``): the ``dock_robot`` action's goal ``{use_dock_id, dock_id,
dock_pose: PoseStamped, dock_type, max_staging_time, navigate_to_staging_pose}``, its result
``{success, error_code, num_retries}`` (Nav2's newer releases add ``error_msg``), its feedback
``{state, docking_time, num_retries}`` sent when each phase starts (NAV_TO_STAGING_POSE 1,
INITIAL_PERCEPTION 2) and continuously only while it drives onto the dock (CONTROLLING 3) and
waits for the charge (WAIT_FOR_CHARGE 4): nothing comes while Nav2 drives the robot to the
staging pose. ``undock_robot``: goal ``{dock_type, max_undocking_time}``, result ``{success,
error_code}``, no feedback at all. A failure ends the goal ABORTED with ``success`` false and
the error code (:data:`DOCK_ERRORS`); a cancel ends it CANCELED. The types are Nav2's
``nav2_msgs/action/...`` from Jazzy on (docking ships with Nav2), the standalone package's
``opennav_docking_msgs/action/...`` on Humble (:data:`DOCK_ACTION_TYPES`).
"""

from __future__ import annotations

from collections.abc import Mapping
from enum import IntEnum
from typing import Any, Final

from serveur.robots import rosbridge as rb
from serveur.robots.liveness import DownCause

__all__ = [
    "ACTION_STATUS",
    "DOCK_ACTION_TYPES",
    "DOCK_ERRORS",
    "DOCK_STACK",
    "NAVIGATE_TO_POSE",
    "STACK",
    "TOPIC_TYPES",
    "UNDOCK_STACK",
    "ActionStatus",
    "dock_outcome",
    "header",
    "heartbeat_verdict",
    "op_cancel_action_goal",
    "op_send_action_goal",
    "op_send_dock_goal",
    "op_send_undock_goal",
    "outcome",
    "pose_with_covariance_stamped",
    "result_of",
    "time",
    "twist_stamped",
    "undock_verdict",
]

NAVIGATE_TO_POSE: Final = "nav2_msgs/action/NavigateToPose"
#: The goal's server, in every goal report (the core shows it as it is).
STACK: Final = "Nav2 navigate_to_pose"

#: The docking server's action types (DockRobot, UndockRobot), by the robot's ``docking`` link
#: option (:data:`serveur.robots.names.DOCKING_SERVERS`).
DOCK_ACTION_TYPES: Final[dict[str, tuple[str, str]]] = {
    "nav2": ("nav2_msgs/action/DockRobot", "nav2_msgs/action/UndockRobot"),
    "opennav": ("opennav_docking_msgs/action/DockRobot", "opennav_docking_msgs/action/UndockRobot"),
}
#: The docking server's actions in goal reports.
DOCK_STACK: Final = "Nav2 dock_robot"
UNDOCK_STACK: Final = "Nav2 undock_robot"
#: DockRobot's and UndockRobot's result ``error_code`` in words (the constants of
#: nav2_msgs/action/DockRobot.action: GOAL_REJECTED 1 and SEND_GOAL_FAILURE 2, the codes of the
#: docking server's exceptions 901-906, TIMEOUT 907 in later releases, UNKNOWN 999).
DOCK_ERRORS: Final[dict[int, str]] = {
    0: "no error code",
    1: "the goal was rejected",
    2: "the goal could not be sent",
    901: "the dock is not in the docking server's database",
    902: "the dock is not valid",
    903: "failed to reach the staging pose",
    904: "failed to detect the dock",
    905: "failed to control the robot",
    906: "the robot did not start charging",
    907: "timed out",
    999: "unknown error",
}

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


def op_send_dock_goal(
    action: str,
    action_type: str,
    goal_id: str,
    x: float,
    y: float,
    yaw: float,
    *,
    dock_id: str,
    frame_id: str,
    max_staging_time: float,
) -> dict[str, Any]:
    """A DockRobot goal to the dock at this pose (``use_dock_id`` false: the server needs no
    database of our docks; ``dock_id`` is sent for its logs), through Nav2 to the staging pose
    first, with feedback (its first feedback, NAV_TO_STAGING_POSE, is the acknowledgement).
    ``max_staging_time``: seconds the server lets Nav2 take to the staging pose before it gives
    up (FAILED_TO_STAGE)."""
    return {
        "op": "send_action_goal",
        "id": goal_id,
        "action": action,
        "action_type": action_type,
        "args": {
            "use_dock_id": False,
            "dock_id": dock_id,
            "dock_pose": {"header": header(0.0, frame_id), "pose": rb.pose_msg(x, y, yaw)},
            "dock_type": "",
            "max_staging_time": float(max_staging_time),
            "navigate_to_staging_pose": True,
        },
        "feedback": True,
    }


def op_send_undock_goal(
    action: str, action_type: str, goal_id: str, *, max_undocking_time: float
) -> dict[str, Any]:
    """An UndockRobot goal (``dock_type`` empty: the dock the server docked at, or its only
    plugin). UndockRobot has no feedback: nothing is asked."""
    return {
        "op": "send_action_goal",
        "id": goal_id,
        "action": action,
        "action_type": action_type,
        "args": {"dock_type": "", "max_undocking_time": float(max_undocking_time)},
        "feedback": False,
    }


def op_cancel_action_goal(action: str, goal_id: str) -> dict[str, Any]:
    return {"op": "cancel_action_goal", "id": goal_id, "action": action}


def _status(op: Mapping[str, Any], stack: str) -> ActionStatus | str:
    """The ``action_result``'s status, or the words for one it does not have."""
    values = op.get("values")
    raw = op.get("status")
    if raw is None and isinstance(values, Mapping):
        raw = values.get("status")
    try:
        return ActionStatus(int(raw))  # type: ignore[arg-type]
    except (TypeError, ValueError):
        return f"{stack} ended with status {raw!r}"


def result_of(op: Mapping[str, Any]) -> Mapping[str, Any]:
    """The action's result message (older bridges nest it in ``values.result``)."""
    values = op.get("values")
    if not isinstance(values, Mapping):
        return {}
    inner = values.get("result", values)
    return inner if isinstance(inner, Mapping) else {}


def outcome(op: Mapping[str, Any]) -> tuple[rb.GoalStatus, str]:
    """An ``action_result`` frame's outcome and the words for it.

    ``result`` is true for every normal end — succeeded, canceled *or* aborted — and the
    outcome is ``status``; older bridges put ``status`` inside ``values``. ``result`` false
    is an exception on the bridge (``values`` is its text). Jazzy's NavigateToPose result has
    ``error_code``/``error_msg``; Humble's is empty.
    """
    if op.get("result") is False:
        return rb.GoalStatus.ABORTED, f"{STACK} failed on the bridge: {op.get('values')}"
    status = _status(op, STACK)
    if isinstance(status, str):
        return rb.GoalStatus.ABORTED, status
    mapped = ACTION_STATUS.get(status, rb.GoalStatus.ABORTED)
    text = f"{STACK} {status.name}"
    inner = result_of(op)
    if inner.get("error_msg"):
        text += f": {inner['error_msg']} (error {inner.get('error_code')})"
    return mapped, text


def dock_outcome(op: Mapping[str, Any], stack: str = DOCK_STACK) -> tuple[rb.GoalStatus, str]:
    """A DockRobot (or UndockRobot, ``stack`` :data:`UNDOCK_STACK`) ``action_result``'s
    outcome and words: SUCCEEDED only with ``success`` true (or absent); a result with
    ``success`` false is ABORTED, whatever its status, and its text names the error code in
    words ("Nav2 dock_robot ABORTED: failed to detect the dock (904)", then the server's
    ``error_msg`` if it sent one); CANCELED is PREEMPTED, as a navigate goal's."""
    if op.get("result") is False:
        return rb.GoalStatus.ABORTED, f"{stack} failed on the bridge: {op.get('values')}"
    status = _status(op, stack)
    if isinstance(status, str):
        return rb.GoalStatus.ABORTED, status
    if status is ActionStatus.CANCELED:
        return rb.GoalStatus.PREEMPTED, f"{stack} CANCELED"
    inner = result_of(op)
    if status is ActionStatus.SUCCEEDED and inner.get("success") is not False:
        return rb.GoalStatus.SUCCEEDED, f"{stack} SUCCEEDED"
    code = inner.get("error_code", 0)
    try:
        words = DOCK_ERRORS.get(int(code), "an error code it does not know")
    except (TypeError, ValueError):
        words = "an error code it does not know"
    text = f"{stack} ABORTED: {words} ({code})"
    if inner.get("error_msg"):
        text += f": {inner['error_msg']}"
    return rb.GoalStatus.ABORTED, text


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


def undock_verdict(op: Mapping[str, Any]) -> tuple[bool, str]:
    """Is the robot off its dock after this UndockRobot ``action_result``? (True, words)
    for SUCCEEDED, and for ABORTED without an error code: opennav_docking's "Robot is not in
    the dock, no need to undock" returns from the server's callback without a verdict, which
    Nav2's SimpleActionServer ends ABORTED (seen on a real robot after the docking server
    restarted: it no longer knew it had docked). (False, words) for every other end: a
    failure with its error code, a cancel, a bridge error."""
    status, text = dock_outcome(op, UNDOCK_STACK)
    if status is rb.GoalStatus.SUCCEEDED:
        return True, text
    code = result_of(op).get("error_code", 0)
    if status is rb.GoalStatus.ABORTED and code == 0 and op.get("result") is not False:
        return True, f"{text}: the robot was not on a dock"
    return False, text
