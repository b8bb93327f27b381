"""When a robot's modes besides delivering move on by themselves (pure; no I/O).

* **How long a robot waits at a stop** (:func:`stop_wait`): at a table with dishes, the site's
  table timeout, then the dishes go back to the pass; at a table with a special delivery (a
  birthday), for ever — the robot waits for Done, the song is the point; collecting used
  dishes, the bussing wait, then it goes on with what it has; at the dish return, for ever
  (staff must empty it: a robot that leaves full comes back full); at a cruise's place, the
  cruise pause, then the next place.
* **Charging** (:func:`charge_due`, :func:`charged`, :class:`ChargeWatch`): a free robot with a
  dock below the site's level goes to charge; on the dock it stays until the upper level,
  then comes back into service. A robot on its dock whose battery does not rise is not
  charging (a dock unplugged, contacts missed — what robot fleets report most about
  charging): staff are told, once.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Final

from serveur.domain import StopPurpose
from serveur.status import RobotStatus

__all__ = [
    "RISE_WITHIN",
    "ChargeWatch",
    "charge_due",
    "charged",
    "stop_wait",
]

#: A charging robot's battery rises by at least ``RISE`` within ``RISE_WITHIN`` seconds: a
#: real waiter robot charges in 4-5 h, about 0.4 % a minute, so ten minutes show 4 %; 1 % is
#: beyond a gauge's noise and still far below it.
RISE_WITHIN: Final = 600.0
RISE: Final = 0.01


def stop_wait(
    purpose: StopPurpose,
    *,
    special: bool,
    table_timeout: float | None,
    bussing_wait: float,
    cruise_pause: float,
) -> float | None:
    """Seconds a robot waits at a stop before it goes on by itself; None: until told."""
    if purpose is StopPurpose.DELIVER:
        return None if special else table_timeout
    if purpose is StopPurpose.COLLECT:
        return bussing_wait
    if purpose is StopPurpose.VISIT:
        return cruise_pause
    return None  # UNLOAD: staff empty it


def charge_due(status: RobotStatus, battery: float | None, *, has_dock: bool, below: float) -> bool:
    """A free automatic robot with a dock and a battery under ``below`` goes to charge."""
    return status is RobotStatus.AWAITING and has_dock and battery is not None and battery < below


def charged(status: RobotStatus, battery: float | None, *, until: float) -> bool:
    """A robot on its dock charged to ``until`` comes back into service."""
    return status is RobotStatus.CHARGING and battery is not None and battery >= until


@dataclass
class ChargeWatch:
    """Is a docked robot's battery rising? Fed each battery report while on the dock."""

    since: float | None = None  # when it docked, or the last rise was seen
    level: float | None = None  # the level then

    def docked(self, now: float, battery: float | None) -> None:
        self.since, self.level = now, battery

    def left(self) -> None:
        self.since = self.level = None

    def not_charging(self, now: float, battery: float | None) -> bool:
        """True while on the dock with no rise of ``RISE`` for ``RISE_WITHIN`` seconds."""
        if self.since is None or battery is None:
            return False
        if self.level is None or battery >= self.level + RISE or battery >= 0.999:
            self.since, self.level = now, battery
            return False
        return now - self.since >= RISE_WITHIN
