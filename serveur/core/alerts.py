"""Alerts: what staff must see on every screen, raised once, acknowledged, cleared (pure; no I/O).

A robot in Error, gone Offline, low on battery, waiting at a table long past the usual; dishes
standing at the pass; a table no robot could reach. Before this module such a robot only
changed colour in one row of the map tab. An alert is *raised once* when its condition starts
(not every second while it lasts), *acknowledged* by a person (who and when are kept: "Ana saw
it at 19:42"), and *cleared* when the condition ends, acknowledged or not — an alert that
outlives its cause teaches staff to ignore alerts. This mirrors how Home Assistant logs a
device's availability: once down, once up.

:func:`conditions` turns a snapshot of the restaurant into the set of conditions that hold now;
:class:`AlertBook` compares it with the alerts already raised. The core's watch loop
(:mod:`serveur.core.watch`) feeds both every second of the service clock and publishes what
changed.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from dataclasses import dataclass

from serveur.domain import Alert, AlertKind, Call
from serveur.errors import Conflict, NotFound
from serveur.status import RobotMode, RobotStatus

__all__ = [
    "Alert",
    "AlertBook",
    "AlertKind",
    "DishFact",
    "RobotFact",
    "Thresholds",
    "TillFacts",
    "conditions",
]


#: Kinds that need someone now (the console sounds them); the others are warnings.
CRITICAL = frozenset(
    {
        AlertKind.ROBOT_ERROR,
        AlertKind.ROBOT_OFFLINE,
        AlertKind.TABLE_UNREACHABLE,
        AlertKind.ROBOT_LOST,
        AlertKind.CALL_WAITING,
        AlertKind.PRINTER_DOWN,
    }
)


@dataclass(frozen=True, slots=True)
class Thresholds:
    """When a condition becomes an alert (service-clock seconds; battery 0..1)."""

    offline_after: float = 10.0  # a Wi-Fi blip is not an alert
    low_battery: float = 0.20
    battery_ok: float = 0.25  # cleared only above this: no flapping around the threshold
    wait_at_table: float = 90.0
    dish_at_pass: float = 120.0
    zone_wait: float = 60.0  # a leg usually waits seconds for an aisle; a minute is stuck


@dataclass(frozen=True, slots=True)
class RobotFact:
    name: str
    status: RobotStatus
    mode: RobotMode
    since: float  # when it entered ``status``
    battery: float | None
    table: str | None = None  # the table it is at or going to
    error: str | None = None
    waiting_for: tuple[str, ...] = ()  # zones it waits to be leased
    waiting_since: float | None = None
    blockers: tuple[str, ...] = ()  # the robots it waits behind
    lost: bool = False  # not sure where it is (serveur.core.localisation)
    not_charging: bool = False  # on its dock, its battery not rising (serveur.core.modes)
    #: At a stop where it waits for people (dishes taken, a birthday's Done, emptied at the
    #: dish return): a long wait is an alert. Collecting plates and a cruise's pause are the
    #: robot's own waits (it goes on by itself): no alert.
    waits_for_people: bool = True


@dataclass(frozen=True, slots=True)
class DishFact:
    table: str
    ready_at: float


Key = tuple[AlertKind, str]


def _minutes(seconds: float) -> str:
    m = int(seconds // 60)
    return f"{m} min" if m >= 1 else f"{int(seconds)} s"


@dataclass(frozen=True, slots=True)
class TillFacts:
    """What the alerts need of the till: the unread tickets, the kitchen printer that does
    not answer (its address)."""

    unread: tuple[int, ...] = ()
    printer_down: str | None = None


def conditions(
    robots: Iterable[RobotFact],
    dishes: Iterable[DishFact],
    blocked: Mapping[str, str],
    *,
    now: float,
    active: Iterable[Key] = (),
    limits: Thresholds = Thresholds(),
    calls: Iterable[Call] = (),
    till: TillFacts | None = None,
) -> dict[Key, str]:
    """The alert conditions that hold at ``now``, each with the message staff read.

    ``blocked`` maps a blocked table to why; ``active`` are the keys raised already (the
    battery alert clears only above ``battery_ok``). Dishes for a blocked table are not
    "waiting at the pass": the table's own alert says why they wait.
    """
    active = set(active)
    out: dict[Key, str] = {}
    for r in robots:
        if r.status is RobotStatus.ERROR:
            out[(AlertKind.ROBOT_ERROR, r.name)] = f"{r.name} is stuck" + (
                f": {r.error}" if r.error else ""
            )
        if r.lost and r.status is not RobotStatus.OFFLINE:
            out[(AlertKind.ROBOT_LOST, r.name)] = (
                f"{r.name} is not sure where it is: set where the robot is on the map"
            )
        if r.status is RobotStatus.OFFLINE and now - r.since >= limits.offline_after:
            out[(AlertKind.ROBOT_OFFLINE, r.name)] = f"{r.name} is not connected"
        if r.battery is not None:
            key = (AlertKind.LOW_BATTERY, r.name)
            limit = limits.battery_ok if key in active else limits.low_battery
            if r.battery < limit:
                out[key] = f"{r.name} battery {round(r.battery * 100)}%"
        if (
            r.status is RobotStatus.DELIVERED
            and r.waits_for_people
            and now - r.since >= limits.wait_at_table
        ):
            where = f" at {r.table}" if r.table else ""
            out[(AlertKind.WAITING_AT_TABLE, r.name)] = (
                f"{r.name} waiting{where} for {_minutes(now - r.since)}"
            )
        if r.not_charging:
            out[(AlertKind.NOT_CHARGING, r.name)] = (
                f"{r.name} is on its dock but not charging: check the dock is plugged in and"
                " the robot sits on its contacts"
            )
        if r.waiting_for and r.waiting_since is not None:
            waited = now - r.waiting_since
            if waited >= limits.zone_wait:
                behind = f" (held by {', '.join(r.blockers)})" if r.blockers else ""
                out[(AlertKind.ZONE_WAIT, r.name)] = (
                    f"{r.name} has waited {_minutes(waited)} for {', '.join(r.waiting_for)}{behind}"
                )
    oldest: dict[str, float] = {}
    for d in dishes:
        if d.table not in blocked:
            oldest[d.table] = min(oldest.get(d.table, d.ready_at), d.ready_at)
    for table, ready_at in oldest.items():
        if now - ready_at >= limits.dish_at_pass:
            out[(AlertKind.DISH_WAITING, table)] = (
                f"dishes for {table} at the pass for {_minutes(now - ready_at)}"
            )
    for table, reason in blocked.items():
        out[(AlertKind.TABLE_UNREACHABLE, table)] = f"robots cannot reach {table}: {reason}"
    for c in calls:  # escalated by the call desk (the site's call_escalate)
        words = {"plates": "a robot for the plates", "waiter": "a waiter", "bill": "the bill"}
        out[(AlertKind.CALL_WAITING, f"{c.table}/{c.kind.value}")] = (
            f"{c.table} asked for {words.get(c.kind.value, c.kind.value)}"
            f" {_minutes(now - c.opened_at)} ago"
        )
    till = till or TillFacts()
    for ticket in till.unread:
        out[(AlertKind.TICKET_UNREAD, f"ticket {ticket}")] = (
            f"ticket {ticket} from the till was not understood: add its dishes by hand, or fix"
            " the pattern"
        )
    if till.printer_down is not None:
        out[(AlertKind.PRINTER_DOWN, till.printer_down)] = (
            "the kitchen printer does not answer: the till is told its tickets did not print"
        )
    return out


class AlertBook:
    """The alerts raised and not yet cleared; numbering is per server run."""

    def __init__(self) -> None:
        self._active: dict[Key, Alert] = {}
        self._by_id: dict[int, Key] = {}
        self._next = 1

    def active(self) -> list[Alert]:
        """Alerts not cleared, oldest first."""
        return sorted(self._active.values(), key=lambda a: a.id)

    def keys(self) -> set[Key]:
        return set(self._active)

    def update(self, now_holding: Mapping[Key, str], now: float) -> list[Alert]:
        """Raise the conditions that are new, clear the alerts whose condition ended; the
        alerts that changed (cleared ones with ``cleared_at`` set), for publishing."""
        changed: list[Alert] = []
        for key in [k for k in self._active if k not in now_holding]:
            alert = self._active.pop(key).model_copy(update={"cleared_at": now})
            del self._by_id[alert.id]
            changed.append(alert)
        for key, message in now_holding.items():
            if key in self._active:
                continue
            kind, subject = key
            alert = Alert(
                id=self._next,
                kind=kind,
                subject=subject,
                severity="critical" if kind in CRITICAL else "warning",
                message=message,
                raised_at=now,
            )
            self._next += 1
            self._active[key] = alert
            self._by_id[alert.id] = key
            changed.append(alert)
        return changed

    def ack(self, alert_id: int, by: str, now: float) -> Alert:
        """A person has seen the alert. Unknown or cleared: NotFound; seen already: Conflict."""
        key = self._by_id.get(alert_id)
        if key is None:
            raise NotFound(f"no alert {alert_id} is raised (cleared already?)", alert=alert_id)
        alert = self._active[key]
        if alert.acked_at is not None:
            raise Conflict(
                f"alert {alert_id} was acknowledged already by {alert.acked_by}",
                alert=alert_id,
                acked_by=alert.acked_by,
            )
        alert = alert.model_copy(update={"acked_at": now, "acked_by": by})
        self._active[key] = alert
        return alert
