"""The ``stats`` verb (owner; scope ``stats``) against ``serveur stats --json`` and the computation.

The service is tests/stats/test_replay_match.py's replayed dinner (its ``replayed`` fixture,
run again for this module: a couple of seconds in virtual time): its events are copied into a
running server's database, so the verb, the command an owner types and
:mod:`serveur.stats.compute` all read the same records and must give the same document,
number for number. The in-process path (a store with no file: ``StatsService(store, None)``)
must give it too. A robot driving in the simulator reports the distance it drove (the server's
odometer, the sum of its pose steps, in every robot status event). Bad ranges are refused with
``invalid_field``, and staff are refused with ``forbidden``.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import shutil
import sys
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur import protocol as P
from serveur.app import App
from serveur.clock import FakeClock
from serveur.domain import EventRecord
from serveur.maps.navigation import load_demo
from serveur.replay.model import PolicyResult
from serveur.stats.compute import read_events, table
from serveur.stats.document import figures_document, trips_document
from serveur.stats.load import load_events
from serveur.stats.periods import parse_offset, parse_when
from serveur.stats.remote import StatsService
from serveur.store.base import Store
from serveur.store.factory import open_store
from tests.conftest import Client, restaurant
from tests.stats.test_replay_match import replayed  # noqa: F401  (the module's own replay)
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

pytestmark = pytest.mark.slow

OFFSET = "+00:00"  # the replay's service opens at 2026-01-01 00:00 UTC and lasts ten minutes
# (by, start, end): every hour and day of the database, a service day, an instant to an instant.
RANGES: list[tuple[str, str | None, str | None]] = [
    ("day", None, None),
    ("hour", None, None),
    ("day", "2025-12-31", "2025-12-31"),
    ("hour", "2026-01-01T00:03", "2026-01-01T00:08:30"),
]


def _figures_msg(by: str, start: str | None, end: str | None) -> dict[str, Any]:
    msg: dict[str, Any] = {"clientmsg": "stats", "action": "figures", "by": by}
    msg["utc_offset"] = OFFSET
    if start is not None:
        msg["start"] = start
    if end is not None:
        msg["end"] = end
    return msg


def _trips_msg(start: str | None, end: str | None) -> dict[str, Any]:
    msg = _figures_msg("day", start, end)
    del msg["by"]
    msg["action"] = "trips"
    return msg


async def _copy(events: list[EventRecord], store: Store) -> None:
    for e in events:
        await store.events.add_event(
            e.kind,
            robot=e.robot,
            task_id=e.task_id,
            order_id=e.order_id,
            data=dict(e.data),
            now=e.ts,
        )


async def _events(db: str | Path) -> list[EventRecord]:
    async with open_store(str(db)) as store:
        return list(await load_events(store))


async def _command(db: Path, *args: str) -> dict[str, Any]:
    """``serveur stats --json ARGS`` as an owner runs it (the installed command if there is
    one, else the same ``main`` in a fresh interpreter)."""
    exe = shutil.which("serveur")
    head = [exe] if exe else [sys.executable, "-c", "import sys; from serveur.cli import main; "
                              "sys.exit(main())"]  # fmt: skip
    proc = await asyncio.create_subprocess_exec(
        *head, "stats", "--db", str(db), "--json", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await proc.communicate()
    assert proc.returncode == 0, err.decode()
    doc: dict[str, Any] = json.loads(out)
    return doc


def _cli_args(msg: dict[str, Any]) -> list[str]:
    args = ["--utc-offset", msg["utc_offset"]]
    if msg["action"] == "trips":
        args.append("--trips")
    else:
        args += ["--by", msg["by"]]
    if "start" in msg:
        args += ["--from", msg["start"]]
    if "end" in msg:
        args += ["--to", msg["end"]]
    return args


def _computed(events: list[EventRecord], msg: dict[str, Any]) -> dict[str, Any]:
    """What serveur/stats/compute.py gives, put in the document's shape (JSON round trip)."""
    tz = parse_offset(msg["utc_offset"])
    start = parse_when(msg["start"], tz) if "start" in msg else None
    end = parse_when(msg["end"], tz, end=True) if "end" in msg else None
    log = read_events(events)
    if msg["action"] == "trips":
        doc = trips_document(log, start, end)
    else:
        rows, total = table(log, msg["by"], tz, start=start, end=end)
        doc = figures_document(rows, total)
    out: dict[str, Any] = json.loads(json.dumps(doc))
    return out


@contextlib.asynccontextmanager
async def _server(db: str | Path, events: list[EventRecord]) -> AsyncIterator[App]:
    """A server with no robots whose database holds ``events`` (added after its start)."""
    _, waypoints = load_demo()
    app = App(db, port=0, clock=FakeClock(), waypoints=waypoints)
    await app.start()
    try:
        await _copy(events, app.store)
        yield app
    finally:
        await app.close()


async def _owner(app: App) -> Client:
    ws = await connect(app.url, max_size=2**24)
    c = Client(ws)
    reply = await c.ok("login", username="owner", password=app.first_owner_password)
    assert reply["session"]["role"] == "owner"
    return c


async def _stats(c: Client, msg: dict[str, Any]) -> dict[str, Any]:
    fields = {k: v for k, v in msg.items() if k != "clientmsg"}
    reply = await c.ok("stats", **fields)
    doc: dict[str, Any] = reply["stats"]
    return doc


def _the_replays_figures(doc: dict[str, Any], result: PolicyResult) -> None:
    """The figures docs/statistics.md quotes for this service (as test_replay_match checks)."""
    s = result.stats()
    total = doc["total"]
    assert total["delivered"] == s["delivered"] == 5
    assert total["wait_mean"] == pytest.approx(s["wait_mean"], abs=0.01)
    assert total["wait_p95"] == pytest.approx(s["wait_p95"], abs=0.01)
    assert total["trips"] == s["trips"] == 8
    assert (total["returned"], total["resent"]) == (s["returned"], s["resent"]) == (6, 6)
    assert total["loading_s"] == pytest.approx(s["loading_s"], abs=0.01)
    busy = {r["robot"]: r["busy_s"] for r in total["robots"]}
    assert busy == pytest.approx({r["name"]: r["busy"] for r in result.robots}, abs=0.01)


# -- (a) and (d): one document, whichever way it is asked -----------------------------------------


async def test_the_command_the_computation_and_the_in_memory_path_agree(
    replayed: tuple[PolicyResult, Path],  # noqa: F811
) -> None:
    result, replay_db = replayed
    events = await _events(replay_db)
    async with open_store(":memory:") as memory:
        await _copy(events, memory)
        here = StatsService(memory, None)  # a store with no file: computed in a thread
        assert here._db is None
        for by, start, end in RANGES:
            msg = _figures_msg(by, start, end)
            want = _computed(events, msg)
            assert want["periods"], msg  # each range holds part of the service
            assert await _command(replay_db, *_cli_args(msg)) == want, msg
            parsed = P.StatsFigures.model_validate({k: v for k, v in msg.items()})
            assert json.loads(json.dumps(await here.handle(parsed))) == {"stats": want}, msg
        msg = _trips_msg(None, None)
        want = _computed(events, msg)
        assert len(want["trips"]) == 8 and not want["more"]
        assert await _command(replay_db, *_cli_args(msg)) == want
        parsed_t = P.StatsTrips.model_validate(msg)
        assert json.loads(json.dumps(await here.handle(parsed_t))) == {"stats": want}
    _the_replays_figures(_computed(events, _figures_msg("day", None, None)), result)


async def test_the_verb_on_an_in_memory_server_gives_the_commands_figures(
    replayed: tuple[PolicyResult, Path],  # noqa: F811
) -> None:
    result, replay_db = replayed
    events = await _events(replay_db)
    async with _server(":memory:", events) as app:
        c = await _owner(app)
        try:
            # The server's records: the service, and what the server wrote at its own start.
            mine = list(await load_events(app.store))
            assert len(mine) > len(events)
            for by, start, end in RANGES:
                msg = _figures_msg(by, start, end)
                got = await _stats(c, msg)
                assert got == _computed(mine, msg), msg
                if start is not None:  # the server's own start is out of these ranges
                    assert got == await _command(replay_db, *_cli_args(msg)), msg
            msg = _trips_msg("2025-12-31", "2025-12-31")
            got = await _stats(c, msg)
            assert got == _computed(mine, msg) == await _command(replay_db, *_cli_args(msg))
            stops = [s for t in got["trips"] for s in t["stops"]]
            assert sum(1 for s in stops if s["outcome"] == "skipped") == 4  # the table timeouts
            assert all(d["dish"] for s in stops for d in s["dishes"])
            _the_replays_figures(await _stats(c, _figures_msg("day", "2025-12-31", None)), result)
        finally:
            await c.close()


async def test_the_verb_on_a_database_file_runs_the_command(
    replayed: tuple[PolicyResult, Path],  # noqa: F811
    tmp_path: Path,
) -> None:
    _, replay_db = replayed
    events = await _events(replay_db)
    db = tmp_path / "s.db"
    async with _server(db, events) as app:
        c = await _owner(app)
        try:
            for by, start, end in RANGES:
                msg = _figures_msg(by, start, end)
                reply = await c.call("stats", **{k: v for k, v in msg.items() if k != "clientmsg"})
                assert reply["servermsg"] == "ok", reply
                # The server's database (the service, and the server's own start) read by the
                # command itself and by the computation here.
                assert reply["stats"] == await _command(db, *_cli_args(msg)), msg
                assert reply["stats"] == _computed(await _events(db), msg), msg
            msg = _trips_msg(None, None)
            got = await _stats(c, msg)
            assert got == await _command(db, *_cli_args(msg)) == _computed(events, msg)
            assert [t["id"] for t in got["trips"]] == list(range(1, 9))
        finally:
            await c.close()


# -- (c): refusals -------------------------------------------------------------------------------


async def test_bad_ranges_are_invalid_and_staff_are_forbidden(tmp_path: Path) -> None:
    async with _server(tmp_path / "s.db", []) as app:
        c = await _owner(app)
        staff_token = await app.issue_token("staff", label="tablet")
        s = Client(
            await connect(app.url, additional_headers={"Authorization": f"Bearer {staff_token}"})
        )
        try:
            bad: list[dict[str, Any]] = [
                {"action": "figures", "start": "2026-11-24", "end": "2026-11-23"},  # end first
                {"action": "figures", "start": "2026-11-24T20:00", "end": "2026-11-24T19:30"},
                {"action": "figures", "start": "2026-11-24T19:30", "end": "2026-11-24T19:30"},
                {"action": "trips", "start": "2026-11-25", "end": "2026-11-24"},
                {"action": "figures", "start": "2026-13-45"},  # not a date
                {"action": "figures", "end": "2026-02-30"},
                {"action": "figures", "start": "2026-11-24T25:00"},
                {"action": "figures", "start": "yesterday"},
                {"action": "figures", "utc_offset": "+25:00"},
                {"action": "figures", "by": "week"},
            ]
            for fields in bad:
                reply = await c.error("stats", "invalid_field", **fields)
                assert reply["message"], fields
            # A good request still works on this connection.
            ok = await c.ok("stats", action="figures", start="2026-11-24", end="2026-11-24")
            assert ok["stats"]["periods"] == [] and ok["stats"]["total"]["delivered"] == 0
            for action in ("figures", "trips"):
                await s.error("stats", "forbidden", action=action)
        finally:
            await c.close()
            await s.close()


# -- (b): distance ------------------------------------------------------------------------------


async def test_a_robot_reports_the_distance_it_drove(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1) as r:  # on a database file: the child command
        robot = r.sim.robots[0]
        driven = 0.0

        async def measure() -> None:  # the simulator's true pose, every couple of ms
            nonlocal driven
            last = robot.pose
            while True:
                await asyncio.sleep(0.002)
                now = robot.pose
                driven += math.hypot(now[0] - last[0], now[1] - last[1])
                last = now

        sampler = asyncio.create_task(measure())
        try:
            c = await staff(r)
            await activate(c, "r1")
            ids = await new_orders(c, ("Laksa", "T12"), ("Satay", "T3"))
            await c.ok("create", type="task", orders=ids)
            for _ in range(2):
                await serve_current_stop(c, "r1")
            await c.status("r1", "Awaiting")
        finally:
            sampler.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await sampler
        assert driven > 10.0  # out to two tables and home

        token = await r.app.issue_token("integration", scopes=["stats"], label="stats")
        s = Client(
            await connect(r.app.url, additional_headers={"Authorization": f"Bearer {token}"})
        )
        try:
            total = (await s.ok("stats", action="figures", by="hour"))["stats"]["total"]
        finally:
            await s.close()
        [r1] = total["robots"]
        assert r1["robot"] == "r1" and r1["trips"] == 1
        assert r1["distance_m"] == pytest.approx(driven, rel=0.05)
        assert total["distance_m"] == r1["distance_m"]
        # The figure is the odometer in the robot's status events: its last reading.
        events = await load_events(r.app.store)
        readings = [
            float(e.data["odometer"])  # type: ignore[arg-type]
            for e in events
            if e.robot == "r1" and "odometer" in e.data
        ]
        assert readings == sorted(readings)
        assert r1["distance_m"] == pytest.approx(readings[-1], abs=0.01)


def test_a_parked_robot_drives_nowhere(
    replayed: tuple[PolicyResult, Path],  # noqa: F811
) -> None:
    result, replay_db = replayed
    events = asyncio.run(_events(replay_db))
    # Each stay at a table (Delivered until the robot goes on): the robot does not move.
    last: dict[str, tuple[str, float]] = {}
    parked: list[tuple[str, float]] = []
    for e in events:
        if e.robot is None or "status" not in e.data or "odometer" not in e.data:
            continue
        odometer = float(e.data["odometer"])  # type: ignore[arg-type]
        before = last.get(e.robot)
        if before is not None and before[0] == "Delivered":
            parked.append((e.robot, odometer - before[1]))
        last[e.robot] = (str(e.data["status"]), odometer)
    assert len(parked) >= 8  # every stop of the eight trips
    assert [(robot, d) for robot, d in parked if d > 0.2] == []
    # And the service's distances are the ones the replay measured on the true poses.
    total = _computed(events, _figures_msg("day", None, None))["total"]
    got = {r["robot"]: r["distance_m"] for r in total["robots"]}
    assert got == pytest.approx({r["name"]: r["distance"] for r in result.robots}, rel=0.1)
