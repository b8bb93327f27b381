"""A robot's camera from ROS's web_video_server: its MJPEG stream over HTTP.

Many robots already run web_video_server (RobotWebTools) for their camera, and then the
camera's address is a URL such as
``http://robot:8080/stream?topic=/camera/image/compressed&type=ros_compressed``. With
``type=ros_compressed`` it forwards the robot's own ``CompressedImage`` JPEG bytes without
encoding them again (../shared/notes/video.md), so what reaches the tablets is exactly what
the camera made, as with :class:`~serveur.robots.camera.RosbridgeCamera`; and it is plain HTTP,
so the camera needs no rosbridge at all.

What web_video_server sends (multipart_stream.cpp): ``HTTP/1.0 200 OK`` with
``Content-type: multipart/x-mixed-replace;boundary=boundarydonotcross``, then
``--boundarydonotcross`` and, per frame, headers (``Content-type: image/jpeg``,
``X-Timestamp`` — the image's header stamp in seconds — and ``Content-Length``), a blank line,
the JPEG bytes and ``\\r\\n--boundarydonotcross\\r\\n``. It drops frames for a client that reads
slowly (a queue of one), so reading late costs frames, never a growing delay.

The reply is read by hand on an asyncio stream rather than by an HTTP library, because what
matters here is what such libraries do not promise: memory bounded by one frame whatever the
server sends (a part larger than ``max_bytes`` is skipped as it streams past, unbuffered, and
counted in :attr:`MjpegCamera.oversize`), and a stream that goes on after a bad part. Other
MJPEG servers are read too: the boundary quoted or not, with or without the ``--`` some servers
wrongly put in the header, parts without ``Content-Length`` (read up to the next boundary line),
garbage between parts (skipped and counted in :attr:`MjpegCamera.malformed`). A reply that is
not a multipart stream (a 404 for an unknown topic, an HTML page) is a failure, retried like a
refused connection: after a pause doubling from 0.5 s to 5 s
(:mod:`serveur.robots.camera_retry`, the loop every camera source shares).

Checking that a frame is a JPEG of an acceptable size is the relay's job
(:mod:`serveur.core.camera`); this only cuts the stream into frames.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import re
import ssl as ssl_module
from collections.abc import Callable, Mapping
from typing import Final, Literal
from urllib.parse import quote, urlsplit

from serveur.errors import LinkError
from serveur.robots.camera_retry import keep_streaming

__all__ = ["MAX_PART_BYTES", "MjpegCamera", "MjpegError", "boundary_of"]

log = logging.getLogger(__name__)

#: The largest part read (bytes): the relay's ``MAX_FRAME_BYTES`` (512 KiB; this package may not
#: import the core, tests/robots/test_mjpeg.py checks the two agree) and a little more, so a frame
#: just over the relay's limit still reaches it and is counted there as too large, where the
#: owner sees it. Anything larger is skipped here as it streams past, never held whole.
MAX_PART_BYTES: Final = 512 * 1024 + 16 * 1024

#: How much is read from the socket at a time.
_CHUNK: Final = 64 * 1024
#: The longest status, header or boundary line; longer lines are garbage (skipped).
_LINE_LIMIT: Final = 8 * 1024
#: The most header lines in a reply or a part.
_MAX_HEADERS: Final = 64
#: The most digits in a Content-Length (a terabyte): more is a lie, read as no length at all.
_MAX_LENGTH_DIGITS: Final = 12
_TOKEN: Final = re.compile(rb"^[!#$%&'*+.^_`|~0-9A-Za-z-]+$")  # an HTTP header name

_Delimiter = Literal["part", "end"]


class MjpegError(LinkError):
    """The reply is not an MJPEG stream (a non-200 status, no multipart boundary...), or it
    ended before a frame: the camera is tried again later."""


class _Closed(MjpegError):
    """The server closed the connection."""


def boundary_of(content_type: str) -> bytes | None:
    """The boundary of a ``multipart/*`` Content-Type, without the dashes some servers put in
    front of it; None when it is not multipart or names no boundary."""
    kind, _, params = content_type.partition(";")
    if not kind.strip().lower().startswith("multipart/"):
        return None
    for param in params.split(";"):
        key, eq, value = param.partition("=")
        if not eq or key.strip().lower() != "boundary":
            continue
        value = value.strip()
        if len(value) >= 2 and value[0] == value[-1] == '"':
            value = value[1:-1]
        # "boundary=--foo": some servers (IP cameras, old mjpg-streamer forks) write the
        # delimiter's dashes in the header too; lines are matched whatever the dashes.
        value = value.lstrip("-")
        return value.encode("latin-1", "replace") if value else None
    return None


def _delimiter(line: bytes | None, token: bytes) -> _Delimiter | None:
    """What ``line`` is: a boundary line starting the next part, the closing one (``--``
    after the boundary: the stream is over), or None for anything else."""
    if line is None or not line.startswith(b"--"):
        return None
    rest = line.rstrip().lstrip(b"-")
    if rest == token:
        return "part"
    if rest == token + b"--":
        return "end"
    return None


def _stamp(headers: Mapping[str, str]) -> float:
    """The capture time a part says (web_video_server: ``X-Timestamp``, the image's header
    stamp in seconds), 0.0 when it gives none that makes sense."""
    try:
        stamp = float(headers.get("x-timestamp", ""))
    except ValueError:
        return 0.0
    return stamp if math.isfinite(stamp) and stamp >= 0.0 else 0.0


def _content_length(headers: Mapping[str, str]) -> int | None:
    """A part's Content-Length, or None when it has none that can be trusted (the part is then
    read up to the next boundary line)."""
    value = headers.get("content-length", "")
    if not value.isascii() or not value.isdigit() or len(value) > _MAX_LENGTH_DIGITS:
        return None
    return int(value)


class _Input:
    """The reply's bytes, read in chunks into a buffer never much larger than one part."""

    def __init__(self, reader: asyncio.StreamReader) -> None:
        self._reader = reader
        self._buf = bytearray()
        #: The most bytes it held at once.
        self.peak = 0

    async def _fill(self) -> None:
        chunk = await self._reader.read(_CHUNK)
        if not chunk:
            raise _Closed("the server closed the stream")
        self._buf += chunk
        self.peak = max(self.peak, len(self._buf))

    async def line(self) -> bytes | None:
        """The next line without its end (LF or CRLF); None for a line longer than
        ``_LINE_LIMIT``, which is skipped whole without being kept."""
        start = 0
        too_long = False
        while True:
            end = self._buf.find(b"\n", start)
            if end >= 0:
                too_long = too_long or end > _LINE_LIMIT
                line = None if too_long else bytes(self._buf[:end]).rstrip(b"\r")
                del self._buf[: end + 1]
                return line
            if len(self._buf) > _LINE_LIMIT:
                too_long = True
                self._buf.clear()
            start = len(self._buf)
            await self._fill()

    def unread(self, line: bytes) -> None:
        """Put a line back: the next :meth:`line` answers it again."""
        self._buf[0:0] = line + b"\n"

    async def exactly(self, n: int) -> bytes:
        while len(self._buf) < n:
            await self._fill()
        data = bytes(self._buf[:n])
        del self._buf[:n]
        return data

    async def skip(self, n: int) -> None:
        """Drop the next ``n`` bytes as they come, holding at most one chunk of them."""
        while n > 0:
            if not self._buf:
                await self._fill()
            k = min(n, len(self._buf))
            del self._buf[:k]
            n -= k

    async def until_delimiter(self, token: bytes, limit: int) -> bytes | None:
        """The bytes up to the next boundary line (left unread), without the line end before
        it; None when they were more than ``limit`` (dropped as they came)."""
        needle = b"--" + token
        # Kept when dropping an oversize part: enough for a delimiter line cut by a read.
        keep = len(needle) + 64
        start = 0
        dropped = False
        while True:
            i = self._buf.find(needle, start)
            if i < 0:
                if len(self._buf) > limit + keep:
                    del self._buf[: len(self._buf) - keep]
                    dropped = True
                start = max(0, len(self._buf) - keep)
                await self._fill()
                continue
            line_start = self._buf.rfind(b"\n", 0, i) + 1
            line_end = self._buf.find(b"\n", i)
            if line_end < 0 and len(self._buf) - line_start <= _LINE_LIMIT:
                start = i  # the line is not all here yet: look again once it is
                await self._fill()
                continue
            line = bytes(self._buf[line_start:line_end]) if line_end >= 0 else None
            if _delimiter(line, token) is None:
                start = i + 1  # the bytes happened to be in the picture
                continue
            body = bytes(self._buf[:line_start])
            del self._buf[:line_start]
            # The line end before a boundary line belongs to the boundary (RFC 2046).
            if body.endswith(b"\n"):
                body = body[:-2] if body.endswith(b"\r\n") else body[:-1]
            return None if dropped or len(body) > limit else body


async def _headers(inp: _Input) -> dict[str, str] | None:
    """Header lines up to a blank one (names in lower case; the last of a repeated one wins);
    None at a line that is not a header, which is put back for the caller to look at."""
    headers: dict[str, str] = {}
    for _ in range(_MAX_HEADERS):
        line = await inp.line()
        if line == b"":
            return headers
        if line is None:
            return None
        name, colon, value = line.partition(b":")
        if not colon or not _TOKEN.match(name):
            inp.unread(line)
            return None
        headers[name.decode("ascii").lower()] = value.strip().decode("latin-1")
    return None


async def _reply(inp: _Input) -> bytes:
    """Read the reply's status and headers; its boundary, or MjpegError for any reply that is
    not a multipart stream."""
    status = await inp.line()
    fields = (status or b"").split(None, 2)
    if len(fields) < 2 or not fields[0].startswith(b"HTTP/"):
        raise MjpegError(f"not an HTTP reply: {(status or b'')[:60]!r}")
    if fields[1] != b"200":
        raise MjpegError(f"HTTP {b' '.join(fields[1:]).decode('latin-1')[:80]}")
    headers = await _headers(inp)
    if headers is None:
        raise MjpegError("malformed HTTP headers")
    if "chunked" in headers.get("transfer-encoding", "").lower():
        # Asked with HTTP/1.0, a server may not chunk its reply; one that does is not read.
        raise MjpegError("a chunked reply to an HTTP/1.0 request")
    content_type = headers.get("content-type", "")
    token = boundary_of(content_type)
    if token is None:
        raise MjpegError(f"not a multipart stream (Content-Type {content_type[:80]!r})")
    return token


class MjpegCamera:
    """:class:`~serveur.core.camera.CameraSource` for an MJPEG stream over HTTP (web_video_server's
    ``/stream?topic=...&type=ros_compressed``, or any ``multipart/x-mixed-replace`` of JPEGs).

    ``ssl`` is the context for an ``https://`` URL (None: the system's default checks);
    ``open_timeout`` bounds connecting and the reply's headers; parts larger than ``max_bytes``
    are skipped unread.
    """

    def __init__(
        self,
        url: str,
        *,
        ssl: ssl_module.SSLContext | None = None,
        open_timeout: float = 5.0,
        max_bytes: int = MAX_PART_BYTES,
    ) -> None:
        parts = urlsplit(url)
        scheme = parts.scheme.lower()
        if scheme not in ("http", "https") or not parts.hostname:
            raise ValueError(f"an MJPEG camera's address is an http(s) URL, not {url!r}")
        self.url = url
        self._host = parts.hostname
        self._port = parts.port or (443 if scheme == "https" else 80)
        self._ssl: ssl_module.SSLContext | bool | None = None
        if scheme == "https":
            self._ssl = ssl if ssl is not None else True
        target = quote(parts.path or "/", safe="/%:@!$&'()*+,;=~") + (
            "?" + quote(parts.query, safe="/%:@!$&'()*+,;=~?") if parts.query else ""
        )
        host = parts.netloc.rpartition("@")[2]  # never the user and password, if any
        # HTTP/1.0: a server may then neither chunk the reply nor keep the connection open.
        self._request = (
            f"GET {target} HTTP/1.0\r\nHost: {host}\r\nUser-Agent: serveur\r\n"
            "Accept: multipart/x-mixed-replace, image/jpeg\r\nConnection: close\r\n\r\n"
        ).encode("latin-1")
        self._open_timeout = open_timeout
        self._max_bytes = max_bytes
        #: Connections opened (tests: one per watch, whatever the viewers).
        self.connects = 0
        #: Frames handed to the relay.
        self.frames = 0
        #: Parts larger than ``max_bytes``, skipped.
        self.oversize = 0
        #: Stretches of garbage between parts and parts without headers, skipped.
        self.malformed = 0
        #: The most bytes of the stream held at once (about ``max_bytes`` plus one read at
        #: most, whatever the server sends).
        self.buffer_peak = 0

    async def run(self, deliver: Callable[[bytes, float], None]) -> None:
        await keep_streaming(
            lambda: self._session(deliver), (OSError, TimeoutError, MjpegError), self.url
        )

    async def _session(self, deliver: Callable[[bytes, float], None]) -> None:
        async with asyncio.timeout(self._open_timeout):
            reader, writer = await asyncio.open_connection(self._host, self._port, ssl=self._ssl)
        self.connects += 1
        frames = self.frames
        inp = _Input(reader)
        try:
            async with asyncio.timeout(self._open_timeout):
                writer.write(self._request)
                await writer.drain()
                token = await _reply(inp)
            await self._parts(inp, token, deliver)
        except _Closed:
            if self.frames == frames:  # a server that answers and hangs up: not a stream
                raise MjpegError("the server closed the stream before its first frame") from None
            # It streamed, then stopped (web_video_server restarted...): again, soon.
        finally:
            self.buffer_peak = max(self.buffer_peak, inp.peak)
            writer.close()
            # asyncio.timeout, not wait_for: Python 3.11's wait_for swallows a cancel that comes
            # as the connection finishes closing, and the relay's cancel must end the source.
            with contextlib.suppress(OSError, TimeoutError):
                async with asyncio.timeout(1.0):
                    await writer.wait_closed()

    async def _parts(
        self, inp: _Input, token: bytes, deliver: Callable[[bytes, float], None]
    ) -> None:
        """Cut the body into parts and deliver each picture, until the server ends it."""
        bad = False  # something since the last good part was skipped
        while True:
            line = await inp.line()
            kind = _delimiter(line, token)
            if kind is None:
                # Blank lines are the line end after a part's bytes; anything else is garbage.
                bad = bad or line != b""
                continue
            if bad:
                bad = False
                self._skipped("malformed")
            if kind == "end":
                return
            headers = await _headers(inp)
            if headers is None:
                bad = True
                continue
            length = _content_length(headers)
            body: bytes | None
            if length is None:
                body = await inp.until_delimiter(token, self._max_bytes)
            elif length > self._max_bytes:
                await inp.skip(length)
                body = None
            else:
                body = await inp.exactly(length)
            if body is None:
                self._skipped("oversize")
            elif not body:
                bad = True
            else:
                self.frames += 1
                deliver(body, _stamp(headers))

    def _skipped(self, what: Literal["malformed", "oversize"]) -> None:
        if what == "oversize":
            self.oversize += 1
            if self.oversize == 1:  # once, not per frame
                log.warning("camera %s: a part over %d bytes skipped", self.url, self._max_bytes)
        else:
            self.malformed += 1
            if self.malformed == 1:
                log.warning("camera %s: malformed MJPEG parts skipped", self.url)
