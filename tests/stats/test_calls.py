"""Guests' calls and bussing trips in the statistics (issue 32), from the hand-made service of
tests/stats/events.py (``with_calls``: deliveries, then six calls and three bussing trips),
every figure worked out by hand; then the same through ``serveur stats`` (tables, CSV, JSON:
the ``stats`` verb's document) on a database holding those events."""

from __future__ import annotations

import asyncio
import csv
import json
import math
import re
from pathlib import Path

import pytest

from serveur.cli import main
from serveur.stats.compute import FIELDS, figures, read_events
from serveur.stats.document import figures_document, trips_document
from serveur.stats.periods import Period
from serveur.store.factory import open_store
from tests.stats.events import T0, service, with_calls

ALL = Period("all", T0, T0 + 10_000)


def test_calls_per_kind_time_to_answer_and_escalations() -> None:
    f = figures(read_events(with_calls()), ALL)
    assert (f.calls, f.calls_plates, f.calls_waiter, f.calls_bill) == (6, 3, 2, 1)
    assert (f.calls_escalated, f.calls_cancelled) == (2, 2)
    # Answered: plates 20 s (robot) and 200 s (robot), a waiter 150 s, the bill 30 s; the
    # cancelled calls have no time to answer. Nearest rank: of [20, 30, 150, 200] the p50 is
    # the 2nd, the p90 the 4th.
    assert (f.answer_p50, f.answer_p90) == (30.0, 200.0)
    assert (f.answer_p50_plates, f.answer_p90_plates) == (20.0, 200.0)
    assert (f.answer_p50_waiter, f.answer_p90_waiter) == (150.0, 150.0)
    assert (f.answer_p50_bill, f.answer_p90_bill) == (30.0, 30.0)


def test_bussing_trips_and_the_time_from_a_call_to_the_robot() -> None:
    log = read_events(with_calls())
    f = figures(log, ALL)
    assert (f.bussing_trips, f.bussing_cancelled) == (2, 1)
    assert (f.call_to_robot_p50, f.call_to_robot_p90) == (20.0, 200.0)
    # The deliveries' figures are the deliveries' alone, as without calls.
    before = figures(read_events(service()), ALL)
    assert (f.trips, f.trips_cancelled) == (before.trips, before.trips_cancelled) == (2, 0)
    assert f.tables_per_trip == before.tables_per_trip == 1.5
    assert f.dishes_per_trip == before.dishes_per_trip
    assert (f.table_timeouts, f.staff_skips) == (before.table_timeouts, before.staff_skips)
    assert [r.trips for r in f.robots] == [r.trips for r in before.robots] == [1, 1]
    # ... but a robot on a bussing trip is busy: r1 from 300 to 420, r2 from 650 to 880.
    assert [r.busy_s for r in f.robots] == pytest.approx(
        [before.robots[0].busy_s + 120.0, before.robots[1].busy_s + 230.0]
    )
    t10, t11, t12 = log.trips[10], log.trips[11], log.trips[12]
    assert (t10.kind, t10.robot, t10.status, t10.started) == ("bussing", "r1", "done", T0 + 300)
    assert [(s.table, s.purpose, s.outcome) for s in t10.stops] == [
        ("T3", "collect", "done"),
        ("dish", "unload", "done"),
    ]
    assert (t11.robot, t11.stops[0].arrived) == ("r2", T0 + 700)
    assert (t12.status, t12.robot) == ("cancelled", None)
    c1, c4, c6 = log.calls[1], log.calls[4], log.calls[6]
    assert (c1.by, c1.after, c1.trip, c1.source) == ("robot:r1", 20.0, 10, "table")
    assert (c4.escalated, c4.answered) == (T0 + 620, T0 + 700)
    assert (c6.cancelled, c6.answered, c6.after) == (T0 + 960, None, 10.0)


def test_each_figure_counts_in_its_period() -> None:
    log = read_events(with_calls())
    # Cut at 480: calls 1-3 opened before, 4-6 after; the waiter's answer (460) before, the
    # escalation of call 4 (620) and its robot (700) after.
    a, b = figures(log, Period("a", T0, T0 + 480)), figures(log, Period("b", T0 + 480, T0 + 9e3))
    assert (a.calls, b.calls) == (3, 3)
    assert (a.calls_plates, b.calls_plates, a.calls_waiter, b.calls_waiter) == (1, 2, 1, 1)
    assert (a.calls_escalated, b.calls_escalated) == (1, 1)
    assert (a.calls_cancelled, b.calls_cancelled) == (0, 2)
    assert (a.answer_p50_waiter, a.answer_p50_bill) == (150.0, 30.0)
    assert math.isnan(b.answer_p50_waiter) and b.answer_p50_plates == 200.0
    assert (a.bussing_trips, b.bussing_trips, b.bussing_cancelled) == (1, 1, 1)
    assert (a.call_to_robot_p90, b.call_to_robot_p50) == (20.0, 200.0)
    # Nothing to measure: counts 0, times NaN (null in the document).
    none = figures(log, Period("none", T0 + 20_000, T0 + 30_000))
    assert none.calls == none.bussing_trips == 0 and math.isnan(none.answer_p90)


def test_the_document_holds_them() -> None:
    log = read_events(with_calls())
    f = figures(log, ALL)
    total = figures_document([f], f)["total"]
    for name in ("calls", "calls_plates", "calls_waiter", "calls_bill", "calls_escalated",
                 "calls_cancelled", "answer_p50", "answer_p90", "answer_p50_plates",
                 "answer_p90_plates", "answer_p50_waiter", "answer_p90_waiter",
                 "answer_p50_bill", "answer_p90_bill", "bussing_trips", "bussing_cancelled",
                 "call_to_robot_p50", "call_to_robot_p90"):  # fmt: skip
        assert name in FIELDS and name in total, name
    assert (total["calls_plates"], total["answer_p90_plates"]) == (3, 200.0)
    assert (total["bussing_trips"], total["call_to_robot_p50"]) == (2, 20.0)
    trips = {t["id"]: t for t in trips_document(log, None, None)["trips"]}
    assert trips[1]["kind"] == "delivery" and trips[10]["kind"] == "bussing"
    assert [s["purpose"] for s in trips[10]["stops"]] == ["collect", "unload"]
    assert trips[1]["stops"][0]["purpose"] == "deliver"


async def _write(db: Path) -> None:
    async with open_store(str(db)) as store:
        for e in with_calls():
            await store.events.add_event(
                e.kind,
                robot=e.robot,
                task_id=e.task_id,
                order_id=e.order_id,
                data=dict(e.data),
                now=e.ts,
            )


def test_the_command_prints_exports_and_answers_them(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "serveur.db"
    asyncio.run(_write(db))
    argv = ["stats", "--db", str(db), "--utc-offset", "UTC", "--by", "hour"]
    assert main([*argv, "--csv", str(tmp_path / "h.csv")]) == 0
    text = capsys.readouterr().out
    assert "Calls (opened, per kind" in text
    # One hour: plates, waiter, bill opened; all answers p50 / p90; per kind; escalated,
    # cancelled; bussing trips; a call to its robot p50 / p90.
    [row] = [line for line in text.split("Calls (")[1].splitlines() if line.startswith("2026")]
    assert re.split(r"\s{2,}", row.strip()) == [
        "2026-01-01 00:00", "3", "2", "1", "30 s / 200 s", "20 s / 200 s", "150 s / 150 s",
        "30 s / 30 s", "2", "2", "2", "20 s / 200 s",
    ]  # fmt: skip
    [csv_row, _total] = list(csv.DictReader((tmp_path / "h.csv").open()))
    assert (csv_row["calls_plates"], csv_row["calls_escalated"]) == ("3", "2")
    assert float(csv_row["answer_p90_waiter"]) == 150.0 and csv_row["bussing_trips"] == "2"
    # The stats verb's document (what the console's Statistics tab reads).
    assert main([*argv, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["total"]["calls"] == 6 and doc["total"]["call_to_robot_p90"] == 200.0
    assert main([*argv, "--trips"]) == 0
    history = capsys.readouterr().out
    assert "trip 10  bussing  r1  done" in history and "dish   (unload)" in history
    # A service without calls prints no calls table.
    plain = tmp_path / "plain.db"

    async def write_plain() -> None:
        async with open_store(str(plain)) as store:
            for e in service():
                await store.events.add_event(
                    e.kind, robot=e.robot, task_id=e.task_id, order_id=e.order_id,
                    data=dict(e.data), now=e.ts,
                )  # fmt: skip

    asyncio.run(write_plain())
    assert main(["stats", "--db", str(plain), "--utc-offset", "UTC"]) == 0
    assert "Calls (" not in capsys.readouterr().out
