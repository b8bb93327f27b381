"""The websocket endpoint ``/ws`` and plain HTTP (health, the web UI), from one process.

Thin on purpose: read a frame, parse it (:mod:`serveur.protocol`), hand it to the core,
queue the reply. Every failure becomes a structured error reply on the same connection —
nothing a client sends can close it, let alone crash the server. Frames are read one at a
time per connection, so each client's requests are answered in order.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import fcntl
import http
import json
import logging
import ssl as ssl_module
import sys
import termios
import time
import typing
from collections import Counter
from collections.abc import Awaitable, Callable
from typing import Any
from urllib.parse import parse_qs, urlsplit

import websockets
from websockets.asyncio.server import Server as WsServer
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.http11 import Request, Response
from websockets.protocol import State

from serveur import protocol as P
from serveur.chain.shipper import Shipper
from serveur.core.backup_desk import DOWNLOAD_PATH, BackupDesk
from serveur.core.call_desk import CALL_PATH
from serveur.core.camera import CameraRelay, CameraViewer
from serveur.core.engine import Core
from serveur.core.hub import Subscriber
from serveur.core.site_map import BACKDROP_PATH, SiteMaps
from serveur.core.uploads import Uploads
from serveur.errors import (
    BackupError,
    Forbidden,
    InvalidField,
    NotFound,
    RateLimited,
    ServeurError,
    Unauthorized,
)
from serveur.replay.forecast import Forecaster, SiteFiles
from serveur.robots.probe import probe
from serveur.security.accounts import handle_account
from serveur.security.auth import Principal, RateLimiter, Role, Scope, ScreenView, authorize
from serveur.security.sessions import CLOSE_AUTH, Sessions
from serveur.stats.remote import StatsService, when_range
from serveur.store.site import AuditQuery
from serveur.web.static import default_site
from serveur.wire.camera import camera_frame

__all__ = ["CLOSE_IDLE", "CLOSE_RESTART", "MAX_FRAME", "Server"]

log = logging.getLogger(__name__)

MAX_FRAME = 64 * 1024
#: The order-intake API's one address (serveur.till.intake listens, :meth:`Server.intake`).
INTAKE_PATH = "/api/orders"
#: An error code's HTTP status on the order-intake API.
_INTAKE_STATUS = {
    "unauthorized": 401,
    "forbidden": 403,
    "not_found": 404,
    "conflict": 409,
    "rate_limited": 429,
    "store_error": 503,  # the database refused or is away: send it again
    "internal_error": 500,
}
#: Close code for a connection idle past ``SecurityConfig.idle_timeout``.
CLOSE_IDLE = 4003
#: The websocket standard's "service restart": the server comes back (a restored backup).
CLOSE_RESTART = 1012
_STATE_TOPICS = frozenset(P.STATE_TOPICS)


def _http(
    status: http.HTTPStatus,
    body: bytes,
    content_type: str,
    *extra: tuple[str, str],
    cache: str = "no-store",
) -> Response:
    headers = Headers(
        [
            ("Content-Type", content_type),
            ("Content-Length", str(len(body))),
            ("X-Content-Type-Options", "nosniff"),
            ("Cache-Control", cache),
            *extra,
        ]
    )
    return Response(status.value, status.phrase, headers, body)


def _peer(ws: ServerConnection) -> str:
    addr = ws.remote_address
    if isinstance(addr, tuple) and len(addr) >= 2:
        return f"{addr[0]}:{addr[1]}"
    return str(addr)


def _host_of(ws: ServerConnection) -> str:
    addr = ws.remote_address
    return str(addr[0]) if isinstance(addr, tuple) and addr else str(addr)


class _Conn:
    """One client connection: its outgoing side, who it is, and its request budget."""

    __slots__ = (
        "active_at",
        "close_after",
        "deadline",
        "limiter",
        "peer",
        "principal",
        "sub",
        "uploads",
        "watching",
        "ws",
    )

    def __init__(self, ws: ServerConnection, sub: Subscriber, limiter: RateLimiter) -> None:
        self.ws = ws
        self.sub = sub
        self.peer = _peer(ws)
        self.limiter = limiter
        self.principal: Principal | None = None
        self.deadline: asyncio.Task[None] | None = None
        #: Close with this (code, reason) once the current reply is sent.
        self.close_after: tuple[int, str] | None = None
        self.active_at = 0.0  # when it connected or last sent a request (monotonic)
        #: Files it is sending (``site upload``), by id: gone with the connection.
        self.uploads = Uploads()
        #: Cameras it watches: robot -> (relay, its viewer slot, the task sending its frames).
        self.watching: dict[str, tuple[CameraRelay, CameraViewer, asyncio.Task[None]]] = {}

    @property
    def actor(self) -> str | None:
        """Who is asking, as the store and the audit name them (None before a login)."""
        return self.principal.actor if self.principal is not None else None


class Server:
    """Serves ``/ws`` for clients and HTTP for everything else, on one port.

    Security (docs/security.md): a browser handshake must come from the page's own origin
    (or a configured one), an address may hold ``max_per_address`` connections, a connection
    must authenticate (``Authorization: Bearer`` on the handshake, or a ``login`` message
    within ``login_deadline`` seconds), every instruction is checked against the
    connection's role and scopes, requests are rate-limited per connection, and every
    state-changing instruction is audited with who gave it and from where.

    With ``ssl`` (see :func:`serveur.security.tls.server_context`) that port speaks only TLS: the
    web UI is https and /ws is wss, so a tablet that loaded the page over https opens its socket
    with the same certificate, and nothing is ever accepted in the clear.
    """

    def __init__(
        self,
        core: Core,
        sessions: Sessions,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        ssl: ssl_module.SSLContext | None = None,
        stats: StatsService | None = None,
        backups: BackupDesk | None = None,
    ) -> None:
        self.core = core
        self.sessions = sessions
        #: The ``stats`` verb (in-process unless the app says which database a child may open).
        self.stats = stats or StatsService(core.store, None)
        #: ``stats forecast``: a recorded day replayed with other fleets, in child processes.
        self.forecaster = Forecaster(
            core.store.orders.list_orders,
            lambda folder: SiteFiles(*core.write_site(folder)),
            lambda rec: core.publisher.pub("forecast", _forecast_info(rec)),
        )
        #: The owner's backups (None: this server keeps none, e.g. a database in memory).
        self.backups = backups
        #: The chain's shipper, which the app sets once it runs it (None: in no chain).
        self.chain: Shipper | None = None
        #: The owner's map actions (a robot's files, a floor plan, the plan under the map).
        self.maps = SiteMaps(core.store, core.places, core.clock)
        self.security = sessions.config
        self.host = host
        self.port = port
        self.ssl = ssl
        self._ws: WsServer | None = None
        self.connections = 0
        self._per_address: Counter[str] = Counter()
        self._handshake: dict[ServerConnection, Principal] = {}
        self._conns: set[_Conn] = set()
        self._idle_task: asyncio.Task[None] | None = None
        self._site = default_site()  # the web UI's files, read once at start, never per request

    async def start(self) -> None:
        self._ws = await serve(
            self._handler,
            self.host,
            self.port,
            process_request=self._process_request,
            max_size=MAX_FRAME,
            max_queue=32,
            ping_interval=20,
            ping_timeout=20,
            compression=None,
            ssl=self.ssl,
        )
        sock = next(iter(self._ws.sockets))
        self.port = sock.getsockname()[1]
        self._idle_task = asyncio.create_task(self._close_idle(), name="idle-connections")
        log.info("serving %s", self.url)

    @property
    def url(self) -> str:
        scheme = "wss" if self.ssl is not None else "ws"
        return f"{scheme}://{self.host}:{self.port}/ws"

    async def close(self) -> None:
        await self.forecaster.close()
        if self._idle_task is not None:
            self._idle_task.cancel()
            self._idle_task = None
        if self._ws is not None:
            self._ws.close(close_connections=True)
            await self._ws.wait_closed()
            self._ws = None

    # -- handshake ---------------------------------------------------------------------------

    async def _process_request(
        self, connection: ServerConnection, request: Request
    ) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == "/ws":
            return await self._ws_handshake(connection, request)
        if path == "/healthz":
            body = json.dumps(
                {"status": "ok", "robots": {n: st.value for n, st in self.core.robot_statuses()}}
            ).encode()
            return _http(http.HTTPStatus.OK, body, "application/json")
        if path.startswith(BACKDROP_PATH):
            found = await self.maps.backdrop_image(path.removeprefix(BACKDROP_PATH))
            if found is None:
                return _http(http.HTTPStatus.NOT_FOUND, b"no such floor plan\n", "text/plain")
            # Named by its digest: the same address is always the same picture.
            return _http(http.HTTPStatus.OK, *found, cache="max-age=31536000, immutable")
        if path.startswith(CALL_PATH):
            return await self._button(connection, request, path.removeprefix(CALL_PATH))
        if path.startswith(DOWNLOAD_PATH) and self.backups is not None:
            status, body = await self.backups.fetch(request.path)
            if status is not http.HTTPStatus.OK:
                return _http(status, body, "text/plain; charset=utf-8")
            name = path.removeprefix(DOWNLOAD_PATH)
            return _http(
                status,
                body,
                "application/vnd.sqlite3",
                ("Content-Disposition", f'attachment; filename="{name}"'),
            )
        return self._site.respond(request)  # the web UI (GET/HEAD), 404 for anything else

    async def _button(self, ws: ServerConnection, request: Request, token: str) -> Response:
        """A Wi-Fi call button's ``GET /call/<token>[?kind=bill]`` (what ESPHome, Tasmota's
        WebSend and Shelly's actions send): answered in plain text, 200 when the call is
        open (new or merged), 4xx with the reason otherwise, nothing changed."""
        if request.method != "GET":
            # A HEAD (a link preview) or anything else is not a press.
            body = b"a call button sends GET\n"
            status = http.HTTPStatus.METHOD_NOT_ALLOWED
            return _http(status, body, "text/plain; charset=utf-8", ("Allow", "GET"))
        kinds = parse_qs(urlsplit(request.path).query).get("kind")
        press = await self.core.calls.press(token, kinds[0] if kinds else None)
        await self.core.flush_events()
        if press.status != 200:
            log.info("call button refused from %s: %s", _peer(ws), press.text.strip())
        extra = [("Retry-After", str(press.retry_after))] if press.retry_after else []
        body = press.text.encode()
        return _http(http.HTTPStatus(press.status), body, "text/plain; charset=utf-8", *extra)

    async def intake(
        self,
        method: str,
        path: str,
        authorization: str | None,
        content_type: str | None,
        body: bytes,
        peer: str,
    ) -> tuple[int, Any, list[tuple[str, str]]]:
        """The order-intake API's ``POST /api/orders`` (:mod:`serveur.till.intake` parses the
        HTTP): an integration token with the ``orders`` scope, a JSON :class:`IntakeOrder`;
        201 with the ticket and its orders, 200 for the same key and body again. Errors are
        the protocol's error objects (``code``, ``message``, ``details``)."""
        if urlsplit(path).path != INTAKE_PATH:
            return 404, NotFound(f"no {urlsplit(path).path[:80]} here: {INTAKE_PATH}").to_dict(), []
        if method != "POST":
            err = InvalidField(f"{INTAKE_PATH} takes POST", field="method")
            return 405, err.to_dict(), [("Allow", "POST")]
        scheme, _, token = (authorization or "").partition(" ")
        try:
            if scheme.lower() != "bearer" or not token.strip():
                raise Unauthorized("Authorization must be: Bearer <token>")
            who = await self.sessions.authenticate_token(token.strip())
        except ServeurError as exc:
            await self.sessions.audit(None, peer, "intake", exc.code, data={"via": "api"})
            return 401, exc.to_dict(), [("WWW-Authenticate", "Bearer")]
        try:
            if Scope.ORDERS not in who.scopes:
                raise Forbidden("the order-intake API needs the 'orders' scope", scope="orders")
            if (content_type or "").split(";")[0].strip().lower() != "application/json":
                err = InvalidField("send JSON (Content-Type: application/json)", field="body")
                return 415, err.to_dict(), []
            req = P.parse_intake(body)
            created, ticket, orders = await self.core.tickets.take_request(
                f"api {who.label or who.actor}", who.token_id, req
            )
            await self.core.flush_events()
        except ServeurError as exc:
            await self.sessions.audit(who, peer, "intake", exc.code, data={"via": "api"})
            return _INTAKE_STATUS.get(exc.code, 400), exc.to_dict(), []
        await self.sessions.audit(
            who, peer, "intake", "ok", data={"ticket": ticket.id, "created": created}
        )
        # Serialised once, as a websocket reply is: the listener sends the text as it is.
        return (201 if created else 200), P.dump({"ticket": ticket, "orders": orders}), []

    async def _ws_handshake(self, ws: ServerConnection, request: Request) -> Response | None:
        origin = request.headers.get("Origin")
        if origin is not None and not self._origin_ok(origin, request.headers.get("Host", "")):
            log.warning("refused a websocket from origin %r (peer %s)", origin[:100], _peer(ws))
            return _http(
                http.HTTPStatus.FORBIDDEN, b"cross-origin websocket refused\n", "text/plain"
            )
        if self._per_address[_host_of(ws)] >= self.security.max_per_address:
            return _http(http.HTTPStatus.TOO_MANY_REQUESTS, b"too many connections\n", "text/plain")
        authz = request.headers.get("Authorization")
        if authz is not None:
            scheme, _, token = authz.partition(" ")
            try:
                if scheme.lower() != "bearer":
                    raise Unauthorized("Authorization must be: Bearer <token>")
                self._handshake[ws] = await self.sessions.authenticate_token(token.strip())
            except ServeurError as exc:
                await self.sessions.audit(
                    None, _peer(ws), "login", exc.code, data={"via": "handshake"}
                )
                return _http(
                    http.HTTPStatus.UNAUTHORIZED, f"{exc.message}\n".encode(), "text/plain"
                )
        return None

    def _origin_ok(self, origin: str, host: str) -> bool:
        """Same-origin (the page this server served) or explicitly allowed. Browsers always
        send Origin on websocket handshakes; scripts usually send none, and pass."""
        if origin in self.security.allowed_origins:
            return True
        parts = urlsplit(origin)
        return parts.scheme in ("http", "https") and bool(host) and parts.netloc == host

    # -- connection --------------------------------------------------------------------------

    async def _handler(self, ws: ServerConnection) -> None:
        self.connections += 1
        host = _host_of(ws)
        self._per_address[host] += 1
        sub = Subscriber(ws.send, ws.close, name=_peer(ws), write_now=_writer_now(ws))
        conn = _Conn(
            ws, sub, RateLimiter(self.security.rate, self.security.burst, self.sessions.monotonic())
        )
        sub.start()
        self.core.hub.add(sub)
        conn.active_at = self.sessions.monotonic()
        self._conns.add(conn)
        principal = self._handshake.pop(ws, None)
        if principal is not None:
            self._become(conn, principal)
        else:
            conn.deadline = asyncio.create_task(self._login_deadline(conn))
        try:
            async for frame in ws:
                await self._serve_one(conn, frame)
        except websockets.exceptions.ConnectionClosed:
            pass
        finally:
            self._conns.discard(conn)
            for robot in list(conn.watching):
                await self._unwatch(conn, robot)
            if conn.deadline is not None:
                conn.deadline.cancel()
            if conn.principal is not None:
                self.sessions.unbind(conn.principal, ws.close)
            self.core.hub.remove(sub)
            await sub.stop()
            self._per_address[host] -= 1
            if self._per_address[host] <= 0:
                del self._per_address[host]

    async def _close_idle(self) -> None:
        """Close connections that neither subscribe to anything nor ask anything for
        ``idle_timeout`` seconds: a script that forgot its socket holds a slot of its address's
        quota for nothing. Subscribers (screens) are never idle: they are listening."""
        limit = self.security.idle_timeout
        while True:
            await asyncio.sleep(min(30.0, limit / 4))
            now = self.sessions.monotonic()
            for conn in list(self._conns):
                if not conn.sub.topics and now - conn.active_at > limit:
                    log.info("closing idle connection %s", conn.peer)
                    asyncio.get_running_loop().create_task(
                        conn.ws.close(CLOSE_IDLE, "idle: nothing subscribed, nothing asked")
                    )

    async def _login_deadline(self, conn: _Conn) -> None:
        await asyncio.sleep(self.security.login_deadline)
        if conn.principal is None:
            await conn.ws.close(CLOSE_AUTH, "log in first")

    def _become(self, conn: _Conn, p: Principal) -> None:
        if conn.principal is not None:
            self.sessions.unbind(conn.principal, conn.ws.close)
            self.core.hub.unsubscribe(conn.sub, list(conn.sub.topics))
        conn.principal = p
        self.sessions.bind(p, conn.ws.close)
        if p.role in (Role.ROBOT_SCREEN, Role.TABLE_SCREEN):
            conn.sub.view = ScreenView(p, self.core.task_robot)
        else:
            conn.sub.view = None
        if conn.deadline is not None:
            conn.deadline.cancel()
            conn.deadline = None

    async def _serve_one(self, conn: _Conn, frame: str | bytes) -> None:
        request_id: Any = None
        msg: Any = None
        try:
            msg = P.parse_client(frame)
            request_id = msg.id
            conn.active_at = self.sessions.monotonic()
            wait = conn.limiter.allow(conn.active_at)
            if wait:
                raise RateLimited("too many requests on this connection", wait=wait)
            payload = await self._dispatch(conn, msg)
            sub_reply, outcome = P.ok_frame(request_id, **payload), "ok"
        except ServeurError as exc:
            if exc.request_id is None:
                exc.request_id = request_id
            sub_reply, outcome = P.error_frame(exc.request_id, exc), exc.code
        except Exception as exc:  # a bug must cost one request, not the connection
            log.exception("internal error handling a request")
            err = ServeurError(f"internal error: {type(exc).__name__}")
            sub_reply, outcome = P.error_frame(request_id, err), err.code
        conn.sub.reply(sub_reply)
        conn.sub.release()  # updates held during a snapshot go out after its reply
        if conn.close_after is not None:
            conn.sub.close_after_replies(*conn.close_after)
        # After the reply is queued: the client need not wait for the audit row, and the
        # connection's next request is read only once it is written.
        await self._audit(conn, msg, outcome)

    async def _dispatch(self, conn: _Conn, msg: Any) -> dict[str, Any]:
        if msg.clientmsg == "login":
            return await self._login(conn, msg)
        p = conn.principal
        if p is not None and p.expired(self.core.clock.epoch()):
            self.sessions.unbind(p, conn.ws.close)
            conn.principal = None
            conn.close_after = (CLOSE_AUTH, "session expired")
            raise Unauthorized("session expired: log in again")
        authorize(p, msg)
        own = _SERVER_VERBS.get(type(msg))
        if own is not None:
            return await own(self, conn, msg)
        table = p.table if p is not None and p.role is Role.TABLE_SCREEN else None
        reply = await self.core.handle(msg, actor=conn.actor, table=table)
        if isinstance(msg, P.SiteSetSettings) and msg.cameras is False:
            # The owner switched the cameras off: nobody watches from now on.
            for other in list(self._conns):
                for robot in list(other.watching):
                    await self._unwatch(other, robot)
        if msg.clientmsg == "site" and reply.get("revoked"):
            # A removed robot's or table's screens: their tokens are revoked, close them now.
            self.sessions.end(reply["revoked"], "its robot or table was removed")
        return reply

    async def _logout(self, conn: _Conn, msg: P.LogoutMsg) -> dict[str, Any]:
        p = conn.principal
        assert p is not None
        self.sessions.unbind(p, conn.ws.close)
        conn.principal = None
        self.core.hub.unsubscribe(conn.sub, list(conn.sub.topics))
        await self.sessions.logout(p)
        return {"session": None}

    async def _camera(self, conn: _Conn, msg: P.CameraMsg) -> dict[str, Any]:
        """Watch a robot's camera or stop: the frames go out as binary messages from a task
        of this connection's own, the newest one whenever the socket can take it."""
        ctl = self.core.controller(msg.robot)  # not_found for a robot that does not exist
        await self._unwatch(conn, msg.robot)
        state = "stopped"
        if msg.watch and not self.core.site.cameras:
            state = "off"
        elif msg.watch:
            relay = await ctl.camera()
            if relay is None:
                state = "none"
            else:
                viewer = relay.watch(conn.peer)
                task = asyncio.get_running_loop().create_task(
                    self._send_frames(conn, viewer), name=f"camera-{msg.robot}-{conn.peer}"
                )
                conn.watching[msg.robot] = (relay, viewer, task)
                state = "watching"
        return {"camera": {"robot": msg.robot, "state": state}}

    async def _send_frames(self, conn: _Conn, viewer: CameraViewer) -> None:
        """Send each new picture unless the last one has not reached the viewer yet. The
        kernel's send buffer on a stalled Wi-Fi link holds hundreds of kB (dozens of pictures)
        before a ``send`` would wait, and every one of them would then be shown late; so a
        picture goes out only when what is still unacknowledged on the socket is less than one
        picture (:func:`_unsent`), else it is skipped and the next one is looked at when it
        comes — the newest wins, and nothing polls the socket between pictures (a timer per
        tablet per picture was a fifth of the relay's CPU, bench/bench_camera.py)."""
        epoch = time.time  # wall time, as the relay's (a picture's age is what staff see)
        ws = conn.ws
        fd = _socket_fd(ws)  # looked up once: the check runs per picture
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            while (f := await viewer.next()) is not None:
                if _unsent(ws, fd) > len(f.jpeg):
                    viewer.skipped += 1  # the last picture is still on its way
                    continue
                await ws.send(camera_frame(f.robot, f.seq, f.captured, f.received, epoch(), f.jpeg))

    async def _unwatch(self, conn: _Conn, robot: str) -> None:
        watched = conn.watching.pop(robot, None)
        if watched is not None:
            relay, viewer, task = watched
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
            await relay.leave(viewer)

    async def _upload(self, conn: _Conn, msg: P.SiteUpload) -> dict[str, Any]:
        return {"upload": conn.uploads.start(msg)}

    async def _upload_part(self, conn: _Conn, msg: P.SiteUploadPart) -> dict[str, Any]:
        return {"upload": conn.uploads.add_part(msg)}

    async def _set_map(self, conn: _Conn, msg: P.SiteSetMap) -> dict[str, Any]:
        return await self.maps.set_map(conn.uploads, msg, conn.actor)

    async def _plan_map(self, conn: _Conn, msg: P.SitePlanMap) -> dict[str, Any]:
        return await self.maps.plan_map(conn.uploads, msg, conn.actor)

    async def _align_map(self, conn: _Conn, msg: P.SiteAlignMap) -> dict[str, Any]:
        return await self.maps.align_map(conn.uploads, msg, conn.actor)

    async def _probe_robot(self, conn: _Conn, msg: P.SiteProbeRobot) -> dict[str, Any]:
        found = await probe(msg.url, ssl=self.core.crew.robot_ssl)
        return {"probe": found.as_dict()}

    def _desk(self) -> BackupDesk:
        if self.backups is None:
            raise BackupError("this server keeps no backups", reason="off")
        return self.backups

    async def _list_backups(self, conn: _Conn, msg: P.SiteBackups) -> dict[str, Any]:
        return await self._desk().backups()

    async def _backup_now(self, conn: _Conn, msg: P.SiteBackupNow) -> dict[str, Any]:
        return await self._desk().backup_now()

    async def _download_backup(self, conn: _Conn, msg: P.SiteDownloadBackup) -> dict[str, Any]:
        return await self._desk().download(msg)

    async def _restore(self, conn: _Conn, msg: P.SiteRestore) -> dict[str, Any]:
        desk = self._desk()
        reply, staged = await desk.restore(msg, conn.uploads)
        if staged is not None:
            # This connection closes once its reply is out (1012: service restart); then the
            # app restarts on the backup, closing every other as at any shutdown (1001).
            conn.close_after = (CLOSE_RESTART, "the server restarts on a backup")
            desk.restart_after(conn.ws.wait_closed(), staged)
        return reply

    async def _ping(self, conn: _Conn, msg: P.PingMsg) -> dict[str, Any]:
        return {"time": self.core.clock.epoch()}

    async def _chain(self, conn: _Conn, msg: P.ChainMsg) -> dict[str, Any]:
        """The site's place in a chain and its outbox, read now (the console asks again every
        20 s while it shows them). Events are numbered with or without a chain."""
        box = await self.core.store.outbox.state()
        shipper = self.chain
        outbox = {**dataclasses.asdict(box), "unsent": box.unsent}
        return {
            "chain": {
                "configured": shipper is not None,
                "site": None if shipper is None else shipper.site,
                "broker": None if shipper is None else shipper.address.describe(),
                "connected": shipper is not None and shipper.connected.is_set(),
                "outbox": outbox,
            }
        }

    async def _account(self, conn: _Conn, msg: Any) -> dict[str, Any]:
        return await handle_account(
            self.sessions, conn.principal, msg, public_url=self.core.site.public_url
        )

    async def _stats(self, conn: _Conn, msg: Any) -> dict[str, Any]:
        return await self.stats.handle(msg)

    async def _forecast_cancel(self, conn: _Conn, msg: P.StatsForecastCancel) -> dict[str, Any]:
        return {"forecast": _forecast_info((await self.forecaster.cancel()).as_dict())}

    async def _forecast(self, conn: _Conn, msg: P.StatsForecast) -> dict[str, Any]:
        _, start, end = when_range(msg.utc_offset, msg.day, msg.day, ("day", "day"))
        assert start is not None and end is not None
        fc = await self.forecaster.start(msg.day, start, end, list(msg.robots), msg.policy)
        return {"forecast": _forecast_info(fc.as_dict())}

    async def _search_audit(self, conn: _Conn, msg: P.SiteAudit) -> dict[str, Any]:
        q = AuditQuery(
            actor=msg.actor,
            verb=msg.verb,
            outcome=msg.outcome,
            target=msg.target,
            since=msg.since,
            until=msg.until,
            before_id=msg.before,
            limit=msg.limit,
        )
        return {"audit": await self.core.store.audit.search_audit(q)}

    async def _login(self, conn: _Conn, msg: P.LoginMsg) -> dict[str, Any]:
        p, token = await self.sessions.login(msg, conn.peer)
        self._become(conn, p)
        session = p.public()
        if token is not None:
            session["token"] = token
        return {"session": session}

    async def _audit(self, conn: _Conn, msg: Any, outcome: str) -> None:
        """Record who asked what from where. Not recorded: unreadable frames, reads and
        teleop frames that went through, and an anonymous connection's requests other than
        ``login`` (an unauthenticated flood must not fill the trail; failed logins do go in).
        """
        if msg is None:
            return
        verb = msg.clientmsg
        refused = outcome in ("forbidden", "unauthorized")
        if conn.principal is None and verb != "login":
            return
        if not refused and (
            verb in self.security.unaudited
            or (verb == "control" and msg.action == "teleop")
            # A file's parts: its upload and what it was used for are audited, not each part.
            or (verb == "site" and msg.action == "upload_part")
            # A read the owner's console repeats while it shows the chain: not a trail's worth.
            or verb == "chain"
        ):
            return
        p = conn.principal
        target = (
            getattr(msg, "robot", None)
            or getattr(msg, "waypoint", None)
            or getattr(msg, "zone", None)
            or getattr(msg, "name", None)
        )
        if target is None and getattr(msg, "table", None) is not None:
            target = msg.table
        data: dict[str, Any] = {}
        for k in ("type", "action", "dish", "orders", "waypoint", "x", "y", "username"):
            v = getattr(msg, k, None)
            if v is not None:
                data[k] = v
        if verb == "account":  # the role asked for and the token id (never a secret)
            for k in ("role", "token", "table", "robot"):
                v = getattr(msg, k, None)
                if v is not None:
                    data[k] = v
            target = target or getattr(msg, "username", None)
        await self.sessions.audit(p, conn.peer, verb, outcome, target=target, data=data)

    async def _data(self, conn: _Conn, msg: Any) -> dict[str, Any]:
        sub = conn.sub
        topics: list[str] = list(msg.topics)
        for t in topics:
            if t not in _STATE_TOPICS:
                kind, _, robot = t.partition(":")
                if kind not in P.ROBOT_TOPICS or not robot:
                    raise InvalidField(f"unknown topic {t!r}", topic=t)
                if not msg.unsubscribe and robot not in dict(self.core.robot_statuses()):
                    # (Leaving a removed robot's stream is fine: nothing to leave.)
                    raise NotFound(f"no robot named {robot!r}", robot=robot)
        if msg.unsubscribe:
            self.core.hub.unsubscribe(sub, topics)
            return {"data": {}}
        sub.hold()  # released by _serve_one once the reply is queued
        self.core.hub.subscribe(sub, topics)
        snapshot = {t: await self._snapshot(t) for t in topics}
        view = sub.view
        if view is not None:
            snapshot = {
                t: view.snapshot(t, snap) if isinstance(snap, list) else snap
                for t, snap in snapshot.items()
            }
        return {"data": snapshot}

    async def _snapshot(self, topic: str) -> Any:
        if topic == "audit":
            return await self.core.store.audit.recent_audit(100)
        if topic == "forecast":
            fc = self.forecaster.current
            return None if fc is None else _forecast_info(fc.as_dict())
        return await self.core.snapshot(topic)


def _forecast_info(rec: dict[str, Any]) -> P.ForecastInfo:
    return P.ForecastInfo.model_validate(rec)


def _writer_now(ws: ServerConnection) -> Callable[[str], bool]:
    """A synchronous ``send`` of one text frame for the hub's stream fast path.

    What ``ServerConnection.send`` does for a plain string, minus its coroutine and context
    manager: frame it and hand it to the transport. It declines (False: the frame is queued
    for the writer task instead) unless the connection is open, not flow-controlled (the
    transport's buffer below its high-water mark) and not in the middle of a fragmented
    message, so it never buffers without bound nor interleaves with another message.
    """

    def write(frame: str) -> bool:
        if ws.protocol.state is not State.OPEN or ws.paused or ws.send_in_progress is not None:
            return False
        try:
            ws.protocol.send_text(frame.encode())
            ws.send_data()
        except Exception:  # a dying socket: let the writer task's send report it
            return False
        return True

    return write


def _unsent(ws: ServerConnection, fd: int | None) -> int:
    """Bytes written to ``ws`` the viewer has not acknowledged yet: the transport's buffer plus
    the kernel's send queue of socket ``fd`` (Linux ``TIOCOUTQ``: queued and unacknowledged;
    not counted elsewhere, or without ``fd``)."""
    n = ws.transport.get_write_buffer_size()
    if fd is not None and _TIOCOUTQ is not None:
        with contextlib.suppress(OSError, ValueError):
            buf = fcntl.ioctl(fd, _TIOCOUTQ, b"\0\0\0\0")
            n += int.from_bytes(buf, sys.byteorder, signed=True)
    return n


_TIOCOUTQ: int | None = getattr(termios, "TIOCOUTQ", None)


def _socket_fd(ws: ServerConnection) -> int | None:
    sock = ws.transport.get_extra_info("socket")
    return None if sock is None else int(sock.fileno())


def _members(alias: Any) -> tuple[type, ...]:
    """The message classes of an ``Annotated[A | B | ..., Field(discriminator=...)]`` alias."""
    return typing.get_args(typing.get_args(alias)[0])


#: The messages the server answers itself (sessions, subscriptions, accounts, statistics, the
#: audit search); every other goes to the core. ``login`` is answered before authorisation.
_SERVER_VERBS: dict[type, Callable[[Server, _Conn, Any], Awaitable[dict[str, Any]]]] = {
    P.LogoutMsg: Server._logout,
    P.DataMsg: Server._data,
    P.PingMsg: Server._ping,
    P.ChainMsg: Server._chain,
    P.CameraMsg: Server._camera,
    P.SiteUpload: Server._upload,
    P.SiteUploadPart: Server._upload_part,
    P.SiteSetMap: Server._set_map,
    P.SitePlanMap: Server._plan_map,
    P.SiteProbeRobot: Server._probe_robot,
    P.SiteAlignMap: Server._align_map,
    P.SiteAudit: Server._search_audit,
    P.SiteBackups: Server._list_backups,
    P.SiteBackupNow: Server._backup_now,
    P.SiteDownloadBackup: Server._download_backup,
    P.SiteRestore: Server._restore,
    P.StatsFigures: Server._stats,
    P.StatsTrips: Server._stats,
    P.StatsForecast: Server._forecast,
    P.StatsForecastCancel: Server._forecast_cancel,
    P.StatsLastService: Server._stats,
    **{cls: Server._account for cls in _members(P.AccountMessage)},
}
