"""The statistics of a replayed service's database agree with the replay's own report.

A short dinner in virtual time (tests/replay/test_dinner.py's: T2's party is away, its
table times out, the dishes come back and are sent again) played by the replay into a
database this test keeps; ``serveur stats`` then reads that database's events and must find
the figures the replay reported: dishes delivered, waits, trips, loading, returned and
re-sent dishes, each robot's busy time.
"""

from __future__ import annotations

import asyncio
import csv
from pathlib import Path

import pytest

from serveur.cli import main
from serveur.replay.model import PolicyResult, ReplayOptions
from serveur.replay.orders import parse_orders
from serveur.replay.service import replay_policy
from serveur.replay.vtime import VirtualTimeLoop
from serveur.stats.compute import Period, figures, read_events
from serveur.stats.load import load_events
from serveur.store.factory import open_store

pytestmark = pytest.mark.slow

LOG = """ready_at,table,dish
5.0,T2,Laksa
6.5,T2,Satay
8.0,T2,Kopi
20.0,T7,Teh tarik
21.5,T7,Mee goreng
"""


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[PolicyResult, Path]:
    work = tmp_path_factory.mktemp("stats-replay")
    # Robots pass through each other here and staff never put a dish on a trip still loading
    # (the replay's defaults before issue 31): this is about the statistics agreeing with the
    # replay, and docs/statistics.md's worked example quotes this very service's figures (8
    # trips, 6 dishes returned), measured that way.
    opts = ReplayOptions(
        robots=2, seed=1, away=0.5, progress=False, robots_see_each_other=False, join=False
    )
    with asyncio.Runner(loop_factory=VirtualTimeLoop) as runner:
        result = runner.run(replay_policy(parse_orders(LOG), opts, "serveur", work))
    return result, work / "serveur.db"  # the server's database, kept in our workdir


async def _events(db: Path) -> list[object]:
    async with open_store(str(db)) as store:
        return list(await load_events(store, page=7))  # small pages: the paging is used


def test_the_statistics_match_the_replays_report(replayed: tuple[PolicyResult, Path]) -> None:
    result, db = replayed
    s = result.stats()
    events = asyncio.run(_events(db))
    assert [e.id for e in events] == list(range(1, len(events) + 1))  # type: ignore[attr-defined]
    log = read_events(events)  # type: ignore[arg-type]
    f = figures(log, Period("all", 0.0, 4e9))
    # The service this test relies on: a table timed out, dishes came back and were re-sent.
    assert s["table_timeouts"] >= 1 and s["returned"] >= 3 and s["resent"] >= 3
    assert f.delivered == s["delivered"] == 5
    assert f.wait_mean == pytest.approx(s["wait_mean"], abs=0.01)
    assert f.wait_p50 == pytest.approx(s["wait_p50"], abs=0.01)
    assert f.wait_p95 == pytest.approx(s["wait_p95"], abs=0.01)
    assert f.wait_max == pytest.approx(s["wait_max"], abs=0.01)
    assert f.trips == s["trips"]
    assert f.tables_per_trip == pytest.approx(s["tables_per_trip"])
    # The replay counts the dishes a trip delivered; the statistics those it carried out.
    done = [t for t in log.trips.values() if t.status == "done"]
    assert sum(t.delivered for t in done) == sum(t["dishes"] for t in result.trips)
    assert f.loading_s == pytest.approx(s["loading_s"], abs=0.01)
    assert f.loading_per_trip == pytest.approx(s["loading_per_trip"], abs=0.01)
    assert (f.returned, f.resent) == (s["returned"], s["resent"])
    assert (f.table_timeouts, f.staff_skips) == (s["table_timeouts"], s["staff_skips"])
    assert f.errors == s["nav_errors"]
    by = {r.robot: r for r in f.robots}
    for r in result.robots:
        assert by[r["name"]].busy_s == pytest.approx(r["busy"], abs=0.01), r["name"]
        assert by[r["name"]].loading_s == pytest.approx(r["loading"], abs=0.01), r["name"]
        assert by[r["name"]].trips == r["trips"], r["name"]


def test_the_command_prints_and_exports_them(
    replayed: tuple[PolicyResult, Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    result, db = replayed
    s = result.stats()
    out = tmp_path / "hours.csv"
    argv = ["stats", "--db", str(db), "--by", "hour", "--utc-offset", "+00:00"]
    assert main([*argv, "--csv", str(out)]) == 0
    text = capsys.readouterr().out
    assert f"{round(s['wait_mean']):d} s" in text and "distance" in text
    rows = list(csv.DictReader(out.open()))
    # The virtual service opens at 2026-01-01 00:00 UTC and lasts ten minutes: one hour
    # (and the range's total, always the last row).
    assert [r["period"] for r in rows] == ["2026-01-01 00:00", "total"]
    head = list(rows[0])
    assert head[:6] == ["period", "start", "end", "delivered", "wait_mean", "wait_p50"]
    for col in ("wait_p95", "pass_mean", "loading_s", "trips", "tables_per_trip",
                "dishes_per_trip", "returned", "resent", "voided", "busy_share", "errors",
                "busy_share:r1", "errors:r2"):  # fmt: skip
        assert col in head, col
    row = rows[0]
    assert row["start"] == "2026-01-01 00:00:00" and row["end"] == "2026-01-01 01:00:00"
    assert int(row["delivered"]) == 5 and int(row["trips"]) == s["trips"]
    assert float(row["wait_p95"]) == pytest.approx(s["wait_p95"], abs=0.01)
    assert int(row["resent"]) == s["resent"]
    # The trip history: a row per stop, the timed-out stops with their reason.
    trips = tmp_path / "trips.csv"
    assert main([*argv, "--trips", "--csv", str(trips)]) == 0
    stops = list(csv.DictReader(trips.open()))
    assert len({r["trip"] for r in stops}) == len(result.trips)
    skipped = [r for r in stops if r["outcome"] == "skipped"]
    assert len(skipped) == s["table_timeouts"] and all("180 s" in r["reason"] for r in skipped)
    assert "trip 1" in capsys.readouterr().out
