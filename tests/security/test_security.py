"""Accounts, roles, limits and audit over real sockets, against a real server and database."""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import os
import sqlite3
import sys
from collections.abc import AsyncIterator, Mapping
from pathlib import Path
from typing import Any

import pytest
import websockets
from websockets.asyncio.client import ClientConnection, connect

from serveur.app import App
from serveur.clock import FakeClock
from serveur.security.sessions import CLOSE_AUTH, SecurityConfig
from tests.conftest import WAIT, Client, Restaurant

# -- helpers ---------------------------------------------------------------------------------


@contextlib.asynccontextmanager
async def bare_server(
    tmp_path: Path, *, app: Mapping[str, Any] | None = None, **security: Any
) -> AsyncIterator[App]:
    """A server with no robots (unless ``app`` gives some) on a fresh database and the demo
    room's waypoints, on a clock the test moves; ``app``: more of App's options (its map,
    zones, robots...)."""
    from serveur.maps.navigation import load_demo

    _, waypoints = load_demo()
    server = App(
        tmp_path / "s.db",
        port=0,
        clock=FakeClock(),
        waypoints=waypoints,
        security=SecurityConfig(**security),
        **(app or {}),
    )
    await server.start()
    try:
        yield server
    finally:
        await server.close()


async def request(ws: ClientConnection, body: dict[str, Any]) -> dict[str, Any]:
    """Send one request and return its reply (updates in between are skipped)."""
    await ws.send(json.dumps({"id": "q", **body}))
    while True:
        msg = json.loads(await asyncio.wait_for(ws.recv(), WAIT))
        if msg.get("servermsg") != "update":
            return msg  # type: ignore[no-any-return]


async def login(ws: ClientConnection, **creds: Any) -> dict[str, Any]:
    return await request(ws, {"clientmsg": "login", **creds})


async def closed_code(ws: ClientConnection) -> int | None:
    with contextlib.suppress(websockets.exceptions.ConnectionClosed):
        while True:
            await asyncio.wait_for(ws.recv(), WAIT)
    return ws.close_code


def audit_rows(db: Path) -> list[dict[str, Any]]:
    with contextlib.closing(sqlite3.connect(db)) as conn:
        conn.row_factory = sqlite3.Row
        return [dict(r) for r in conn.execute("SELECT * FROM audit ORDER BY id")]


def counts(db: Path) -> tuple[int, int, int]:
    with contextlib.closing(sqlite3.connect(db)) as conn:
        return tuple(  # type: ignore[return-value]
            conn.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]
            for t in ("orders", "task", "waypoints")
        )


ORDER = {"clientmsg": "create", "type": "order", "dish": "soup", "table": "T1"}

# -- logging in ------------------------------------------------------------------------------


async def test_anonymous_connections_can_only_log_in(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        before = counts(tmp_path / "s.db")
        async with connect(app.url) as ws:
            for body in (
                ORDER,
                {"clientmsg": "data", "topics": ["orders"]},
                {"clientmsg": "create", "type": "waypoint", "name": "w", "x": 1, "y": 1},
                {"clientmsg": "create", "type": "robot", "name": "x", "url": "ws://h:1"},
                {"clientmsg": "stop", "robot": "r1"},
                {"clientmsg": "logout"},
            ):
                reply = await request(ws, body)
                assert reply["code"] == "unauthorized", reply
        assert counts(tmp_path / "s.db") == before


async def test_first_start_creates_one_owner_who_logs_in(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        password = app.first_owner_password
        assert password and len(password) >= 12
        async with connect(app.url) as ws:
            reply = await login(ws, username="owner", password=password)
            session = reply["session"]
            assert session["role"] == "owner" and session["user"] == "owner"
            assert session["token"].startswith("srv_") and session["expires"] > 0
            assert "audit" in session["scopes"]
            assert (await request(ws, ORDER))["servermsg"] == "ok"
        # The session token works on a new connection, in a login message or the handshake.
        async with connect(app.url) as ws:
            again = await login(ws, token=session["token"])
            assert again["session"]["user"] == "owner" and "token" not in again["session"]
        headers = {"Authorization": f"Bearer {session['token']}"}
        async with connect(app.url, additional_headers=headers) as ws:
            assert (await request(ws, ORDER))["servermsg"] == "ok"
    # Second start of the same database: no new owner, no password shown.
    async with bare_server(tmp_path) as app:
        assert app.first_owner_password is None
    with contextlib.closing(sqlite3.connect(tmp_path / "s.db")) as conn:
        users = conn.execute("SELECT name, role, pw_hash FROM users").fetchall()
        assert [(u[0], u[1]) for u in users] == [("owner", "owner")]
        assert password not in users[0][2] and users[0][2].startswith("scrypt$")
        digests = [r[0] for r in conn.execute("SELECT digest FROM tokens")]
        assert session["token"] not in digests and len(digests[0]) == 64


async def test_wrong_logins_are_refused_then_slowed_down(tmp_path: Path) -> None:
    async with bare_server(tmp_path, free_failures=3) as app:
        async with connect(app.url) as ws:
            for _ in range(3):
                reply = await login(ws, username="owner", password="wrong-password")
                assert reply["code"] == "unauthorized"
            # Locked now: even the right password is refused until the lock ends.
            reply = await login(ws, username="owner", password=app.first_owner_password)
            assert reply["code"] == "rate_limited" and reply["details"]["retry_after"] > 0
            assert (await login(ws, token="srv_" + "x" * 43))["code"] == "rate_limited"
            assert (await request(ws, ORDER))["code"] == "unauthorized"
        rows = audit_rows(tmp_path / "s.db")
        logins = [r for r in rows if r["verb"] == "login"]
        assert [r["outcome"] for r in logins] == ["unauthorized"] * 3 + ["rate_limited"] * 2
        assert all(r["actor"] == "anonymous" and r["peer"].startswith("127.0.0.1") for r in logins)
        assert "wrong-password" not in json.dumps(rows)


async def test_bad_handshake_tokens_get_401(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        for value in ("Bearer srv_nope", "Basic b3duZXI6eA==", "Bearer "):
            with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
                async with connect(app.url, additional_headers={"Authorization": value}):
                    pass
            assert exc.value.response.status_code == 401


async def test_unauthenticated_connections_are_closed_after_the_deadline(tmp_path: Path) -> None:
    async with bare_server(tmp_path, login_deadline=0.2) as app:
        async with connect(app.url) as ws:
            assert await closed_code(ws) == CLOSE_AUTH
        token = await app.issue_token("staff")
        async with connect(app.url) as ws:
            await login(ws, token=token)
            # Logged in before the deadline: still open well after it.
            await asyncio.sleep(0.4)  # the deadline must pass: nothing to wait on but time
            assert (await request(ws, {"clientmsg": "data", "topics": ["orders"]}))["data"]


async def test_logout_revokes_the_session_everywhere(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        async with connect(app.url) as ws1, connect(app.url) as ws2:
            token = (await login(ws1, username="owner", password=app.first_owner_password))[
                "session"
            ]["token"]
            await login(ws2, token=token)
            reply = await request(ws1, {"clientmsg": "logout"})
            assert reply["servermsg"] == "ok" and reply["session"] is None
            assert (await request(ws1, ORDER))["code"] == "unauthorized"
            assert await closed_code(ws2) == CLOSE_AUTH
        async with connect(app.url) as ws:
            assert (await login(ws, token=token))["code"] == "unauthorized"


async def test_sessions_expire(tmp_path: Path) -> None:
    async with bare_server(tmp_path, session_ttl=3600.0) as app:
        clock = app.clock
        assert isinstance(clock, FakeClock)
        async with connect(app.url) as ws:
            await login(ws, username="owner", password=app.first_owner_password)
            assert (await request(ws, ORDER))["servermsg"] == "ok"
            await clock.advance(3601.0)
            assert (await request(ws, ORDER))["code"] == "unauthorized"
            assert await closed_code(ws) == CLOSE_AUTH


def cli(*args: str, stdin: str = "") -> tuple[int, str, str]:
    import subprocess

    proc = subprocess.run(
        [sys.executable, "-m", "serveur.cli", *args],
        input=stdin,
        capture_output=True,
        text=True,
        timeout=60,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    return proc.returncode, proc.stdout, proc.stderr


async def test_cli_users_and_tokens_against_a_live_server(tmp_path: Path) -> None:
    db = str(tmp_path / "s.db")
    async with bare_server(tmp_path, sweep_every=0.05) as app:
        run = asyncio.to_thread
        code, out, err = await run(cli, "user", "add", "alice", "--db", db, stdin="pw-alice-1\n")
        assert code == 0, err
        assert (await run(cli, "user", "add", "alice", "--db", db, stdin="pw-alice-1\n"))[0] == 1
        code, _, err = await run(cli, "user", "add", "bob", "--db", db, stdin="short\n")
        assert code == 1 and "at least 8" in err
        code, out, _ = await run(cli, "user", "list", "--db", db)
        assert "alice\tstaff" in out and "owner\towner" in out
        async with connect(app.url) as ws:
            assert (await login(ws, username="alice", password="pw-alice-1"))["session"]
            # A password change in another process ends the live session within a sweep.
            assert (await run(cli, "user", "passwd", "alice", "--db", db, stdin="pw-alice-2\n"))[
                0
            ] == 0
            assert await closed_code(ws) == CLOSE_AUTH
        async with connect(app.url) as ws:
            assert (await login(ws, username="alice", password="pw-alice-1"))["code"]
            assert (await login(ws, username="alice", password="pw-alice-2"))["session"]

        code, out, err = await run(
            cli, "token", "create", "--role", "integration", "--scope", "orders", "--db", db
        )
        assert code == 0, err
        token = out.strip()
        assert token.startswith("srv_") and "Shown once" in err
        headers = {"Authorization": f"Bearer {token}"}
        async with connect(app.url, additional_headers=headers) as ws:
            assert (await request(ws, ORDER))["servermsg"] == "ok"
            assert (await request(ws, {"clientmsg": "create", "type": "task", "orders": [1]}))[
                "code"
            ] == "forbidden"
            code, out, _ = await run(cli, "token", "list", "--db", db)
            tid = next(line.split("\t")[0] for line in out.splitlines() if "integration" in line)
            assert (await run(cli, "token", "revoke", tid, "--db", db))[0] == 0
            assert await closed_code(ws) == CLOSE_AUTH
        with pytest.raises(websockets.exceptions.InvalidStatus):
            async with connect(app.url, additional_headers=headers):
                pass
        bad = await run(cli, "token", "create", "--role", "robot-screen", "--db", db)
        assert bad[0] == 1 and "--robot" in bad[2]
        bad = await run(
            cli, "token", "create", "--role", "table-screen", "--table", "T99", "--db", db
        )
        assert bad[0] == 1 and "T99" in bad[2]
        code, out, _ = await run(cli, "audit", "--db", db)
        assert "forbidden" in out and "user:alice" in out
        assert (await run(cli, "user", "remove", "owner", "--db", db))[0] == 1  # the last owner
        assert (await run(cli, "user", "remove", "alice", "--db", db))[0] == 0


# -- roles over the wire ---------------------------------------------------------------------


async def as_token(r: Restaurant, token: str | None) -> Client:
    """A client authenticated by ``token`` on the handshake (None: anonymous)."""
    headers = {"Authorization": f"Bearer {token}"} if token else {}
    c = Client(await connect(r.app.url, additional_headers=headers))
    r.clients.append(c)
    return c


async def test_robot_and_table_screens_see_and_do_only_their_own(two_robots: Restaurant) -> None:
    r = two_robots
    staff = await r.client()
    await staff.subscribe("robots", "orders", "tasks")
    await staff.status("r1", "Ready")
    await staff.status("r2", "Ready")
    screen = await as_token(r, await r.app.issue_token("robot-screen", robot="r1"))
    table = await as_token(r, await r.app.issue_token("table-screen", table="T1"))

    snap = await screen.subscribe("robots", "orders", "tasks")
    assert [x["name"] for x in snap["data"]["robots"]] == ["r1"]
    await screen.error("data", "forbidden", topics=["events"])
    await screen.error("data", "forbidden", topics=["pose:r2"])
    await screen.ok("data", topics=["pose:r1"])
    await screen.error("create", "forbidden", type="order", dish="x", table="T1")
    await screen.error("control", "forbidden", robot="r1", action="auto")
    await screen.error("stop", "forbidden", robot="r2")
    await screen.error("order", "forbidden", robot="r2")
    await screen.error("next", "not_allowed_in_status", robot="r1")  # allowed, wrong status

    await table.error("data", "forbidden", topics=["robots"])
    await table.subscribe("orders")
    await table.error("order", "forbidden", table="T2")
    await table.error("stop", "forbidden", robot="r1")

    await staff.ok("control", robot="r1", action="auto")
    o1 = (await staff.ok("create", type="order", dish="soup", table="T1"))["order"]["id"]
    o2 = (await staff.ok("create", type="order", dish="cake", table="T2"))["order"]["id"]
    await staff.ok("create", type="task", orders=[o1, o2])
    await screen.until(
        lambda: {o1, o2} <= set(screen.records.get("orders", {})), what="r1's tray on its screen"
    )
    await screen.status("r1", "Delivering")
    await table.until(lambda: o1 in table.records.get("orders", {}), what="T1's dish")
    assert o2 not in table.records.get("orders", {})
    cart = (await table.ok("order", table="T1"))["orders"]
    assert [o["id"] for o in cart] == [o1]
    # Never a word about the other robot, on any topic.
    assert all(f["data"].get("name") != "r2" for f in screen.frames if f.get("topic") == "robots")
    assert set(screen.records["robots"]) == {"r1"}
    await screen.ok("stop", robot="r1")
    await staff.status("r1", "Stopped")
    await screen.ok("cancel", robot="r1")


async def test_staff_may_not_register_robots_or_read_the_audit(one_robot: Restaurant) -> None:
    staff = await one_robot.client()
    await staff.error("create", "forbidden", type="robot", name="r9", url="ws://127.0.0.1:1")
    await staff.error("data", "forbidden", topics=["audit"])


async def test_audit_records_who_did_what_from_where(one_robot: Restaurant) -> None:
    r = one_robot
    db = Path(str(r.db))
    owner = await as_token(r, None)  # anonymous, then a password login
    pw = r.app.first_owner_password
    assert pw is not None
    await owner.ok("login", username="owner", password=pw)
    await owner.subscribe("audit")
    staff = await r.client()
    await staff.subscribe("robots")
    await staff.status("r1", "Ready")  # a loaded machine: the robot may still be connecting
    await staff.ok("create", type="order", dish="soup", table="T1")
    await staff.ok("control", robot="r1", action="manual")
    await staff.ok("control", robot="r1", action="teleop", vx=0.1, wz=0.0)
    await staff.error("create", "forbidden", type="robot", name="r9", url="ws://127.0.0.1:1")
    await staff.ok("data", topics=["orders"])
    await owner.until(
        lambda: _audit_seen(owner) >= 3,
        what="3 audit updates pushed to the owner",
    )
    rows = [x for x in audit_rows(db) if x["actor"].startswith("token:")]
    assert [(x["verb"], x["outcome"]) for x in rows] == [
        ("create", "ok"),
        ("control", "ok"),
        ("create", "forbidden"),
    ]
    assert rows[0]["target"] == "T1" and json.loads(rows[0]["data"])["dish"] == "soup"
    assert rows[1]["target"] == "r1" and json.loads(rows[1]["data"])["action"] == "manual"
    assert all(x["role"] == "staff" and x["peer"].startswith("127.0.0.1:") for x in rows)


def _audit_seen(c: Client) -> int:
    return sum(1 for f in c.frames if f.get("topic") == "audit")


# -- limits ----------------------------------------------------------------------------------


async def test_cross_site_websocket_handshakes_are_refused(tmp_path: Path) -> None:
    async with bare_server(tmp_path, allowed_origins=("https://pos.example",)) as app:
        host = app.url.removeprefix("ws://").removesuffix("/ws")
        with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
            async with connect(app.url, origin="http://evil.example"):  # type: ignore[arg-type]
                pass
        assert exc.value.response.status_code == 403
        for ok in (f"http://{host}", "https://pos.example"):
            async with connect(app.url, origin=ok) as ws:  # type: ignore[arg-type]
                assert (await request(ws, ORDER))["code"] == "unauthorized"


async def test_connections_per_address_are_capped(tmp_path: Path) -> None:
    async with bare_server(tmp_path, max_per_address=3) as app:
        async with contextlib.AsyncExitStack() as stack:
            for _ in range(3):
                await stack.enter_async_context(connect(app.url))
            with pytest.raises(websockets.exceptions.InvalidStatus) as exc:
                async with connect(app.url):
                    pass
            assert exc.value.response.status_code == 429
        async with connect(app.url):  # the slots are free again once those closed
            pass


async def test_a_burst_is_never_told_to_retry_at_once(tmp_path: Path) -> None:
    """300 requests as fast as a script sends them, at 200/s: the refusals' waits are a few
    ms, and each must still say a wait above zero (it said ``retry_after: 0.0`` for 16-23 %
    of them), never below the bucket's real wait."""
    async with bare_server(tmp_path, rate=200.0, burst=2.0) as app:
        token = await app.issue_token("staff")
        headers = {"Authorization": f"Bearer {token}"}
        async with connect(app.url, additional_headers=headers) as ws:
            for i in range(300):
                await ws.send(json.dumps({"clientmsg": "ping", "id": i}))
            replies = [json.loads(await asyncio.wait_for(ws.recv(), WAIT)) for _ in range(300)]
        limited = [m["details"]["retry_after"] for m in replies if m.get("code") == "rate_limited"]
        assert limited, "the burst was never limited: nothing was measured"
        assert min(limited) >= 0.01, sorted(limited)[:10]


async def test_requests_are_rate_limited_per_connection(tmp_path: Path) -> None:
    async with bare_server(tmp_path, rate=2.0, burst=5.0) as app:
        token = await app.issue_token("staff")
        headers = {"Authorization": f"Bearer {token}"}
        async with (
            connect(app.url, additional_headers=headers) as ws,
            connect(app.url, additional_headers=headers) as other,
        ):
            for i in range(12):
                await ws.send(json.dumps({**ORDER, "id": i, "dish": f"d{i}"}))
            replies = [json.loads(await asyncio.wait_for(ws.recv(), WAIT)) for _ in range(12)]
            replies = [m for m in replies if m.get("servermsg") != "update"]
            oks = [m for m in replies if m["servermsg"] == "ok"]
            limited = [m for m in replies if m.get("code") == "rate_limited"]
            assert len(oks) in (5, 6) and len(oks) + len(limited) == len(replies)
            assert limited[0]["details"]["retry_after"] > 0
            # The other connection has its own budget.
            assert (await request(other, ORDER))["servermsg"] == "ok"
        assert counts(tmp_path / "s.db")[0] == len(oks) + 1


async def test_oversized_frames_close_the_connection(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app, connect(app.url, max_size=None) as ws:
        await ws.send("x" * (65 * 1024))
        assert await closed_code(ws) == 1009


async def test_no_secret_reaches_the_logs_even_at_debug(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.DEBUG)
    async with bare_server(tmp_path) as app:
        token = await app.issue_token("staff")
        password = app.first_owner_password
        assert password
        async with connect(app.url, additional_headers={"Authorization": f"Bearer {token}"}) as ws:
            assert (await request(ws, ORDER))["servermsg"] == "ok"
        async with connect(app.url) as ws:
            session = (await login(ws, username="owner", password=password))["session"]
            await login(ws, username="owner", password="a wrong one")
        assert any(
            "Authorization" in r.getMessage() or "[redacted]" in r.getMessage()
            for r in caplog.records
        ), "websockets logged no handshake: test is blind"
    text = "\n".join(r.getMessage() for r in caplog.records)
    for secret in (token, password, session["token"], "a wrong one"):
        assert secret not in text


async def test_idle_connections_without_subscriptions_are_closed(tmp_path: Path) -> None:
    async with bare_server(tmp_path, idle_timeout=0.4) as app:
        token = await app.issue_token("staff")
        headers = {"Authorization": f"Bearer {token}"}
        async with (
            connect(app.url, additional_headers=headers) as idle,
            connect(app.url, additional_headers=headers) as listening,
        ):
            await request(listening, {"clientmsg": "data", "topics": ["orders"]})
            assert await closed_code(idle) == 4003
            # The subscriber is listening, not idle: still served after the idle one is gone.
            assert (await request(listening, ORDER))["servermsg"] == "ok"
