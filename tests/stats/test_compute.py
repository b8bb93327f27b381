"""The statistics computed from a hand-made event log (tests/stats/events.py): every figure
checked against numbers worked out by hand."""

from __future__ import annotations

import math
from datetime import UTC

import pytest

from serveur.stats.compute import figures, read_events, table
from serveur.stats.periods import Period, parse_offset, parse_when, period_of
from tests.stats.events import T0, Log, service

ALL = Period("all", T0, T0 + 10_000)


def test_dishes_waits_and_time_on_the_pass() -> None:
    log = read_events(service())
    f = figures(log, ALL)
    # Dishes 1 and 2 collected at 120 (ready at 10 and 12); dish 3 at 230, its wait counted
    # from its first ready time (14), not from when it was sent again (150).
    assert log.dishes[3].wait == pytest.approx(216.0)
    assert f.delivered == 3
    assert f.wait_mean == pytest.approx((110 + 108 + 216) / 3)
    assert (f.wait_p50, f.wait_p95, f.wait_max) == pytest.approx((110.0, 216.0, 216.0))
    # On the pass until a robot took the trip: 15, 13, 11 and 5 s (dish 4 ready at 20) for
    # trip 1 at 25; dish 3 again from its re-send (150) to trip 2 at 160: 10 s.
    assert log.dishes[3].on_pass == [(T0 + 14, T0 + 25), (T0 + 150, T0 + 160)]
    assert f.pass_mean == pytest.approx((15 + 13 + 11 + 5 + 10) / 5)
    assert (f.pass_p95, f.pass_max) == pytest.approx((15.0, 15.0))
    # The skipped stop returned dishes 3 and 4; 3 was sent again, 4 and 5 voided.
    assert (f.returned, f.resent, f.voided) == (2, 1, 2)
    assert (f.staff_skips, f.table_timeouts) == (1, 0)
    assert log.dishes[4].voided == T0 + 155 and log.dishes[4].delivered is None


def test_trips_loading_and_robots() -> None:
    log = read_events(service())
    f = figures(log, ALL)
    assert (f.trips, f.trips_cancelled) == (2, 0)
    assert f.tables_per_trip == pytest.approx(1.5)
    assert f.dishes_per_trip == pytest.approx((4 + 1) / 2)  # carried: delivered + returned
    # Loading: r1 from 25 to Go at 40, r2 from 160 to 170.
    assert f.loading_s == pytest.approx(25.0) and f.loading_per_trip == pytest.approx(12.5)
    r1, r2 = f.robots
    assert (r1.robot, r1.loading_s, r1.trips, r1.errors) == ("r1", 15.0, 1, 0)
    assert (r2.robot, r2.loading_s, r2.trips, r2.errors) == ("r2", 10.0, 1, 1)
    assert f.errors == 1
    # Busy from Loading to Awaiting again; online from link up to the last event (250).
    assert r1.busy_s == pytest.approx(115.0) and r1.online_s == pytest.approx(249.0)
    assert r2.busy_s == pytest.approx(90.0)
    assert r1.busy_share == pytest.approx(115 / 249)
    assert f.busy_share == pytest.approx((115 + 90) / (249 + 249))


def test_trip_history_with_each_stop() -> None:
    log = read_events(service())
    t1, t2 = log.trips[1], log.trips[2]
    assert (t1.robot, t1.status, t1.started, t1.left, t1.ended) == (
        "r1", "done", T0 + 25, T0 + 40, T0 + 120,
    )  # fmt: skip
    assert t1.loading == pytest.approx(15.0)
    # Stops in the visiting order the robot was given, not the cart's.
    assert [s.table for s in t1.stops] == ["T5", "T3"]
    t5, t3 = t1.stops
    assert (t5.outcome, t5.arrived, t5.ended, t5.orders) == ("skipped", T0 + 60, T0 + 90, [3, 4])
    assert (t5.reason, t5.by) == ("skipped by staff", "user:ana")
    assert (t3.outcome, t3.arrived, t3.ended, t3.orders) == ("done", T0 + 100, T0 + 120, [1, 2])
    assert (t1.delivered, t1.returned, t1.dishes) == (2, 2, 4)
    assert (t2.robot, t2.left, t2.delivered) == ("r2", T0 + 170, 1)
    assert log.dishes[3].trip == 2 and log.dishes[1].dish == "Laksa"


def test_periods_split_the_figures_and_clip_the_spells() -> None:
    log = read_events(service())
    whole = figures(log, ALL)
    first, second = (
        figures(log, Period("a", T0, T0 + 150)),
        figures(log, Period("b", T0 + 150, T0 + 10_000)),
    )
    assert first.delivered + second.delivered == whole.delivered == 3
    assert (first.returned, second.returned, first.resent, second.resent) == (2, 0, 0, 1)
    assert (first.voided, second.voided) == (1, 1)
    assert first.loading_s + second.loading_s == pytest.approx(whole.loading_s)
    # r2's spell from 160 falls in the second part only; r1's busy 25-140 in the first.
    assert [r.busy_s for r in first.robots] == pytest.approx([115.0, 0.0])
    assert [r.busy_s for r in second.robots] == pytest.approx([0.0, 90.0])
    # Cut in the middle of r1's loading (25-40): each side gets its part.
    a, b = figures(log, Period("a", T0, T0 + 30)), figures(log, Period("b", T0 + 30, T0 + 999))
    assert (a.robots[0].loading_s, b.robots[0].loading_s) == pytest.approx((5.0, 10.0))


def test_table_by_hour_and_day() -> None:
    events = service()
    # The same service again an hour later (ids and times moved on).
    later = [
        e.model_copy(update={"id": e.id + 1000, "ts": e.ts + 3600,
                             "task_id": e.task_id and e.task_id + 10,
                             "order_id": e.order_id and e.order_id + 10,
                             "data": _shift(e.data)})
        for e in events
    ]  # fmt: skip
    log = read_events([*events, *later])
    rows, total = table(log, "hour", UTC)
    assert [r.period.label for r in rows] == ["2026-01-01 00:00", "2026-01-01 01:00"]
    assert [r.delivered for r in rows] == [3, 3] and total.delivered == 6
    assert [r.trips for r in rows] == [2, 2] and total.trips == 4
    assert rows[0].wait_mean == pytest.approx(rows[1].wait_mean)
    days, dtotal = table(log, "day", UTC)
    assert [d.period.label for d in days] == ["2025-12-31"]  # before 04:00: the day before
    assert dtotal.delivered == days[0].delivered == 6
    # A range keeps what happened inside it.
    rows, total = table(log, "hour", UTC, start=T0 + 3600)
    assert [r.period.label for r in rows] == ["2026-01-01 01:00"] and total.delivered == 3


def _shift(data: dict[str, object]) -> dict[str, object]:
    out = dict(data)
    for k in ("orders", "orders_returned"):
        if isinstance(out.get(k), list):
            out[k] = [i + 10 for i in out[k]]
    if isinstance(out.get("stops"), list) and out["stops"] and isinstance(out["stops"][0], dict):
        out["stops"] = [{**s, "orders": [i + 10 for i in s["orders"]]} for s in out["stops"]]
    if isinstance(out.get("ready_at"), float):
        out["ready_at"] = out["ready_at"] + 3600
    return out


def test_a_restart_does_not_count_the_night_as_online() -> None:
    events = service()
    g = Log()
    g.events = list(events)
    n = len(events)
    for i, r in enumerate(("r1", "r2")):
        g.events.append(
            events[0].model_copy(update={"id": n + i + 1, "ts": T0 + 40_000, "robot": r})
        )
    log = read_events(g.events)
    f = figures(log, Period("all", T0, T0 + 50_000))
    # Both robots Awaiting until the last event before the restart (250), not until 40000.
    assert [r.online_s for r in f.robots] == pytest.approx([249.0, 249.0])


def test_a_cancelled_trip_puts_its_dishes_back_on_the_pass() -> None:
    g = Log()
    g.status(0, "r1", "Awaiting", "auto")
    g.add(
        10, "order.created", order=1, dish="Laksa", table="T3", ready_at=T0 + 10, status="pending"
    )
    g.add(11, "task.created", task=1, stops=[{"table": "T3", "orders": [1]}])
    g.add(20, "task.started", robot="r1", task=1, data={"robot": "r1"}, stops=["T3"])
    g.status(20, "r1", "Loading", "assign")
    g.add(
        30, "task.cancelled", robot="r1", task=1, reason="cancelled by staff", orders_returned=[1]
    )
    g.status(30, "r1", "Awaiting", "cancel")
    g.add(31, "task.created", task=2, stops=[{"table": "T3", "orders": [1]}])
    g.add(40, "task.started", robot="r1", task=2, data={"robot": "r1"}, stops=["T3"])
    # A queued trip cancelled (its table blocked) never took dish 2 off the pass: one spell.
    g.add(50, "order.created", order=2, dish="Kopi", table="T4", ready_at=T0 + 50, status="pending")
    g.add(51, "task.created", task=3, stops=[{"table": "T4", "orders": [2]}])
    g.add(60, "task.cancelled", task=3, reason="table blocked", orders_returned=[2])
    g.add(61, "task.created", task=4, stops=[{"table": "T4", "orders": [2]}])
    g.add(70, "task.started", robot="r1", task=4, data={"robot": "r1"}, stops=["T4"])
    log = read_events(g.events)
    f = figures(log, ALL)
    assert (f.trips, f.trips_cancelled) == (0, 2)
    assert log.dishes[2].on_pass == [(T0 + 50, T0 + 70)]
    assert log.trips[1].stops[0].outcome == "cancelled" and log.trips[1].loading == 10.0
    assert log.dishes[1].on_pass == [(T0 + 10, T0 + 20), (T0 + 30, T0 + 40)]
    assert math.isnan(f.wait_mean) and f.delivered == 0


def test_periods_and_dates_in_local_time() -> None:
    plus2 = parse_offset("+02:00")
    assert parse_offset("-0530").utcoffset(None).total_seconds() == -(5 * 3600 + 1800)
    assert parse_offset("UTC").utcoffset(None).total_seconds() == 0
    with pytest.raises(ValueError):
        parse_offset("two")
    # 23:30 UTC is 01:30 the next day at +02:00: still the service day that began the day before.
    ts = T0 - 1800
    assert period_of(ts, "hour", plus2).label == "2026-01-01 01:00"
    assert period_of(ts, "day", plus2).label == "2025-12-31"
    assert period_of(ts, "day", plus2, day_start=0).label == "2026-01-01"
    day = period_of(T0 + 12 * 3600, "day", UTC)
    assert (day.start, day.end) == (T0 + 4 * 3600, T0 + 28 * 3600)
    assert parse_when("2026-01-01", UTC) == T0 + 4 * 3600
    assert parse_when("2026-01-01", UTC, end=True) == T0 + 28 * 3600
    assert parse_when("2026-01-01 18:30", plus2) == T0 + 16.5 * 3600
    with pytest.raises(ValueError):
        parse_when("yesterday", UTC)
