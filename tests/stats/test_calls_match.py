"""The statistics of a replayed service with guests' calls and bussing agree with the replay.

A short service (tests/replay/test_modes.py's four parties, each calling for its plates, a
waiter and the bill) played by the replay into a database this test keeps, then read back by
:mod:`serveur.stats.compute` from the events alone. The replay reads the calls' and trips'
own records (call rows, task stops): calls per kind, times to answer, escalations, bussing
trips and the time from a plates call to the robot at the table must come out the same, and
the deliveries' figures must not count the bussing trips. The kitchen enters each dish a
minute ahead (``ordered``, then ready: ``serveur replay``'s default), and the waits still
count from ready.
"""

from __future__ import annotations

import asyncio

import pytest

from serveur.domain import EventRecord
from serveur.replay.model import PolicyResult, ReplayOptions, percentile
from serveur.replay.orders import parse_orders
from serveur.replay.service import replay_policy
from serveur.replay.vtime import VirtualTimeLoop
from serveur.stats.compute import CALL_KINDS, figures, read_events
from serveur.stats.load import load_events
from serveur.stats.periods import Period
from serveur.store.factory import open_store
from tests.replay.test_modes import LOG

pytestmark = pytest.mark.slow


@pytest.fixture(scope="module")
def replayed(tmp_path_factory: pytest.TempPathFactory) -> tuple[PolicyResult, list[EventRecord]]:
    work = tmp_path_factory.mktemp("stats-calls")
    opts = ReplayOptions(
        robots=2, seed=1, away=0.0, progress=False, calls=True, call_plates=1.0,
        call_waiter=1.0, call_bill=1.0, eat=(60.0, 240.0), kitchen_ahead=60.0,
    )  # fmt: skip
    with asyncio.Runner(loop_factory=VirtualTimeLoop) as runner:
        result = runner.run(replay_policy(parse_orders(LOG), opts, "serveur", work))

    async def events() -> list[EventRecord]:
        async with open_store(str(work / "serveur.db")) as store:
            return await load_events(store)

    return result, asyncio.run(events())


def test_calls_and_bussing_match_the_replays_records(
    replayed: tuple[PolicyResult, list[EventRecord]],
) -> None:
    result, events = replayed
    log = read_events(events)
    f = figures(log, Period("all", 0.0, 4e9))
    modes = result.modes()
    assert len(result.calls) == 12 and modes["bussing"]["done"] == 4  # the service tested
    assert f.calls == len(result.calls)
    for kind in CALL_KINDS:
        mine = [c for c in result.calls if c["kind"] == kind]
        assert getattr(f, f"calls_{kind}") == len(mine) == 4, kind
        after = [c["after"] for c in mine if c["answered"] is not None]
        assert getattr(f, f"answer_p50_{kind}") == pytest.approx(percentile(after, 50), abs=0.01)
        assert getattr(f, f"answer_p90_{kind}") == pytest.approx(percentile(after, 90), abs=0.01)
        assert modes["calls"][kind]["answer_p90"] == pytest.approx(percentile(after, 90))
    every = [c["after"] for c in result.calls if c["answered"] is not None]
    assert (f.answer_p50, f.answer_p90) == pytest.approx(
        (percentile(every, 50), percentile(every, 90)), abs=0.01
    )
    assert f.calls_escalated == modes["escalated"]
    assert f.calls_cancelled == 0
    # Bussing: the trips finished, and from each plates call to the robot at its table (the
    # replay: the trip's stop arrival; the statistics: the call's answer by the robot).
    assert f.bussing_trips == modes["bussing"]["done"] and f.bussing_cancelled == 0
    assert f.call_to_robot_p50 == pytest.approx(modes["bussing"]["call_to_robot_p50"], abs=0.01)
    assert f.call_to_robot_p90 == pytest.approx(modes["bussing"]["call_to_robot_p90"], abs=0.01)
    # The deliveries are counted as the replay counts them, and robots are busy on both.
    s = result.stats()
    assert f.trips == s["trips"] and f.delivered == s["delivered"] == 10
    assert f.wait_mean == pytest.approx(s["wait_mean"], abs=0.01)
    by = {r.robot: r for r in f.robots}
    for r in result.robots:
        assert by[r["name"]].trips == r["trips"], r["name"]
        assert by[r["name"]].busy_s == pytest.approx(r["busy"], abs=0.01), r["name"]
    kinds = {t.kind for t in log.trips.values()}
    assert kinds == {"delivery", "bussing"}
    # The kitchen entered every dish a minute ahead, then marked it ready.
    created = [e for e in events if e.kind == "order.created"]
    assert len(created) == 10 and all(e.data["status"] == "ordered" for e in created)
    ready = [e for e in events if e.kind == "order.ready" and e.data.get("from") == "ordered"]
    assert len(ready) == 10
