"""The websocket endpoint ``/ws`` and plain HTTP (health, the web UI), from one process.

Thin on purpose: read a frame, parse it (:mod:`serveur.protocol`), hand it to the core,
queue the reply. Every failure becomes a structured error reply on the same connection —
nothing a client sends can close it, let alone crash the server. Frames are read one at a
time per connection, so each client's requests are answered in order.
"""

from __future__ import annotations

import http
import json
import logging
import ssl as ssl_module
from typing import Any

import websockets
from websockets.asyncio.server import Server as WsServer
from websockets.asyncio.server import ServerConnection, serve
from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from serveur import protocol as P
from serveur.core import Core
from serveur.errors import InvalidField, NotFound, ServeurError
from serveur.hub import Subscriber
from serveur.static import default_site

__all__ = ["MAX_FRAME", "Server"]

log = logging.getLogger(__name__)

MAX_FRAME = 64 * 1024
_STATE_TOPICS = {"robots", "orders", "tasks", "waypoints", "map", "events"}


def _http(status: http.HTTPStatus, body: bytes, content_type: str) -> Response:
    headers = Headers(
        [
            ("Content-Type", content_type),
            ("Content-Length", str(len(body))),
            ("X-Content-Type-Options", "nosniff"),
            ("Cache-Control", "no-store"),
        ]
    )
    return Response(status.value, status.phrase, headers, body)


class Server:
    """Serves ``/ws`` for clients and HTTP for everything else, on one port.

    With ``ssl`` (see :func:`serveur.tls.server_context`) that port speaks only TLS: the web UI
    is https and /ws is wss, so a tablet that loaded the page over https opens its socket with
    the same certificate, and nothing is ever accepted in the clear.
    """

    def __init__(
        self,
        core: Core,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        ssl: ssl_module.SSLContext | None = None,
    ) -> None:
        self.core = core
        self.host = host
        self.port = port
        self.ssl = ssl
        self._ws: WsServer | None = None
        self.connections = 0
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
        log.info("serving %s", self.url)

    @property
    def url(self) -> str:
        scheme = "wss" if self.ssl is not None else "ws"
        return f"{scheme}://{self.host}:{self.port}/ws"

    async def close(self) -> None:
        if self._ws is not None:
            self._ws.close(close_connections=True)
            await self._ws.wait_closed()
            self._ws = None

    def _process_request(self, connection: ServerConnection, request: Request) -> Response | None:
        path = request.path.split("?", 1)[0]
        if path == "/ws":
            return None
        if path == "/healthz":
            body = json.dumps(
                {"status": "ok", "robots": {n: st.value for n, st in self.core.robot_statuses()}}
            ).encode()
            return _http(http.HTTPStatus.OK, body, "application/json")
        return self._site.respond(request)  # the web UI (GET/HEAD), 404 for anything else

    async def _handler(self, ws: ServerConnection) -> None:
        self.connections += 1
        peer = ws.remote_address
        sub = Subscriber(ws.send, ws.close, name=f"{peer}")
        sub.start()
        self.core.hub.add(sub)
        try:
            async for frame in ws:
                await self._serve_one(sub, frame)
        except websockets.exceptions.ConnectionClosed:
            pass
        finally:
            self.core.hub.remove(sub)
            await sub.stop()

    async def _serve_one(self, sub: Subscriber, frame: str | bytes) -> None:
        request_id: Any = None
        try:
            msg = P.parse_client(frame)
            request_id = msg.id
            if msg.clientmsg == "data":
                payload = await self._data(sub, msg)
            else:
                payload = await self.core.handle(msg)
            sub.reply(P.ok_frame(request_id, **payload))
        except ServeurError as exc:
            if exc.request_id is None:
                exc.request_id = request_id
            sub.reply(P.error_frame(exc.request_id, exc))
        except Exception as exc:  # a bug must cost one request, not the connection
            log.exception("internal error handling a request")
            err = ServeurError(f"internal error: {type(exc).__name__}")
            sub.reply(P.error_frame(request_id, err))

    async def _data(self, sub: Subscriber, msg: Any) -> dict[str, Any]:
        topics: list[str] = list(msg.topics)
        for t in topics:
            if t not in _STATE_TOPICS:
                kind, _, robot = t.partition(":")
                if kind not in ("pose", "scan") or not robot:
                    raise InvalidField(f"unknown topic {t!r}", topic=t)
                if robot not in dict(self.core.robot_statuses()):
                    raise NotFound(f"no robot named {robot!r}", robot=robot)
        if msg.unsubscribe:
            self.core.hub.unsubscribe(sub, topics)
            return {"data": {}}
        self.core.hub.subscribe(sub, topics)
        snapshot = {t: await self.core.snapshot(t) for t in topics}
        return {"data": snapshot}
