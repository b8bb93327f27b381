"""The order-intake API's HTTP listener: ``POST /api/orders`` for integrations that can reach
the restaurant's server (a POS bridge on site, a poller of a cloud POS run on site).

The websocket endpoint's HTTP side (python-websockets) reads a request's headers and never its
body, so a POST needs its own listener: h11 (the sans-I/O HTTP/1.1 parser python-websockets'
peers use: httpx, hypercorn, uvicorn's h11 worker) does the protocol, this module only the
asyncio shell around it. What a request means — the token, the body, the order — is the
``handle`` function given (``serveur.server.Server.intake``): this shell never reads it.

Bounded: a request's headers at most 16 kB, its body :data:`MAX_BODY` (413 beyond, before it
is read), :data:`TIMEOUT` seconds between two reads of a request (a connection that stalls is
closed), :data:`MAX_CONNECTIONS` at once. Keep-alive is honoured.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import ssl
from collections.abc import Awaitable, Callable
from typing import Any, Final

import h11

__all__ = ["MAX_BODY", "Handle", "IntakeServer"]

log = logging.getLogger(__name__)

MAX_BODY: Final = 64 * 1024
TIMEOUT: Final = 10.0
MAX_CONNECTIONS: Final = 32
_INTERNAL: Final = {
    "code": "internal_error",
    "message": "the server failed on this request; it was not taken: send it again later",
}
_TOO_LARGE: Final = {
    "code": "invalid_field",
    "message": f"a request is at most {MAX_BODY} bytes",
    "details": {"field": "body"},
}

#: (method, path, Authorization header or None, Content-Type or None, body, peer) ->
#: (status, reply, extra headers); the reply is JSON text already, a JSON-able value, or
#: bytes sent as they are (a page or a script of the chain's dashboard, its Content-Type
#: among the extra headers).
Handle = Callable[
    [str, str, str | None, str | None, bytes, str],
    Awaitable[tuple[int, Any, list[tuple[str, str]]]],
]


class IntakeServer:
    """One listening socket; each connection parsed by h11."""

    def __init__(
        self, handle: Handle, host: str, port: int, *, ssl_context: ssl.SSLContext | None = None
    ) -> None:
        self._handle = handle
        self.host = host
        self.port = port
        self._ssl = ssl_context
        self._server: asyncio.Server | None = None
        self._slots = asyncio.Semaphore(MAX_CONNECTIONS)
        self._tasks: set[asyncio.Task[None]] = set()

    async def start(self) -> None:
        self._server = await asyncio.start_server(
            self._connection, self.host, self.port, ssl=self._ssl
        )
        self.port = int(self._server.sockets[0].getsockname()[1])
        log.info("order-intake API on port %d", self.port)

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
            self._server = None
        for task in list(self._tasks):
            task.cancel()
        if self._tasks:
            await asyncio.gather(*self._tasks, return_exceptions=True)

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._tasks.add(task)
        peer = writer.get_extra_info("peername")
        where = f"{peer[0]}:{peer[1]}" if isinstance(peer, tuple) else str(peer)
        try:
            if self._slots.locked():
                return
            async with self._slots:
                await self._serve(reader, writer, where)
        except (OSError, ConnectionError, TimeoutError):
            pass
        except Exception:  # one request never takes the listener down
            log.exception("order-intake API: a connection from %s failed", where)
        finally:
            self._tasks.discard(task)
            writer.close()
            with contextlib.suppress(OSError, ConnectionError):
                await writer.wait_closed()

    async def _serve(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, where: str
    ) -> None:
        conn = h11.Connection(h11.SERVER, max_incomplete_event_size=16 * 1024)
        request: h11.Request | None = None
        body = bytearray()
        while True:
            try:
                event = conn.next_event()
            except h11.RemoteProtocolError as exc:
                if conn.our_state in (h11.IDLE, h11.SEND_RESPONSE):
                    await self._send(
                        writer, conn, 400, {"code": "bad_request", "message": str(exc)}
                    )
                return
            if event is h11.NEED_DATA:
                data = await asyncio.wait_for(reader.read(64 * 1024), TIMEOUT)
                conn.receive_data(data)
                continue
            if isinstance(event, h11.Request):
                request, body = event, bytearray()
                length = _header(event, b"content-length")
                if length is not None and length.isdigit() and int(length) > MAX_BODY:
                    await self._send(writer, conn, 413, _TOO_LARGE, close=True)
                    return
            elif isinstance(event, h11.Data):
                body += event.data
                if len(body) > MAX_BODY:
                    await self._send(writer, conn, 413, _TOO_LARGE, close=True)
                    return
            elif isinstance(event, h11.EndOfMessage) and request is not None:
                try:
                    status, reply, extra = await self._handle(
                        request.method.decode("ascii", "replace"),
                        request.target.decode("ascii", "replace"),
                        _header(request, b"authorization"),
                        _header(request, b"content-type"),
                        bytes(body),
                        where,
                    )
                except Exception:  # a bug: answered, logged, the listener goes on
                    log.exception("order-intake API: a request from %s failed", where)
                    status, reply, extra = 500, _INTERNAL, []
                await self._send(writer, conn, status, reply, extra=extra)
                if conn.our_state is h11.MUST_CLOSE or conn.their_state is h11.MUST_CLOSE:
                    return
                conn.start_next_cycle()
                request = None
            elif isinstance(event, h11.ConnectionClosed):
                return

    async def _send(
        self,
        writer: asyncio.StreamWriter,
        conn: h11.Connection,
        status: int,
        reply: Any,
        *,
        extra: list[tuple[str, str]] | None = None,
        close: bool = False,
    ) -> None:
        extra = list(extra or [])
        if isinstance(reply, bytes):  # a file, its Content-Type among ``extra``
            body, kind = reply, []
        else:
            text = (
                reply
                if isinstance(reply, str)
                else json.dumps(reply, ensure_ascii=False, separators=(",", ":"))
            )
            body, kind = (
                text.encode() + b"\n",
                [("Content-Type", "application/json; charset=utf-8")],
            )
        headers = [
            *kind,
            ("Content-Length", str(len(body))),
            *(
                []
                if any(k == "Cache-Control" for k, _ in extra)
                else [("Cache-Control", "no-store")]
            ),
            *extra,
        ]
        if close:
            headers.append(("Connection", "close"))
        writer.write(conn.send(h11.Response(status_code=status, headers=headers)) or b"")
        writer.write(conn.send(h11.Data(data=body)) or b"")
        writer.write(conn.send(h11.EndOfMessage()) or b"")
        await writer.drain()


def _header(request: h11.Request, name: bytes) -> str | None:
    for key, value in request.headers:
        if key == name:
            return bytes(value).decode("latin-1")
    return None
