"""Shared fixtures: a real server on a real SQLite file, real simulated robots, real clients.

``Client`` keeps the latest state of every record it has heard of (from snapshots and pushed
updates) and lets a test wait for a condition on it with a timeout — never a sleep.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import os
import tempfile
import time
import urllib.error
import urllib.request
from collections.abc import AsyncIterator, Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
import websockets
from websockets.asyncio.client import ClientConnection, connect

from serveur.app import App, RobotSpec
from serveur.clock import Clock, ScaledClock
from serveur.core.engine import CoreConfig
from serveur.replay.vtime import LoopClock, VirtualTimeLoop
from serveur.security import auth

# The private MariaDB server (once per session) and a fresh database for a test that asks.
from tests.mariadb_server import mariadb_server, mariadb_url  # noqa: F401
from tests.netproxy import LinkProxy

TIME_SCALE = 10.0

# The plan cache (serveur.maps.plancache) of this test run: shared by both workers and every
# server they start in a child process, fresh for each run (never the developer's own).
os.environ.setdefault(
    "SERVEUR_PLAN_CACHE",
    str(
        Path(tempfile.gettempdir())
        / f"serveur-test-plans-{os.environ.get('PYTEST_XDIST_TESTRUNUID', os.getpid())}"
    ),
)

# Passwords hashed in this process: scrypt at N=2**10 instead of the product's 2**15 (32 MiB and
# about 0.12 s a hash on this box, several hundred logins a run; as Django's tests swap their
# password hasher). The hash names its N and verify_password reads it there, so the code under
# test is the same; servers started in a child process keep the product's cost.
PRODUCT_SCRYPT_N = auth._SCRYPT_N
auth._SCRYPT_N = 2**10  # type: ignore[misc]


def subscribers(sim: Any, topic: str, robot: int = 0) -> int:
    """How many clients a simulated robot's rosbridge serves ``topic`` to now."""
    return len(sim.robots[robot].outbox.subs.get(topic, ()))


async def poll_until(cond: Callable[[], Any], timeout: float, what: str) -> Any:
    """Wait until ``cond()`` holds, polling every 10 ms; fail after ``timeout`` wall seconds.

    For state with no event to wait on: a simulated robot's own goals and pose, read in this
    process while its server runs elsewhere or is not told.
    """
    deadline = time.monotonic() + timeout
    while not (value := cond()):
        if time.monotonic() > deadline:
            raise AssertionError(f"timed out waiting for {what}")
        await asyncio.sleep(0.01)
    return value


class _LinkDrops(logging.Handler):
    """Robot links that went down, other than for a server shutting down."""

    def __init__(self) -> None:
        super().__init__(logging.WARNING)
        self.drops: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        msg = record.getMessage()
        if "link down (" in msg and "server shutting down" not in msg:
            self.drops.append(msg)


#: Tests that run on virtual time (serveur.replay.vtime: the loop's clock jumps to the next
#: timer once every task waits, as trio's autojump clock): the rules of the core and whole
#: services through the real server and simulated robots, whose waits are a matter of rules,
#: not of the wall: a robot's drive, a heartbeat, a Wi-Fi stall (the links count its allowance
#: in wall seconds, and on :class:`LoopClock` a wall second is a loop second). MariaDB is another
#: process, but its store says it is busy while a query is out, so time holds meanwhile. Not
#: here: tests with a browser or another process on the other end of a socket (its replies take
#: wall time: virtual time would jump past them), tests of rules kept on ``time.monotonic``
#: (sessions, idle connections, rate limits), and tests marked ``wall_clock``.
VIRTUAL_TIME = (
    "tests/core/",
    "tests/test_e2e.py",
    "tests/test_protocol_doc.py",
    "tests/test_scheduler.py",
    "tests/robots/test_nav2_link.py",
    "tests/robots/test_names.py",
    "tests/robots/test_link_faults.py",
    "tests/robots/test_dropouts.py",
    "tests/robots/test_ros2_liveness.py",
    "tests/robots/test_link_realstack.py",
    "tests/robots/test_conformance.py",
    "tests/test_e2e_mariadb.py",
    "tests/test_localisation.py",
)


def pytest_asyncio_loop_factories(config: Any, item: Any) -> Mapping[str, Any]:
    path = Path(str(item.path)).relative_to(Path(str(config.rootpath))).as_posix()
    if path.startswith(VIRTUAL_TIME) and item.get_closest_marker("wall_clock") is None:
        return {"virtual-time": VirtualTimeLoop}
    return {"asyncio": asyncio.SelectorEventLoop}


#: The longest modules (wall seconds with three workers on two cores, longest first) start
#: first: with ``--no-loadscope-reorder`` (pyproject.toml) xdist's ``--dist loadscope`` hands
#: modules out in collection order (by default it sorts them by their number of tests), and a
#: long module handed out last keeps one worker busy for a minute after the others are done.
LONGEST_FIRST = (
    "tests/replay/test_replay.py",
    "tests/web/test_ui.py",
    "tests/stats/test_stats_verb.py",
    "tests/store/test_crash.py",
    "tests/test_fuzz.py",
    "tests/replay/test_traffic.py",
    "tests/web/test_forecast_ui.py",
    "tests/web/test_service_ui.py",
    "tests/web/test_modes_staff.py",
    "tests/web/test_modes_guest.py",
    "tests/web/test_stats_ui.py",
    "tests/web/test_map_legend.py",
    "tests/web/test_zones_ui.py",
    "tests/test_shutdown.py",
    "tests/web/test_guest_screens.py",
    "tests/web/test_a11y.py",
)


def pytest_collection_modifyitems(config: Any, items: list[Any]) -> None:
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    root = Path(str(config.rootpath))

    def first(item: Any) -> int:
        path = Path(str(item.path)).relative_to(root).as_posix()
        return rank.get(path, len(rank))

    items.sort(key=first)  # stable: each module's tests keep their order


@pytest.fixture(autouse=True)
def _queries_hold_time(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Every server a test starts on a virtual-time loop holds time still while its SQLite
    queries run in aiosqlite's thread (the replay does the same for its server)."""
    start = App.start

    async def holding(self: App) -> App:
        loop = asyncio.get_running_loop()
        if isinstance(loop, VirtualTimeLoop):
            loop.add_busy(self.store.busy)
        return await start(self)

    monkeypatch.setattr(App, "start", holding)
    yield


@pytest.fixture(autouse=True)
def no_robot_offline_by_accident(request: pytest.FixtureRequest) -> Iterator[None]:
    """No robot goes Offline in a test unless the test cuts links on purpose (``cuts_links``):
    a false drop (a stalled loop, a heartbeat too tight for a loaded CI box) fails the test
    that saw it, where it would otherwise pass unnoticed, as it would in a restaurant."""
    handler = _LinkDrops()
    logger = logging.getLogger("serveur.robots.ros1.link")
    logger.addHandler(handler)
    try:
        yield
    finally:
        logger.removeHandler(handler)
    if handler.drops and request.node.get_closest_marker("cuts_links") is None:
        pytest.fail(f"a robot link went down: {handler.drops}", pytrace=False)


WAIT = 30.0  # wall seconds: generous for a loaded 2-core CI box; tests end as soon as they can


def budget(timeout: float) -> float:
    """A wait's bound on the running loop: ``timeout`` wall seconds, or on virtual time the
    simulated time those cover at ``TIME_SCALE`` (a robot charging for two simulated minutes
    fits in 30 wall seconds at 10x; 30 virtual seconds it does not)."""
    if isinstance(asyncio.get_running_loop(), VirtualTimeLoop):
        return timeout * TIME_SCALE
    return timeout


class Client:
    """A scripted staff tablet: request/reply by id, and a live view of every topic."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self._ids = itertools.count(1)
        self._pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self.records: dict[str, dict[Any, dict[str, Any]]] = {}
        self.streams: dict[str, Any] = {}
        self.seqs: list[int] = []
        self.frames: list[dict[str, Any]] = []
        self._changed = asyncio.Condition()
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                msg = json.loads(frame)
                self.frames.append(msg)
                if msg["servermsg"] == "update":
                    self.seqs.append(msg["seq"])
                    self._apply(msg["topic"], msg["data"])
                else:
                    if msg["servermsg"] == "ok" and isinstance(msg.get("data"), dict):
                        # A snapshot, applied here in frame order: updates after it are newer
                        # (the server sends them after the reply), so none is overwritten.
                        self._apply_snapshot(msg["data"])
                    fut = self._pending.pop(msg.get("id"), None)
                    if fut is not None and not fut.done():
                        fut.set_result(msg)
                async with self._changed:
                    self._changed.notify_all()

    def _apply(self, topic: str, data: Any) -> None:
        keys = {"robots": "name", "waypoints": "name", "menu": "dish", "blocks": "table"}
        if topic in (
            "robots",
            "orders",
            "tasks",
            "waypoints",
            "events",
            "alerts",
            "menu",
            "blocks",
            "calls",
            "tickets",
        ):
            self.records.setdefault(topic, {})[data[keys.get(topic, "id")]] = data
        else:
            self.streams[topic] = data

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        rid = next(self._ids)
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self._pending[rid] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": rid, **fields}))
        return await asyncio.wait_for(fut, budget(WAIT))

    async def ok(self, verb: str, **fields: Any) -> dict[str, Any]:
        reply = await self.call(verb, **fields)
        assert reply["servermsg"] == "ok", reply
        return reply

    async def error(self, verb: str, code: str, **fields: Any) -> dict[str, Any]:
        reply = await self.call(verb, **fields)
        assert reply["servermsg"] == "error" and reply["code"] == code, reply
        return reply

    def _apply_snapshot(self, data: dict[str, Any]) -> None:
        for topic, snap in data.items():
            if isinstance(snap, list):
                for rec in snap:
                    self._apply(topic, rec)
            elif snap is not None:
                self._apply(topic, snap)

    async def subscribe(self, *topics: str) -> dict[str, Any]:
        return await self.ok("data", topics=list(topics))  # the reader applies the snapshot

    def robot(self, name: str) -> dict[str, Any]:
        return self.records.get("robots", {}).get(name, {})

    def order(self, oid: int) -> dict[str, Any]:
        return self.records.get("orders", {}).get(oid, {})

    def task(self, tid: int) -> dict[str, Any]:
        return self.records.get("tasks", {}).get(tid, {})

    async def until(self, cond: Callable[[], Any], timeout: float = WAIT, what: str = "") -> Any:
        async def wait() -> Any:
            async with self._changed:
                while not (res := cond()):
                    await self._changed.wait()
                return res

        try:
            return await asyncio.wait_for(wait(), budget(timeout))
        except TimeoutError:
            raise AssertionError(f"timed out waiting for {what or cond}") from None

    async def status(self, robot: str, status: str, timeout: float = WAIT) -> dict[str, Any]:
        await self.until(
            lambda: self.robot(robot).get("status") == status,
            timeout,
            f"{robot} to be {status} (is {self.robot(robot).get('status')})",
        )
        return self.robot(robot)

    async def close(self) -> None:
        await self.ws.close()
        self._reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._reader


@dataclass
class Restaurant:
    app: App
    sim: Any
    clock: Clock
    db: Path | str  # a SQLite file, or a database URL (mariadb://...)
    specs: list[RobotSpec]
    clients: list[Client]
    #: How this restaurant's server is built: (db, clock, specs, port) -> App.
    make: Callable[[Path | str, Clock, list[RobotSpec], int], App] = lambda *a: make_app(*a)

    #: A staff token made at start (the database keeps it across restart_server).
    token: str = ""
    #: With ``restaurant(..., proxied=True)``: each robot's link goes through one of these.
    proxies: list[LinkProxy] = field(default_factory=list)

    @property
    def http_base(self) -> str:
        """The server's plain HTTP address (the pages, downloads, the floor plan's image)."""
        return self.app.url.replace("ws://", "http://").removesuffix("/ws")

    async def get(self, path: str) -> tuple[int, bytes, str]:
        """GET ``path`` as a browser does (a tapped link, an image): status, body, type."""

        def fetch() -> tuple[int, bytes, str]:
            try:
                with urllib.request.urlopen(self.http_base + path, timeout=10) as resp:
                    return resp.status, resp.read(), resp.headers["Content-Type"]
            except urllib.error.HTTPError as exc:
                return exc.code, exc.read(), exc.headers["Content-Type"]

        return await asyncio.to_thread(fetch)

    def auth_headers(self) -> dict[str, str]:
        """Handshake headers that authenticate a raw ``connect(self.app.url, ...)`` as staff.

        Use :meth:`client` where you can; a test that needs its own connection passes
        ``additional_headers=r.auth_headers()``.
        """
        return {"Authorization": f"Bearer {self.token}"}

    async def client(self) -> Client:
        c = Client(
            await connect(self.app.url, max_size=2**24, additional_headers=self.auth_headers())
        )
        self.clients.append(c)
        return c

    async def screen(self, role: str, **bound: str) -> Client:
        """A connection with a new screen token (``robot-screen`` with ``robot=``,
        ``table-screen`` with ``table=``), as that screen would log in."""
        token = await self.app.issue_token(role, label=f"{role} {bound}", **bound)
        headers = {"Authorization": f"Bearer {token}"}
        c = Client(await connect(self.app.url, max_size=2**24, additional_headers=headers))
        self.clients.append(c)
        return c

    async def restart_server(self) -> None:
        """Stop the server (clean close) and start a new one on the same database and port,
        as a real restart does: pages reconnect to the address they were loaded from."""
        assert self.app.server is not None
        port = self.app.server.port
        for c in self.clients:
            await c.close()
        self.clients.clear()
        await self.app.close()
        self.app = self.make(self.db, self.clock, self.specs, port)
        await self.app.start()


def test_clock(time_scale: float = TIME_SCALE) -> Clock:
    """The clock a test's server and robots share.

    On a virtual-time loop (tests/core: time jumps when every task waits, as trio's autojump
    clock) it is the loop's own: a robot's drive costs CPU time only. Elsewhere it is the wall
    clock sped up ``time_scale`` times.
    """
    if isinstance(asyncio.get_running_loop(), VirtualTimeLoop):
        return LoopClock()
    return ScaledClock(time_scale)


test_clock.__test__ = False  # type: ignore[attr-defined]  # a helper, not a test


def make_app(
    db: Path | str,
    clock: Clock,
    specs: list[RobotSpec],
    port: int = 0,
    *,
    config: CoreConfig | None = None,
    backups: Path | None = None,
    mqtt: str | None = None,
) -> App:
    from serveur.maps.navigation import load_demo

    nav_map, waypoints = load_demo()
    cfg = config or CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=True)
    return App(
        db,
        port=port,
        clock=clock,
        nav_map=nav_map,
        waypoints=waypoints,
        robots=specs,
        config=cfg,
        backups=backups,
        mqtt=mqtt,
    )


def sim_link(robot: Any) -> dict[str, str]:
    """The registration options of a simulated robot: its namespace, and ``ros=2`` for one
    that speaks ROS 2 (Nav2 over rosbridge 2.x)."""
    link = {"ns": robot.namespace} if robot.namespace else {}
    if robot.ros == 2:
        link["ros"] = "2"
    return link


@contextlib.asynccontextmanager
async def restaurant(
    tmp_path: Path,
    robots: int = 1,
    time_scale: float = TIME_SCALE,
    db_url: str | None = None,
    *,
    proxied: bool = False,
    config: CoreConfig | None = None,
    link: Mapping[str, str] | None = None,
    backups: bool = False,
    mqtt: str | None = None,
    **sim_options: Any,
) -> AsyncIterator[Restaurant]:
    """A running restaurant on a SQLite file in ``tmp_path``, or on ``db_url`` if given.

    ``link``: more link options for every robot (``{"camera": "camera/image/compressed"}``).
    ``backups``: the server keeps its backups in ``tmp_path / "backups"``.

    ``proxied``: each robot is reached through a :class:`~tests.netproxy.LinkProxy` that a
    test can blackhole or inject frames into. ``sim_options`` go to ``start_simulation``.
    """
    from serveur.maps.navigation import demo_map_path
    from serveur.robot_sim import start_simulation

    clock = test_clock(time_scale)
    # The simulator's real-stack mode: AMCL latched and sparse (0.2 m / 30 degrees), as a real
    # robot publishes it; actionlib's stamp rule and move_base ignoring /cmd_vel are always on.
    sim_options.setdefault("amcl", "real")
    sim = await start_simulation(
        robots,
        port=0,
        map_path=demo_map_path(),
        time_scale=time_scale,
        clock=clock,
        **sim_options,
    )
    proxies = [await LinkProxy.for_url(url).start() for url in sim.urls] if proxied else []
    urls = [p.url for p in proxies] if proxied else sim.urls
    specs = [
        RobotSpec(r.name, url, f"home{i + 1}", link={**sim_link(r), **(link or {})})
        for i, (r, url) in enumerate(zip(sim.robots, urls, strict=True))
    ]
    db = db_url or tmp_path / "serveur.db"
    folder = tmp_path / "backups" if backups else None
    app = make_app(db, clock, specs, config=config, backups=folder, mqtt=mqtt)
    await app.start()
    r = Restaurant(app, sim, clock, db, specs, [], proxies=proxies)
    if backups:
        r.make = lambda *a: make_app(*a, config=config, backups=folder)
    r.token = await app.issue_token("staff", label="tests")
    try:
        yield r
    finally:
        for c in r.clients:
            await c.close()
        await r.app.close()
        for proxy in proxies:
            await proxy.close()
        await sim.close()


@contextlib.asynccontextmanager
async def intake_app(tmp_path: Path, clock: Clock | None = None) -> AsyncIterator[App]:
    """A server of the demo room without robots, its order-intake API listening on a port the
    system chooses (``app.intake.port``): the till's tests and the integration token's."""
    from serveur.maps.navigation import load_demo

    nav_map, waypoints = load_demo()
    app = App(
        tmp_path / "serveur.db",
        port=0,
        clock=clock or test_clock(),
        nav_map=nav_map,
        waypoints=waypoints,
        config=CoreConfig(heartbeat=10.0, ack_timeout=5.0),
        plan_in_child=False,
        intake_port=0,
    )
    await app.start()
    try:
        yield app
    finally:
        await app.close()


@contextlib.asynccontextmanager
async def served_by(
    tmp_path: Path, make: Callable[[Path | str, Clock, list[RobotSpec], int], App], label: str
) -> AsyncIterator[Restaurant]:
    """One simulated robot (r1, at home1, the wall clock sped up) and a server built by
    ``make`` (a test module's own ``make_app`` with its config), a staff token made: the
    restaurant the Chromium tests drive."""
    from serveur.maps.navigation import demo_map_path
    from serveur.robot_sim import start_simulation

    clock = ScaledClock(TIME_SCALE)
    sim = await start_simulation(
        1, port=0, map_path=demo_map_path(), time_scale=TIME_SCALE, clock=clock
    )
    specs = [RobotSpec(sim.robots[0].name, sim.urls[0], "home1")]
    db = tmp_path / "serveur.db"
    r = Restaurant(make(db, clock, specs, 0), sim, clock, db, specs, [], make=make)
    try:
        await r.app.start()
        r.token = await r.app.issue_token("staff", label=label)
        yield r
    finally:
        for c in r.clients:
            await c.close()
        await r.app.close()
        await sim.close()


@pytest.fixture
async def one_robot(tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=1) as r:
        yield r


@pytest.fixture
async def two_robots(tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=2) as r:
        yield r


@pytest.fixture(params=[1, 2], ids=["ros1", "ros2"])
async def any_robot(request: pytest.FixtureRequest, tmp_path: Path) -> AsyncIterator[Restaurant]:
    """One robot, run once as a ROS1 and once as a ROS 2 robot: a module that takes its
    ``one_robot`` from this checks that nothing above the robot driver tells them apart."""
    async with restaurant(tmp_path, robots=1, ros=request.param) as r:
        yield r


@pytest.fixture(params=[[1, 1], [1, 2]], ids=["ros1", "mixed"])
async def any_two_robots(
    request: pytest.FixtureRequest, tmp_path: Path
) -> AsyncIterator[Restaurant]:
    """Two ROS1 robots, then a mixed fleet (one ROS1, one ROS 2)."""
    async with restaurant(tmp_path, robots=2, ros=request.param) as r:
        yield r
