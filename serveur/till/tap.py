"""serveur as a network printer: the till's kitchen tickets arrive on a raw TCP port (what a
POS calls a "LAN", "Ethernet" or "9100" printer) and each job is handed to the ticket desk.

Two ways to stand in the till's path, the owner's choice:

* **forward** (a kitchen printer's address is set): the till prints to serveur, and every byte
  it sends goes on to the real kitchen printer as it comes, and every byte the printer answers
  (status) goes back to the till — the kitchen's paper is what it was. The printer is reached
  *before* anything is read from the till: when it does not answer within
  :data:`CONNECT_TIMEOUT`, the till's connection is reset unread, so the till itself reports
  "printer offline" and reprints or uses its backup printer, as it would had the printer been
  down with serveur absent; and the printer is reported down (once, and once back up). A job
  is handed to the desk only when the till finished sending and the printer took it all: a
  job cut short is the till's to send again (the desk reads a reprint once).
* **mirror** (no kitchen printer): the till prints to serveur as to a second printer, and
  serveur answers the real-time status requests (``DLE EOT n``) as an online printer with
  paper does, so a till that asks before it sends goes on.

A job ends when the till closes its connection, or after :data:`IDLE_END` seconds without a
byte (tills that keep the connection open between tickets); a connection silent for
:data:`IDLE_CLOSE` seconds is closed (a till gone from the Wi-Fi holds no slot for ever). A
job larger than :data:`MAX_JOB` is forwarded whole but not read (logged). Connections are bounded
(:data:`MAX_CONNECTIONS`); the listening port is re-opened when the owner changes it.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import struct
from collections.abc import Awaitable, Callable
from dataclasses import dataclass, replace
from typing import Final

from serveur.till.escpos import status_replies

__all__ = ["CONNECT_TIMEOUT", "IDLE_END", "MAX_JOB", "PrinterTap", "TapStatus"]

log = logging.getLogger(__name__)

CONNECT_TIMEOUT: Final = 3.0
IDLE_END: Final = 2.0
#: A connection that sends nothing for this long is closed (a till gone from the Wi-Fi).
IDLE_CLOSE: Final = 60.0
MAX_JOB: Final = 4 * 1024 * 1024
MAX_CONNECTIONS: Final = 16
#: How often a forwarding tap checks the kitchen printer when no job came (s).
PROBE_EVERY: Final = 60.0
_CHUNK: Final = 64 * 1024

Sink = Callable[[str, bytes], Awaitable[object]]


@dataclass(frozen=True, slots=True)
class TapStatus:
    """How the printer port is: open, the kitchen printer answering (None: not tried yet, or
    no kitchen printer to forward to), why it could not open."""

    listening: bool = False
    printer_up: bool | None = None
    error: str | None = None


def _reset(writer: asyncio.StreamWriter) -> None:
    """Close with a reset, unread: the till's send fails, as a printer that is not there."""
    sock = writer.get_extra_info("socket")
    if sock is not None:
        with contextlib.suppress(OSError):
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, struct.pack("ii", 1, 0))
    writer.transport.abort()


def _split(printer: str) -> tuple[str, int]:
    host, _, port = printer.rpartition(":")
    return host.strip("[]"), int(port)


class PrinterTap:
    """The printer port: one listening socket, a relay per connection."""

    def __init__(
        self,
        sink: Sink,
        *,
        host: str = "0.0.0.0",
        on_change: Callable[[], None] = lambda: None,
        connect_timeout: float = CONNECT_TIMEOUT,
        idle_end: float = IDLE_END,
        idle_close: float = IDLE_CLOSE,
        probe_every: float = PROBE_EVERY,
    ) -> None:
        self._sink = sink
        self._host = host
        self._on_change = on_change
        self._connect_timeout = connect_timeout
        self._idle_end = idle_end
        self._idle_close = idle_close
        self._probe_every = probe_every
        self._state = TapStatus()
        self.port = 0
        self.printer = ""
        self._server: asyncio.Server | None = None
        self._probe: asyncio.Task[None] | None = None
        self._handlers: set[asyncio.Task[None]] = set()
        self._slots = asyncio.Semaphore(MAX_CONNECTIONS)

    def status(self) -> TapStatus:
        return self._state

    @property
    def bound_port(self) -> int:
        """The port listened on now (0: none)."""
        if self._server is None or not self._server.sockets:
            return 0
        return int(self._server.sockets[0].getsockname()[1])

    async def configure(self, port: int, printer: str) -> None:
        """Listen on ``port`` (0: not at all) and forward to ``printer`` ("": mirror)."""
        if printer != self.printer:
            self.printer = printer
            self._state = replace(self._state, printer_up=None)
            self._restart_probe()
        if port != self.port or (port and self._server is None):
            await self._close_server()
            self.port = port
            self._state = replace(self._state, error=None)
            if port:
                try:
                    self._server = await asyncio.start_server(
                        self._connection, self._host, port, limit=_CHUNK
                    )
                    self._state = replace(self._state, listening=True)
                    log.info("listening as a printer on port %d", port)
                except OSError as exc:
                    error = f"port {port} cannot be opened: {exc.strerror or exc}"
                    self._state = replace(self._state, error=error)
                    log.error("the printer port: %s", error)
        self._on_change()

    def _restart_probe(self) -> None:
        if self._probe is not None:
            self._probe.cancel()
            self._probe = None
        if self.printer and self._probe_every > 0:
            self._probe = asyncio.create_task(self._probing(), name="till-printer-probe")

    async def _probing(self) -> None:
        while True:
            if not self._handlers:  # a job being relayed already says how the printer is
                reached = await self._reach()
                if reached is not None:
                    writer = reached[1]
                    writer.close()
                    with contextlib.suppress(OSError):
                        await writer.wait_closed()
            await asyncio.sleep(self._probe_every)

    def _printer_is(self, up: bool) -> None:
        if self._state.printer_up is not up:
            if up:
                log.info("the kitchen printer %s answers", self.printer)
            else:
                log.error("the kitchen printer %s does not answer", self.printer)
            self._state = replace(self._state, printer_up=up)
            self._on_change()

    async def _reach(self) -> tuple[asyncio.StreamReader, asyncio.StreamWriter] | None:
        """A connection to the kitchen printer, or None (and the printer marked down)."""
        try:
            host, port = _split(self.printer)
            reached = await asyncio.wait_for(
                asyncio.open_connection(host, port, limit=_CHUNK), self._connect_timeout
            )
        except (OSError, TimeoutError, ValueError, OverflowError):  # an address set wrong too
            self._printer_is(False)
            return None
        self._printer_is(True)
        return reached

    async def _connection(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._handlers.add(task)
        peer = writer.get_extra_info("peername")
        source = f"printer {peer[0]}" if isinstance(peer, tuple) else "printer"
        try:
            if self._slots.locked():
                log.warning("the printer port is full: %s refused", source)
                _reset(writer)  # a close would tell the till its ticket printed
                return
            async with self._slots:
                if self.printer:
                    await self._forward(reader, writer, source)
                else:
                    await self._mirror(reader, writer, source)
        except Exception:  # one till's connection never takes the port down
            log.exception("the printer port: a connection from %s failed", source)
        finally:
            self._handlers.discard(task)
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()

    async def _mirror(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, source: str
    ) -> None:
        job = bytearray()
        while chunk := await self._next(reader, job, source):
            replies = status_replies(bytes(job[-2:]) + chunk)
            if replies:
                writer.write(replies)
                await writer.drain()
            if len(job) <= MAX_JOB:
                job += chunk
        if job:
            await self._hand(source, bytes(job))

    async def _forward(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, source: str
    ) -> None:
        reached = await self._reach()
        if reached is None:
            _reset(writer)  # the till sees its print fail, as with the printer alone
            return
        from_printer, printer = reached
        job = bytearray()
        back = asyncio.create_task(self._relay_back(from_printer, writer))
        ok = True
        try:
            while chunk := await self._next(reader, job, source):
                printer.write(chunk)
                await printer.drain()
                if len(job) <= MAX_JOB:  # beyond, forwarded but not kept (_hand says so)
                    job += chunk
            if printer.can_write_eof():
                printer.write_eof()
            await printer.drain()
        except (OSError, ConnectionError) as exc:
            ok = False
            log.error("the kitchen printer %s failed during a job: %s", self.printer, exc)
            self._printer_is(False)
            writer.transport.abort()
        finally:
            back.cancel()
            printer.close()
            with contextlib.suppress(OSError, ConnectionError):
                await printer.wait_closed()
        if ok and job:
            await self._hand(source, bytes(job))

    async def _next(self, reader: asyncio.StreamReader, job: bytearray, source: str) -> bytes:
        """The till's next bytes; b"" at its end, or once it sent nothing for
        :data:`IDLE_CLOSE` seconds (a till that went away without closing). A pause of
        ``idle_end`` ends the job so far (a till that keeps its connection open)."""
        quiet = 0.0
        while True:
            try:
                return await asyncio.wait_for(reader.read(_CHUNK), self._idle_end)
            except TimeoutError:
                if job:
                    await self._hand(source, bytes(job))
                    job.clear()
                quiet += self._idle_end
                if quiet >= self._idle_close:
                    log.info("the printer port: %s sent nothing for %.0f s", source, quiet)
                    return b""

    async def _relay_back(self, printer: asyncio.StreamReader, till: asyncio.StreamWriter) -> None:
        """The printer's answers (status bytes) back to the till."""
        with contextlib.suppress(OSError, ConnectionError):
            while chunk := await printer.read(_CHUNK):
                till.write(chunk)
                await till.drain()

    async def _hand(self, source: str, job: bytes) -> None:
        if len(job) > MAX_JOB:
            log.error("a print job of %d bytes from %s is too large to read", len(job), source)
            return
        try:
            await self._sink(source, job)
        except Exception:  # the desk failed (a full disk): the paper printed, say it loudly
            log.exception("a print job from %s could not be kept", source)

    async def _close_server(self) -> None:
        if self._server is not None:
            self._server.close()
            with contextlib.suppress(Exception):
                await asyncio.wait_for(self._server.wait_closed(), 1.0)
            self._server = None
        self._state = replace(self._state, listening=False)

    async def close(self) -> None:
        if self._probe is not None:
            self._probe.cancel()
            self._probe = None
        await self._close_server()
        for task in list(self._handlers):
            task.cancel()
        if self._handlers:
            await asyncio.gather(*self._handlers, return_exceptions=True)
