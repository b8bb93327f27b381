"""``serveur stats`` on a database holding the hand-made service twice, an hour apart."""

from __future__ import annotations

import asyncio
import csv
from pathlib import Path

import pytest

from serveur.cli import main
from serveur.store.factory import open_store
from tests.stats.events import service


async def _write(db: Path) -> None:
    async with open_store(str(db)) as store:
        for hour in (0, 1):
            for e in service():
                data = dict(e.data)
                if isinstance(data.get("ready_at"), float):
                    data["ready_at"] = data["ready_at"] + 3600 * hour  # type: ignore[operator]
                await store.events.add_event(
                    e.kind,
                    robot=e.robot,
                    task_id=e.task_id,
                    order_id=e.order_id,
                    data=data,
                    now=e.ts + 3600 * hour,
                )


@pytest.fixture
def db(tmp_path: Path) -> Path:
    path = tmp_path / "serveur.db"
    asyncio.run(_write(path))
    return path


def test_by_hour_to_csv(db: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    out = tmp_path / "h.csv"
    argv = ["stats", "--db", str(db), "--utc-offset", "UTC", "--by", "hour", "--csv", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    assert "2026-01-01 01:00" in text and "total" in text and "CSV written" in text
    rows = list(csv.DictReader(out.open()))
    assert [r["period"] for r in rows] == ["2026-01-01 00:00", "2026-01-01 01:00", "total"]
    assert [int(r["delivered"]) for r in rows] == [3, 3, 6]
    assert [int(r["trips"]) for r in rows] == [2, 2, 4]
    assert [float(r["wait_mean"]) for r in rows] == pytest.approx([434 / 3] * 3, abs=0.001)
    assert [int(r["errors:r2"]) for r in rows] == [1, 1, 2]
    assert rows[0]["loading_s:r1"] == "15.0" and rows[0]["voided"] == "2"
    assert rows[0]["start"] == "2026-01-01 00:00:00"
    # A column per figure, then the robots'.
    assert list(rows[0])[:5] == ["period", "start", "end", "delivered", "wait_mean"]
    assert list(rows[0])[-6:] == [
        "busy_s:r2", "busy_share:r2", "loading_s:r2", "trips:r2", "errors:r2", "distance_m:r2",
    ]  # fmt: skip


def test_a_range_and_a_day(db: Path, capsys: pytest.CaptureFixture[str]) -> None:
    base = ["stats", "--db", str(db), "--utc-offset", "+01:00", "--csv", "-"]
    # At +01:00 the second service is at 02:00 local; the range from 01:30 keeps it alone.
    assert main([*base, "--by", "hour", "--from", "2026-01-01 01:30"]) == 0
    rows = list(csv.DictReader(capsys.readouterr().out.splitlines()))
    assert [r["period"] for r in rows] == ["2026-01-01 02:00", "total"]
    assert rows[-1]["delivered"] == "3"
    # Both are in the service day that began on Dec 31 at 04:00 local.
    assert main([*base, "--to", "2025-12-31"]) == 0
    rows = list(csv.DictReader(capsys.readouterr().out.splitlines()))
    assert [r["period"] for r in rows] == ["2025-12-31", "total"]
    assert rows[0]["delivered"] == "6"


def test_trip_history_and_refusals(
    db: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["stats", "--db", str(db), "--utc-offset", "UTC", "--trips"]) == 0
    text = capsys.readouterr().out
    assert "trip 1  r1  done" in text and "skipped (skipped by staff)" in text
    assert "3 Rendang, 4 Kopi" in text
    assert main(["stats", "--db", str(tmp_path / "none.db")]) == 2
    assert not (tmp_path / "none.db").exists()  # not created by asking
    assert main(["stats", "--db", str(db), "--from", "soon"]) == 2
    assert main(["stats", "--db", str(db), "--utc-offset", "+25:00"]) == 2
