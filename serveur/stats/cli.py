"""``serveur stats``: the statistics and trip history of past services, as tables or CSV.

:mod:`serveur.cli` registers the subcommand through :func:`add_stats_parser`; the store is
opened only when the command runs. What each figure means: docs/statistics.md.
"""

from __future__ import annotations

import argparse
import asyncio
import csv
import json
import math
import os
import sys
from collections.abc import Sequence
from datetime import tzinfo
from pathlib import Path
from typing import TYPE_CHECKING, TextIO

from serveur.domain import EventRecord
from serveur.errors import ServeurError
from serveur.stats.periods import BY, local, parse_offset, parse_when

if TYPE_CHECKING:  # the computation is imported when the command runs
    from serveur.stats.compute import Figures, ServiceLog

__all__ = ["add_stats_parser", "render", "trip_rows", "write_csv"]


# -- formatting ------------------------------------------------------------------------------


def _s(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{round(v):d} s"


def _min(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v / 60:.1f} min"


def _x(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{v:.1f}"


def _pct(v: float) -> str:
    return "-" if not math.isfinite(v) else f"{100 * v:.0f} %"


def _grid(title: str, head: Sequence[str], rows: Sequence[Sequence[str]]) -> str:
    widths = [
        max(len(h), *(len(r[i]) for r in rows)) if rows else len(h) for i, h in enumerate(head)
    ]
    line = "  ".join(
        f"{h:<{w}}" if i == 0 else f"{h:>{w}}"
        for i, (h, w) in enumerate(zip(head, widths, strict=True))
    )
    out = [title, line, "-" * len(line)]
    for r in rows:
        out.append(
            "  ".join(
                f"{c:<{w}}" if i == 0 else f"{c:>{w}}"
                for i, (c, w) in enumerate(zip(r, widths, strict=True))
            )
        )
    return "\n".join(out) + "\n"


def render(rows: Sequence[Figures], total: Figures) -> str:
    """The figures as readable tables: dishes, trips, robots (each period, then the total
    when there are several), and calls and bussing trips when the range has any."""
    every = [*rows, total] if len(rows) != 1 else list(rows)
    dishes = [
        [
            f.period.label,
            str(f.delivered),
            _s(f.wait_mean),
            _s(f.wait_p50),
            _s(f.wait_p95),
            _s(f.wait_max),
            _s(f.pass_mean),
            _s(f.pass_p95),
            str(f.returned),
            str(f.resent),
            str(f.voided),
        ]
        for f in every
    ]
    trips = [
        [
            f.period.label,
            str(f.trips),
            str(f.trips_cancelled),
            _x(f.tables_per_trip),
            _x(f.dishes_per_trip),
            _min(f.loading_s),
            _s(f.loading_per_trip),
            str(f.table_timeouts),
            str(f.staff_skips),
        ]
        for f in every
    ]
    robots = [
        [
            f.period.label,
            r.robot,
            _min(r.busy_s),
            _pct(r.busy_share),
            _min(r.loading_s),
            str(r.trips),
            str(r.errors),
            str(r.link_drops),
            f"{r.distance_m:.0f} m",
        ]
        for f in every
        for r in f.robots
    ]
    tables = [
        _grid(
            "Dishes (wait: first ready at the pass -> food collected; on the pass: ready "
            "-> a robot took its trip)",
            [
                "period",
                "delivered",
                "wait mean",
                "p50",
                "p95",
                "max",
                "on pass mean",
                "p95",
                "returned",
                "re-sent",
                "voided",
            ],
            dishes,
        ),
        _grid(
            "Trips (deliveries finished; loading: robots Loading at the pass until Go)",
            [
                "period",
                "trips",
                "cancelled",
                "tables/trip",
                "dishes/trip",
                "loading",
                "per trip",
                "timeouts",
                "skips",
            ],
            trips,
        ),
        _grid(
            "Robots (busy: on a trip or going home; share of the time online; distance: "
            "the server's odometer)",
            [
                "period",
                "robot",
                "busy",
                "busy %",
                "loading",
                "trips",
                "errors",
                "link drops",
                "distance",
            ],
            robots,
        ),
    ]
    if any(f.calls or f.bussing_trips or f.bussing_cancelled for f in every):
        tables.append(_calls_grid(every))
    return "\n".join(tables)


def _p(p50: float, p90: float) -> str:
    return f"{_s(p50)} / {_s(p90)}"


def _calls_grid(every: Sequence[Figures]) -> str:
    """Guests' calls and bussing trips (shown only when the range has any)."""
    rows = [
        [
            f.period.label,
            str(f.calls_plates),
            str(f.calls_waiter),
            str(f.calls_bill),
            _p(f.answer_p50, f.answer_p90),
            _p(f.answer_p50_plates, f.answer_p90_plates),
            _p(f.answer_p50_waiter, f.answer_p90_waiter),
            _p(f.answer_p50_bill, f.answer_p90_bill),
            str(f.calls_escalated),
            str(f.calls_cancelled),
            str(f.bussing_trips),
            _p(f.call_to_robot_p50, f.call_to_robot_p90),
        ]
        for f in every
    ]
    return _grid(
        "Calls (opened, per kind; answer: p50 / p90 from the call to its answer, per kind) and "
        "bussing trips (finished; robot: p50 / p90 from a plates call to the robot at the table)",
        [
            "period",
            "plates",
            "waiter",
            "bill",
            "answer: all",
            "plates",
            "waiter",
            "bill",
            "escalated",
            "cancelled",
            "bussing",
            "robot",
        ],
        rows,
    )


def _when(ts: float | None, tz: tzinfo | None) -> str:
    return "" if ts is None else local(ts, tz).strftime("%Y-%m-%d %H:%M:%S")


def _clock(ts: float | None, tz: tzinfo | None) -> str:
    return "-" if ts is None else local(ts, tz).strftime("%H:%M:%S")


def render_trips(log: ServiceLog, tz: tzinfo | None, start: float | None, end: float | None) -> str:
    """The trip history: each trip, then each stop with its dishes."""
    from serveur.stats.document import trips_in

    out: list[str] = []
    for t in trips_in(log, start, end):
        who = t.robot or "-"
        if t.handed_over:
            who += f" (handed over from {', '.join(t.handed_over)})"
        if t.kind == "delivery":
            kind, what = "", f"{t.tables} table(s), {t.delivered} delivered, {t.returned} returned"
        else:  # a bussing trip's tables (then the dish return), a cruise's places
            kind = f"{t.kind}  "
            n = sum(1 for s in t.stops if s.purpose in ("collect", "visit"))
            what = f"{n} {'table' if t.kind == 'bussing' else 'place'}(s)"
        out.append(
            f"trip {t.id}  {kind}{who}  {t.status}  created {_when(t.created, tz)}  "
            f"started {_clock(t.started, tz)}  left the pass {_clock(t.left, tz)} "
            f"(loading {_s(t.loading)})  ended {_clock(t.ended, tz)}  {what}"
        )
        for i, s in enumerate(t.stops):
            names = ", ".join(
                f"{oid} {log.dishes[oid].dish}".strip() if oid in log.dishes else str(oid)
                for oid in s.orders
            )
            why = f" ({s.reason})" if s.outcome == "skipped" and s.reason else ""
            to = "" if s.purpose == "deliver" else f" ({s.purpose})"
            out.append(
                f"  {i + 1}. {s.table:<6}{to} arrived {_clock(s.arrived, tz)}  "
                f"{s.outcome}{why} {_clock(s.ended, tz)}  dishes: {names or '-'}"
            )
    return "\n".join(out) + ("\n" if out else "no trip in this range\n")


def trip_rows(
    log: ServiceLog, tz: tzinfo | None, start: float | None, end: float | None
) -> list[dict[str, object]]:
    """The trip history for a CSV: one row per stop."""
    from serveur.stats.document import trips_in

    rows: list[dict[str, object]] = []
    for t in trips_in(log, start, end):
        for i, s in enumerate(t.stops):
            rows.append(
                {
                    "trip": t.id,
                    "kind": t.kind,
                    "robot": t.robot or "",
                    "status": t.status,
                    "created": _when(t.created, tz),
                    "started": _when(t.started, tz),
                    "left_pass": _when(t.left, tz),
                    "ended": _when(t.ended, tz),
                    "loading_s": t.loading,
                    "stop": i + 1,
                    "table": s.table,
                    "purpose": s.purpose,
                    "arrived": _when(s.arrived, tz),
                    "stop_ended": _when(s.ended, tz),
                    "outcome": s.outcome,
                    "reason": s.reason or "",
                    "by": s.by or "",
                    "at_table_s": (
                        s.ended - s.arrived if s.ended is not None and s.arrived is not None else ""
                    ),
                    "dishes": " ".join(str(o) for o in s.orders),
                }
            )
    return rows


def _cell(v: object) -> object:
    if isinstance(v, float):
        return "" if not math.isfinite(v) else round(v, 3)
    return v


def write_csv(rows: Sequence[dict[str, object]], out: TextIO) -> None:
    """``rows`` as CSV (NaN: an empty cell; seconds to the millisecond)."""
    if not rows:
        return
    w = csv.DictWriter(out, fieldnames=list(rows[0]), lineterminator="\n")
    w.writeheader()
    for r in rows:
        w.writerow({k: _cell(v) for k, v in r.items()})


def figure_rows(
    rows: Sequence[Figures], total: Figures, robots: Sequence[str], tz: tzinfo | None
) -> list[dict[str, object]]:
    out = []
    for f in [*rows, total]:
        r = f.row(robots)
        r["start"], r["end"] = _when(f.period.start, tz), _when(f.period.end, tz)
        out.append(r)
    return out


# -- the command -----------------------------------------------------------------------------


def _missing_file(db: str) -> bool:
    if db.startswith("sqlite://"):
        path = db[len("sqlite://") :]
    elif db.startswith("sqlite:"):
        path = db[len("sqlite:") :]
    elif "://" in db:
        return False
    else:
        path = db
    return not Path(path).exists()


async def _load(db: str) -> list[EventRecord]:
    from serveur.stats.load import load_events
    from serveur.store.factory import open_store

    async with open_store(db) as store:
        return await load_events(store)


def _cmd_stats(ns: argparse.Namespace) -> int:
    try:
        tz = None if ns.utc_offset is None else parse_offset(ns.utc_offset)
        start = None if ns.start is None else parse_when(ns.start, tz, ns.day_start)
        end = None if ns.end is None else parse_when(ns.end, tz, ns.day_start, end=True)
    except ValueError as exc:
        print(f"serveur stats: {exc}", file=sys.stderr)
        return 2
    if _missing_file(ns.db):  # opening it would create an empty database
        print(f"serveur stats: no database at {ns.db}", file=sys.stderr)
        return 2
    try:
        events = asyncio.run(_load(ns.db))
    except ServeurError as exc:
        print(f"serveur stats: {exc}", file=sys.stderr)
        return 1
    from serveur.stats.compute import read_events, table

    log = read_events(events)
    if ns.json:
        from serveur.stats.document import figures_document, trips_document

        if ns.trips:
            doc = trips_document(log, start, end)
        else:
            rows, total = table(log, ns.by, tz, start=start, end=end, day_start=ns.day_start)
            doc = figures_document(rows, total)
        json.dump(doc, sys.stdout, separators=(",", ":"))
        return 0
    if ns.trips:
        text = render_trips(log, tz, start, end)
        csv_rows = trip_rows(log, tz, start, end)
    else:
        rows, total = table(log, ns.by, tz, start=start, end=end, day_start=ns.day_start)
        text = render(rows, total)
        csv_rows = figure_rows(rows, total, log.robots, tz)
    if ns.csv == "-":
        write_csv(csv_rows, sys.stdout)
        return 0
    print(text, end="")
    if ns.csv:
        with open(ns.csv, "w", encoding="utf-8", newline="") as fh:
            write_csv(csv_rows, fh)
        print(f"CSV written to {ns.csv}")
    return 0


def add_stats_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur stats`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "stats",
        help="statistics and trip history of past services, from the events table",
        description="Dishes delivered, waits, time on the pass, loading, returned and voided "
        "dishes, trips, each robot's busy share and errors, guests' calls and the time to "
        "answer them, bussing trips, per hour or service day, from the server's events table "
        "(docs/statistics.md). Safe while the server runs.",
    )
    p.add_argument(
        "--db",
        default=os.environ.get("SERVEUR_DB", "./serveur.db"),
        help="the server's database: a SQLite file or URL, or mariadb://... "
        "(default: $SERVEUR_DB, else ./serveur.db)",
    )
    p.add_argument(
        "--from",
        dest="start",
        metavar="DATE",
        help="from this service day (2026-05-01) or instant (2026-05-01 18:30)",
    )
    p.add_argument(
        "--to",
        dest="end",
        metavar="DATE",
        help="to the end of this service day, or to this instant (excluded)",
    )
    p.add_argument("--by", choices=BY, default="day", help="one row per hour or service day")
    p.add_argument(
        "--utc-offset",
        metavar="+HH:MM",
        help="the restaurant's local time (default: this machine's time zone)",
    )
    p.add_argument(
        "--day-start",
        type=int,
        default=4,
        choices=range(24),
        metavar="H",
        help="a service day starts at this hour, local time (default 4: a dinner past "
        "midnight stays in its day)",
    )
    p.add_argument("--csv", metavar="FILE", help="also write the figures as CSV ('-': stdout)")
    p.add_argument(
        "--json",
        action="store_true",
        help="print the figures (or with --trips the trip history) as JSON, as the"
        " protocol's stats verb replies (docs/protocol.md)",
    )
    p.add_argument(
        "--trips",
        action="store_true",
        help="the trip history instead: each trip and its stops (CSV: one row per stop)",
    )
    p.set_defaults(func=_cmd_stats, is_async=False)
