"""The statistics as JSON: what ``serveur stats --json`` prints and the ``stats`` verb replies.

One shape for both, so a script reading the command and the console reading the protocol see
the same figures (they are the same computation, :mod:`serveur.stats.compute`). Seconds and
metres are numbers; a figure with nothing to measure (NaN in the computation) is ``null``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

from serveur.stats.compute import FIELDS, Figures, RobotFigures, ServiceLog, Trip

__all__ = ["figures_document", "trips_document", "trips_in"]

_ROBOT_FIELDS = (
    "busy_s",
    "online_s",
    "busy_share",
    "loading_s",
    "trips",
    "errors",
    "link_drops",
    "distance_m",
)


def _num(v: Any) -> Any:
    if isinstance(v, float):
        return round(v, 3) if math.isfinite(v) else None
    return v


def _robot(r: RobotFigures) -> dict[str, Any]:
    return {"robot": r.robot, **{k: _num(getattr(r, k)) for k in _ROBOT_FIELDS}}


def _figures(f: Figures) -> dict[str, Any]:
    return {
        "period": f.period.label,
        "start": f.period.start,
        "end": f.period.end,
        **{k: _num(getattr(f, k)) for k in FIELDS},
        "robots": [_robot(r) for r in f.robots],
    }


def figures_document(rows: Sequence[Figures], total: Figures) -> dict[str, Any]:
    """Each period's figures and the whole range's (``total``)."""
    return {"periods": [_figures(f) for f in rows], "total": _figures(total)}


def trips_in(log: ServiceLog, start: float | None, end: float | None) -> list[Trip]:
    """The trips that started (or, never started, were created) in ``[start, end)``."""
    lo = -math.inf if start is None else start
    hi = math.inf if end is None else end
    return [t for t in log.trips.values() if lo <= (t.started or t.created) < hi]


def trips_document(
    log: ServiceLog, start: float | None, end: float | None, *, limit: int = 1000
) -> dict[str, Any]:
    """The trip history of ``[start, end)``: the latest ``limit`` trips, oldest first, each
    with its stops and their dishes."""
    trips = trips_in(log, start, end)
    out = []
    for t in trips[-limit:]:
        stops = []
        for s in t.stops:
            dishes = [
                {"order": oid, "dish": log.dishes[oid].dish if oid in log.dishes else ""}
                for oid in s.orders
            ]
            stops.append(
                {
                    "table": s.table,
                    "purpose": s.purpose,
                    "arrived": s.arrived,
                    "ended": s.ended,
                    "outcome": s.outcome,
                    "reason": s.reason,
                    "by": s.by,
                    "dishes": dishes,
                }
            )
        out.append(
            {
                "id": t.id,
                "kind": t.kind,
                "robot": t.robot,
                "handed_over": t.handed_over,
                "status": t.status,
                "created": t.created,
                "started": t.started,
                "left": t.left,
                "ended": t.ended,
                "loading_s": _num(t.loading),
                "delivered": t.delivered,
                "returned": t.returned,
                "stops": stops,
            }
        )
    return {"trips": out, "more": len(trips) > limit}
