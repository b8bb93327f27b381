"""What the chain's dashboard shows of a site, read from the events the centre stored (pure).

The same events as the site's own, so the same code: the figures and the trip history are
:mod:`serveur.stats` (``read_events``, ``table``, the documents ``serveur stats --json``
prints), not a second bookkeeping; a site's figures here equal its own ``serveur stats``.
The robots and the open alerts are the last word of their events: a robot's last status
event, the alerts raised and not cleared.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from datetime import tzinfo
from typing import Any

from serveur.domain import EventRecord
from serveur.stats.compute import ServiceLog, read_events, table
from serveur.stats.document import figures_document, trips_document
from serveur.stats.periods import period_of

__all__ = ["SiteView", "open_alerts", "robots_now"]


def robots_now(events: Iterable[EventRecord]) -> list[dict[str, Any]]:
    """Each robot's last status (and since when), by name; a removed robot is gone."""
    robots: dict[str, dict[str, Any]] = {}
    for e in events:
        if e.robot is None:
            continue
        if e.kind == "robot.removed":
            robots.pop(e.robot, None)
            continue
        status = e.data.get("status")
        if isinstance(status, str):
            was = robots.get(e.robot)
            since = was["since"] if was is not None and was["status"] == status else e.ts
            robots[e.robot] = {
                "robot": e.robot,
                "status": status,
                "since": since,
                "error": e.data.get("last_error"),
            }
    return [robots[name] for name in sorted(robots)]


def open_alerts(events: Iterable[EventRecord]) -> list[dict[str, Any]]:
    """The alerts raised and not cleared yet, oldest first (acknowledged ones say by whom)."""
    alerts: dict[object, dict[str, Any]] = {}
    for e in events:
        ident = e.data.get("alert")
        if e.kind == "alert.raised":
            alerts[ident] = {
                "alert": ident,
                "kind": e.data.get("kind"),
                "subject": e.data.get("subject"),
                "message": e.data.get("message"),
                "since": e.ts,
                "acked_by": None,
            }
        elif e.kind == "alert.cleared":
            alerts.pop(ident, None)
        elif e.kind == "alert.acked" and ident in alerts:
            alerts[ident]["acked_by"] = e.data.get("by")
    return list(alerts.values())


class SiteView:
    """One site's events as the centre holds them, and what the dashboard reads of them.

    Kept in memory and extended with each newly stored part (``extend``), so a dashboard
    refresh reads nothing twice from the database."""

    def __init__(self, site: str) -> None:
        self.site = site
        self.events: list[EventRecord] = []
        self.seq = 0
        self._log: tuple[int, ServiceLog] | None = None  # read at ``seq``

    def log(self) -> ServiceLog:
        """The events read back into dishes, trips and timelines: once per new stored part,
        not at every dashboard refresh (the figures, trips and summary only read it)."""
        if self._log is None or self._log[0] != self.seq:
            self._log = (self.seq, read_events(self.events))
        return self._log[1]

    def extend(self, numbered: Sequence[tuple[int, EventRecord]]) -> None:
        for seq, event in numbered:
            if seq == self.seq + 1:
                self.events.append(event)
                self.seq = seq

    def figures(
        self,
        by: str,
        tz: tzinfo | None,
        *,
        start: float | None = None,
        end: float | None = None,
        day_start: int = 4,
    ) -> dict[str, Any]:
        rows, total = table(self.log(), by, tz, start=start, end=end, day_start=day_start)
        return figures_document(rows, total)

    def trips(self, start: float | None, end: float | None, limit: int = 200) -> dict[str, Any]:
        return trips_document(self.log(), start, end, limit=limit)

    def summary(self, now: float, tz: tzinfo | None, day_start: int = 4) -> dict[str, Any]:
        """Robots, open alerts and the current service day's figures (the overview's row)."""
        day = period_of(now, "day", tz, day_start)
        today = self.figures("day", tz, start=day.start, end=day.end, day_start=day_start)
        return {
            "robots": robots_now(self.events),
            "alerts": open_alerts(self.events),
            "today": today["total"],
            "last_event_at": self.events[-1].ts if self.events else None,
        }
