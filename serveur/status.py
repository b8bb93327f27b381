"""The robot status machine and the allowed-actions table (pure; no I/O).

Every robot has exactly one :class:`RobotStatus`. It decides which instructions staff, screens
and scripts may give (:data:`ALLOWED`): anything else is refused with ``not_allowed_in_status``,
never silently ignored. The server turns client instructions and robot reports into
:class:`Event` values and asks :func:`apply` for the next state, so the rules live here, in one
table, tested without sockets.

``mode`` is kept beside the status because it survives what the status does not: a robot that
drops off the network while in automatic mode is Offline, but comes back automatic. ``resume``
is the status to return to after Stopped, Error or Offline (Delivering or Transit), so that
"continue" and a reconnect go back to the same kind of move.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from enum import StrEnum

from serveur.errors import NotAllowedInStatus

__all__ = [
    "ALLOWED",
    "TRANSITIONS",
    "Action",
    "Event",
    "RobotMode",
    "RobotState",
    "RobotStatus",
    "allowed_actions",
    "apply",
    "check_allowed",
]


class RobotStatus(StrEnum):
    """What a robot is doing, as staff and screens see it."""

    OFFLINE = "Offline"  # no rosbridge link (or its status heartbeat stopped)
    READY = "Ready"  # linked, not activated
    AWAITING = "Awaiting"  # automatic, at home, no job
    LOADING = "Loading"  # at the pass with a trip: staff load the trays, then press Go
    DELIVERING = "Delivering"  # moving to a table with food
    DELIVERED = "Delivered"  # at a table, waiting for "food collected" (next)
    STOPPED = "Stopped"  # halted by staff during a move
    TRANSIT = "Transit"  # moving without food: going home
    MANUAL = "Manual"  # under staff control (teleop, calibration, goals, go-to)
    ERROR = "Error"  # navigation aborted or a goal was never acknowledged
    CHARGING = "Charging"  # on its dock, charging: no trips until it leaves (work)


class RobotMode(StrEnum):
    """Who drives the robot; persisted so it survives Offline and server restarts."""

    OFF = "off"
    AUTO = "auto"
    MANUAL = "manual"


class Action(StrEnum):
    """Robot-bound instructions a client can give (the allowed-actions table's columns)."""

    AUTO = "auto"  # control: switch to automatic mode
    MANUAL = "manual"  # control: take manual control
    TELEOP = "teleop"  # control: velocity command
    INITIALPOSE = "initialpose"  # control: calibrate (set the initial pose)
    GOAL = "goal"  # control: post a goal pose
    GOTO = "goto"  # control: go to a named waypoint
    READY = "ready"  # control finished: hand the robot back (leave manual or automatic)
    NEXT = "next"  # food collected at this table
    STOP = "stop"
    CONTINUE = "continue"
    CANCEL = "cancel"
    SAVE_WAYPOINT = "save_waypoint"  # create a waypoint at the robot's current pose
    GO = "go"  # trays loaded: leave on the trip
    SKIP = "skip"  # leave this table unserved, its dishes returned
    CHARGE = "charge"  # go to the dock and charge
    WORK = "work"  # leave the dock, back into service
    CRUISE = "cruise"  # go round a route of places


S = RobotStatus
A = Action

#: Which instructions each status allows. Reading (``data``, ``order``) and creating orders,
#: tasks and waypoints from explicit poses are not robot-bound and always allowed.
ALLOWED: dict[RobotStatus, frozenset[Action]] = {
    S.OFFLINE: frozenset(),
    S.READY: frozenset({A.AUTO, A.MANUAL, A.SAVE_WAYPOINT}),
    S.AWAITING: frozenset({A.READY, A.MANUAL, A.SAVE_WAYPOINT, A.CHARGE, A.CRUISE}),
    S.LOADING: frozenset({A.GO, A.CANCEL, A.MANUAL, A.SAVE_WAYPOINT}),
    S.DELIVERING: frozenset({A.STOP, A.MANUAL, A.SAVE_WAYPOINT}),
    S.DELIVERED: frozenset({A.NEXT, A.SKIP, A.STOP, A.MANUAL, A.SAVE_WAYPOINT}),
    S.STOPPED: frozenset({A.CONTINUE, A.CANCEL, A.SKIP, A.MANUAL, A.SAVE_WAYPOINT}),
    S.TRANSIT: frozenset({A.STOP, A.MANUAL, A.SAVE_WAYPOINT}),
    S.MANUAL: frozenset({A.TELEOP, A.INITIALPOSE, A.GOAL, A.GOTO, A.READY, A.SAVE_WAYPOINT}),
    S.ERROR: frozenset({A.CONTINUE, A.CANCEL, A.SKIP, A.MANUAL, A.SAVE_WAYPOINT}),
    S.CHARGING: frozenset({A.WORK, A.MANUAL, A.SAVE_WAYPOINT}),
}


class Event(StrEnum):
    """Everything that can change a robot's status: instructions and robot reports."""

    LINK_UP = "link_up"
    LINK_DOWN = "link_down"
    AUTO = "auto"
    MANUAL = "manual"
    RELEASE = "release"  # the ``ready`` instruction
    DISPATCH = "dispatch"  # a trip starts at once (auto-depart): goal sent to its first table
    ASSIGN = "assign"  # a trip is given to the robot at the pass, to be loaded
    GO = "go"  # loaded: the trip starts, goal sent to its first table
    GO_HOME = "go_home"  # an automatic robot is sent home without food
    ARRIVED = "arrived"  # the current goal succeeded
    NAV_FAILED = "nav_failed"  # the goal aborted, was rejected or never acknowledged
    NEXT_TABLE = "next_table"  # food collected, more tables on this trip
    NEXT_HOME = "next_home"  # food collected at the trip's last table
    STOP = "stop"
    CONTINUE = "continue"
    CANCEL = "cancel"
    CHARGE = "charge"  # sent to its dock (by staff, or below the site's charge level)
    DOCKED = "docked"  # on the dock: the goal to it succeeded
    UNDOCK = "undock"  # leaves the dock, home (by staff, or charged)
    RECALL = "recall"  # a cruise ends, called back to deliveries: home without stopping first


@dataclass(frozen=True, slots=True)
class RobotState:
    """A robot's status plus what survives it: the mode and the status to resume."""

    status: RobotStatus = RobotStatus.OFFLINE
    mode: RobotMode = RobotMode.OFF
    resume: RobotStatus | None = None


_MOVING = (S.DELIVERING, S.TRANSIT)

#: (status, event) -> next status, for the transitions that need no context.
TRANSITIONS: dict[tuple[RobotStatus, Event], RobotStatus] = {
    (S.READY, Event.AUTO): S.AWAITING,
    (S.READY, Event.MANUAL): S.MANUAL,
    (S.ERROR, Event.MANUAL): S.MANUAL,
    # Staff take a robot in one step from wherever it is (a trip it had is given up first).
    (S.AWAITING, Event.MANUAL): S.MANUAL,
    (S.DELIVERING, Event.MANUAL): S.MANUAL,
    (S.DELIVERED, Event.MANUAL): S.MANUAL,
    (S.STOPPED, Event.MANUAL): S.MANUAL,
    (S.TRANSIT, Event.MANUAL): S.MANUAL,
    (S.MANUAL, Event.RELEASE): S.READY,
    (S.AWAITING, Event.RELEASE): S.READY,
    (S.AWAITING, Event.DISPATCH): S.DELIVERING,
    (S.AWAITING, Event.ASSIGN): S.LOADING,
    (S.LOADING, Event.GO): S.DELIVERING,
    (S.LOADING, Event.MANUAL): S.MANUAL,
    # Cancelled before it left: the robot is still at the pass.
    (S.LOADING, Event.CANCEL): S.AWAITING,
    # A table skipped from a stopped or failed robot: on to the next table, or home.
    (S.STOPPED, Event.NEXT_TABLE): S.DELIVERING,
    (S.STOPPED, Event.NEXT_HOME): S.TRANSIT,
    (S.ERROR, Event.NEXT_TABLE): S.DELIVERING,
    (S.ERROR, Event.NEXT_HOME): S.TRANSIT,
    (S.AWAITING, Event.GO_HOME): S.TRANSIT,
    (S.DELIVERING, Event.ARRIVED): S.DELIVERED,
    (S.TRANSIT, Event.ARRIVED): S.AWAITING,
    (S.MANUAL, Event.ARRIVED): S.MANUAL,
    (S.MANUAL, Event.NAV_FAILED): S.MANUAL,
    (S.DELIVERED, Event.NEXT_TABLE): S.DELIVERING,
    (S.DELIVERED, Event.NEXT_HOME): S.TRANSIT,
    (S.STOPPED, Event.CANCEL): S.TRANSIT,
    (S.ERROR, Event.CANCEL): S.TRANSIT,
    # A stopped or failed robot whose trip is handed back goes home without food.
    (S.STOPPED, Event.GO_HOME): S.TRANSIT,
    (S.ERROR, Event.GO_HOME): S.TRANSIT,
    (S.AWAITING, Event.CHARGE): S.TRANSIT,
    (S.TRANSIT, Event.DOCKED): S.CHARGING,
    (S.CHARGING, Event.UNDOCK): S.TRANSIT,
    (S.CHARGING, Event.MANUAL): S.MANUAL,
    (S.DELIVERING, Event.RECALL): S.TRANSIT,
    (S.DELIVERED, Event.RECALL): S.TRANSIT,
}


def allowed_actions(status: RobotStatus) -> frozenset[Action]:
    """The instructions a robot in ``status`` accepts."""
    return ALLOWED[status]


def check_allowed(status: RobotStatus, action: Action) -> None:
    """Raise ``NotAllowedInStatus`` unless ``action`` is allowed in ``status``."""
    if action not in ALLOWED[status]:
        allowed = ", ".join(sorted(a.value for a in ALLOWED[status])) or "nothing"
        raise NotAllowedInStatus(
            f"{action.value!r} is not allowed while the robot is {status.value} "
            f"(allowed: {allowed})",
            status=status.value,
            action=action.value,
        )


def _by_mode(mode: RobotMode) -> RobotStatus:
    return {RobotMode.OFF: S.READY, RobotMode.AUTO: S.AWAITING, RobotMode.MANUAL: S.MANUAL}[mode]


def apply(state: RobotState, event: Event) -> RobotState:
    """The state after ``event``; ``NotAllowedInStatus`` for a transition not in the table."""
    status = state.status
    if event is Event.LINK_DOWN:
        if status is S.OFFLINE:
            return state
        keep: RobotStatus | None = status
        if status in (S.READY, S.AWAITING, S.MANUAL):
            keep = state.resume  # re-derived from the mode on link-up
        return RobotState(S.OFFLINE, state.mode, keep)
    if event is Event.LINK_UP:
        if status is not S.OFFLINE:
            return state
        target = state.resume if state.resume is not None else _by_mode(state.mode)
        return RobotState(target, state.mode, None)
    if event is Event.STOP and (status in _MOVING or status is S.DELIVERED):
        # Stopped where it stands: at a stop it is held there (no timeout, no pause ending:
        # a guest touching a cruising robot at its place) until it goes on.
        return RobotState(S.STOPPED, state.mode, status)
    if event is Event.NAV_FAILED and status in _MOVING:
        return RobotState(S.ERROR, state.mode, status)
    if event is Event.CONTINUE and status in (S.STOPPED, S.ERROR):
        return RobotState(state.resume or S.TRANSIT, state.mode, None)
    nxt = TRANSITIONS.get((status, event))
    if nxt is None:
        raise NotAllowedInStatus(
            f"{event.value!r} cannot happen while the robot is {status.value}",
            status=status.value,
            event=event.value,
        )
    mode = state.mode
    if event is Event.AUTO:
        mode = RobotMode.AUTO
    elif event is Event.MANUAL:
        mode = RobotMode.MANUAL
    elif event is Event.RELEASE:
        mode = RobotMode.OFF
    return replace(state, status=nxt, mode=mode, resume=None)
