"""The centre's dashboard API over a real socket (serveur/hq/dashboard.py): its own accounts,
read-only, bad requests answered with a structured error and nothing changed."""

from __future__ import annotations

import asyncio
import http.client
import json
import time
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest

from serveur.domain import EventRecord
from serveur.hq.dashboard import Dashboard
from serveur.hq.store import HqStore, open_hq_db
from serveur.security.auth import hash_password
from serveur.till.intake import IntakeServer

pytestmark = pytest.mark.asyncio


class Api:
    def __init__(self, port: int) -> None:
        self.port = port

    def _call(
        self, method: str, path: str, body: Any = None, token: str | None = None
    ) -> tuple[int, Any, dict[str, str]]:
        conn = http.client.HTTPConnection("127.0.0.1", self.port, timeout=10)
        headers = {"Authorization": f"Bearer {token}"} if token else {}
        data = (
            None
            if body is None
            else (body if isinstance(body, bytes) else json.dumps(body).encode())
        )
        conn.request(method, path, body=data, headers=headers)
        reply = conn.getresponse()
        raw = reply.read()
        conn.close()
        ctype = reply.getheader("Content-Type") or ""
        parsed = json.loads(raw) if ctype.startswith("application/json") else raw
        return reply.status, parsed, dict(reply.getheaders())

    async def __call__(
        self, method: str, path: str, body: Any = None, token: str | None = None
    ) -> tuple[int, Any, dict[str, str]]:
        return await asyncio.to_thread(self._call, method, path, body, token)


@pytest.fixture
async def api(tmp_path: Path) -> AsyncIterator[tuple[Api, HqStore]]:
    async with HqStore(open_hq_db(str(tmp_path / "hq.db"))) as hq:
        await hq.add_user("alice", hash_password("correct horse", n=2**10), time.time())
        events = [
            EventRecord(
                id=i,
                ts=1767225600.0 + i,
                kind="robot.status",
                robot="r1",
                data={"status": "Awaiting", "last_error": None},
            )
            for i in range(1, 4)
        ]
        await hq.take("bistro", 1, events, time.time())
        web = IntakeServer(Dashboard(hq, time.time).handle, "127.0.0.1", 0)
        await web.start()
        try:
            yield Api(web.port), hq
        finally:
            await web.close()


async def test_login_and_read_only_routes(api: tuple[Api, HqStore]) -> None:
    call, hq = api
    status, body, _ = await call("GET", "/api/sites")
    assert (status, body["code"]) == (401, "unauthorized")
    status, body, _ = await call("POST", "/api/login", {"name": "alice", "password": "wrong"})
    assert (status, body["code"]) == (401, "unauthorized")
    status, body, _ = await call("POST", "/api/login", b"{not json")
    assert (status, body["code"]) == (400, "invalid_field")
    status, body, _ = await call(
        "POST", "/api/login", {"name": "alice", "password": "correct horse"}
    )
    assert status == 200
    token = body["token"]
    status, body, _ = await call("GET", "/api/sites?utc_offset=%2B01:00", token=token)
    assert status == 200
    (site,) = body["sites"]
    assert (site["site"], site["stored"], site["behind"]) == ("bistro", 3, 0)
    assert site["robots"] == [
        {"robot": "r1", "status": "Awaiting", "since": 1767225601.0, "error": None}
    ]
    # Read-only: nothing but GET; bad parameters are named; unknown sites and routes are 404s.
    status, body, _ = await call("POST", "/api/sites", {}, token=token)
    assert (status, body["code"]) == (405, "method_not_allowed")
    status, body, _ = await call("GET", "/api/sites?utc_offset=noon", token=token)
    assert (status, body["code"], body["details"]["field"]) == (400, "invalid_field", "utc_offset")
    status, body, _ = await call("GET", "/api/figures?by=week", token=token)
    assert (status, body["details"]["field"]) == (400, "by")
    for path in ("/api/sites/nowhere/figures", "/api/sites/bistro/other", "/api/elsewhere"):
        status, body, _ = await call("GET", path, token=token)
        assert (status, body["code"]) == (404, "not_found"), path
    status, body, _ = await call("GET", "/api/sites/Not%20A%20Site/trips", token=token)
    assert status == 400
    assert [r.stored for r in await hq.sites()] == [3]  # nothing changed
    # The page: its files, nothing else.
    status, page, headers = await call("GET", "/")
    assert status == 200 and headers["Content-Type"].startswith("text/html")
    assert b'type="module"' in page  # the dashboard's own page, its scripts from 'self'
    assert "default-src 'self'" in headers["Content-Security-Policy"]
    for path in ("/../../etc/passwd", "/%2e%2e/pyproject.toml", "/nope.js"):
        status, _, _ = await call("GET", path)
        assert status == 404, path


async def test_password_guessing_is_slowed(api: tuple[Api, HqStore]) -> None:
    call, _ = api
    for _ in range(5):
        status, _, _ = await call("POST", "/api/login", {"name": "alice", "password": "guess"})
        assert status == 401
    status, body, headers = await call(
        "POST", "/api/login", {"name": "alice", "password": "correct horse"}
    )
    assert (status, body["code"]) == (429, "rate_limited")
    assert int(headers["Retry-After"]) >= 1
