"""The driver for a robot, from the ROS it runs (its ``ros`` link option: 1 or 2).

Kept apart from :mod:`serveur.robots.driver` so the interface never imports what implements it.
"""

from __future__ import annotations

import ssl as ssl_module

from serveur.clock import Clock
from serveur.robots.driver import LinkListener, RobotDriver
from serveur.robots.names import RosNames
from serveur.robots.ros1.link import RobotLink
from serveur.robots.ros2.link import Nav2Link

__all__ = ["make_driver"]


def make_driver(
    name: str,
    url: str,
    listener: LinkListener,
    clock: Clock,
    *,
    names: RosNames,
    heartbeat: float,
    ack_timeout: float,
    ack_retries: int,
    want_map: bool,
    ssl: ssl_module.SSLContext | None,
    pose_watched: bool,
    moving_pose_ms: int,
    status_ms: int,
    battery_ms: int,
) -> RobotDriver:
    """A ROS1 move_base link or a ROS 2 Nav2 link; the core cannot tell them apart."""
    if names.ros == 2:
        return Nav2Link(
            name,
            url,
            listener,
            clock,
            heartbeat=heartbeat,
            ack_timeout=ack_timeout,
            ack_retries=ack_retries,
            want_map=want_map,
            ssl=ssl,
            names=names,
        )
    return RobotLink(
        name,
        url,
        listener,
        clock,
        heartbeat=heartbeat,
        ack_timeout=ack_timeout,
        ack_retries=ack_retries,
        want_map=want_map,
        ssl=ssl,
        pose_watched=pose_watched,
        moving_pose_ms=moving_pose_ms,
        status_ms=status_ms,
        battery_ms=battery_ms,
        names=names,
    )
