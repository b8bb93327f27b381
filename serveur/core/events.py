"""What happens to a robot, as typed values: the reports its link makes and the timers the
server sets for it.

Each is a frozen dataclass. They are queued per robot (:mod:`serveur.core.link_reports`) and
handled in arrival order under the robot's lock by its
:class:`~serveur.core.robot.RobotController`, which dispatches on the type through one table:
adding an event is one class here and one entry there, and a misspelt kind is a type error,
not a report silently ignored (they were untyped tuples like ``("goal", id, status, text)``
sorted by ten string ``if``s).
"""

from __future__ import annotations

from dataclasses import dataclass

from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss

__all__ = [
    "ChargeDue",
    "Charged",
    "CruiseResume",
    "GoalEnded",
    "HandoverDue",
    "LeaseGranted",
    "LinkDown",
    "LinkFailed",
    "LinkUp",
    "PersistPose",
    "RobotEvent",
    "TableTimeout",
]


@dataclass(frozen=True, slots=True)
class LinkUp:
    """The link is up: the robot answered with a pose (it resumes what it was doing)."""


@dataclass(frozen=True, slots=True)
class LinkDown:
    """The link dropped (the robot goes Offline, keeping its trip for a while)."""

    reason: str


@dataclass(frozen=True, slots=True)
class LinkFailed:
    """The link cannot connect: shown to staff with the robot, once per distinct reason."""

    reason: str


@dataclass(frozen=True, slots=True)
class GoalEnded:
    """A goal ended on the robot (succeeded, aborted, ...) or was given up by the link
    (``status`` LOST, ``text`` saying why and ``loss`` what that says of the table)."""

    goal_id: str
    status: rb.GoalStatus
    text: str
    loss: GoalLoss | None = None  # why, for a LOST goal


@dataclass(frozen=True, slots=True)
class LeaseGranted:
    """The zones the robot waited for are its own now: it may drive its leg."""


@dataclass(frozen=True, slots=True)
class HandoverDue:
    """The robot has been Offline with a trip past the hand-over limit."""


@dataclass(frozen=True, slots=True)
class PersistPose:
    """Time to store the robot's last pose and battery (for the map after a restart)."""


@dataclass(frozen=True, slots=True)
class TableTimeout:
    """Nobody collected the food at the table the robot reached at ``since`` on ``task_id``."""

    task_id: int
    since: float


@dataclass(frozen=True, slots=True)
class ChargeDue:
    """A free robot with a dock is below the site's charge level: off to charge."""


@dataclass(frozen=True, slots=True)
class Charged:
    """A robot on its dock reached the site's upper level: back into service."""


@dataclass(frozen=True, slots=True)
class CruiseResume:
    """A cruising robot someone stopped at ``since`` has waited the site's cruise_resume."""

    task_id: int
    since: float


RobotEvent = (
    LinkUp
    | LinkDown
    | LinkFailed
    | GoalEnded
    | LeaseGranted
    | HandoverDue
    | PersistPose
    | TableTimeout
    | ChargeDue
    | Charged
    | CruiseResume
)
