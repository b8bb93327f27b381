"""Twenty restaurants, one centre, a broker that crashes (issue 34's "done when").

Every part is real: twenty ``serveur run`` processes, each on its own copy of a replayed
service's SQLite database (the service recorded while the chain was unreachable: a dinner's
events waiting in each outbox), a TLS Mosquitto with per-site passwords and the production
ACL (deploy/chain/acl), ``serveur hq run`` as a process on a real MariaDB. While they ship,
the test writes new events into running sites, kills sites with SIGKILL and starts them
again, keeps one site dead past the centre's down limit, kills the centre, and crashes the
broker (SIGKILL before its first autosave: what it queued for the absent centre is lost, so
the centre must find the gap and ask again). At the end every site is killed and its outbox
drained by the same :class:`~serveur.chain.shipper.Shipper` (so no site records anything
after the comparison starts), and:

* the centre holds each site's every event exactly once, in the site's order;
* the dashboard's figures for each site equal that site's own ``serveur stats --json``;
* the site kept dead went down once and came back up once, and no site changed twice the
  same way.
"""

from __future__ import annotations

import asyncio
import contextlib
import io
import itertools
import json
import os
import random
import shutil
import sqlite3
import sys
import time
import urllib.error
import urllib.request
from collections.abc import AsyncIterator, Awaitable, Callable
from pathlib import Path
from typing import Any

import pytest

from serveur.chain.address import ChainAddress
from serveur.chain.shipper import Shipper
from serveur.cli import main
from serveur.clock import ScaledClock
from serveur.hq.store import HqStore, open_hq_db
from serveur.replay.model import ReplayOptions
from serveur.replay.orders import parse_orders
from serveur.replay.service import replay_policy
from serveur.replay.vtime import VirtualTimeLoop
from serveur.store.sqlite.store import SQLiteStore
from tests.chain.broker import ChainBroker, need_mosquitto
from tests.subprocess_server import ServeurProcess, free_port, run_cli

pytestmark = [pytest.mark.slow, pytest.mark.timeout(400)]

SITES = [f"site{k:02d}" for k in range(1, 21)]
DEAD = "site07"  # kept dead past the centre's down limit
DOWN_AFTER = 4.0
# A short dinner: a dish every 45 s at eight tables (the replay's cost follows the virtual
# time its robots drive; a longer service adds events of the same kinds, not new cases).
LOG = "ready_at,table,dish\n" + "".join(
    f"{10 + 45 * i}.0,T{1 + i % 8},Dish {i}\n" for i in range(16)
)
# The sites and the centre run at a lower priority than the other tests' processes (20
# servers starting on a 2-core machine would otherwise starve a neighbour's child processes
# past their limits); on a quiet machine it changes nothing.
NICE = ["nice", "-n", "5"]


@pytest.fixture(scope="module")
def service_db(tmp_path_factory: pytest.TempPathFactory) -> Path:
    work = tmp_path_factory.mktemp("chain-replay")
    opts = ReplayOptions(robots=2, seed=3, progress=False)
    with asyncio.Runner(loop_factory=VirtualTimeLoop) as runner:
        runner.run(replay_policy(parse_orders(LOG), opts, "serveur", work))
    mark("replayed")
    return work / "serveur.db"


def site_rows(db: Path, sql: str, params: tuple[Any, ...] = ()) -> list[tuple[Any, ...]]:
    with contextlib.closing(sqlite3.connect(db)) as conn:
        return conn.execute(sql, params).fetchall()


def head_of(db: Path) -> int:
    return int(site_rows(db, "SELECT head FROM outbox_state")[0][0])


class Chain:
    """The broker, the centre and the sites of one test."""

    def __init__(self, root: Path, service: Path, hq_db: str) -> None:
        self.root = root
        self.passwords = {s: f"pw {s}:{i}@x" for i, s in enumerate(["hq", *SITES])}
        self.broker = ChainBroker(root / "broker", self.passwords)
        self.hq_db = hq_db
        self.hq_port = free_port()
        self.dbs: dict[str, Path] = {}
        self.sites: dict[str, ServeurProcess] = {}
        for site in SITES:
            self.dbs[site] = root / f"{site}.db"
            shutil.copy(service, self.dbs[site])
        self.hq = ServeurProcess(
            [
                *NICE,
                sys.executable,
                "-m",
                "serveur.cli",
                "hq",
                "run",
                "--db",
                hq_db,
                "--broker",
                self.broker.url("hq"),
                "--ca",
                str(self.broker.ca),
                "--port",
                str(self.hq_port),
                "--down-after",
                str(DOWN_AFTER),
                "--tick",
                "0.2",
            ]
        )
        for site in SITES:
            self.sites[site] = ServeurProcess(
                [
                    *NICE,
                    sys.executable,
                    "-m",
                    "serveur.cli",
                    "run",
                    "--db",
                    str(self.dbs[site]),
                    "--port",
                    str(free_port()),
                    "--chain",
                    self.broker.url(site),
                    "--chain-ca",
                    str(self.broker.ca),
                    "--chain-heartbeat",
                    "1",
                ]
            )
        self.token = ""

    async def start_sites(self, sites: list[str]) -> None:
        """Start ``sites``, three at a time: twenty Python processes importing at once on two
        cores would each take longer than a start is allowed."""
        gate = asyncio.Semaphore(3)

        async def one(site: str) -> None:
            async with gate:
                await self.sites[site].start()

        await asyncio.gather(*(one(s) for s in sites))

    def address(self, site: str) -> ChainAddress:
        return ChainAddress.parse(self.broker.url(site), ca=str(self.broker.ca))

    def api(self, path: str) -> Any:
        """GET a dashboard route, logging in first (again after the centre restarted: its
        logins live in its memory)."""
        for _ in range(2):
            req = urllib.request.Request(
                f"http://127.0.0.1:{self.hq_port}{path}",
                headers={"Authorization": f"Bearer {self.token}"},
            )
            try:
                with urllib.request.urlopen(req, timeout=30) as reply:
                    return json.loads(reply.read())
            except urllib.error.HTTPError as exc:
                if exc.code != 401:
                    raise
                self.login()
        raise AssertionError("the centre refused a fresh login")

    def login(self) -> None:
        body = json.dumps({"name": "chain-ops", "password": "lookout-tower-9"}).encode()
        req = urllib.request.Request(
            f"http://127.0.0.1:{self.hq_port}/api/login",
            data=body,
            headers={"Content-Type": "application/json"},
        )
        with urllib.request.urlopen(req, timeout=30) as reply:
            self.token = json.loads(reply.read())["token"]

    async def stored(self) -> dict[str, int]:
        sites = await asyncio.to_thread(self.api, "/api/sites")
        return {s["site"]: s["stored"] for s in sites["sites"]}

    async def state_of(self, site: str) -> str | None:
        rows = await asyncio.to_thread(self.api, "/api/sites")
        return next((s["state"] for s in rows["sites"] if s["site"] == site), None)

    async def synced(self) -> bool:
        got = await self.stored()
        return all(got.get(s) == head_of(db) for s, db in self.dbs.items())


async def until(cond: Callable[[], Awaitable[bool]], timeout: float, what: str) -> None:
    """Wait until ``cond()`` holds, asking every 0.2 s: the outcome is in another process
    (the centre's dashboard, a site's database), there is no event to wait on here."""
    try:
        async with asyncio.timeout(timeout):
            while True:
                if await cond():
                    return
                await asyncio.sleep(0.2)
    except TimeoutError:
        raise AssertionError(f"timed out waiting for {what}") from None


async def add_events(db: Path, n: int, rng: random.Random) -> None:
    """New events written into a running site (a second writer, as a second server is)."""
    async with SQLiteStore(db) as store:
        for i in range(n):
            await store.events.add_event(
                "robot.report",
                robot=rng.choice(["r1", "r2"]),
                data={"battery": round(rng.random(), 3), "i": i},
                now=1767225600.0 + 4000 + i,
            )


@pytest.fixture
async def chain(tmp_path: Path, service_db: Path, mariadb_url: str) -> AsyncIterator[Chain]:
    need_mosquitto()
    mark("mariadb")
    c = Chain(tmp_path, service_db, mariadb_url)
    os.environ["SERVEUR_HQ_PASSWORD"] = "lookout-tower-9"  # the child's password, not asked
    try:
        await run_cli("hq", "user", "add", "chain-ops", "--db", mariadb_url)
    finally:
        del os.environ["SERVEUR_HQ_PASSWORD"]
    try:
        yield c
    except BaseException:
        print("the centre said:\n" + "\n".join(c.hq.output))
        raise
    finally:
        for proc in [c.hq, *c.sites.values()]:
            with contextlib.suppress(Exception):
                await proc.close()
        c.broker.stop(kill=True)


async def test_twenty_sites_reach_the_centre_exactly_once_through_crashes(chain: Chain) -> None:
    c = chain
    rng = random.Random(34)
    # The sites start with the broker down: their service waits in their outboxes.
    mark("set up")
    await c.hq.start()
    await c.start_sites(SITES)
    mark("sites started")
    c.login()
    assert await c.stored() == {}
    for site in rng.sample(SITES, 5):
        await add_events(c.dbs[site], 30, rng)
    await asyncio.to_thread(c.broker.start)

    # The centre away while the sites ship: the broker queues for its persistent session...
    async def some_stored() -> bool:
        return sum((await c.stored()).values()) > 0

    await until(some_stored, 60, "the centre's first events")
    await c.hq.kill()
    sent = {s: site_rows(db, "SELECT sent FROM outbox_state")[0][0] for s, db in c.dbs.items()}
    for site in rng.sample(SITES, 4):  # the restaurants go on while the centre is away
        await add_events(c.dbs[site], 20, rng)

    async def shipped_meanwhile() -> bool:
        return any(
            site_rows(db, "SELECT sent FROM outbox_state")[0][0] > sent[s]
            for s, db in c.dbs.items()
        )

    await until(shipped_meanwhile, 60, "a site shipping while the centre is away")
    # ... and crashes before its first autosave: what it queued is gone.
    await asyncio.to_thread(c.broker.restart, kill=True)
    await c.hq.start()
    mark("broker crashed")

    async def dead_is(state: str) -> bool:
        return await c.state_of(DEAD) == state

    await until(lambda: dead_is("up"), 30, f"{DEAD} heard by the centre")
    # Chaos: sites killed and started again, events written into running sites, one site
    # dead past the down limit, a clean broker restart.
    await c.sites[DEAD].kill()
    for round_ in range(3):
        victims = rng.sample([s for s in SITES if s != DEAD], 2)
        await asyncio.gather(*(c.sites[v].kill() for v in victims))
        await add_events(c.dbs[rng.choice(SITES)], 25, rng)
        for v in victims:
            await add_events(c.dbs[v], 10, rng)  # recorded while its server is down
        await c.start_sites(victims)
        if round_ == 1:
            await asyncio.to_thread(c.broker.restart)
    mark("chaos")
    await until(lambda: dead_is("down"), 30, f"{DEAD} shown down")
    await c.sites[DEAD].start()
    await until(lambda: dead_is("up"), 30, f"{DEAD} shown up again")

    mark("dead site down and up")
    # The end: every site stopped dead, its outbox drained by the shipper itself.
    for proc in c.sites.values():
        await proc.kill()
    shippers = [
        Shipper(SQLiteStore(c.dbs[s]), c.address(s), ScaledClock(1.0), heartbeat=1.0) for s in SITES
    ]
    for sh in shippers:
        await sh.store.open()
        sh.start()
    try:
        await until(c.synced, 120, "the centre to hold every site's every event")
    finally:
        for sh in shippers:
            await sh.close()
            await sh.store.close()

    mark("drained")
    # Exactly once, in order: the centre's copy is each site's events, number for number.
    # (The outbox rows the centre confirmed are pruned once older than the retention — the
    # replayed service is months old — so the order is checked on the events, whose ids
    # follow the numbers on SQLite, and on the rows still kept.)
    async with HqStore(open_hq_db(c.hq_db)) as hq:
        for site in SITES:
            db = c.dbs[site]
            mine = site_rows(db, "SELECT id, kind, data FROM events ORDER BY id")
            theirs = await hq.events(site, limit=10**6)
            assert [seq for seq, _ in theirs] == list(range(1, head_of(db) + 1)), site
            assert [(e.id, e.kind, e.data) for _, e in theirs] == [
                (ident, kind, json.loads(data)) for ident, kind, data in mine
            ], site
            kept = site_rows(db, "SELECT seq, event_id FROM outbox ORDER BY seq")
            assert all(theirs[seq - 1][1].id == ident for seq, ident in kept), site
            (confirmed,) = site_rows(db, "SELECT confirmed FROM outbox_state")[0]
            assert not kept or kept[0][0] == 1 or kept[0][0] <= confirmed + 1, site
        # Liveness: changes alternate (each reported once); the dead site went down and up.
        for site in SITES:
            states = [s for _, s in await hq.liveness(site)]
            assert states and states[0] == "up", site
            assert all(a != b for a, b in itertools.pairwise(states)), (site, states)
        assert "down" in [s for _, s in await hq.liveness(DEAD)]
    out = "\n".join(c.hq.output)
    assert "asked again" in out, out[-3000:]  # the broker's crash made a gap, filled

    # The dashboard's figures are each site's own `serveur stats`.
    for site in SITES:
        mine = await asyncio.to_thread(stats_json, c.dbs[site])
        theirs = await asyncio.to_thread(
            c.api, f"/api/sites/{site}/figures?by=day&utc_offset=%2B00:00"
        )
        assert theirs == mine, site
        assert mine["total"]["delivered"] > 0
    await c.hq.terminate()


T_START = time.monotonic()


def mark(what: str) -> None:
    print(f"{time.monotonic() - T_START:6.1f} s  {what}", flush=True)


def stats_json(db: Path) -> dict[str, Any]:
    out = io.StringIO()
    with contextlib.redirect_stdout(out):
        assert main(["stats", "--db", str(db), "--json", "--utc-offset", "+00:00"]) == 0
    parsed: dict[str, Any] = json.loads(out.getvalue())
    return parsed
