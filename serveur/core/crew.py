"""What every robot's controller works with: the collaborators the core builds once and passes
to each :class:`~serveur.core.robot.RobotController`.

One frozen bundle instead of a dozen constructor arguments, and no back-reference to the core:
a controller reaches the store, the trips, the service, the zones and the screens through
these, each an object testable on its own.
"""

from __future__ import annotations

import ssl
from collections.abc import Awaitable, Callable
from dataclasses import dataclass

from serveur.clock import Clock
from serveur.core.call_desk import CallDesk
from serveur.core.hub import Hub
from serveur.core.link_reports import LinkReports
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig
from serveur.core.service import Service
from serveur.core.traffic import Traffic
from serveur.core.trips import Trips
from serveur.domain import Robot, Task
from serveur.store.base import Store

__all__ = ["Crew"]


@dataclass(frozen=True, slots=True)
class Crew:
    """The shared collaborators of the robots' controllers."""

    store: Store
    clock: Clock
    config: CoreConfig
    hub: Hub
    places: Places
    publisher: Publisher
    service: Service
    trips: Trips
    traffic: Traffic
    reports: LinkReports
    #: Guests' calls: a bussing robot at a table answers the plates call it was sent for.
    calls: CallDesk
    #: Every robot's record as stored (name -> Robot), shared with :class:`Trips`, which
    #: writes the record back after each trip step.
    records: dict[str, Robot]
    #: Let the dispatcher look at the queue again (a robot became free, trays changed...).
    kick: Callable[[], None]
    #: A robot whose delivery just ended may take a queued bussing trip on its way back
    #: (``Core.chain_bussing``): the trip taken, or None (home).
    chain: Callable[[str], Awaitable[Task | None]]
    #: How links verify ``wss://`` robots (None: the system trust store).
    robot_ssl: ssl.SSLContext | None = None
