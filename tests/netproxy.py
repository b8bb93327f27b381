"""A TCP proxy between the server and a robot that can fail the way Wi-Fi fails.

Real faults a robot link meets, made on purpose:

* :meth:`LinkProxy.blackhole` — the path goes dead with the socket open: no byte goes either
  way, nothing is closed, no FIN, no RST (a robot driving out of Wi-Fi range, an access point
  that hangs). Bytes written meanwhile are swallowed, as a dead path swallows them.
* :meth:`LinkProxy.stall` — the path stalls with the socket open: nothing gets through, but
  nothing is lost either — TCP retransmits, so on :meth:`resume` what was held arrives late
  (a tablet's Wi-Fi pausing for a second, a microwave next to the access point).
* :meth:`LinkProxy.resume` — the path comes back (the same TCP connections carry on).
* :meth:`LinkProxy.inject` — a raw text frame from the "robot", byte for byte as given
  (``1e999`` stays ``1e999``; a JSON encoder would have written ``Infinity``).
* :meth:`LinkProxy.cut` — every connection reset.

The robot-to-server direction is parsed into websocket frames so that an injected frame goes
between two whole frames; server frames to a client are never masked (RFC 6455 5.1), which is
what keeps the parser small. Loopback only, and every task ends with :meth:`close`.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import struct

__all__ = ["LinkProxy"]


def text_frame(payload: bytes) -> bytes:
    """An unmasked, final websocket text frame (server to client)."""
    n = len(payload)
    if n < 126:
        head = struct.pack("!BB", 0x81, n)
    elif n < 1 << 16:
        head = struct.pack("!BBH", 0x81, 126, n)
    else:
        head = struct.pack("!BBQ", 0x81, 127, n)
    return head + payload


class _Pair:
    def __init__(self, down_w: asyncio.StreamWriter, up_w: asyncio.StreamWriter) -> None:
        self.down_w = down_w  # towards the server (the websocket client)
        self.up_w = up_w  # towards the robot
        self.down_lock = asyncio.Lock()
        self.tasks: list[asyncio.Task[None]] = []


class LinkProxy:
    """Listens on 127.0.0.1 and forwards every connection to ``target`` (host, port)."""

    def __init__(self, target_host: str, target_port: int, *, window: int | None = None) -> None:
        """``window``: the receive buffer (bytes) on the target's side, as a device's TCP
        window. A stalled Wi-Fi path acknowledges nothing, so the sender's queue grows; here
        the proxy's own kernel would acknowledge into its large loopback buffer (megabytes)
        and the target could not tell a stall. With a small window it fills after a few kB,
        as a phone's does."""
        self._target = (target_host, target_port)
        self._window = window
        self._server: asyncio.Server | None = None
        self._pairs: set[_Pair] = set()
        self._dead = False
        self._flowing = asyncio.Event()
        self._flowing.set()
        self.connections = 0

    @classmethod
    def for_url(cls, url: str, *, window: int | None = None) -> LinkProxy:
        host, port = url.split("//", 1)[1].split("/", 1)[0].rsplit(":", 1)
        return cls(host, int(port), window=window)

    async def start(self) -> LinkProxy:
        self._server = await asyncio.start_server(self._accept, "127.0.0.1", 0)
        return self

    @property
    def url(self) -> str:
        assert self._server is not None
        port = self._server.sockets[0].getsockname()[1]
        return f"ws://127.0.0.1:{port}"

    def blackhole(self) -> None:
        self._dead = True

    def stall(self) -> None:
        self._flowing.clear()

    def resume(self) -> None:
        self._dead = False
        self._flowing.set()

    async def inject(self, text: str) -> int:
        """Send ``text`` as one frame from the robot to every connected server; how many."""
        n = 0
        for pair in list(self._pairs):
            async with pair.down_lock:
                pair.down_w.write(text_frame(text.encode()))
                await pair.down_w.drain()
            n += 1
        return n

    def cut(self) -> None:
        for pair in list(self._pairs):
            for w in (pair.down_w, pair.up_w):
                w.transport.abort()

    async def close(self) -> None:
        if self._server is not None:
            self._server.close()
        self.cut()
        for pair in list(self._pairs):
            for t in pair.tasks:
                t.cancel()
            await asyncio.gather(*pair.tasks, return_exceptions=True)
        self._pairs.clear()
        if self._server is not None:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 2.0)

    async def _accept(self, down_r: asyncio.StreamReader, down_w: asyncio.StreamWriter) -> None:
        try:
            if self._window is None:
                up_r, up_w = await asyncio.open_connection(*self._target)
            else:
                sock = socket.socket()
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, self._window)
                sock.setblocking(False)
                await asyncio.get_running_loop().sock_connect(sock, self._target)
                up_r, up_w = await asyncio.open_connection(sock=sock, limit=self._window)
        except OSError:
            down_w.transport.abort()
            return
        self.connections += 1
        pair = _Pair(down_w, up_w)
        self._pairs.add(pair)
        pair.tasks = [
            asyncio.create_task(self._upstream(down_r, pair)),
            asyncio.create_task(self._downstream(up_r, pair)),
        ]
        await asyncio.gather(*pair.tasks, return_exceptions=True)
        self._pairs.discard(pair)
        for w in (down_w, up_w):
            w.transport.abort()

    async def _upstream(self, down_r: asyncio.StreamReader, pair: _Pair) -> None:
        """Server to robot: bytes as they come (dropped while dead)."""
        while data := await down_r.read(65536):
            await self._flowing.wait()
            if not self._dead:
                pair.up_w.write(data)
                await pair.up_w.drain()
        pair.up_w.transport.abort()

    async def _downstream(self, up_r: asyncio.StreamReader, pair: _Pair) -> None:
        """Robot to server: the HTTP upgrade response, then whole frames (dropped while dead)."""
        handshake = await up_r.readuntil(b"\r\n\r\n")
        async with pair.down_lock:
            pair.down_w.write(handshake)
            await pair.down_w.drain()
        while True:
            head = await up_r.readexactly(2)
            n = head[1] & 0x7F
            ext = b""
            if n == 126:
                ext = await up_r.readexactly(2)
                n = struct.unpack("!H", ext)[0]
            elif n == 127:
                ext = await up_r.readexactly(8)
                n = struct.unpack("!Q", ext)[0]
            mask = await up_r.readexactly(4) if head[1] & 0x80 else b""
            body = await up_r.readexactly(n)
            await self._flowing.wait()
            if self._dead:
                continue
            async with pair.down_lock:
                pair.down_w.write(head + ext + mask + body)
                await pair.down_w.drain()
