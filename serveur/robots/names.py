"""A robot's ROS names: its topics, its move_base action and its map frame (pure).

Real robots rarely use the bare names our simulator publishes: a fleet on one ROS master is
namespaced (``/r1/move_base``, ``/r1/amcl_pose``), vendors rename topics (``/odom_combined``,
``/battery``), and a map frame may be ``world``. Each robot gets a :class:`RosNames`, built from
the options given at registration (``--robot r1=ws://...,ns=/r1`` or ``create type=robot``
with ``link``), stored with the robot, and used by its link for every topic it touches.

Defaults are today's names. ``ns`` puts every default name under a namespace (as a ROS node
pushed into that namespace resolves its relative names); each name can then be set alone,
absolute (``/battery``) or relative (``battery``, resolved under ``ns``).

``docking`` says a ROS 2 robot runs a docking server the link drives its dock goals through
(:data:`DOCKING_SERVERS`): ``nav2`` (Nav2's opennav_docking, Jazzy and later, whose actions are
``nav2_msgs/action/DockRobot`` and ``UndockRobot``) or ``opennav`` (the standalone
open-navigation/opennav_docking a Humble robot runs, ``opennav_docking_msgs/action/...``).
Its actions are ``dock_robot`` and ``undock_robot`` under ``ns`` (the docking server's own
names). Without it (and on every ROS1 robot) a dock is a plain goal to the dock's pose.
"""

from __future__ import annotations

import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import cached_property

__all__ = ["DOCKING_SERVERS", "OPTION_KEYS", "ROS_VERSIONS", "RosNames"]

#: Option key -> the default name, in the order docs/robots.md lists them: the move_base
#: action (goal, cancel, status, result, feedback), joystick velocities, the localised pose,
#: calibration, the battery, the laser, the map (when the server has none), and a ROS 2
#: robot's heartbeat service (Nav2's navigator lifecycle state).
_DEFAULTS: dict[str, str] = {
    "move_base": "move_base",
    "navigate": "navigate_to_pose",  # ROS 2: Nav2's NavigateToPose action
    "cmd_vel": "cmd_vel",
    "pose": "amcl_pose",
    "initialpose": "initialpose",
    "battery": "battery_state",
    "scan": "scan",
    "map": "map",
    # ROS 2: the service whose answer proves the robot alive and able to take goals
    # (lifecycle_msgs/srv/GetState answering "active", or std_srvs/srv/Trigger's success).
    "heartbeat": "bt_navigator/get_state",
    # AMCL's particle cloud: ROS1 amcl's ``particlecloud``; Nav2's amcl calls it
    # ``particle_cloud`` (nav2_amcl amcl_node.cpp), the default for a ROS 2 robot.
    "cloud": "particlecloud",
    # tf, for a robot whose pose comes from it (``tf`` names its base frame)
    "tf_topic": "tf",
    "tf_static": "tf_static",
}
#: Defaults that differ on a ROS 2 robot.
_ROS2_DEFAULTS: dict[str, str] = {"cloud": "particle_cloud"}
#: Every option a robot's ``link`` may carry. ``camera`` has no default: a robot has a camera
#: to watch only when its CompressedImage topic is named (``camera/image/compressed``...).
#: ``tf`` has none either: a robot takes its pose from tf (``map`` -> that base frame) instead of
#: ``/amcl_pose`` only when its base frame is named (``base_link``, ``base_footprint``).
#: ``camera_url`` instead names the robot's web_video_server stream (``http://robot:8080/
#: stream?topic=/camera/image/compressed&type=ros_compressed``): the same JPEGs over HTTP.
#: ``docking`` has none either: a robot docks through a docking server only when it names one.
OPTION_KEYS = ("ros", "ns", *_DEFAULTS, "frame", "camera", "camera_url", "tf", "docking")
#: The ROS versions a robot may run: "1" (move_base) or "2" (Nav2).
ROS_VERSIONS = ("1", "2")
#: The docking servers a ROS 2 robot may run (its ``docking`` option): Nav2's opennav_docking
#: (Jazzy and later: its actions are in nav2_msgs) or the standalone opennav_docking (Humble:
#: opennav_docking_msgs).
DOCKING_SERVERS = ("nav2", "opennav")
_NAME = re.compile(r"^/?[A-Za-z][A-Za-z0-9_]*(/[A-Za-z][A-Za-z0-9_]*)*$")
_FRAME = re.compile(r"^[A-Za-z][A-Za-z0-9_/]*$")
_URL = re.compile(r"^https?://[^\s/?#]+(/[^\s]*)?$", re.IGNORECASE)


def _resolve(ns: str, name: str) -> str:
    if name.startswith("/"):
        return name
    return f"{ns}/{name}" if ns else f"/{name}"


@dataclass(frozen=True)
class RosNames:
    """The resolved names of one robot (absolute ROS graph names) and its map frame."""

    ros: int = 1
    ns: str = ""
    move_base: str = "/move_base"
    navigate: str = "/navigate_to_pose"
    cmd_vel: str = "/cmd_vel"
    pose: str = "/amcl_pose"
    initialpose: str = "/initialpose"
    battery: str = "/battery_state"
    scan: str = "/scan"
    map: str = "/map"
    heartbeat: str = "/bt_navigator/get_state"
    frame: str = "map"
    cloud: str = "/particlecloud"
    tf_topic: str = "/tf"
    tf_static: str = "/tf_static"
    #: The camera's sensor_msgs/CompressedImage topic; "" when the robot has none.
    camera: str = ""
    #: The robot's base frame when its pose comes from tf; "" when it comes from /amcl_pose.
    tf_base: str = ""
    #: The robot's web_video_server stream URL (MJPEG), "" for none: a camera without rosbridge.
    camera_url: str = ""
    #: The robot's docking server (:data:`DOCKING_SERVERS`), "" for none: docks are goals.
    docking: str = ""

    @classmethod
    def from_options(cls, options: Mapping[str, str]) -> RosNames:
        """Names from registration options; ValueError names the bad option and why."""
        unknown = sorted(set(options) - set(OPTION_KEYS))
        if unknown:
            raise ValueError(
                f"unknown robot link option {unknown[0]!r} (known: {', '.join(OPTION_KEYS)})"
            )
        for key, value in options.items():
            if not isinstance(value, str):
                raise ValueError(f"robot link option {key!r} must be a string")
            if key == "ros":
                if value not in ROS_VERSIONS:
                    raise ValueError(f"robot link option ros={value!r}: the robot runs ROS 1 or 2")
                continue
            if key == "docking":
                if value not in DOCKING_SERVERS:
                    raise ValueError(
                        f"robot link option docking={value[:40]!r}: 'nav2' (Nav2's docking "
                        "server, Jazzy and later) or 'opennav' (opennav_docking on Humble)"
                    )
                continue
            if key == "camera_url":
                if not _URL.match(value) or len(value) > 256:
                    raise ValueError(
                        f"robot link option camera_url={value[:80]!r} is not an http(s) URL"
                    )
                continue
            pattern = _FRAME if key in ("frame", "tf") else _NAME
            if not pattern.match(value) or len(value) > 128:
                raise ValueError(f"robot link option {key}={value!r} is not a valid ROS name")
        ns = options.get("ns", "")
        if ns and not ns.startswith("/"):
            ns = "/" + ns
        ns = ns.rstrip("/")
        ros = int(options.get("ros", "1"))
        if options.get("docking") and ros != 2:
            raise ValueError(
                "robot link option docking: a docking server's actions are ROS 2's (ros=2); "
                "a ROS1 robot docks with a goal to its dock"
            )
        defaults = {**_DEFAULTS, **_ROS2_DEFAULTS} if ros == 2 else _DEFAULTS
        names = {key: _resolve(ns, options.get(key, default)) for key, default in defaults.items()}
        camera = _resolve(ns, options["camera"]) if options.get("camera") else ""
        return cls(
            ros=ros,
            ns=ns,
            frame=options.get("frame", "map"),
            camera=camera,
            tf_base=options.get("tf", ""),
            camera_url=options.get("camera_url", ""),
            docking=options.get("docking", ""),
            **names,
        )

    def topic(self, default: str) -> str:
        """This robot's name for one of the default topic names (``/move_base/goal``...)."""
        return self._by_default[default]

    def default_of(self, topic: str) -> str | None:
        """The default topic name a topic of this robot stands for (None: not one of ours)."""
        return self._reverse.get(topic)

    @cached_property
    def _by_default(self) -> dict[str, str]:
        mb = self.move_base
        return {
            "/move_base/goal": f"{mb}/goal",
            "/move_base/cancel": f"{mb}/cancel",
            "/move_base/status": f"{mb}/status",
            "/move_base/result": f"{mb}/result",
            "/move_base/feedback": f"{mb}/feedback",
            "/navigate_to_pose": self.navigate,
            "/cmd_vel": self.cmd_vel,
            "/amcl_pose": self.pose,
            "/initialpose": self.initialpose,
            "/battery_state": self.battery,
            "/scan": self.scan,
            "/map": self.map,
            "/particlecloud": self.cloud,
            "/tf": self.tf_topic,
            "/tf_static": self.tf_static,
            # the docking server's actions (ROS 2, ``docking``): its own names, under ``ns``
            "/dock_robot": f"{self.ns}/dock_robot",
            "/undock_robot": f"{self.ns}/undock_robot",
        }

    @cached_property
    def _reverse(self) -> dict[str, str]:
        return {v: k for k, v in self._by_default.items()}
