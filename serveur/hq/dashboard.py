"""The chain's dashboard over HTTP: its page, a login, and read-only JSON (``serveur hq``).

Served by the same small h11 listener as the site's order-intake API
(:class:`serveur.till.intake.IntakeServer`); this module is only what a request means.
Read-only by design: the dashboard shows every site, and a command still goes to the site's
own console, where its staff and its rules are.

Routes (all JSON but the page's files; every ``/api`` route but ``login`` needs
``Authorization: Bearer <token>``, a token ``POST /api/login`` gives for the centre's own
accounts — never a site's):

* ``GET /`` and the page's scripts, styles and catalogs (``serveur/web/hq/``);
* ``POST /api/login`` ``{"name", "password"}`` → ``{"token"}`` (guessing is slowed as on a
  site: after 5 failures per address or name, 429 with ``Retry-After``);
* ``GET /api/sites`` → every site: up or down, what is stored, robots, open alerts, today's
  figures;
* ``GET /api/figures?by=day|hour`` → each site's figures (``serveur stats --json``'s shape);
* ``GET /api/sites/<site>/figures?by=`` and ``/api/sites/<site>/trips`` → one site's.

Times: ``utc_offset=+HH:MM`` says the reader's local time (days start at ``day_start``, 4 h
by default, as on the site).
"""

from __future__ import annotations

import asyncio
import json
import secrets
import time
from collections.abc import Callable
from datetime import tzinfo
from pathlib import Path
from typing import Any, Final
from urllib.parse import parse_qs, urlsplit

from serveur.chain.wire import check_site
from serveur.errors import InvalidField, RateLimited
from serveur.hq.store import HqStore, SiteRow
from serveur.hq.views import SiteView
from serveur.security.auth import LoginThrottle, verify_password
from serveur.stats.periods import BY, parse_offset
from serveur.web.static import SECURITY_HEADERS, StaticSite

__all__ = ["HQ_ROOT", "Dashboard"]

HQ_ROOT: Final = Path(__file__).resolve().parent.parent / "web" / "hq"
#: Seconds a login lasts.
SESSION: Final = 12 * 3600.0
_MAX_SESSIONS: Final = 1000

Reply = tuple[int, Any, list[tuple[str, str]]]


def _error(status: int, code: str, message: str) -> Reply:
    return status, {"code": code, "message": message}, []


class Dashboard:
    def __init__(
        self,
        store: HqStore,
        now: Callable[[], float],
        *,
        ledgers: Callable[[], dict[str, Any]] | None = None,
        site: StaticSite | None = None,
    ) -> None:
        self.store = store
        self.now = now
        self._ledgers = ledgers
        self.files = site or StaticSite.load(HQ_ROOT)
        self.views: dict[str, SiteView] = {}
        self._sessions: dict[str, float] = {}  # token -> expiry (monotonic)
        self._lock = asyncio.Lock()
        self._throttle = LoginThrottle()  # the site's own: per address and per name

    async def handle(
        self,
        method: str,
        target: str,
        auth: str | None,
        ctype: str | None,
        body: bytes,
        peer: str,
    ) -> Reply:
        url = urlsplit(target)
        path, query = url.path, parse_qs(url.query)
        if not path.startswith("/api/"):
            if method not in ("GET", "HEAD"):
                return _error(405, "method_not_allowed", "the page's files are read with GET")
            asset = self.files.resolve("/index.html" if path == "/" else path)
            if asset is None:
                return _error(404, "not_found", f"no page {path}")
            return 200, asset.body, [("Content-Type", asset.content_type), *SECURITY_HEADERS]
        if path == "/api/login":
            if method != "POST":
                return _error(405, "method_not_allowed", "log in with POST")
            return await self._login(body, peer)
        if not self._allowed(auth):
            return _error(401, "unauthorized", "log in first (POST /api/login)")
        if method != "GET":
            return _error(405, "method_not_allowed", "the dashboard is read-only")
        try:
            tz = self._tz(query)
            by = self._by(query)
            parts = path.split("/")[2:]
            if parts == ["sites"]:
                return 200, await self._sites(tz), []
            if parts == ["figures"]:
                views = await self._views()
                figures = {
                    s: await asyncio.to_thread(v.figures, by, tz) for s, v in sorted(views.items())
                }
                return 200, {"sites": figures}, []
            if len(parts) == 3 and parts[0] == "sites" and parts[2] in ("figures", "trips"):
                site = check_site(parts[1])
                view = (await self._views()).get(site)
                if view is None:
                    return _error(404, "not_found", f"no site {site!r}")
                if parts[2] == "figures":
                    return 200, await asyncio.to_thread(view.figures, by, tz), []
                return 200, await asyncio.to_thread(view.trips, None, None), []
        except InvalidField as exc:
            return 400, exc.to_dict(), []
        return _error(404, "not_found", f"no route {path}")

    def _allowed(self, auth: str | None) -> bool:
        if not auth or not auth.startswith("Bearer "):
            return False
        expiry = self._sessions.get(auth.removeprefix("Bearer ").strip())
        return expiry is not None and expiry > time.monotonic()

    async def _login(self, body: bytes, peer: str) -> Reply:
        try:
            obj = json.loads(body)
            name, password = obj["name"], obj["password"]
            if not isinstance(name, str) or not isinstance(password, str):
                raise TypeError
        except (ValueError, KeyError, TypeError):
            return _error(400, "invalid_field", 'log in with {"name": ..., "password": ...}')
        keys = (f"peer:{peer.rsplit(':', 1)[0]}", f"name:{name}")
        try:
            self._throttle.check(keys, time.monotonic())
        except RateLimited as exc:
            return 429, exc.to_dict(), [("Retry-After", str(int(exc.details["retry_after"]) + 1))]
        stored = await self.store.password_hash(name)
        # scrypt is ~0.1 s of CPU: off the loop; a missing account costs the same time.
        ok = await asyncio.to_thread(
            verify_password, password, stored or "scrypt$16384$8$1$AAAA$AAAA"
        )
        if stored is None or not ok:
            self._throttle.failure(keys, time.monotonic())
            return _error(401, "unauthorized", "wrong name or password")
        self._throttle.success(keys)
        now = time.monotonic()
        self._sessions = {t: e for t, e in self._sessions.items() if e > now}
        if len(self._sessions) >= _MAX_SESSIONS:
            self._sessions.pop(min(self._sessions, key=self._sessions.__getitem__))
        token = secrets.token_urlsafe(32)
        self._sessions[token] = now + SESSION
        return 200, {"token": token, "name": name}, []

    def _tz(self, query: dict[str, list[str]]) -> tzinfo | None:
        text = query.get("utc_offset", [None])[0]
        if text is None:
            return None
        try:
            return parse_offset(text)
        except ValueError as exc:
            raise InvalidField(str(exc), field="utc_offset") from exc

    def _by(self, query: dict[str, list[str]]) -> str:
        by = query.get("by", ["day"])[0]
        if by not in BY:
            raise InvalidField(f"by is one of {', '.join(BY)}", field="by")
        return by

    async def _views(self) -> dict[str, SiteView]:
        return (await self._read())[1]

    async def _read(self) -> tuple[list[SiteRow], dict[str, SiteView]]:
        """The sites as stored now, and each one's view brought up to them (only the new
        events are read). One read of the sites for both: a site that appears meanwhile
        is in neither, never in one only."""
        async with self._lock:
            rows = await self.store.sites()
            for row in rows:
                view = self.views.setdefault(row.site, SiteView(row.site))
                while view.seq < row.stored:
                    part = await self.store.events(row.site, after=view.seq, limit=5000)
                    if not part:
                        break
                    view.extend(part)
            return rows, dict(self.views)

    async def _sites(self, tz: tzinfo | None) -> dict[str, Any]:
        rows, views = await self._read()
        now = self.now()
        out = []
        for row in rows:
            view = views[row.site]
            summary = await asyncio.to_thread(view.summary, now, tz)
            out.append(
                {
                    "site": row.site,
                    "state": row.state,
                    "state_at": row.state_at,
                    "heard_at": row.heard_at,
                    "stored": row.stored,
                    "head": row.head,
                    "behind": max(0, row.head - row.stored),
                    **summary,
                }
            )
        return {"now": now, "sites": out}
