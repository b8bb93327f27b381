"""TLS end to end: a private CA (trustme), the server on https + wss, robots on wss.

Everything is real — sockets, handshakes, certificate checks — so these tests fail if the
server or a link ever talks in the clear or stops verifying. Waits are on events with timeouts.
"""

from __future__ import annotations

import asyncio
import contextlib
import http.client
import json
import logging
import os
import re
import signal
import ssl
import sys
from collections.abc import AsyncIterator, Iterator, Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest
import trustme
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import InvalidHandshake

from serveur.app import App, RobotSpec
from serveur.cli import main
from serveur.clock import ScaledClock
from serveur.core.engine import CoreConfig
from serveur.security.tls import client_context, server_context
from tests.conftest import TIME_SCALE, WAIT, Client, Restaurant
from tests.subprocess_server import free_port
from tests.test_cli import read_until

# -- a private CA and certificates ------------------------------------------------------------


@dataclass(frozen=True)
class Pki:
    """PEM files of one CA and of a certificate it issued (as an operator would have them)."""

    ca: Path
    cert: Path
    key: Path

    def server(self) -> ssl.SSLContext:
        return server_context(str(self.cert), str(self.key))

    def client(self) -> ssl.SSLContext:
        return client_context(str(self.ca))


def write_pki(ca: trustme.CA, where: Path, *names: str) -> Pki:
    where.mkdir(parents=True, exist_ok=True)
    leaf = ca.issue_cert(*names)
    pki = Pki(where / "ca.pem", where / "cert.pem", where / "key.pem")
    ca.cert_pem.write_to_path(str(pki.ca))
    for i, blob in enumerate(leaf.cert_chain_pems):
        blob.write_to_path(str(pki.cert), append=i > 0)
    leaf.private_key_pem.write_to_path(str(pki.key))
    return pki


@pytest.fixture(scope="module")
def our_ca() -> trustme.CA:
    return trustme.CA()


@pytest.fixture(scope="module")
def pki(our_ca: trustme.CA, tmp_path_factory: pytest.TempPathFactory) -> Pki:
    """The restaurant's CA and a certificate for this machine (127.0.0.1 and localhost)."""
    return write_pki(our_ca, tmp_path_factory.mktemp("pki"), "127.0.0.1", "localhost")


@pytest.fixture(scope="module")
def other_pki(tmp_path_factory: pytest.TempPathFactory) -> Pki:
    """Someone else's CA (a certificate for the right names, but not one we trust)."""
    return write_pki(trustme.CA(), tmp_path_factory.mktemp("other"), "127.0.0.1", "localhost")


# -- connecting: the one place this file opens client websockets ------------------------------


async def open_ws(
    url: str, ctx: ssl.SSLContext | None, headers: Mapping[str, str]
) -> ClientConnection:
    """Open a client websocket; ``ctx`` None lets websockets pick (system trust for wss://).

    ``headers`` authenticate the connection (``Restaurant.auth_headers()``), so a refusal
    seen here is about TLS, never about a missing login.
    """
    kwargs: dict[str, Any] = {"ssl": ctx} if ctx is not None else {}
    return await connect(
        url, max_size=2**24, open_timeout=WAIT, additional_headers=dict(headers), **kwargs
    )


async def tls_client(r: Restaurant, ctx: ssl.SSLContext) -> Client:
    c = Client(await open_ws(r.app.url, ctx, r.auth_headers()))
    r.clients.append(c)
    return c


# -- a restaurant whose server and/or robots use TLS ------------------------------------------


def tls_app(
    db: Path | str,
    clock: ScaledClock,
    specs: list[RobotSpec],
    port: int = 0,
    *,
    server_tls: ssl.SSLContext | None = None,
    robot_tls: ssl.SSLContext | None = None,
) -> App:
    """conftest.make_app with the TLS options (same map, waypoints and link tunables)."""
    from serveur.maps.navigation import load_demo

    nav_map, waypoints = load_demo()
    return App(
        db,
        port=port,
        clock=clock,
        nav_map=nav_map,
        waypoints=waypoints,
        robots=specs,
        config=CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=True),
        ssl=server_tls,
        robot_ssl=robot_tls,
    )


@contextlib.asynccontextmanager
async def tls_restaurant(
    tmp_path: Path,
    *,
    server_tls: ssl.SSLContext | None,
    robot_server_tls: ssl.SSLContext | None = None,
    robot_tls: ssl.SSLContext | None = None,
) -> AsyncIterator[Restaurant]:
    """conftest.restaurant() with one robot, TLS where asked: ``server_tls`` for /ws and the
    UI, ``robot_server_tls`` for the simulated robot's rosbridge, ``robot_tls`` for the link."""
    from serveur.maps.navigation import demo_map_path
    from serveur.robot_sim import start_simulation

    clock = ScaledClock(TIME_SCALE)
    sim = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=clock, ssl=robot_server_tls
    )
    specs = [RobotSpec(sim.robots[0].name, sim.urls[0], "home1")]
    db = tmp_path / "serveur.db"

    def make(db: Path | str, clock: ScaledClock, specs: list[RobotSpec], port: int) -> App:
        return tls_app(db, clock, specs, port, server_tls=server_tls, robot_tls=robot_tls)

    app = make(db, clock, specs, 0)
    await app.start()
    r = Restaurant(app, sim, clock, db, specs, [], make)
    r.token = await app.issue_token("staff", label="tls tests")
    try:
        yield r
    finally:
        for c in r.clients:
            await c.close()
        await r.app.close()
        await sim.close()


def https_get(url: str, path: str, ctx: ssl.SSLContext) -> tuple[int, bytes]:
    """GET over https with ``ctx`` (http.client: no proxy from the environment in the way)."""
    host, _, port = url.split("://", 1)[1].split("/", 1)[0].rpartition(":")
    conn = http.client.HTTPSConnection(host, int(port), context=ctx, timeout=WAIT)
    try:
        conn.request("GET", path)
        resp = conn.getresponse()
        return resp.status, resp.read()
    finally:
        conn.close()


# -- (a) the server over TLS ------------------------------------------------------------------


async def test_staff_client_trusting_the_ca_uses_wss(tmp_path: Path, pki: Pki) -> None:
    async with tls_restaurant(tmp_path, server_tls=pki.server()) as r:
        assert r.app.url.startswith("wss://127.0.0.1:")
        c = await tls_client(r, pki.client())
        tls = c.ws.transport.get_extra_info("ssl_object")
        assert tls is not None and tls.version() in ("TLSv1.2", "TLSv1.3")
        reply = await c.subscribe("robots", "waypoints")
        assert [rb["name"] for rb in reply["data"]["robots"]] == ["r1"]
        assert any(w["name"] == "home1" for w in reply["data"]["waypoints"])
        await c.status("r1", "Ready")  # the plain ws:// robot link is unaffected


async def test_healthz_and_ui_over_https(tmp_path: Path, pki: Pki) -> None:
    async with tls_restaurant(tmp_path, server_tls=pki.server()) as r:
        status, body = await asyncio.to_thread(https_get, r.app.url, "/healthz", pki.client())
        assert status == 200
        health = json.loads(body)
        assert health["status"] == "ok" and "r1" in health["robots"]
        status, body = await asyncio.to_thread(https_get, r.app.url, "/", pki.client())
        assert status == 200 and b"<html" in body.lower()


async def test_staff_console_over_https_opens_wss(tmp_path: Path, pki: Pki) -> None:
    """The page chooses its socket's scheme from its own: loaded over https, it must use wss
    (a ws:// socket from an https page is blocked by browsers as mixed content)."""
    from tests.web.conftest import CHROMIUM, CHROMIUM_ARGS, need_browser

    need_browser()  # skipped without chromium or playwright, saying which; failed in CI
    import playwright.async_api as pw

    async with tls_restaurant(tmp_path, server_tls=pki.server()) as r, pw.async_playwright() as p:
        browser = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            # Chromium does not read our CA file; the certificate checks are the other tests'.
            context = await browser.new_context(ignore_https_errors=True)
            page = await context.new_page()
            web = r.app.url.replace("wss://", "https://", 1).removesuffix("/ws")
            async with page.expect_websocket(timeout=WAIT * 1000) as opened:
                await page.goto(web + f"/#token={r.token}")
            ws = await opened.value
            assert ws.url.startswith("wss://"), ws.url
            await ws.wait_for_event("framereceived", timeout=WAIT * 1000)  # the server answers
            # ...and the page logged in and is live over it.
            await pw.expect(page.locator("body")).to_have_attribute(
                "data-connection", "online", timeout=WAIT * 1000
            )
        finally:
            await browser.close()


# -- (b) nothing in the clear, nothing unverified ---------------------------------------------


async def test_plain_ws_client_is_refused_by_the_tls_port(tmp_path: Path, pki: Pki) -> None:
    async with tls_restaurant(tmp_path, server_tls=pki.server()) as r:
        plain = r.app.url.replace("wss://", "ws://", 1)
        with pytest.raises(InvalidHandshake):  # TLS alert bytes are not an HTTP response
            await open_ws(plain, None, r.auth_headers())

        def http_get() -> int:
            host, port = plain.split("//")[1].split("/")[0].split(":")
            conn = http.client.HTTPConnection(host, int(port), timeout=WAIT)
            try:
                conn.request("GET", "/healthz")
                return conn.getresponse().status
            finally:
                conn.close()

        with pytest.raises((http.client.HTTPException, ConnectionError)):
            await asyncio.to_thread(http_get)
        # ... and the server is none the worse for it.
        c = await tls_client(r, pki.client())
        await c.subscribe("robots")


async def test_client_not_trusting_the_ca_fails_verification(
    tmp_path: Path, pki: Pki, other_pki: Pki
) -> None:
    async with tls_restaurant(tmp_path, server_tls=pki.server()) as r:
        for ctx in (None, other_pki.client()):  # the system store, then another CA
            with pytest.raises(ssl.SSLCertVerificationError):
                await open_ws(r.app.url, ctx, r.auth_headers())
        with pytest.raises(ssl.SSLCertVerificationError):
            await asyncio.to_thread(https_get, r.app.url, "/healthz", ssl.create_default_context())


# -- (c) robots over wss:// -------------------------------------------------------------------


async def test_robot_over_wss_becomes_ready_and_delivers(tmp_path: Path, pki: Pki) -> None:
    async with tls_restaurant(
        tmp_path, server_tls=pki.server(), robot_server_tls=pki.server(), robot_tls=pki.client()
    ) as r:
        assert r.specs[0].url.startswith("wss://127.0.0.1:")
        c = await tls_client(r, pki.client())
        await c.subscribe("robots", "orders", "tasks")
        await c.status("r1", "Ready")
        # Goals and reports cross the TLS link both ways: drive one order to its table.
        await c.ok("control", robot="r1", action="auto")
        await c.status("r1", "Awaiting")
        oid = (await c.ok("create", type="order", dish="Laksa", table="T3"))["order"]["id"]
        await c.ok("create", type="task", orders=[oid])
        await c.status("r1", "Delivered")


@pytest.mark.cuts_links  # the robot is stopped before the server
async def test_robot_added_from_the_console_over_wss(tmp_path: Path, pki: Pki) -> None:
    """A robot created at run time gets the same robot CA as the ones on the command line."""
    from serveur.robot_sim import start_simulation

    async with tls_restaurant(tmp_path, server_tls=pki.server(), robot_tls=pki.client()) as r:
        # Registering robots is the owner's (or an integration given the "robots" scope).
        r.token = await r.app.issue_token("integration", scopes=["robots", "read"])
        c = await tls_client(r, pki.client())
        await c.subscribe("robots")
        async with await start_simulation(
            1, port=0, clock=r.clock, names=["r2"], ssl=pki.server()
        ) as sim:
            url = sim.urls[0].replace("wss://", "WSS://", 1)  # schemes are case-insensitive
            await c.ok("create", type="robot", name="r2", url=url, home="home2")
            await c.status("r2", "Ready")


class _LinkLog(logging.Handler):
    """Collects serveur.robots.ros1.link records and wakes a waiter (the link logs on the loop)."""

    def __init__(self) -> None:
        super().__init__(logging.DEBUG)
        self.records: list[logging.LogRecord] = []
        self.changed = asyncio.Event()

    def emit(self, record: logging.LogRecord) -> None:
        self.records.append(record)
        self.changed.set()

    def tls_failures(self) -> list[logging.LogRecord]:
        return [r for r in self.records if "TLS:" in r.getMessage()]

    async def until_tls_failures(self, n: int) -> list[logging.LogRecord]:
        async def wait() -> list[logging.LogRecord]:
            while len(found := self.tls_failures()) < n:
                self.changed.clear()
                await self.changed.wait()
            return found

        return await asyncio.wait_for(wait(), WAIT)


@contextlib.contextmanager
def link_log() -> Iterator[_LinkLog]:
    logger = logging.getLogger("serveur.robots.ros1.link")
    handler, level = _LinkLog(), logger.level
    logger.addHandler(handler)
    logger.setLevel(logging.DEBUG)
    try:
        yield handler
    finally:
        logger.removeHandler(handler)
        logger.setLevel(level)


@pytest.mark.parametrize("fault", ["untrusted CA", "wrong host name"])
async def test_robot_failing_verification_stays_offline(
    tmp_path: Path, our_ca: trustme.CA, pki: Pki, other_pki: Pki, fault: str
) -> None:
    if fault == "untrusted CA":
        robot_cert, expected = other_pki, "certificate verify failed"
    else:  # signed by our CA, but for another machine: the hostname check must catch it
        robot_cert = write_pki(our_ca, tmp_path / "robot7", "robot7.example")
        expected = "mismatch"
    with link_log() as log:
        async with tls_restaurant(
            tmp_path,
            server_tls=pki.server(),
            robot_server_tls=robot_cert.server(),
            robot_tls=pki.client(),
        ) as r:
            failures = await log.until_tls_failures(2)  # it failed, and kept retrying
            assert expected in failures[0].getMessage()
            said = [f for f in failures if f.levelno >= logging.WARNING]
            assert len(said) == 1, "the operator is told once, not once per retry"
            # The server carries on: it answers, and reports the robot Offline.
            c = await tls_client(r, pki.client())
            await c.subscribe("robots")
            assert c.robot("r1")["status"] == "Offline"
            _, body = await asyncio.to_thread(https_get, r.app.url, "/healthz", pki.client())
            assert json.loads(body)["robots"] == {"r1": "Offline"}


# -- (d) the command line ---------------------------------------------------------------------


@pytest.mark.parametrize("command", ["run", "demo", "sim"])
@pytest.mark.parametrize("given", ["--certfile", "--keyfile"])
def test_certfile_and_keyfile_go_together(
    command: str, given: str, pki: Pki, capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exc:
        main([command, given, str(pki.cert)])
    assert exc.value.code == 2
    assert "--certfile and --keyfile go together" in capsys.readouterr().err


@pytest.mark.parametrize("command", ["run", "demo", "sim"])
def test_unusable_certificate_refuses_to_start(
    command: str, tmp_path: Path, pki: Pki, other_pki: Pki, capsys: pytest.CaptureFixture[str]
) -> None:
    db = ["--db", str(tmp_path / "x.db")] if command != "sim" else []
    # A key that does not match the certificate: refuse, never fall back to the clear.
    args = [command, "--port", "0", *db, "--certfile", str(pki.cert), "--keyfile"]
    assert main([*args, str(other_pki.key)]) == 1
    err = capsys.readouterr().err
    assert "cannot start" in err and str(pki.cert) in err
    assert main([*args, str(tmp_path / "missing.pem")]) == 1
    assert "not found" in capsys.readouterr().err
    assert not (tmp_path / "x.db").exists()  # refused before opening anything


@pytest.mark.parametrize("command", ["run", "demo"])
def test_missing_robot_cafile_refuses_to_start(
    command: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    missing = str(tmp_path / "nope.pem")
    db = str(tmp_path / "x.db")
    assert main([command, "--port", "0", "--db", db, "--robot-cafile", missing]) == 1
    assert f"CA file not found: {missing}" in capsys.readouterr().err


async def test_cli_sim_and_run_over_tls(tmp_path: Path, pki: Pki) -> None:
    """`serveur sim` and `serveur run` as an operator starts them, everything over TLS."""
    sim_port, port = free_port(2), free_port()
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    tls = ["--certfile", str(pki.cert), "--keyfile", str(pki.key)]
    procs: list[asyncio.subprocess.Process] = []

    async def start(*args: str) -> asyncio.subprocess.Process:
        proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "serveur.cli",
            *args,
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.STDOUT,
            env=env,
        )
        procs.append(proc)
        return proc

    try:
        sim = await start(
            "sim", "--robots", "1", "--port", str(sim_port), "--time-scale", "5", *tls
        )
        await read_until(sim, f"wss://127.0.0.1:{sim_port}")
        run = await start(
            "run",
            "--port",
            str(port),
            "--db",
            str(tmp_path / "s.db"),
            "--time-scale",
            "5",
            "--robot",
            f"r1=wss://127.0.0.1:{sim_port}",
            "--robot-cafile",
            str(pki.ca),
            *tls,
        )
        url = f"wss://127.0.0.1:{port}/ws"
        out = await read_until(run, "setup.html#setup=")  # the first start's setup link
        assert url in out
        code = re.search(r"https://\S+/setup\.html#setup=(\S+)", out)
        assert code, out
        c = Client(await open_ws(url, pki.client(), {}))
        try:
            await c.ok("login", setup=code[1], username="owner", password="a long pass")
            await c.subscribe("robots")
            await c.status("r1", "Ready")
        finally:
            await c.close()
        for proc in procs:
            proc.send_signal(signal.SIGTERM)
            assert await asyncio.wait_for(proc.wait(), 20) == 0
    finally:
        for proc in procs:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
