"""The centre's rules for a site's stream, on plain numbers (serveur.chain.ledger, .wire)."""

from __future__ import annotations

import random

import pytest

from serveur.chain.ledger import RESEND_EVERY, Liveness, SiteLedger, Verdict
from serveur.chain.wire import (
    Alive,
    Batch,
    Confirmed,
    Resend,
    batches,
    check_site,
    read_alive,
    read_batch,
    read_confirmed,
    read_resend,
    site_of,
    topic,
)
from serveur.domain import EventRecord
from serveur.errors import InvalidField


def ev(i: int) -> EventRecord:
    return EventRecord(id=i, ts=1000.0 + i, kind="order.created", data={"n": i})


def batch(first: int, n: int, site: str = "bistro") -> Batch:
    return Batch(site, first, tuple(ev(i) for i in range(first, first + n)))


def test_take_duplicate_and_gap() -> None:
    led = SiteLedger("bistro")
    d = led.judge(batch(1, 3), 0.0)
    assert d.verdict is Verdict.TAKE and d.first == 1 and [e.id for e in d.events] == [1, 2, 3]
    led.stored_up_to(3, 0.0)
    # The same batch again (QoS 1 redelivery, or a site that restarted before noting it).
    assert led.judge(batch(1, 3), 0.1).verdict is Verdict.DUPLICATE
    # Overlapping: only the new part is taken.
    d = led.judge(batch(2, 4), 0.2)
    assert d.verdict is Verdict.TAKE and d.first == 4 and [e.id for e in d.events] == [4, 5]
    led.stored_up_to(5, 0.2)
    # A hole: nothing taken, ask again from 6, once per RESEND_EVERY.
    d = led.judge(batch(9, 2), 0.3)
    assert d.verdict is Verdict.GAP and d.events == () and d.resend_from == 6
    assert led.judge(batch(11, 2), 0.4).resend_from is None
    assert led.judge(batch(13, 2), 0.3 + RESEND_EVERY).resend_from == 6
    # The gap filled: a new gap may be asked about at once.
    led.stored_up_to(8, 6.0)
    assert led.judge(batch(20, 1), 6.1).resend_from == 9


def test_a_lost_tail_is_asked_for_by_the_heartbeat() -> None:
    led = SiteLedger("bistro")
    led.judge(batch(1, 5), 0.0)
    led.stored_up_to(5, 0.0)
    assert led.alive(5, 1.0) is None  # in sync
    assert led.alive(7, 1.0) is None  # behind, but events came just now: in flight
    assert led.alive(7, RESEND_EVERY + 0.5) == 6
    assert led.alive(7, RESEND_EVERY + 1.0) is None  # paced


def test_liveness_changes_are_reported_once() -> None:
    led = SiteLedger("bistro", down_after=60.0)
    assert led.check(0.0, 0.0) is None  # never heard: neither up nor down
    assert led.heard(0.0) is Liveness.UP
    assert led.heard(10.0) is None
    assert [led.check(t, 0.0) for t in (50.0, 69.9)] == [None, None]
    assert led.check(70.0, 0.0) is Liveness.DOWN
    assert [led.check(t, 0.0) for t in (80.0, 500.0)] == [None, None]
    assert led.heard(501.0) is Liveness.UP
    assert led.heard(502.0) is None
    # The centre itself cut off from the broker: nobody is judged, and silence counts from
    # when it is back.
    assert led.check(600.0, None) is None
    assert led.check(600.0, 590.0) is None
    assert led.check(650.0, 590.0) is Liveness.DOWN


def test_any_order_of_delivery_stores_every_event_once_in_order() -> None:
    """Batches duplicated, reordered and dropped at random, the site resending what it is
    asked for: the ledger's copy ends a prefix, then all, of the site's numbers."""
    rng = random.Random(7)
    site = [ev(i) for i in range(1, 401)]
    led = SiteLedger("bistro")
    stored: list[int] = []
    now = 0.0
    cursor = 0
    in_flight: list[Batch] = []
    while len(stored) < len(site):
        now += 1.0
        if cursor < len(site):
            n = rng.randint(1, 20)
            in_flight.append(Batch("bistro", cursor + 1, tuple(site[cursor : cursor + n])))
            cursor = min(len(site), cursor + n)
        rng.shuffle(in_flight)
        keep = []
        for b in in_flight:
            fate = rng.random()
            if fate < 0.15:
                continue  # lost
            if fate < 0.3:
                keep.append(b)  # duplicated: comes again later
            d = led.judge(b, now)
            if d.verdict is Verdict.TAKE:
                assert d.first == len(stored) + 1
                stored += [e.id for e in d.events]
                led.stored_up_to(len(stored), now)
            if d.resend_from is not None:
                cursor = d.resend_from - 1
        in_flight = keep
        ask = led.alive(len(site), now)
        if ask is not None:
            cursor = ask - 1
    assert stored == [e.id for e in site]


def test_the_wire_reads_only_messages() -> None:
    b = batch(4, 3)
    assert read_batch("bistro", b.encode()) == b
    assert read_alive("bistro", Alive("bistro", 9, 1.5).encode()) == Alive("bistro", 9, 1.5)
    assert read_resend(Resend(4).encode()) == Resend(4)
    assert read_confirmed(Confirmed(8).encode()) == Confirmed(8)
    with pytest.raises(InvalidField):
        read_batch("cafe", b.encode())  # a site speaks only for itself
    for bad in (
        b"",
        b"[]",
        b"{}",
        b'{"v": 2, "site": "bistro", "first": 1, "events": []}',
        b'{"v": 1, "site": "bistro", "first": 0, "events": [[1, 1, "k", null, null, null, {}]]}',
        b'{"v": 1, "site": "bistro", "first": 1, "events": []}',
        b'{"v": 1, "site": "bistro", "first": 1, "events": [[1, 1, "", null, null, null, {}]]}',
        b'{"v": 1, "site": "bistro", "first": 1, "events": [[1, "x", "k", null, null, null, {}]]}',
        b'{"v": 1, "site": "bistro", "first": 1, "events": [[1, 1, "k", 5, null, null, {}]]}',
        b'{"v": 1, "site": "bistro", "first": true, "events": [[1, 1, "k", null, null, null, {}]]}',
        b"\xff\xfe",
        b"x" * (1024 * 1024 + 1),
    ):
        with pytest.raises(InvalidField):
            read_batch("bistro", bad)
    with pytest.raises(InvalidField):
        read_alive("bistro", b'{"v": 1, "site": "bistro", "head": -1, "at": 0}')
    with pytest.raises(InvalidField):
        read_resend(b'{"v": 1, "from": 0}')


def test_site_names_and_topics() -> None:
    assert check_site("sokcho-11") == "sokcho-11"
    for bad in ("hq", "", "A", "-x", "a/b", "a+", "#", "x" * 33, 7):
        with pytest.raises(InvalidField):
            check_site(bad)
    assert topic("bistro", "events") == "chain/bistro/events"
    assert site_of("chain/bistro/alive") == ("bistro", "alive")
    assert site_of("chain/hq/events") is None
    assert site_of("chain/bistro/other") is None
    assert site_of("elsewhere/bistro/events") is None


def test_batches_are_cut_by_size_and_at_holes() -> None:
    numbered = [(i, ev(i)) for i in (*range(1, 11), *range(15, 18))]
    cut = batches("bistro", numbered, max_bytes=400)
    assert [(b.first, b.last) for b in cut][-1] == (15, 17)
    flat = [e.id for b in cut for e in b.events]
    assert flat == [i for i, _ in numbered]
    assert all(b.last - b.first + 1 == len(b.events) for b in cut)
    assert len(cut) > 2  # 400 bytes hold a few events each
