"""Values the server core and its collaborators share: tunables, destinations, a robot's runtime.

They live apart from :mod:`serveur.core.engine` so that the core's collaborators
(:mod:`serveur.core.link_reports`, :mod:`serveur.core.trips`, :mod:`serveur.core.creation`)
can name them without importing the core, which imports them.
"""

from __future__ import annotations

import asyncio
from dataclasses import dataclass, field

from serveur.core.events import RobotEvent
from serveur.core.localisation import Localisation
from serveur.core.modes import ChargeWatch
from serveur.domain import StopPurpose, TaskKind
from serveur.robots.driver import RobotDriver
from serveur.status import RobotState

__all__ = ["CoreConfig", "Destination", "Runtime", "pose_dict"]


@dataclass
class CoreConfig:
    """Tunables; times are simulated seconds."""

    capacity: int = 4
    heartbeat: float = 1.0
    ack_timeout: float = 2.0
    ack_retries: int = 2
    arrive_tolerance: float = 0.35  # a robot this close to its goal is "there" (reconciliation)
    far_tolerance: float = 0.6  # SUCCEEDED this far from the goal is an error, not an arrival
    pose_persist_period: float = 5.0
    #: rosbridge throttles (ms) of a moving robot's unwatched pose, move_base status and the
    #: battery; 0 for real robots, raised by accelerated replays (serveur.replay.service).
    moving_pose_ms: int = 0
    status_ms: int = 0
    battery_ms: int = 0
    robot_radius: float = 0.2
    #: A robot Offline this long (simulated seconds) with a trip has the trip handed to another
    #: robot; ``None`` never hands over. Two minutes: long enough for a Wi-Fi dead spot or a
    #: rosbridge restart (seconds) to resume in place, short enough that food is still warm
    #: when the kitchen re-plates it for another robot.
    handover_after: float | None = 120.0
    #: "serveur": trips by area, stops in shortest-route order (scheduler.plan_trips);
    #: "baseline": the design report's behaviour, stops in the order of the cart (replay A/B).
    policy: str = "serveur"
    #: False (the default, as on commercial waiter robots): a trip given to a robot waits at
    #: the pass (Loading) until staff have loaded the trays and press Go. True: it leaves at
    #: once (a site where the kitchen loads as the trip is planned, and the replay's A/B runs).
    auto_depart: bool = False
    #: A robot waiting at a table this long (simulated s) without "food collected" skips it:
    #: the dishes are returned to the pass. None: it waits for ever. Three minutes: a party
    #: that has not taken its food by then is away from the table or did not notice.
    table_timeout: float | None = 180.0
    #: When conditions become alerts (serveur.core.alerts.Thresholds).
    alert_offline_after: float = 10.0
    alert_low_battery: float = 0.20
    alert_wait_at_table: float = 90.0
    alert_dish_at_pass: float = 120.0
    alert_zone_wait: float = 60.0
    #: Zones are leased (serveur.core.leases) when the owner has drawn any; False ignores
    #: them (the replay's "without leases" runs).
    leases: bool = True
    #: Guests' calls (serveur.core.calls): a call nobody answered this long (s) is escalated
    #: (every console rings louder, an alert is raised). Two minutes: a waiter on the floor
    #: answers within one; the hospitality call systems escalate after one to three.
    call_escalate: float = 120.0
    #: Bussing: how long a robot waits at a table for the used dishes before it goes on by
    #: itself, and the most a bussing trip may hold back a dish waiting at the pass (s).
    bussing_wait: float = 120.0
    bussing_max_delay: float = 90.0
    #: Charging (serveur.core.charging): a free robot with a dock goes to charge below
    #: ``charge_below`` and comes back into service at ``charge_until`` (battery fractions).
    charge_below: float = 0.25
    charge_until: float = 0.90
    #: Cruise: seconds at each place of the round, and before going on once someone touched
    #: the robot's screen.
    cruise_pause: float = 20.0
    cruise_resume: float = 30.0
    #: The pages' languages (the owner's settings change them): offered, and the default.
    languages: tuple[str, ...] = ("en", "zh", "ms")
    language: str = "en"


@dataclass(frozen=True, slots=True)
class Destination:
    """Where a robot was last sent: the goal a SUCCEEDED result is checked against."""

    kind: str  # "table" | "place" (dish return, a cruise's) | "home" | "dock" | "manual"
    name: str
    x: float
    y: float
    yaw: float


@dataclass
class Runtime:
    """One robot's live state in this server process (the store holds what must survive it).

    ``lock`` serialises everything that touches the robot; ``events`` is its queue of link
    reports, drained in arrival order by ``worker`` (see :mod:`serveur.core.link_reports`).
    """

    name: str
    state: RobotState
    link: RobotDriver | None = None
    lock: asyncio.Lock = field(default_factory=asyncio.Lock)
    events: asyncio.Queue[RobotEvent] = field(default_factory=asyncio.Queue)
    worker: asyncio.Task[None] | None = None
    dest: Destination | None = None
    goal_id: str | None = None
    idle_since: float = 0.0
    pose: tuple[float, float, float] | None = None
    battery: float | None = None
    pose_saved_at: float = -1e9
    #: (x, y, yaw, battery) the store was last asked to keep: a parked robot's is not
    #: written again every period (serveur.core.link_reports.worth_saving).
    pose_saved: tuple[float, float, float, float | None] | None = None
    handover: asyncio.Task[None] | None = None  # the hand-over timer while Offline with a trip
    offline_since: float | None = None  # epoch (clock) the robot was last seen, while Offline
    link_started: float | None = None  # epoch (clock) its link was last (re)started
    #: The status (its status_since) a timer's event was last posted for: a table timeout, a
    #: cruise's resume, going to charge or back from it; one each, since each ends its status.
    posted_for: float | None = None
    link_error: str | None = None  # the link's last connection failure, until it connects
    waiting_for: list[str] | None = None  # zones it waits to be leased (its goal not sent)
    waiting_since: float | None = None  # clock.epoch() it started waiting
    resume_dest: Destination | None = None  # where it goes once back from a zone's waiting spot
    odometer_at: tuple[float, float] | None = None  # where the odometer last counted from
    odometer: float = 0.0  # metres driven since this server started (in each status event)
    #: How sure it is of where it is (lost: no trips, an alert); from its poses' spread.
    localisation: Localisation = field(default_factory=Localisation)
    #: What its trip is for, and what it does at the stop it stands at (None: no trip, or not
    #: at a stop): the screens' words and how long it waits there (serveur.core.modes).
    trip_kind: TaskKind | None = None
    at_stop: StopPurpose | None = None
    special: bool = False  # a special delivery (a birthday) at this stop: no timeout
    to_dock: bool = False  # its Transit is to its dock, not home
    #: Whether its battery rises while on the dock (serveur.core.modes.ChargeWatch).
    charge_watch: ChargeWatch = field(default_factory=ChargeWatch)
    not_charging: bool = False


def pose_dict(pose: tuple[float, float, float], stamp: float) -> dict[str, float]:
    """A pose as the ``pose:<robot>`` topic carries it."""
    return {"x": pose[0], "y": pose[1], "yaw": pose[2], "stamp": stamp}
