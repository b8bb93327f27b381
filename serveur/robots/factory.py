"""The driver for a robot, from the ROS it runs (its ``ros`` link option: 1 or 2), or a fake one.

Kept apart from :mod:`serveur.robots.driver` so the interface never imports what implements it.

A robot whose URL is ``fake://NAME`` gets :class:`~serveur.robots.fake.FakeDriver`: a robot
inside the server's process, with no socket and no ROS, for tests of the core and demos or
replays that need robots that drive but no simulator. Its query sets where it starts and how
it drives: ``fake://r1?x=4.0&y=10.8&yaw=1.57&speed=0.5&battery=0.9`` (metres, radians, m/s of
clock time, 0..1; the defaults: the map's origin facing +x, :data:`~serveur.robots.fake.SPEED`,
full). A fake robot has no map to send: the server takes its map from its own files. Clients
cannot register one (the protocol takes ``ws://`` and ``wss://`` URLs only): it is given by
whoever starts the server, as an :class:`~serveur.app.App` ``RobotSpec`` or on the command
line (``--robot 'r1=fake://r1?x=4.0&y=10.8,home=home1'``).
"""

from __future__ import annotations

import math
import ssl as ssl_module
from urllib.parse import parse_qsl, urlsplit

from serveur.clock import Clock
from serveur.robots.driver import LinkListener, RobotDriver
from serveur.robots.fake import SPEED, FakeDriver
from serveur.robots.names import RosNames
from serveur.robots.ros1.link import RobotLink
from serveur.robots.ros2.link import Nav2Link

__all__ = ["FAKE_SCHEME", "make_driver"]

#: The URL scheme of a fake robot (tests and demos without sockets).
FAKE_SCHEME = "fake"
_FAKE_OPTIONS = ("x", "y", "yaw", "speed", "battery")


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
    """A ROS1 move_base link, a ROS 2 Nav2 link, or for a ``fake://`` URL a fake robot; the
    core cannot tell them apart."""
    if urlsplit(url).scheme.lower() == FAKE_SCHEME:
        return _fake(name, url, listener, clock, heartbeat=heartbeat, ack_timeout=ack_timeout)
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


def _fake(
    name: str,
    url: str,
    listener: LinkListener,
    clock: Clock,
    *,
    heartbeat: float,
    ack_timeout: float,
) -> FakeDriver:
    """A fake robot from its URL's query (see the module's docstring); a bad option is an
    error here, where the robot is set up, not a robot that silently starts elsewhere."""
    opts: dict[str, float] = {}
    for key, value in parse_qsl(urlsplit(url).query, keep_blank_values=True):
        if key not in _FAKE_OPTIONS:
            raise ValueError(
                f"{url}: unknown fake robot option {key!r} ({', '.join(_FAKE_OPTIONS)})"
            )
        try:
            number = float(value)
        except ValueError:
            number = math.nan
        if not math.isfinite(number):
            raise ValueError(f"{url}: {key} must be a finite number, not {value!r}")
        opts[key] = number
    speed = opts.get("speed", SPEED)
    if speed <= 0:
        raise ValueError(f"{url}: speed must be > 0")
    return FakeDriver(
        name,
        url,
        listener,
        clock,
        pose=(opts.get("x", 0.0), opts.get("y", 0.0), opts.get("yaw", 0.0)),
        battery=opts.get("battery", 1.0),
        speed=speed,
        heartbeat=heartbeat,
        ack_timeout=ack_timeout,
    )
