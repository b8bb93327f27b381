"""The loader reads every event of either backend, a page at a time, and the figures come out
the same from SQLite and MariaDB (the MariaDB case skips itself where no server can run)."""

from __future__ import annotations

from pathlib import Path

import pytest

from serveur.stats.compute import figures, read_events
from serveur.stats.load import load_events
from serveur.store.factory import open_store
from tests.stats.events import T0, service
from tests.stats.test_compute import ALL


@pytest.fixture(params=["sqlite", "mariadb"])
def url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "serveur.db")
    db: str = request.getfixturevalue("mariadb_url")
    return db


async def test_every_event_in_pages_on_both_backends(url: str) -> None:
    made = service()
    async with open_store(url) as store:
        before = len(await load_events(store))  # a new database may hold its own first events
        for e in made:
            await store.events.add_event(
                e.kind,
                robot=e.robot,
                task_id=e.task_id,
                order_id=e.order_id,
                data=e.data,
                now=e.ts,
            )
        for page in (1, 7, len(made) + before, 5000):
            got = await load_events(store, page=page)
            assert len(got) == before + len(made), page
            assert [e.id for e in got] == sorted({e.id for e in got})
    ours = got[before:]
    assert [(e.kind, e.ts, e.data) for e in ours] == [(e.kind, e.ts, e.data) for e in made]
    f = figures(read_events(got), ALL)
    assert (f.delivered, f.trips, f.returned, f.resent, f.voided) == (3, 2, 2, 1, 2)
    assert f.wait_mean == pytest.approx((110 + 108 + 216) / 3)
    assert read_events(got).trips[1].left == T0 + 40
