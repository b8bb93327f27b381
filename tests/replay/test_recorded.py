"""A recorded service played again (issue 20 item 3, "how many robots do I need?"): the
restaurant's own night, read from its database as an order log, replayed with another fleet."""

from __future__ import annotations

import asyncio
import json
from datetime import datetime, timedelta, timezone
from pathlib import Path

import pytest

from serveur.app import import_waypoints
from serveur.cli import main
from serveur.domain import DishAction, OrderStatus
from serveur.maps.navigation import load_demo
from serveur.store.sqlite.store import SQLiteStore

SGT = timezone(timedelta(hours=8))  # a restaurant in Singapore
DINNER = datetime(2026, 11, 20, 18, 0, tzinfo=SGT).timestamp()


async def recorded_night(db: Path) -> None:
    """Tuesday's dinner as the store keeps it, plus dishes that must not be replayed."""
    async with SQLiteStore(db) as store:
        _, wps = load_demo()
        await import_waypoints(store, wps.values(), now=DINNER)
        await store.orders.add_order("Laksa", "T1", ready_at=DINNER + 60, now=DINNER, quantity=2)
        await store.orders.add_order("Satay", "T6", ready_at=DINNER + 90, now=DINNER)
        voided = await store.orders.add_order("Cendol", "T6", ready_at=DINNER + 95, now=DINNER)
        await store.orders.step_order(voided.id, DishAction.VOID, now=DINNER + 100)
        # Still at the kitchen when the night ended: never ready, not in the log.
        await store.orders.add_order(
            "Kopi", "T2", ready_at=None, now=DINNER, status=OrderStatus.ORDERED
        )
        await store.orders.add_order("Teh", "T2", ready_at=DINNER + 150, now=DINNER)
        # The next service day (after 04:00): not in Tuesday's log.
        await store.orders.add_order("Roti", "T1", ready_at=DINNER + 11 * 3600, now=DINNER)


def test_a_recorded_night_is_an_order_log_the_replay_plays_again(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    db = tmp_path / "restaurant.db"
    asyncio.run(recorded_night(db))
    args = ["orders", "--from-db", str(db), "--day", "2026-11-20", "--utc-offset", "+08:00"]
    assert main(args) == 0
    log = capsys.readouterr().out
    assert log.splitlines() == [
        "ready_at,table,dish",
        "0.0,T1,Laksa",  # quantity 2: two plates
        "0.0,T1,Laksa",
        "30.0,T6,Satay",
        "90.0,T2,Teh",
    ]
    # The same night, played again with one robot instead of the restaurant's fleet.
    path = tmp_path / "tuesday.csv"
    path.write_text(log)
    out = tmp_path / "one-robot"
    replay = ["replay", str(path), "--robots", "1", "--policy", "serveur", "--quiet", "--no-calls"]
    assert main([*replay, "--seed", "2", "--out", str(out)]) == 0
    summary = json.loads((out / "report.json").read_text())["policies"]["serveur"]["summary"]
    assert summary["orders"] == summary["delivered"] == 4
    assert main(["orders", "--from-db", str(db), "--day", "2026-11-22"]) == 1  # nothing then
    assert "no dish was ready" in capsys.readouterr().err
    assert main(["orders", "--from-db", str(db), "--day", "Tuesday"]) == 2
