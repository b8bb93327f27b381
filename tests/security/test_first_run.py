"""A restaurant nobody has set up (issue 29): ``serveur run`` prints one setup link and its QR
code instead of a password; the link's code makes the owner, once, with the password they
choose; the public address they give is what every screen's setup link and QR code holds."""

from __future__ import annotations

import asyncio
import json
import re
import sys
from pathlib import Path

import pytest
from websockets.asyncio.client import connect

from serveur.app import App
from serveur.maps.navigation import load_demo
from serveur.security.accounts import qr_svg
from serveur.security.first_run import setup_url
from tests.subprocess_server import free_port


async def call(ws: object, **msg: object) -> dict:
    await ws.send(json.dumps({"id": 1, **msg}))  # type: ignore[attr-defined]
    return json.loads(await asyncio.wait_for(ws.recv(), 10))  # type: ignore[attr-defined]


async def test_the_setup_code_makes_the_owner_once(tmp_path: Path) -> None:
    db = tmp_path / "s.db"
    app = await App(db, port=0, setup=True, waypoints=load_demo()[1]).start()
    try:
        code = app.setup_code
        assert code and app.first_owner_password is None
        assert await app.store.accounts.count_users() == 0
        async with connect(app.url) as ws:
            wrong = await call(
                ws, clientmsg="login", setup="x" + code, username="ana", password="a long pass"
            )
            assert wrong["code"] == "unauthorized" and "setup link" in wrong["message"]
            short = await call(ws, clientmsg="login", setup=code, username="ana", password="short")
            assert short["code"] == "invalid_field"
            ok = await call(
                ws, clientmsg="login", setup=code, username="ana", password="a long pass"
            )
            assert ok["servermsg"] == "ok" and ok["session"]["role"] == "owner", ok
            assert ok["session"]["user"] == "ana" and ok["session"]["token"]
            # Logged in as the owner: the restaurant's name and address.
            url = "http://192.168.1.20:8765"
            got = await call(
                ws, clientmsg="site", action="set_settings", name="Chez Ana", public_url=url
            )
            assert got["settings"]["name"] == "Chez Ana" and got["settings"]["public_url"] == url
            # A screen's QR code holds the public address, not the base this page saw.
            made = await call(
                ws,
                clientmsg="account",
                action="create_token",
                role="table-screen",
                table="T3",
                base="http://127.0.0.1:8765",
            )
            assert made["qr"] == qr_svg(url + made["link"])
        async with connect(app.url) as ws:  # the code is spent
            again = await call(
                ws, clientmsg="login", setup=code, username="eve", password="another pass"
            )
            assert again["code"] == "unauthorized"
        assert [u.name for u in await app.store.accounts.list_users()] == ["ana"]
    finally:
        await app.close()
    app = await App(db, port=0, setup=True).start()  # set up: no code any more
    try:
        assert app.setup_code is None
        assert app.core is not None and app.core.site.name == "Chez Ana"
    finally:
        await app.close()


def test_the_link_names_the_box_as_a_tablet_reaches_it() -> None:
    assert setup_url("10.0.0.5", 8765, "abc") == "http://10.0.0.5:8765/setup.html#setup=abc"
    anywhere = setup_url("0.0.0.0", 8765, "abc", tls=True)
    assert anywhere.startswith("https://") and "0.0.0.0" not in anywhere
    assert "127.0.0.1" not in anywhere and anywhere.endswith(":8765/setup.html#setup=abc")


async def test_serveur_run_prints_the_link_and_its_qr_code_not_a_password(tmp_path: Path) -> None:
    port = free_port()
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "run",
        "--db",
        str(tmp_path / "new.db"),
        "--host",
        "127.0.0.1",
        "--port",
        str(port),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
    )
    try:
        assert proc.stdout is not None
        lines: list[str] = []
        while not any("setup.html#setup=" in x for x in lines):
            line = (await asyncio.wait_for(proc.stdout.readline(), 30)).decode()
            assert line, "serveur run ended: " + "".join(lines)
            lines.append(line)
        qr = [(await asyncio.wait_for(proc.stdout.readline(), 10)).decode() for _ in range(10)]
        out = "".join(lines)
        assert re.search(rf"http://127\.0\.0\.1:{port}/setup\.html#setup=\S+", out), out
        assert "password" not in out.lower()
        assert all(set(row.strip("\n")) <= set(" █▀▄") for row in qr), qr  # the QR code, drawn
        assert any("█" in row for row in qr)
    finally:
        proc.terminate()
        await proc.wait()


def test_a_generated_password_never_starts_with_a_dash(monkeypatch: pytest.MonkeyPatch) -> None:
    """A password starting with "-" was read as an option by the README's
    ``first_trip.py --password PASSWORD`` (one in 64 generated did)."""
    import secrets

    from serveur.security import auth

    drawn = iter(["-dash-first", "_fine", "ok-later"])
    monkeypatch.setattr(secrets, "token_urlsafe", lambda n: next(drawn))
    assert auth.new_password() == "_fine"
