"""Service statistics and trip history computed from the server's event records (pure).

:func:`read_events` replays the ``events`` table (oldest first) into a :class:`ServiceLog`:
every dish (first ready, on the pass, delivered, returned, sent again, voided), every trip
with its stops (deliveries, bussing trips, cruises), every guest's call (opened, answered,
cancelled, escalated), every robot's status spells. :func:`figures` gives the figures of one period
``[start, end)``, :func:`table` those of each hour or service day of a range and the range's
total. Nothing here reads a database or the clock: :mod:`serveur.stats.load` fetches the
events, and the tests feed hand-made ones.

Where each figure comes from is in docs/statistics.md. A robot's distance comes from the
server's odometer, written in each of its status events (serveur.core.link_reports): poses
themselves are not events.
"""

from __future__ import annotations

import math
from bisect import bisect_left
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import tzinfo

from serveur.domain import EventRecord
from serveur.stats.periods import Period, period_of

__all__ = [
    "BUSY",
    "CALL_KINDS",
    "CallRecord",
    "Dish",
    "Figures",
    "RobotFigures",
    "ServiceLog",
    "Span",
    "Stop",
    "Trip",
    "figures",
    "percentile",
    "read_events",
    "table",
]

#: Statuses in which a robot is out on service work (not free for a new trip): at the pass
#: being loaded, on its way, at a table, halted or failed on the way, going home.
BUSY = frozenset({"Loading", "Delivering", "Delivered", "Stopped", "Transit", "Error"})
#: What guests call for (serveur.domain.CallKind's values), in the figures' order.
CALL_KINDS = ("plates", "waiter", "bill")
#: Events a starting server writes before anything else: not a sign it was running before.
_STARTUP = frozenset(
    {"robot.restored", "robot.added", "robot.updated", "robot.trays", "waypoint.saved"}
)


def percentile(values: Sequence[float], q: float) -> float:
    """Nearest-rank percentile (the value one dish actually had; the replay's definition)."""
    if not values:
        return math.nan
    s = sorted(values)
    return s[max(0, math.ceil(q / 100.0 * len(s)) - 1)]


# -- records ---------------------------------------------------------------------------------


@dataclass
class Dish:
    """One order as the events tell it. ``ready``: the first time it was ready at the pass
    (a dish returned and sent again keeps it, as the store does)."""

    id: int
    dish: str = ""
    table: str = ""
    ready: float | None = None
    delivered: float | None = None
    trip: int | None = None
    voided: float | None = None
    returned: list[float] = field(default_factory=list)
    resent: list[float] = field(default_factory=list)
    #: Closed spells on the pass: (became pending, a robot took its trip).
    on_pass: list[tuple[float, float]] = field(default_factory=list)
    pending_since: float | None = None

    @property
    def wait(self) -> float | None:
        """Seconds from first ready to "food collected" (None: not delivered)."""
        if self.delivered is None or self.ready is None:
            return None
        return self.delivered - self.ready


@dataclass
class Stop:
    """One table of a trip. ``outcome``: ``pending``, ``done``, ``skipped`` (staff's skip or
    the table timeout: its dishes returned) or ``cancelled`` (the trip was given up first)."""

    table: str
    orders: list[int] = field(default_factory=list)
    purpose: str = "deliver"  # deliver, or a bussing trip's collect / unload, a cruise's visit
    arrived: float | None = None
    ended: float | None = None
    outcome: str = "pending"
    reason: str | None = None
    by: str | None = None


@dataclass
class Trip:
    """One task. ``started``: a robot took it (it is Loading at the pass from then);
    ``left``: Go (or an immediate dispatch); ``ended``: finished or cancelled. ``kind``:
    ``delivery``, ``bussing`` or ``cruise`` (``task.created``'s)."""

    id: int
    created: float
    kind: str = "delivery"
    robot: str | None = None
    handed_over: list[str] = field(default_factory=list)
    started: float | None = None
    left: float | None = None
    ended: float | None = None
    status: str = "queued"
    loading: float = 0.0
    stops: list[Stop] = field(default_factory=list)

    @property
    def tables(self) -> int:
        return len(self.stops)

    @property
    def delivered(self) -> int:
        return sum(len(s.orders) for s in self.stops if s.outcome == "done")

    @property
    def returned(self) -> int:
        return sum(len(s.orders) for s in self.stops if s.outcome == "skipped")

    @property
    def dishes(self) -> int:
        """Dishes it carried out: delivered, or returned from a skipped table."""
        return self.delivered + self.returned

    def stop(self, table: str) -> Stop:
        for s in self.stops:
            if s.table == table:
                return s
        s = Stop(table)
        self.stops.append(s)
        return s


@dataclass
class CallRecord:
    """One guest's call: ``by`` who answered it (``robot:<name>`` for the bussing robot that
    reached the table); ``after``: seconds from opening to its answer (or cancel)."""

    id: int
    table: str
    kind: str
    opened: float
    source: str | None = None
    answered: float | None = None
    by: str | None = None
    cancelled: float | None = None
    escalated: float | None = None
    after: float | None = None
    trip: int | None = None


@dataclass(frozen=True, slots=True)
class Span:
    """A robot in one status from ``start`` to ``end``."""

    status: str
    start: float
    end: float


@dataclass(frozen=True, slots=True)
class _Fact:
    ts: float
    what: str
    robot: str | None = None
    value: float = 0.0
    trip: int | None = None


@dataclass
class ServiceLog:
    """Everything read off the events; ``facts`` (sorted by time) and ``spans`` are what
    :func:`figures` counts."""

    dishes: dict[int, Dish] = field(default_factory=dict)
    trips: dict[int, Trip] = field(default_factory=dict)
    calls: dict[int, CallRecord] = field(default_factory=dict)
    spans: dict[str, list[Span]] = field(default_factory=dict)
    facts: list[_Fact] = field(default_factory=list)
    stamps: list[float] = field(default_factory=list)
    fact_ts: list[float] = field(default_factory=list)
    span_ends: dict[str, list[float]] = field(default_factory=dict)

    @property
    def robots(self) -> list[str]:
        return sorted(self.spans)


# -- reading the events ------------------------------------------------------------------------


def _num(v: object) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


def _ids(v: object) -> list[int]:
    if not isinstance(v, list):
        return []
    return [i for i in v if isinstance(i, int) and not isinstance(i, bool)]


def _text(v: object) -> str | None:
    return v if isinstance(v, str) else None


class _Reader:
    def __init__(self) -> None:
        self.log = ServiceLog()
        self.status: dict[str, tuple[str, float]] = {}  # robot -> (status, since)
        self.loading_trip: dict[str, int | None] = {}  # robot -> the trip it is loading
        self.odometer: dict[str, float] = {}  # robot -> its last odometer reading
        self.robot_trip: dict[str, int] = {}
        self.last_ts: float | None = None  # the last event before a restart's
        self.facts: list[_Fact] = []

    def dish(self, oid: int) -> Dish:
        d = self.log.dishes.get(oid)
        if d is None:
            d = self.log.dishes[oid] = Dish(oid)
        return d

    def trip(self, tid: int, ts: float) -> Trip:
        t = self.log.trips.get(tid)
        if t is None:
            t = self.log.trips[tid] = Trip(tid, created=ts)
        return t

    def fact(
        self,
        ts: float,
        what: str,
        robot: str | None = None,
        value: float = 0.0,
        trip: int | None = None,
    ) -> None:
        self.facts.append(_Fact(ts, what, robot, value, trip))

    # robots ----------------------------------------------------------------------------

    def close(self, robot: str, at: float) -> str | None:
        cur = self.status.pop(robot, None)
        if cur is None:
            return None
        status, since = cur
        at = max(at, since)
        self.log.spans.setdefault(robot, []).append(Span(status, since, at))
        if status == "Loading":
            tid = self.loading_trip.pop(robot, None)
            if tid is not None and tid in self.log.trips:
                self.log.trips[tid].loading += at - since
        return status

    def robot_status(self, e: EventRecord, robot: str, status: str) -> None:
        data = e.data
        if e.kind == "robot.restored":
            # The server was down: the robot's last status ended with the last event before.
            prev = self.close(robot, e.ts if self.last_ts is None else self.last_ts)
        elif robot in self.status and self.status[robot][0] == status:
            return  # a report that left the status as it was (a Manual goal reached)
        else:
            prev = self.close(robot, e.ts)
        self.log.spans.setdefault(robot, [])
        self.status[robot] = (status, e.ts)
        if status == "Loading":
            self.loading_trip[robot] = self.robot_trip.get(robot)
        if status == "Error" and prev != "Error":
            self.fact(e.ts, "error", robot=robot)
        if data.get("event") == "link_down":
            self.fact(e.ts, "link_drop", robot=robot)
        if status == "Delivering" and data.get("event") in ("go", "dispatch"):
            tid = self.robot_trip.get(robot)
            if tid is not None and tid in self.log.trips and self.log.trips[tid].left is None:
                self.log.trips[tid].left = e.ts

    # dishes and trips ------------------------------------------------------------------

    def distance(self, e: EventRecord, robot: str, odometer: float) -> None:
        """The server's odometer of ``robot`` (metres driven since it started, in each status
        event): the part since the last reading is a distance fact. It counts from 0 again
        after a restart, so a reading below the last one is all new."""
        last = self.odometer.get(robot, 0.0)
        self.odometer[robot] = odometer
        driven = odometer - last if odometer >= last else odometer
        if driven > 0:
            self.fact(e.ts, "distance", robot=robot, value=driven)

    def on_event(self, e: EventRecord) -> None:
        kind, data, ts = e.kind, e.data, e.ts
        if kind.startswith("robot.") and e.robot is not None:
            odometer = _num(data.get("odometer"))
            if odometer is not None:
                self.distance(e, e.robot, odometer)
        if kind.startswith("robot.") and e.robot is not None and "status" in data:
            self.robot_status(e, e.robot, str(data["status"]))
        elif kind == "order.created" and e.order_id is not None:
            d = self.dish(e.order_id)
            d.dish, d.table = _text(data.get("dish")) or "", _text(data.get("table")) or ""
            if data.get("status", "pending") == "pending":
                d.ready = _num(data.get("ready_at"))
                d.ready = ts if d.ready is None else d.ready
                d.pending_since = d.ready
        elif kind == "order.ready" and e.order_id is not None:
            d = self.dish(e.order_id)
            if d.ready is None:
                d.ready = ts
            if data.get("from") == "returned":
                d.resent.append(ts)
                self.fact(ts, "resent")
            d.pending_since = ts
        elif kind == "order.voided" and e.order_id is not None:
            d = self.dish(e.order_id)
            d.voided, d.pending_since = ts, None
            self.fact(ts, "voided")
        elif kind == "order.edited" and e.order_id is not None:
            table = _text(data.get("table"))
            if table:
                self.dish(e.order_id).table = table
        elif kind == "task.created" and e.task_id is not None:
            t = self.trip(e.task_id, ts)
            t.kind = _text(data.get("kind")) or "delivery"
            stops = data.get("stops")
            for s in stops if isinstance(stops, list) else []:
                if isinstance(s, Mapping):
                    purpose = _text(s.get("purpose")) or "deliver"
                    t.stops.append(Stop(str(s.get("table")), _ids(s.get("orders")), purpose))
        elif kind == "task.stops_dropped" and e.task_id is not None:
            t = self.trip(e.task_id, ts)
            gone = data.get("tables")
            t.stops = [s for s in t.stops if not (isinstance(gone, list) and s.table in gone)]
        elif kind == "task.started" and e.task_id is not None:
            self.started(e, self.trip(e.task_id, ts))
        elif kind == "task.requeued" and e.task_id is not None:
            t = self.trip(e.task_id, ts)
            if t.robot is not None:
                t.handed_over.append(t.robot)
                self.robot_trip.pop(t.robot, None)
            t.robot, t.status = None, "queued"
            for s in t.stops:
                if s.outcome == "pending":
                    s.arrived = None
        elif kind in ("stop.arrived", "stop.done", "stop.skipped") and e.task_id is not None:
            self.stop_event(e, self.trip(e.task_id, ts))
        elif kind in ("task.finished", "task.cancelled") and e.task_id is not None:
            t = self.trip(e.task_id, ts)
            t.status, t.ended = ("done" if kind == "task.finished" else "cancelled"), ts
            if t.robot is not None and self.robot_trip.get(t.robot) == t.id:
                del self.robot_trip[t.robot]
            # Deliveries are "trip" facts; bussing trips "bussing" ones; cruises are counted
            # by neither (a cruise only ends cancelled).
            what = {"delivery": "trip", "bussing": "bussing"}.get(t.kind, t.kind)
            if kind == "task.cancelled":
                for s in t.stops:
                    if s.outcome == "pending":
                        s.outcome, s.ended = "cancelled", ts
                for oid in _ids(data.get("orders_returned")):
                    d = self.dish(oid)  # back at the pass (a queued trip's never left it)
                    if d.pending_since is None:
                        d.pending_since = ts
                self.fact(ts, f"{what}_cancelled", robot=t.robot, trip=t.id)
            else:
                self.fact(ts, f"{what}_done", robot=t.robot, trip=t.id)
        elif kind.startswith("call.") and isinstance(data.get("call"), int):
            self.call_event(e)
        if kind not in _STARTUP:
            self.last_ts = ts

    def call_event(self, e: EventRecord) -> None:
        """``call.opened`` / ``answered`` / ``cancelled`` / ``escalated``: a call's kind in
        the period it was opened, its time to answer in the period it was answered."""
        data, ts = e.data, e.ts
        cid = data["call"]
        assert isinstance(cid, int)
        call = self.log.calls.get(cid)
        if call is None:
            kind = _text(data.get("kind")) or "?"
            call = CallRecord(cid, _text(data.get("table")) or "", kind, ts)
            self.log.calls[cid] = call
        if e.kind == "call.opened":
            call.opened, call.source = ts, _text(data.get("source"))
            self.fact(ts, f"call:{call.kind}")
        elif e.kind == "call.answered":
            call.answered, call.by, call.trip = ts, _text(data.get("by")), e.task_id
            after = _num(data.get("after"))
            call.after = ts - call.opened if after is None else after
            self.fact(ts, f"answer:{call.kind}", value=call.after)
            if (call.by or "").startswith("robot:"):
                robot = (call.by or "")[len("robot:") :]
                self.fact(ts, "robot_at_call", robot=robot, value=call.after, trip=e.task_id)
        elif e.kind == "call.cancelled":
            call.cancelled, call.by = ts, _text(data.get("by"))
            after = _num(data.get("after"))
            call.after = ts - call.opened if after is None else after
            self.fact(ts, "call_cancelled")
        elif e.kind == "call.escalated":
            call.escalated = ts
            self.fact(ts, "call_escalated")

    def started(self, e: EventRecord, t: Trip) -> None:
        robot = _text(e.data.get("robot")) or e.robot
        t.robot, t.started, t.status = robot, e.ts, "active"
        if robot is not None:
            self.robot_trip[robot] = t.id
        order = e.data.get("stops")
        if isinstance(order, list):
            rank = {table: i for i, table in enumerate(order)}
            t.stops.sort(key=lambda s: rank.get(s.table, len(rank)))
        for s in t.stops:
            if s.outcome != "pending":
                continue
            for oid in s.orders:
                d = self.dish(oid)
                if d.pending_since is not None:
                    d.on_pass.append((d.pending_since, e.ts))
                    self.fact(e.ts, "pass", value=e.ts - d.pending_since)
                    d.pending_since = None

    def stop_event(self, e: EventRecord, t: Trip) -> None:
        s = t.stop(str(e.data.get("table")))
        if e.kind == "stop.arrived":
            s.arrived = e.ts
            return
        s.ended = e.ts
        s.orders = _ids(e.data.get("orders"))
        if e.kind == "stop.done":
            s.outcome = "done"
            for oid in s.orders:
                d = self.dish(oid)
                d.delivered, d.trip = e.ts, t.id
                w = d.wait
                self.fact(e.ts, "delivered", value=math.nan if w is None else w)
        else:
            s.outcome = "skipped"
            s.reason, s.by = _text(e.data.get("reason")), _text(e.data.get("by"))
            if s.purpose != "deliver":
                return  # a bussing trip's or a cruise's stop: no dishes, no table timeout
            self.fact(e.ts, "skip" if s.by is not None else "timeout")
            for oid in s.orders:
                self.dish(oid).returned.append(e.ts)
                self.fact(e.ts, "returned")


def read_events(events: Iterable[EventRecord], end: float | None = None) -> ServiceLog:
    """The service as the events (oldest first) tell it. A robot's last status lasts until
    ``end`` (default: the last event)."""
    r = _Reader()
    last: float | None = None
    for e in events:
        r.on_event(e)
        r.log.stamps.append(e.ts)
        last = e.ts
    stop_at = end if end is not None else last
    for robot in list(r.status):
        r.close(robot, r.status[robot][1] if stop_at is None else stop_at)
    r.facts.sort(key=lambda f: f.ts)
    r.log.facts = r.facts
    r.log.fact_ts = [x.ts for x in r.facts]
    r.log.span_ends = {k: [s.end for s in v] for k, v in r.log.spans.items()}
    r.log.stamps.sort()
    return r.log


# -- figures -----------------------------------------------------------------------------------


@dataclass
class RobotFigures:
    """One robot in one period. ``busy_share``: busy time over its time online (any status
    but Offline); NaN if it was never online."""

    robot: str
    busy_s: float = 0.0
    online_s: float = 0.0
    loading_s: float = 0.0
    trips: int = 0
    errors: int = 0
    link_drops: int = 0
    distance_m: float = 0.0

    @property
    def busy_share(self) -> float:
        return self.busy_s / self.online_s if self.online_s > 0 else math.nan


@dataclass
class Figures:
    """The figures of one period (seconds unless said otherwise; NaN: nothing to measure)."""

    period: Period
    delivered: int = 0
    wait_mean: float = math.nan
    wait_p50: float = math.nan
    wait_p95: float = math.nan
    wait_max: float = math.nan
    pass_mean: float = math.nan
    pass_p95: float = math.nan
    pass_max: float = math.nan
    loading_s: float = 0.0
    returned: int = 0
    resent: int = 0
    voided: int = 0
    table_timeouts: int = 0
    staff_skips: int = 0
    trips: int = 0
    trips_cancelled: int = 0
    tables_per_trip: float = math.nan
    dishes_per_trip: float = math.nan
    errors: int = 0
    link_drops: int = 0
    distance_m: float = 0.0
    # Guests' calls, by the period they were opened in (counts) or answered in (times).
    calls: int = 0
    calls_plates: int = 0
    calls_waiter: int = 0
    calls_bill: int = 0
    calls_escalated: int = 0
    calls_cancelled: int = 0
    answer_p50: float = math.nan
    answer_p90: float = math.nan
    answer_p50_plates: float = math.nan
    answer_p90_plates: float = math.nan
    answer_p50_waiter: float = math.nan
    answer_p90_waiter: float = math.nan
    answer_p50_bill: float = math.nan
    answer_p90_bill: float = math.nan
    # Bussing trips (finished, cancelled) and, for the plates calls a robot answered, the
    # seconds from the call to the robot at the table.
    bussing_trips: int = 0
    bussing_cancelled: int = 0
    call_to_robot_p50: float = math.nan
    call_to_robot_p90: float = math.nan
    robots: list[RobotFigures] = field(default_factory=list)

    @property
    def loading_per_trip(self) -> float:
        return self.loading_s / self.trips if self.trips else math.nan

    @property
    def busy_share(self) -> float:
        online = sum(r.online_s for r in self.robots)
        return sum(r.busy_s for r in self.robots) / online if online > 0 else math.nan

    def row(self, robots: Sequence[str]) -> dict[str, object]:
        """A flat row for the CSV: fleet figures, then ``<figure>:<robot>`` for each robot."""
        out: dict[str, object] = {
            "period": self.period.label,
            "start": self.period.start,
            "end": self.period.end,
        }
        for name in FIELDS:
            out[name] = getattr(self, name)
        by = {r.robot: r for r in self.robots}
        for name in robots:
            r = by.get(name, RobotFigures(name))
            out[f"busy_s:{name}"] = r.busy_s
            out[f"busy_share:{name}"] = r.busy_share
            out[f"loading_s:{name}"] = r.loading_s
            out[f"trips:{name}"] = r.trips
            out[f"errors:{name}"] = r.errors
            out[f"distance_m:{name}"] = r.distance_m
        return out


#: The fleet columns of :meth:`Figures.row`, in order.
FIELDS = (
    "delivered",
    "wait_mean",
    "wait_p50",
    "wait_p95",
    "wait_max",
    "pass_mean",
    "pass_p95",
    "pass_max",
    "loading_s",
    "loading_per_trip",
    "trips",
    "trips_cancelled",
    "tables_per_trip",
    "dishes_per_trip",
    "returned",
    "resent",
    "voided",
    "table_timeouts",
    "staff_skips",
    "busy_share",
    "errors",
    "link_drops",
    "distance_m",
    "calls",
    "calls_plates",
    "calls_waiter",
    "calls_bill",
    "calls_escalated",
    "calls_cancelled",
    "answer_p50",
    "answer_p90",
    "answer_p50_plates",
    "answer_p90_plates",
    "answer_p50_waiter",
    "answer_p90_waiter",
    "answer_p50_bill",
    "answer_p90_bill",
    "bussing_trips",
    "bussing_cancelled",
    "call_to_robot_p50",
    "call_to_robot_p90",
)


def _overlap(span: Span, start: float, end: float) -> float:
    return max(0.0, min(span.end, end) - max(span.start, start))


def figures(log: ServiceLog, period: Period) -> Figures:
    """The figures of ``[period.start, period.end)``. A dish counts in the period it was
    delivered, returned, sent again or voided in; time on the pass in the period its trip
    took it; a trip in the period it finished (or was cancelled); loading and busy time are
    the parts of the robots' spells inside the period."""
    f = Figures(period)
    a, b = period.start, period.end
    facts = log.facts[bisect_left(log.fact_ts, a) : bisect_left(log.fact_ts, b)]
    waits = [x.value for x in facts if x.what == "delivered"]
    f.delivered = len(waits)
    waits = [w for w in waits if not math.isnan(w)]
    if waits:
        f.wait_mean = sum(waits) / len(waits)
        f.wait_p50, f.wait_p95, f.wait_max = (
            percentile(waits, 50),
            percentile(waits, 95),
            max(waits),
        )
    passes = [x.value for x in facts if x.what == "pass"]
    if passes:
        f.pass_mean, f.pass_p95, f.pass_max = (
            sum(passes) / len(passes),
            percentile(passes, 95),
            max(passes),
        )
    count = {w: sum(1 for x in facts if x.what == w) for w in _COUNTED}
    f.returned, f.resent, f.voided = count["returned"], count["resent"], count["voided"]
    f.table_timeouts, f.staff_skips = count["timeout"], count["skip"]
    f.errors, f.link_drops = count["error"], count["link_drop"]
    f.trips_cancelled = count["trip_cancelled"]
    _calls(f, facts)
    done = [log.trips[x.trip] for x in facts if x.what == "trip_done" and x.trip is not None]
    f.trips = len(done)
    if done:
        f.tables_per_trip = sum(t.tables for t in done) / len(done)
        f.dishes_per_trip = sum(t.dishes for t in done) / len(done)
    for robot in log.robots:
        rf = RobotFigures(robot)
        spans = log.spans[robot]
        # A robot's spans follow each other: those ending after a start from a bisection.
        i = bisect_left(log.span_ends[robot], a)
        for s in spans[i:]:
            if s.start >= b:
                break
            part = _overlap(s, a, b)
            if s.status != "Offline":
                rf.online_s += part
            if s.status in BUSY:
                rf.busy_s += part
            if s.status == "Loading":
                rf.loading_s += part
        rf.trips = sum(1 for t in done if t.robot == robot)
        rf.errors = sum(1 for x in facts if x.what == "error" and x.robot == robot)
        rf.link_drops = sum(1 for x in facts if x.what == "link_drop" and x.robot == robot)
        rf.distance_m = sum(x.value for x in facts if x.what == "distance" and x.robot == robot)
        f.loading_s += rf.loading_s
        f.distance_m += rf.distance_m
        f.robots.append(rf)
    return f


_COUNTED = (
    "returned",
    "resent",
    "voided",
    "timeout",
    "skip",
    "error",
    "link_drop",
    "trip_cancelled",
)


def _calls(f: Figures, facts: Sequence[_Fact]) -> None:
    """The calls' and bussing trips' figures of a period's facts."""
    counts: dict[str, int] = {}
    answers: dict[str, list[float]] = {k: [] for k in CALL_KINDS}
    reach: list[float] = []
    for x in facts:
        what = x.what
        if what.startswith("answer:"):
            answers.setdefault(what[len("answer:") :], []).append(x.value)
        elif what == "robot_at_call":
            reach.append(x.value)
        else:
            counts[what] = counts.get(what, 0) + 1
    f.calls_plates, f.calls_waiter, f.calls_bill = (counts.get(f"call:{k}", 0) for k in CALL_KINDS)
    f.calls = sum(n for w, n in counts.items() if w.startswith("call:"))
    f.calls_escalated = counts.get("call_escalated", 0)
    f.calls_cancelled = counts.get("call_cancelled", 0)
    every = [v for values in answers.values() for v in values]
    f.answer_p50, f.answer_p90 = percentile(every, 50), percentile(every, 90)
    for kind in CALL_KINDS:
        setattr(f, f"answer_p50_{kind}", percentile(answers[kind], 50))
        setattr(f, f"answer_p90_{kind}", percentile(answers[kind], 90))
    f.bussing_trips = counts.get("bussing_done", 0)
    f.bussing_cancelled = counts.get("bussing_cancelled", 0)
    f.call_to_robot_p50, f.call_to_robot_p90 = percentile(reach, 50), percentile(reach, 90)


def periods(
    log: ServiceLog,
    by: str,
    tz: tzinfo | None,
    *,
    start: float | None = None,
    end: float | None = None,
    day_start: int = 4,
) -> list[Period]:
    """The hours or service days of ``[start, end)`` in which anything was recorded or a robot
    was busy, each clipped to the range (its label kept)."""
    lo = -math.inf if start is None else start
    hi = math.inf if end is None else end
    found: dict[str, Period] = {}
    last = Period("", math.inf, -math.inf)  # the latest period found, unclipped

    def add(ts: float) -> float:
        nonlocal last
        if not last.start <= ts < last.end:  # stamps come sorted: most are in the last one
            last = period_of(ts, by, tz, day_start)
            found.setdefault(last.label, Period(last.label, max(last.start, lo), min(last.end, hi)))
        return last.end

    for ts in log.stamps:
        if lo <= ts < hi:
            add(ts)
    for spans in log.spans.values():
        for s in spans:
            if s.status in BUSY:
                t = max(s.start, lo)
                while t < min(s.end, hi):
                    t = add(t)
    return sorted(found.values(), key=lambda p: p.start)


def table(
    log: ServiceLog,
    by: str,
    tz: tzinfo | None,
    *,
    start: float | None = None,
    end: float | None = None,
    day_start: int = 4,
) -> tuple[list[Figures], Figures]:
    """The figures of each hour or service day (``by``) of ``[start, end)``, and of the
    whole range (its period runs from the first to the last of those periods)."""
    rows = [
        figures(log, p) for p in periods(log, by, tz, start=start, end=end, day_start=day_start)
    ]
    if rows:
        whole = Period("total", rows[0].period.start, rows[-1].period.end)
    else:
        whole = Period("total", start or 0.0, end or 0.0)
    return rows, figures(log, whole)
