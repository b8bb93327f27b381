"""A simulated robot's web_video_server: its camera as an MJPEG stream over HTTP.

Robots often serve their camera with ROS's web_video_server (RobotWebTools) rather than through
rosbridge; the server reads it with :class:`~serveur.robots.mjpeg.MjpegCamera`. This is that
node as the server meets it on the wire, so the source is tested against something that
behaves like the real one rather than against the tests' own idea of MJPEG. From
web_video_server's sources (web_video_server.cpp, multipart_stream.cpp, ros_compressed_streamer.cpp,
and async_web_server_cpp for the HTTP replies):

* ``GET /stream?topic=T&type=ros_compressed`` (``type`` defaults to ``mjpeg``, which the real
  one re-encodes from the raw image; here both send the rendered JPEG as it is) answers
  ``HTTP/1.0 200 OK``, ``Connection: close``, ``Server: web_video_server``, the no-cache headers,
  ``Content-type: multipart/x-mixed-replace;boundary=boundarydonotcross``,
  ``Access-Control-Allow-Origin: *``; the body starts with ``--boundarydonotcross`` and each
  frame is a part: ``Content-type: image/jpeg``, ``X-Timestamp`` (the image's stamp, seconds with
  six decimals), ``Content-Length``, a blank line, the JPEG, ``\\r\\n--boundarydonotcross\\r\\n``.
* A path other than ``/stream``, a topic it does not serve or another ``type`` (png, vp8,
  h264: not simulated) gets async_web_server_cpp's stock 404 page.
* One subscription per HTTP request: each connection gets its own frames, rendered for it
  (:func:`rendered_camera`: 10-20 ms of CPU a frame, in a worker thread, one at a time per
  connection), at the camera's rate.
* A client that reads slowly loses frames, it never queues them: web_video_server's multipart
  writer keeps one frame in flight (``max_queue_size`` 1) and drops a new one while the last is
  still being sent. Here a frame is dropped (not even rendered) while the previous one has not
  left for the kernel, whose send buffer is kept small as the rosbridge endpoint's is.

Plain HTTP by default, as web_video_server is; with ``ssl`` (the simulator's ``--certfile``) it
speaks HTTPS, as a robot behind a TLS proxy does.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import socket
import ssl as ssl_module
from collections.abc import Awaitable, Callable, Mapping
from dataclasses import dataclass
from typing import Final
from urllib.parse import parse_qs, urlsplit

from serveur.maps.navigation import OccupancyMap
from serveur.sim.camera import CameraView

__all__ = [
    "BOUNDARY",
    "STREAM_TYPES",
    "FrameSource",
    "VideoCounts",
    "VideoServer",
    "rendered_camera",
]

log = logging.getLogger("serveur.robot_sim")

#: web_video_server's multipart boundary.
BOUNDARY: Final = "boundarydonotcross"
#: The stream types served (``mjpeg`` is web_video_server's default ``type``).
STREAM_TYPES: Final = ("ros_compressed", "mjpeg")
#: A camera's next frame, (JPEG bytes, capture stamp in Unix seconds), or None when it has none
#: now (a stalled camera): called once per frame, never twice at a time for one connection.
FrameSource = Callable[[], Awaitable[tuple[bytes, float] | None]]

#: SO_SNDBUF of stream sockets (the kernel doubles it): a client that stops reading backs up into
#: a frame dropped within a few frames, not into megabytes of old pictures in the kernel.
_SEND_BUFFER: Final = 64 * 1024
#: Wall seconds a client has to send its request.
_REQUEST_TIMEOUT: Final = 5.0
_REQUEST_LIMIT: Final = 16 * 1024
_REPLY_OK: Final = (
    "HTTP/1.0 200 OK\r\n"
    "Connection: close\r\n"
    "Server: web_video_server\r\n"
    "Cache-Control: no-cache, no-store, must-revalidate, pre-check=0, post-check=0, max-age=0\r\n"
    "Pragma: no-cache\r\n"
    f"Content-type: multipart/x-mixed-replace;boundary={BOUNDARY}\r\n"
    "Access-Control-Allow-Origin: *\r\n"
    "\r\n"
    f"--{BOUNDARY}\r\n"
).encode("ascii")
_NOT_FOUND_PAGE: Final = (
    b"<html><head><title>Not Found</title></head><body><h1>404 Not Found</h1></body></html>"
)
_REPLY_NOT_FOUND: Final = (
    b"HTTP/1.0 404 Not Found\r\n"
    + f"Content-Length: {len(_NOT_FOUND_PAGE)}\r\n".encode("ascii")
    + b"Content-Type: text/html\r\n\r\n"
    + _NOT_FOUND_PAGE
)
_FOOTER: Final = f"\r\n--{BOUNDARY}\r\n".encode("ascii")


def _part(jpeg: bytes, stamp: float) -> bytes:
    head = f"Content-type: image/jpeg\r\nX-Timestamp: {stamp:.6f}\r\nContent-Length: {len(jpeg)}"
    return head.encode("ascii") + b"\r\n\r\n" + jpeg + _FOOTER


def rendered_camera(
    grid: OccupancyMap,
    pose: Callable[[], tuple[float, float, float]],
    stamp: Callable[[], float],
    on: Callable[[], bool] = lambda: True,
) -> FrameSource:
    """A simulated robot's camera as a :data:`FrameSource`: the view of ``grid`` from
    ``pose()`` (the robot's true pose), stamped ``stamp()`` (its ROS time), both read on the
    event loop when the frame is asked for; the rendering and JPEG encoding (10-20 ms of CPU)
    run in a worker thread so the robots' physics never waits on a picture. None while
    ``on()`` is false (the camera stalled). The view is made at the first frame: a camera
    nobody watches costs nothing."""
    views: list[CameraView] = []

    async def frame() -> tuple[bytes, float] | None:
        if not on():
            return None
        if not views:
            views.append(CameraView(grid))
        x, y, yaw = pose()
        taken = stamp()
        loop = asyncio.get_running_loop()
        jpeg = await loop.run_in_executor(None, views[0].jpeg, x, y, yaw)
        return jpeg, taken

    return frame


@dataclass
class VideoCounts:
    """What one server did since it was made (read by tests)."""

    #: Streams opened (one per accepted ``/stream`` request).
    streams: int = 0
    #: Requests answered 404.
    not_found: int = 0
    frames_sent: int = 0
    #: Frames dropped because the client had not taken the previous one yet.
    frames_dropped: int = 0


class VideoServer:
    """One robot's web_video_server: an HTTP server streaming each of ``topics``' frames at
    ``fps`` to every client that asks. Can be stopped and started again on its port."""

    def __init__(
        self,
        topics: Mapping[str, FrameSource],
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        fps: float = 10.0,
        ssl: ssl_module.SSLContext | None = None,
    ) -> None:
        if not fps > 0:
            raise ValueError("fps must be positive")
        self.topics = dict(topics)
        self.host = host
        self.port = port
        self.period = 1.0 / fps
        self.ssl = ssl
        self.counts = VideoCounts()
        #: Set whenever a count changes or a connection ends (tests wait on it, then clear it).
        self.changed = asyncio.Event()
        self._server: asyncio.Server | None = None
        self._handlers: set[asyncio.Task[None]] = set()

    def url(self, topic: str, kind: str = "ros_compressed") -> str:
        """The stream's URL, as a robot's owner would register it."""
        host = f"[{self.host}]" if ":" in self.host else self.host
        scheme = "https" if self.ssl is not None else "http"
        return f"{scheme}://{host}:{self.port}/stream?topic={topic}&type={kind}"

    @property
    def streaming(self) -> int:
        """Connections open now (streams and requests being read)."""
        return len(self._handlers)

    async def start(self) -> None:
        if self._server is not None:
            return
        self._server = await asyncio.start_server(
            self._handle, self.host, self.port, ssl=self.ssl, reuse_address=True
        )
        if self.port == 0:
            self.port = int(self._server.sockets[0].getsockname()[1])

    async def stop(self) -> None:
        """Stop listening and drop every connection (a web_video_server killed)."""
        server, self._server = self._server, None
        if server is None:
            return
        server.close()
        handlers = list(self._handlers)
        for task in handlers:
            task.cancel()
        await asyncio.gather(*handlers, return_exceptions=True)
        await server.wait_closed()

    async def __aenter__(self) -> VideoServer:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.stop()

    def _count(self, what: str) -> None:
        setattr(self.counts, what, getattr(self.counts, what) + 1)
        self.changed.set()

    async def _handle(self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        task = asyncio.current_task()
        assert task is not None
        self._handlers.add(task)
        try:
            source = await self._route(reader)
            if source is None:
                writer.write(_REPLY_NOT_FOUND)
                self._count("not_found")
                with contextlib.suppress(OSError):
                    await writer.drain()
            else:
                await self._stream(reader, writer, source)
        except (OSError, TimeoutError, asyncio.IncompleteReadError, asyncio.LimitOverrunError):
            pass  # the client went, or never said what it wanted
        except Exception:  # the camera failed (a bug): this stream ends, the server goes on
            log.exception("video server %s:%s: stream failed", self.host, self.port)
        finally:
            self._handlers.discard(task)
            self.changed.set()
            writer.close()

    async def _route(self, reader: asyncio.StreamReader) -> FrameSource | None:
        """The frames the request asks for; None for anything web_video_server answers 404."""
        async with asyncio.timeout(_REQUEST_TIMEOUT):
            head = await reader.readuntil(b"\r\n\r\n")
        if len(head) > _REQUEST_LIMIT:
            return None
        fields = head.split(b"\r\n", 1)[0].decode("latin-1").split()
        if len(fields) != 3 or fields[0] != "GET":
            return None
        target = urlsplit(fields[1])
        query = parse_qs(target.query)
        topic = query.get("topic", [""])[0]
        kind = query.get("type", ["mjpeg"])[0]
        if target.path != "/stream" or kind not in STREAM_TYPES:
            return None
        return self.topics.get(topic)

    async def _stream(
        self, reader: asyncio.StreamReader, writer: asyncio.StreamWriter, source: FrameSource
    ) -> None:
        """Send ``source``'s frames at the set rate until the client goes."""
        sock = writer.get_extra_info("socket")
        if sock is not None:
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, _SEND_BUFFER)
        transport = writer.transport
        writer.write(_REPLY_OK)
        self._count("streams")
        gone = asyncio.ensure_future(_until_eof(reader))
        loop = asyncio.get_running_loop()
        due = loop.time()
        try:
            while not gone.done() and not transport.is_closing():
                if transport.get_write_buffer_size() > 0:
                    self._count("frames_dropped")  # the last frame is still on its way
                else:
                    got = await source()
                    if got is not None and not transport.is_closing():
                        writer.write(_part(*got))
                        self._count("frames_sent")
                due += self.period
                now = loop.time()
                if due < now:  # rendering fell behind: the next frame now, no burst
                    due = now
                await asyncio.wait({gone}, timeout=due - now)
        finally:
            gone.cancel()


async def _until_eof(reader: asyncio.StreamReader) -> None:
    """Read what the client sends (nothing, after its request) until it closes."""
    with contextlib.suppress(OSError):
        while await reader.read(4096):
            pass
