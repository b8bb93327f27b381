"""The robot-driver interface: what the core asks of a robot, and what a robot reports back.

The core (:mod:`serveur.core`) drives every robot through :class:`RobotDriver` and hears from
it through :class:`LinkListener`; nothing above this interface knows which ROS a robot runs.
Two drivers implement it: :class:`serveur.robots.ros1.link.RobotLink` (ROS1, move_base over
rosbridge) and :class:`serveur.robots.ros2.link.Nav2Link` (ROS 2, Nav2's navigate_to_pose over
rosbridge 2.x). :func:`serveur.robots.factory.make_driver` picks one from the robot's ``ros``
option; this module never imports them (an interface does not know its implementations).

The interface is small on purpose, like Equinor ISAR's robot interface: go to a pose, dock
and leave the dock, cancel, stop for good, steer, set the pose; reports of pose, battery, goal
outcomes and liveness.
Goal outcomes use one vocabulary, :class:`~serveur.robots.rosbridge.GoalStatus` (actionlib's,
the richer of the two): a driver for another stack maps its own outcomes onto it (Nav2's
CANCELED is PREEMPTED, a goal that never got an answer is LOST).

A lost goal also says *why* it was lost, typed (:class:`GoalLoss`): the link failed (the table
is fine), the robot never took the goal, or it navigated and could not finish: the ``cause``
of :meth:`LinkListener.goal_lost`.

**Docking** (issue 32): :meth:`RobotDriver.dock` drives the robot onto its charger and reports
its end as a goal's (SUCCEEDED once docked); :meth:`RobotDriver.undock` takes it off before
the next goal. A ROS 2 robot whose link options name a docking server (``docking=nav2``, Nav2's
opennav_docking; ``docking=opennav``, its standalone package on Humble) docks through that
server's ``dock_robot`` / ``undock_robot`` actions; every other robot (ROS1, ROS 2 without the
option, the fake) docks with a plain goal to the dock's pose and has nothing to do to undock.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping
from enum import Enum
from typing import Any, Protocol

from serveur.robots import rosbridge as rb
from serveur.robots.sensing import Cloud

__all__ = [
    "GoalLoss",
    "LinkListener",
    "RobotDriver",
    "connect_failed",
]


class GoalLoss(Enum):
    """Why a goal was lost: what the core may conclude about the place it was going to.

    * ``LINK``: the link to the robot failed while the goal ran (or the bridge could not carry
      it): nothing is known about the way or the table; the robot is Offline or soon will be.
      Not a reason to block a table.
    * ``NOT_ACCEPTED``: the robot never took the goal (no acknowledgement after every re-send,
      or its navigator refused it): the robot's navigation is not working, not the table's way.
    * ``NAVIGATION``: the robot took the goal and its end never came (it stopped reporting
      progress away from the goal): as a navigation failure, the way may be at fault.

    A goal whose end came (SUCCEEDED, ABORTED...) is not lost: ``goal_done`` says it.
    """

    LINK = "link"
    NOT_ACCEPTED = "not_accepted"
    NAVIGATION = "navigation"


class LinkListener(Protocol):
    """What a driver reports. Called on the event loop; must not block."""

    def link_up(self, robot: str) -> None: ...

    def link_down(self, robot: str, reason: str) -> None: ...

    def link_failed(self, robot: str, reason: str) -> None:
        """Connecting failed for a new reason (a wrong address, a robot switched off): said
        once per distinct reason in a row, for staff to see why the robot stays Offline."""

    def pose(self, robot: str, x: float, y: float, yaw: float, stamp: float) -> None: ...

    def localisation(self, robot: str, metres: float, radians: float) -> None:
        """How spread the robot's estimate of its pose is, with each pose that says it (the
        standard deviations of its covariance: worst floor direction, heading)."""

    def cloud(self, robot: str, cloud: Cloud) -> None:
        """The localiser's particle cloud (only while :meth:`RobotDriver.want_cloud`)."""

    def battery(self, robot: str, fraction: float) -> None: ...

    def goal_done(self, robot: str, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        """The goal reached a terminal state (SUCCEEDED, ABORTED, PREEMPTED, REJECTED...);
        ``text`` says it in the robot's own terms ("move_base ABORTED: ...")."""

    def goal_lost(
        self, robot: str, goal_id: str, reason: str, *, cause: GoalLoss = GoalLoss.NAVIGATION
    ) -> None:
        """The goal was never acknowledged after every re-send, its end never came, or the
        link failed under it; ``reason`` says it in the robot's own terms ("goal not
        acknowledged by Nav2 ..."), ``cause`` what that says of the place it was going to.
        The driver has already asked the robot to cancel it (a goal nobody watches drives
        on)."""

    def scan(self, robot: str, msg: Mapping[str, Any]) -> None: ...

    def map(self, robot: str, msg: Mapping[str, Any]) -> None: ...


class RobotDriver(Protocol):
    """One robot's connection, kept up for the life of the server.

    Commands raise :class:`~serveur.errors.LinkError` when the robot cannot be reached (or the
    server is shutting down after :meth:`halt`); reports go to the listener given at creation.
    """

    name: str
    url: str
    #: Why the last connection attempt failed ("" once connected), for the console.
    last_failure: str
    #: "ROS1 move_base" or "ROS 2 Nav2": shown to staff and in logs.
    kind: str

    @property
    def pose(self) -> tuple[float, float, float] | None:
        """The last pose reported (map frame), None until one came."""
        ...

    @property
    def battery(self) -> float | None:
        """The last battery fraction reported, None until one came."""
        ...

    @property
    def up(self) -> bool:
        """Connected, alive and localised: the server may act on this robot."""
        ...

    @property
    def goal_id(self) -> str | None:
        """The handle of the goal under way, if any."""
        ...

    def start(self) -> None: ...

    async def close(self) -> None: ...

    async def drop(self) -> None:
        """Close the connection as if the network failed (it reconnects by itself)."""
        ...

    async def halt(self) -> None:
        """Stop the robot for good (shutdown): cancel its goal, zero velocity, refuse more."""
        ...

    async def send_goal(self, x: float, y: float, yaw: float) -> str:
        """Send the robot to a map pose; the handle its outcome will be reported under."""
        ...

    async def dock(self, x: float, y: float, yaw: float, dock_id: str) -> str:
        """Drive onto the charging dock whose pose is (x, y, yaw) (map frame, the pose the
        robot stands in when on the charger) and whose name is ``dock_id``; returns a goal
        handle whose outcome is reported through :meth:`LinkListener.goal_done` /
        :meth:`LinkListener.goal_lost` exactly like :meth:`send_goal`'s (SUCCEEDED once
        docked). It replaces a goal under way as :meth:`send_goal` does, and
        :meth:`cancel_goal` cancels it. Without a docking server it *is* a goal to the dock's
        pose."""
        ...

    async def undock(self) -> None:
        """Leave the dock before the next goal: returns when the robot is off the dock, or
        at once where the robot has nothing to do for it (no docking server: its navigator
        drives it off with the next goal). A goal under way (a dock still running) is
        cancelled first, unreported, as by :meth:`cancel_goal`. Raises
        :class:`~serveur.errors.LinkError` when the robot cannot be reached, and when its
        docking server failed to take it off the dock or never answered (the text says why in
        the robot's words): the robot may still stand on its dock then."""
        ...

    async def cancel_goal(self) -> None:
        """Cancel the goal under way (the robot stops where it is)."""
        ...

    async def teleop(self, vx: float, vy: float, wz: float) -> None:
        """One joystick velocity; the driver stops the robot if none follows soon."""
        ...

    async def initial_pose(self, x: float, y: float, yaw: float) -> None:
        """Tell the robot's localisation where it is."""
        ...

    async def want_pose(self, on: bool) -> None:
        """Someone watches the pose live (full rate) or nobody does any more."""
        ...

    async def want_scan(self, on: bool) -> None:
        """Stream the laser scan while someone looks at it."""
        ...

    async def want_cloud(self, on: bool) -> None:
        """Stream the localiser's particle cloud while someone looks at it."""
        ...

    def heartbeat_timeout(self) -> float:
        """Clock seconds of silence after which the robot is declared down."""
        ...


def connect_failed(
    driver: RobotDriver, listener: LinkListener, reason: str, log: logging.Logger
) -> str:
    """A driver's connection attempt failed: tell the operator (on the driver's ``log``) and
    the listener once per distinct reason in a row (kept in ``last_failure`` until the next
    connection), not once per retry. Returns ``reason``."""
    if reason != driver.last_failure:
        driver.last_failure = reason
        log.warning("%s: cannot connect to %s: %s", driver.name, driver.url, reason)
        listener.link_failed(driver.name, reason)
    else:
        log.debug("%s: cannot connect to %s: %s", driver.name, driver.url, reason)
    return reason
