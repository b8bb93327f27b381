"""When backups are made, what they are called and which are kept (serveur.core.backups, pure).
The shelf that makes them is tested in tests/test_backups.py (files and threads)."""

from __future__ import annotations

import time
from datetime import UTC, datetime, timedelta, timezone

import pytest

from serveur.core.backups import (
    KEEP,
    BackupEntry,
    BackupKind,
    backup_name,
    kind_of,
    next_nightly,
    to_prune,
)

PLUS8 = timezone(timedelta(hours=8))


def at(text: str, tz: timezone = PLUS8) -> float:
    return datetime.fromisoformat(text).replace(tzinfo=tz).timestamp()


def test_the_nightly_backup_is_at_half_past_three_local_time() -> None:
    assert next_nightly(at("2026-11-28T02:00"), PLUS8) == at("2026-11-28T03:30")
    assert next_nightly(at("2026-11-28T03:30"), PLUS8) == at("2026-11-29T03:30")  # just made
    assert next_nightly(at("2026-11-28T23:59"), PLUS8) == at("2026-11-29T03:30")
    # At the restaurant's time, not UTC's: 03:30 in Kuala Lumpur is 19:30 UTC the day before.
    assert next_nightly(at("2026-11-28T12:00", UTC), PLUS8) == at("2026-11-28T19:30", UTC)


def test_names_say_the_kind_and_nothing_else_is_a_backup() -> None:
    name = backup_name(BackupKind.NIGHTLY, at("2026-11-28T03:30"), PLUS8)
    assert name == "serveur-nightly-20261128-033000.db"
    assert kind_of(name) is BackupKind.NIGHTLY
    assert kind_of(backup_name(BackupKind.NOW, 0, UTC, 2)) is BackupKind.NOW
    for other in ("../serveur.db", "serveur.db", "serveur-nightly-20261128-033000.db/../x", ""):
        assert kind_of(other) is None


def test_each_kind_keeps_its_newest() -> None:
    entries = [BackupEntry(f"n{i}", BackupKind.NIGHTLY, float(i), 1, "ok") for i in range(10)] + [
        BackupEntry(f"b{i}", BackupKind.BEFORE_RESTORE, float(i), 1, "ok") for i in range(2)
    ]
    gone = to_prune(entries)
    assert gone == ["n0", "n1", "n2"]  # 7 nights kept; both before-restore copies too
    assert KEEP[BackupKind.NIGHTLY] == 7


def test_a_daylight_saving_night_is_still_half_past_three(monkeypatch: pytest.MonkeyPatch) -> None:
    """With the box's own zone (tz None), on the nights the clocks change: 03:30 local, not an
    hour off (a POSIX rule, so no zone database is needed: Paris, CET/CEST)."""
    monkeypatch.setenv("TZ", "CET-1CEST,M3.5.0,M10.5.0/3")
    time.tzset()
    try:
        for evening in ("2026-03-28T22:00:00", "2026-10-24T22:00:00"):  # before each change
            start = time.mktime(time.strptime(evening, "%Y-%m-%dT%H:%M:%S"))
            due = time.localtime(next_nightly(start))
            assert (due.tm_hour, due.tm_min) == (3, 30), (evening, due)
            assert due.tm_mday == int(evening[8:10]) + 1
    finally:
        monkeypatch.delenv("TZ")
        time.tzset()
