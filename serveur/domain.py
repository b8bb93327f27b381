"""The restaurant's records: robots, waypoints, orders, tasks (trips) and events.

These are what the store returns, what the server pushes to subscribers and what
``docs/protocol.md`` shows, so they are pydantic models: one definition gives validation, the
JSON a client receives and the JSON Schema that ``serveur schema`` prints.

Lifecycle of a dish (an *order*):
``ordered`` (taken by a waiter or a POS) -> ``cooking`` (the kitchen started it) -> ``pending``
(ready at the kitchen pass) -> ``assigned`` (in a task: on a trip, loading, queued or under
way) -> ``delivered`` (the guest pressed "food collected") or ``returned`` (the table was
skipped or timed out: the dish came back to the pass, never delivered, for staff to send again
or void). ``voided`` is a dish withdrawn before it left the pass. A script may create a dish
straight at ``pending`` (a kitchen display that only says "ready"). Cancelling a trip puts its
undelivered orders back to ``pending``. :data:`ORDER_STEPS` is the rule for each step.

A *task* is one trip of one robot: ordered stops, one per table, each carrying that table's
dishes. Staff confirm a cart of dishes; the scheduler splits it into tasks of at most the tray
capacity in tables, each ``queued`` until a robot takes it (``active``), then ``done`` or
``cancelled``.
"""

from __future__ import annotations

import json
from enum import StrEnum
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, field_validator

from serveur.status import RobotMode, RobotStatus

__all__ = [
    "ORDER_STEPS",
    "Alert",
    "AlertKind",
    "AuditRecord",
    "Call",
    "CallButton",
    "CallKind",
    "DishAction",
    "EventRecord",
    "MenuItem",
    "Order",
    "OrderStatus",
    "Robot",
    "Stop",
    "StopPurpose",
    "StopStatus",
    "TableBlock",
    "Task",
    "TaskKind",
    "TaskStatus",
    "TicketStatus",
    "TillTicket",
    "WaypointKind",
    "WaypointRecord",
    "ZoneLease",
    "ZoneRecord",
]


class OrderStatus(StrEnum):
    ORDERED = "ordered"
    COOKING = "cooking"
    PENDING = "pending"  # ready at the pass
    ASSIGNED = "assigned"
    DELIVERED = "delivered"
    RETURNED = "returned"
    VOIDED = "voided"


class DishAction(StrEnum):
    """What staff, the kitchen or a POS script may do to one dish (the ``dish`` instruction)."""

    COOKING = "cooking"  # the kitchen started it
    READY = "ready"  # at the pass (or, for a returned dish: send it again)
    VOID = "void"  # withdraw it
    EDIT = "edit"  # change quantity, note or table


_O = OrderStatus
#: From which statuses each dish action may be taken, and the status it leads to (None: the
#: status does not change). A dish on a robot or delivered is beyond staff's edits: its trip
#: is changed instead (skip, cancel).
ORDER_STEPS: dict[DishAction, tuple[frozenset[OrderStatus], OrderStatus | None]] = {
    DishAction.COOKING: (frozenset({_O.ORDERED}), _O.COOKING),
    DishAction.READY: (frozenset({_O.ORDERED, _O.COOKING, _O.RETURNED}), _O.PENDING),
    DishAction.VOID: (frozenset({_O.ORDERED, _O.COOKING, _O.PENDING, _O.RETURNED}), _O.VOIDED),
    DishAction.EDIT: (frozenset({_O.ORDERED, _O.COOKING, _O.PENDING, _O.RETURNED}), None),
}


class TaskStatus(StrEnum):
    QUEUED = "queued"
    ACTIVE = "active"
    DONE = "done"
    CANCELLED = "cancelled"


class TaskKind(StrEnum):
    """What a trip is for. Every kind runs through the same statuses (a robot on a trip is
    Delivering between stops and Delivered at one); the screens word them by the kind."""

    DELIVERY = "delivery"  # dishes from the pass to tables
    BUSSING = "bussing"  # used dishes from tables to the dish return
    CRUISE = "cruise"  # a round of places (snacks, tasting, adverts), again and again


class StopPurpose(StrEnum):
    """What the robot does at a stop, and so what ends its wait there."""

    DELIVER = "deliver"  # guests take their dishes: "food collected" (or the table timeout)
    COLLECT = "collect"  # guests or staff put used dishes on: Done (or the bussing wait)
    UNLOAD = "unload"  # staff empty it at the dish return: Done (no timeout)
    VISIT = "visit"  # a cruise's place: it pauses, then goes on by itself


class StopStatus(StrEnum):
    PENDING = "pending"  # not reached yet
    ARRIVED = "arrived"  # robot at the table, waiting for "food collected"
    DONE = "done"  # food collected
    SKIPPED = "skipped"  # not served: skipped by staff, timed out, or the trip was cancelled


class WaypointKind(StrEnum):
    TABLE = "table"
    HOME = "home"
    PASS = "pass"
    OTHER = "other"
    DISH_RETURN = "dish_return"  # where bussing robots are emptied
    DOCK = "dock"  # a robot's charger


class _Record(BaseModel):
    model_config = ConfigDict(frozen=True, extra="forbid", use_enum_values=False)


class Robot(_Record):
    """A robot as the server knows it. ``x, y, yaw`` is the last reported map pose."""

    name: str
    url: str
    home: str | None = None
    kinematics: str = "omni"
    link: dict[str, str] = Field(
        default_factory=dict,
        description="Which ROS (ros: 1 or 2) and the ROS names that differ from the defaults: "
        "ns, move_base, navigate, cmd_vel, pose, initialpose, battery, scan, map, frame, cloud, "
        "tf_topic, tf_static, camera, camera_url, tf, docking "
        "(docs/robots.md)",
    )
    mode: RobotMode = RobotMode.OFF
    status: RobotStatus = RobotStatus.OFFLINE
    resume: RobotStatus | None = None
    current_task: int | None = None
    battery: float | None = Field(default=None, description="0..1, None if unknown")
    x: float | None = None
    y: float | None = None
    yaw: float | None = None
    last_error: str | None = None
    trays: int | None = Field(default=None, description="tables per trip; None: the site's")
    dock: str | None = Field(default=None, description="the place of its charger (a dock)")
    updated_at: float = 0.0
    status_since: float = Field(default=0.0, description="when it entered its status (epoch s)")
    link_error: str | None = Field(
        default=None,
        description="why the server cannot reach the robot (its last connection failure),"
        " while Offline; not stored",
    )
    removed: bool = Field(
        default=False, description="true only in the update saying the owner removed it"
    )
    waiting_for: list[str] | None = Field(
        default=None,
        description="the zones it waits to be leased before it drives on (null: not waiting);"
        " not stored",
    )
    to_dock: bool = Field(
        default=False, description="its Transit is to its dock, to charge (not home); not stored"
    )
    lost: bool = Field(
        default=False,
        description="not sure where it is (its localisation spread out): staff set where it is"
        " on the map; it gets no trips meanwhile; not stored",
    )

    @field_validator("link", mode="before")
    @classmethod
    def _link_from_json(cls, v: Any) -> Any:
        # The store keeps the options as a JSON object in one column.
        return json.loads(v) if isinstance(v, str) else v


class AlertKind(StrEnum):
    ROBOT_ERROR = "robot_error"  # subject: the robot
    ROBOT_OFFLINE = "robot_offline"
    LOW_BATTERY = "low_battery"
    WAITING_AT_TABLE = "waiting_at_table"
    DISH_WAITING = "dish_waiting"  # subject: the table whose dishes wait at the pass
    TABLE_UNREACHABLE = "table_unreachable"  # subject: the table
    ZONE_WAIT = "zone_wait"  # subject: the robot waiting for a zone (serveur.core.leases)
    ROBOT_LOST = "robot_lost"  # subject: the robot not sure where it is (core.localisation)
    CALL_WAITING = "call_waiting"  # subject: "<table>/<kind>", a guest's call nobody answered
    NOT_CHARGING = "not_charging"  # subject: the robot on its dock whose battery does not rise
    TICKET_UNREAD = "ticket_unread"  # subject: "ticket <id>", a till's ticket not understood
    PRINTER_DOWN = "printer_down"  # subject: the kitchen printer's address (host:port)


class Alert(_Record):
    """One alert as screens see it (``alerts`` topic). ``cleared_at`` set: it is over."""

    id: int
    kind: AlertKind
    subject: str
    severity: str
    message: str
    raised_at: float
    acked_at: float | None = None
    acked_by: str | None = None
    cleared_at: float | None = None


class MenuItem(_Record):
    """A dish the console offers. ``price_cents`` is optional (many sites keep prices in the
    POS); ``available`` False hides a dish that ran out without losing its place."""

    dish: str
    category: str = ""
    price_cents: int | None = None
    available: bool = True
    position: int = 0


class TableBlock(_Record):
    """A table no robot is sent to: a robot could not reach it (``reason``), until staff clear
    it."""

    table: str
    reason: str
    robot: str | None = None
    since: float


class ZoneRecord(_Record):
    """A part of the room leased to at most ``capacity`` robots at a time (an aisle, a
    doorway, the pass): a polygon of map points, in metres (serveur.core.leases)."""

    name: str
    points: list[tuple[float, float]]
    capacity: int = 1
    wait_at: str | None = Field(
        default=None,
        description="a waypoint outside the zone: a robot standing in the zone that cannot get"
        " the other zones of its next leg goes there to wait, so it holds nothing meanwhile",
    )
    updated_at: float = 0.0
    removed: bool = Field(default=False, description="true only in the update saying so")

    @field_validator("points", mode="before")
    @classmethod
    def _points_from_json(cls, v: Any) -> Any:
        return json.loads(v) if isinstance(v, str) else v


class ZoneLease(_Record):
    """A zone's leases now (the ``leases`` topic): who holds it, who waits for it."""

    zone: str
    capacity: int
    holders: list[str]
    waiting: list[str]


class WaypointRecord(_Record):
    """A named map pose: a table's serving spot, a robot's home, the kitchen pass."""

    name: str
    x: float
    y: float
    yaw: float = 0.0
    kind: WaypointKind = WaypointKind.OTHER
    removed: bool = Field(
        default=False, description="true only in the update saying it was removed or renamed"
    )


class Order(_Record):
    """One dish for one table (``quantity`` plates of it). ``ready_at`` is when it was ready at
    the pass (None while ordered or cooking)."""

    id: int
    dish: str
    table: str
    status: OrderStatus = OrderStatus.PENDING
    task_id: int | None = None
    key: str | None = None
    ready_at: float | None = None
    dispatched_at: float | None = None
    delivered_at: float | None = None
    quantity: int = 1
    note: str | None = None
    ordered_at: float | None = None
    returned_at: float | None = None
    voided_at: float | None = None
    special: str | None = Field(
        default=None,
        description="a special delivery (a birthday): the message the robot shows at the table,"
        " where it plays a song and waits for Done",
    )
    tray: int | None = Field(default=None, description="the tray staff chose; None: the plan's")
    ticket: int | None = Field(
        default=None, description="the till's ticket it came from (serveur.till); None: staff's"
    )


class TicketStatus(StrEnum):
    """What became of a ticket from the till."""

    UNREAD = "unread"  # not understood: staff see it as it printed
    ORDERED = "ordered"  # its dishes are orders
    REPRINT = "reprint"  # printed again: the first one's orders stand (of_ticket)
    VOID = "void"  # it withdrew dishes
    BY_HAND = "by_hand"  # staff added its dishes themselves


class TillTicket(_Record):
    """One ticket the till printed (or an order-intake request), as printed, what the
    owner's ticket pattern read on it and what became of it."""

    id: int
    job: int
    part: int = 0
    source: str
    received_at: float
    lines: list[str]
    status: TicketStatus = TicketStatus.UNREAD
    key: str | None = None
    table: str | None = None
    reading: dict[str, Any] | None = None
    problem: str | None = None
    of_ticket: int | None = None
    read_at: float | None = None
    handled_by: str | None = None


class CallKind(StrEnum):
    """What a guest calls for."""

    PLATES = "plates"  # a robot to take the used dishes (answered by a bussing trip)
    WAITER = "waiter"
    BILL = "bill"


class Call(_Record):
    """A guest's call from a table: open until staff (or the robot sent) answer it, or staff
    cancel it. ``presses``: how many presses were merged into it."""

    id: int
    table: str
    kind: CallKind
    source: str = Field(description='"table" (its screen), "staff", or "button:<name>"')
    opened_at: float
    presses: int = 1
    escalated_at: float | None = None
    answered_at: float | None = None
    answered_by: str | None = None
    cancelled_at: float | None = None
    cancelled_by: str | None = None
    task_id: int | None = Field(default=None, description="the bussing trip sent for it")


class CallButton(_Record):
    """A Wi-Fi call button (ESPHome, Tasmota, Shelly...): it calls ``kind`` to ``table`` with
    an HTTP request carrying its token. The token is shown once, when it is made."""

    name: str
    table: str
    kind: CallKind
    created_at: float
    revoked_at: float | None = None
    last_press: float | None = None


class Stop(_Record):
    """One table on a trip, with the ids of the dishes for it."""

    seq: int
    table: str
    status: StopStatus = StopStatus.PENDING
    purpose: StopPurpose = StopPurpose.DELIVER
    orders: list[int] = Field(default_factory=list)
    arrived_at: float | None = None
    done_at: float | None = None


class Task(_Record):
    """One trip of one robot: stops in visiting order; ``current_stop`` indexes ``stops``."""

    id: int
    robot: str | None = None
    kind: TaskKind = TaskKind.DELIVERY
    status: TaskStatus = TaskStatus.QUEUED
    stops: list[Stop] = Field(default_factory=list)
    current_stop: int = 0
    created_at: float
    started_at: float | None = None
    finished_at: float | None = None


class EventRecord(_Record):
    """One recorded state change (audit trail and replay analysis)."""

    id: int
    ts: float
    kind: str
    robot: str | None = None
    task_id: int | None = None
    order_id: int | None = None
    data: dict[str, object] = Field(default_factory=dict)


class AuditRecord(_Record):
    """One instruction as given: who (``actor``, ``role``), from where (``peer``), what, and
    how it ended (``outcome``: ``ok`` or the error code). Security trail, owner-readable."""

    id: int
    ts: float
    actor: str
    role: str
    peer: str
    verb: str
    target: str | None = None
    outcome: str
    data: dict[str, object] = Field(default_factory=dict)
