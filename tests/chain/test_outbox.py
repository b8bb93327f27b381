"""The site's outbox and the centre's store, on real SQLite files and a real MariaDB (issue 34):
every event numbered in its own transaction, gapless, once; the centre stores each number once."""

from __future__ import annotations

import asyncio
import contextlib
import sqlite3
from pathlib import Path

import pytest

from serveur.domain import EventRecord
from serveur.errors import InvalidField
from serveur.hq.store import HqStore, open_hq_db
from serveur.store import rows
from serveur.store.sql import Tx
from serveur.store.sqlite.store import SQLiteStore
from tests.store.test_store import T0, Backend, seed

pytestmark = pytest.mark.asyncio


async def numbers(s: object) -> list[tuple[int, int]]:
    found = await s.outbox.after(0, limit=100000)  # type: ignore[attr-defined]
    return [(n.seq, n.event.id) for n in found]


async def test_every_event_takes_the_next_number_once_even_when_two_servers_write(
    backend: Backend,
) -> None:
    async with backend.new() as s1, backend.new() as s2:
        await seed(s1)
        before = await numbers(s1)
        await asyncio.gather(
            *(
                s.events.add_event("robot.report", robot="r1", data={"i": i}, now=T0 + i)
                for i in range(60)
                for s in (s1, s2)
            )
        )
        found = await numbers(s1)
        seqs = [seq for seq, _ in found]
        assert seqs == list(range(1, len(found) + 1))  # gapless from 1
        assert len(found) == len(before) + 120
        ids = [e for _, e in found]
        assert len(set(ids)) == len(ids)  # one number per event
        events = await s1.events.list_events(limit=100000)
        assert sorted(ids) == [e.id for e in events]  # every event has one
        state = await s1.outbox.state()
        assert (state.head, state.sent, state.confirmed) == (len(found), 0, 0)
        assert state.size == len(found)
        assert state.oldest_unsent_at == min(e.ts for e in events)


async def test_a_change_that_fails_takes_no_number(store: object) -> None:
    s = store
    await s.events.add_event("a", now=T0)  # type: ignore[attr-defined]

    async def work(tx: Tx) -> None:
        await rows.add_event(tx, "b", T0)
        raise InvalidField("refused after its event was written", field="x")

    with pytest.raises(InvalidField):
        await s.db.transact(work, "write")  # type: ignore[attr-defined]
    await s.events.add_event("c", now=T0)  # type: ignore[attr-defined]
    found = await s.outbox.after(0)  # type: ignore[attr-defined]
    assert [(n.seq, n.event.kind) for n in found] == [(1, "a"), (2, "c")]


async def test_sent_confirmed_rewind_and_prune(store: object) -> None:
    s = store
    for i in range(10):
        await s.events.add_event("k", data={"i": i}, now=T0 + i)  # type: ignore[attr-defined]
    ob = s.outbox  # type: ignore[attr-defined]
    await ob.mark_sent(6, T0 + 20)
    await ob.mark_sent(4, T0 + 21)  # a late acknowledgement never moves back
    await ob.mark_sent(99, T0 + 21)  # nor past the last number given
    st = await ob.state()
    assert (st.sent, st.sent_at, st.unsent, st.oldest_unsent_at) == (6, T0 + 20, 4, T0 + 6)
    await ob.confirm(5)
    await ob.confirm(3)
    assert (await ob.state()).confirmed == 5
    # Pruned: only what the centre confirmed and older than the retention.
    assert await ob.prune(T0 + 3.5 + 100, retention=100) == 4  # 1..4 (at < T0+3.5)
    assert await ob.prune(T0 + 1000, retention=100) == 1  # then 5 (confirmed), not 6..10
    assert [n.seq for n in await ob.after(0)] == [6, 7, 8, 9, 10]
    st = await ob.state()
    assert (st.size, st.head) == (5, 10)
    await ob.rewind(2)  # the centre asked again from 3: 3..5 are gone (confirmed), 6.. remain
    assert (await ob.state()).sent == 2
    assert [n.seq for n in await ob.after(2, limit=2)] == [6, 7]
    with pytest.raises(InvalidField):
        await ob.after(-1)
    with pytest.raises(InvalidField):
        await ob.after(0, limit=0)


async def test_the_migration_numbers_the_events_already_recorded(tmp_path: Path) -> None:
    path = tmp_path / "site.db"
    async with SQLiteStore(path) as s:
        for i in range(5):
            await s.events.add_event("k", data={"i": i}, now=T0 + i)
    # As a site before migration 013 was: events, no outbox.
    with contextlib.closing(sqlite3.connect(path)) as conn:
        conn.executescript(
            "DROP TABLE outbox; DROP TABLE outbox_state;"
            " DELETE FROM schema_migrations WHERE version = 13;"
            " DELETE FROM events WHERE id = 2;"  # ids need not be contiguous
        )
    async with SQLiteStore(path) as s:
        found = await numbers(s)
        assert found == [(1, 1), (2, 3), (3, 4), (4, 5)]
        await s.events.add_event("next", now=T0 + 9)
        assert (await numbers(s))[-1] == (5, 6)


def ev(i: int) -> EventRecord:
    return EventRecord(id=100 + i, ts=T0 + i, kind="order.created", data={"dish": "Laksa", "i": i})


@pytest.fixture(params=["sqlite", "mariadb"])
def hq_url(request: pytest.FixtureRequest, tmp_path: Path) -> str:
    if request.param == "sqlite":
        return str(tmp_path / "hq.db")
    return str(request.getfixturevalue("mariadb_url"))


async def test_the_centre_stores_each_number_once_and_never_past_a_hole(hq_url: str) -> None:
    async with HqStore(open_hq_db(hq_url)) as a, HqStore(open_hq_db(hq_url)) as b:
        evs = [ev(i) for i in range(1, 21)]
        assert await a.take("bistro", 1, evs[:5], T0) == 5
        assert await a.take("bistro", 1, evs[:5], T0) == 5  # duplicate: nothing changes
        assert await a.take("bistro", 8, evs[7:10], T0) == 5  # a hole: nothing stored
        # Two consumers store the same overlapping batches at once: each number once.
        got = await asyncio.gather(
            a.take("bistro", 4, evs[3:12], T0), b.take("bistro", 6, evs[5:20], T0)
        )
        assert max(got) == 20 or await a.take("bistro", 6, evs[5:20], T0) == 20
        stored = await a.events("bistro")
        assert [seq for seq, _ in stored] == list(range(1, 21))
        assert [e for _, e in stored] == evs
        (row,) = await a.sites()
        assert (row.site, row.stored, row.head) == ("bistro", 20, 20)
        await a.take("cafe", 1, evs[:2], T0)
        assert [r.site for r in await a.sites()] == ["bistro", "cafe"]
        await a.set_state("cafe", "down", T0 + 5)
        await a.set_state("cafe", "up", T0 + 9)
        assert await a.liveness("cafe") == [(T0 + 5, "down"), (T0 + 9, "up")]
