"""The web_video_server camera source (serveur.robots.mjpeg) over real sockets: against the
simulator's web_video_server lookalike (serveur.sim.video_server), alone and under a camera
relay, and against small hand-made servers for what a real one may send: parts without a
Content-Length, boundaries quoted or dashed, an oversize part, garbage, a 404, a server that
hangs up mid-part. No sleeps: everything waits on an event, bounded by WAIT."""

from __future__ import annotations

import asyncio
import contextlib
import io
import logging
import re
import socket
import ssl
from collections.abc import AsyncIterator, Sequence
from dataclasses import dataclass

import pytest
import trustme
from PIL import Image

from serveur.clock import ScaledClock
from serveur.core.camera import MAX_FRAME_BYTES, CameraRelay
from serveur.maps.navigation import demo_map_path
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import camera_retry
from serveur.robots.mjpeg import MAX_PART_BYTES, MjpegCamera, boundary_of
from serveur.sim.camera import CAMERA_SIZE
from serveur.sim.sensors import CAMERA_TOPIC
from serveur.sim.video_server import VideoServer

WAIT = 5.0


def jpeg(n: int, size: int = 300) -> bytes:
    """A JPEG-shaped frame numbered ``n``, with bytes inside that look like boundaries (not at
    a line start, or followed by more than the boundary) to trip a careless parser."""
    tricky = b"\r\n--frame-not\r\nxx--frame\r\n--frameworks\n"
    body = tricky + n.to_bytes(4, "big") * max(1, (size - len(tricky)) // 4)
    return b"\xff\xd8" + body + b"\xff\xd9"


class Frames:
    """A source's ``deliver``: what it got, and a wait for more."""

    def __init__(self) -> None:
        self.got: list[tuple[bytes, float]] = []
        self._more = asyncio.Event()

    def __call__(self, data: bytes, captured: float) -> None:
        self.got.append((data, captured))
        self._more.set()

    async def until(self, n: int) -> list[tuple[bytes, float]]:
        while len(self.got) < n:
            self._more.clear()
            await asyncio.wait_for(self._more.wait(), WAIT)
        return self.got

    @property
    def images(self) -> list[bytes]:
        return [data for data, _ in self.got]


@contextlib.asynccontextmanager
async def running(source: MjpegCamera) -> AsyncIterator[Frames]:
    """Run ``source`` as a relay would, cancelled at the end; it must not have died."""
    frames = Frames()
    task = asyncio.create_task(source.run(frames))
    try:
        yield frames
    finally:
        assert not task.done(), "the source died"
        task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await task


# -- the simulator's web_video_server ---------------------------------------------------------


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=ScaledClock(1.0), video_port=0
    )
    try:
        yield s
    finally:
        await s.close()


async def test_frames_from_the_simulators_web_video_server_with_their_stamps(
    sim: Simulation,
) -> None:
    url = sim.video_urls[0]
    assert url == f"http://127.0.0.1:{sim.video[0].port}/stream?topic={CAMERA_TOPIC}" + (
        "&type=ros_compressed"
    )
    source = MjpegCamera(url)
    async with running(source) as frames:
        got = await frames.until(4)
    stamps = [captured for _, captured in got]
    assert stamps == sorted(stamps) and len(set(stamps)) == len(stamps)
    assert all(abs(s - sim.clock.epoch()) < 2.0 for s in stamps)  # the robot's clock
    for data, _ in got:
        assert data.startswith(b"\xff\xd8") and data.endswith(b"\xff\xd9")
        with Image.open(io.BytesIO(data)) as img:
            assert img.format == "JPEG" and img.size == CAMERA_SIZE
    assert source.connects == 1 and source.malformed == source.oversize == 0


async def test_a_relay_on_web_video_server_feeds_its_viewers_and_hangs_up_after(
    sim: Simulation,
) -> None:
    source = MjpegCamera(sim.video_urls[0])
    relay = CameraRelay("r1", source, asyncio.get_running_loop().time)
    viewers = [relay.watch("tablet 1"), relay.watch("tablet 2")]
    for v in viewers:
        frames = [await asyncio.wait_for(v.next(), WAIT) for _ in range(3)]
        assert all(f is not None and f.jpeg.startswith(b"\xff\xd8") for f in frames)
    assert source.connects == 1 and sim.video[0].counts.streams == 1  # one upstream for both
    assert relay.counts.not_jpeg == relay.counts.too_large == 0
    for v in viewers:
        await relay.leave(v)
    server = sim.video[0]
    while server.streaming:  # the simulator sees the connection closed
        server.changed.clear()
        await asyncio.wait_for(server.changed.wait(), WAIT)


async def _request(port: int, target: str) -> tuple[bytes, bytes]:
    """(the reply's head, what follows it up to the first part's bytes) for a GET of
    ``target`` on a local server."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    try:
        writer.write(f"GET {target} HTTP/1.1\r\nHost: robot\r\n\r\n".encode())
        head = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), WAIT)
        rest = b""
        if head.startswith(b"HTTP/1.0 200"):
            rest = await asyncio.wait_for(reader.readuntil(b"\r\n\r\n"), WAIT)
        return head, rest
    finally:
        writer.close()


async def test_the_simulators_reply_is_web_video_servers(sim: Simulation) -> None:
    port = sim.video[0].port
    for kind in ("ros_compressed", "mjpeg"):
        head, rest = await _request(port, f"/stream?topic={CAMERA_TOPIC}&type={kind}")
        assert head.split(b"\r\n") == [
            b"HTTP/1.0 200 OK",
            b"Connection: close",
            b"Server: web_video_server",
            b"Cache-Control: no-cache, no-store, must-revalidate, pre-check=0, post-check=0, "
            b"max-age=0",
            b"Pragma: no-cache",
            b"Content-type: multipart/x-mixed-replace;boundary=boundarydonotcross",
            b"Access-Control-Allow-Origin: *",
            b"",
            b"",
        ]
        assert re.fullmatch(
            rb"--boundarydonotcross\r\nContent-type: image/jpeg\r\n"
            rb"X-Timestamp: \d+\.\d{6}\r\nContent-Length: \d+\r\n\r\n",
            rest,
        )
    for target in (
        "/stream?topic=/no/such/topic&type=ros_compressed",
        f"/stream?topic={CAMERA_TOPIC}&type=vp8",
        f"/snapshot?topic={CAMERA_TOPIC}",
    ):
        head, _ = await _request(port, target)
        assert head.startswith(b"HTTP/1.0 404 Not Found\r\n")
    assert sim.video[0].counts.not_found == 3


async def test_a_client_that_reads_slowly_loses_frames_it_does_not_queue_them() -> None:
    big = jpeg(1, 200_000)

    async def frame() -> tuple[bytes, float]:
        return big, 1.0

    async with VideoServer({"/cam": frame}, fps=50.0) as server:
        sock = socket.socket()
        sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)  # a tablet on bad Wi-Fi
        sock.setblocking(False)
        await asyncio.get_running_loop().sock_connect(sock, ("127.0.0.1", server.port))
        _, writer = await asyncio.open_connection(sock=sock)
        writer.write(b"GET /stream?topic=/cam HTTP/1.0\r\n\r\n")  # then never reads
        try:
            while server.counts.frames_dropped < 5:
                assert server.counts.frames_sent <= 3  # one in flight, not a growing backlog
                server.changed.clear()
                await asyncio.wait_for(server.changed.wait(), WAIT)
            assert server.counts.frames_sent <= 3
        finally:
            writer.close()


async def test_https() -> None:
    ca = trustme.CA()
    server_ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ca.issue_cert("127.0.0.1").configure_cert(server_ctx)
    client_ctx = ssl.create_default_context()
    ca.configure_trust(client_ctx)

    async def frame() -> tuple[bytes, float]:
        return jpeg(7), 12.25

    async with VideoServer({"/cam": frame}, ssl=server_ctx) as server:
        assert server.url("/cam").startswith("https://")
        source = MjpegCamera(server.url("/cam"), ssl=client_ctx)
        async with running(source) as frames:
            assert (await frames.until(1))[0] == (jpeg(7), 12.25)


# -- hand-made servers ------------------------------------------------------------------------


@dataclass
class Reply:
    """What a hand-made server sends one connection: ``data`` (in ``pieces`` bytes at a time,
    so that parts straddle reads), then it hangs up (``close``) or waits for the client to."""

    data: bytes
    close: bool = False
    pieces: int = 0


@contextlib.asynccontextmanager
async def served(replies: Sequence[Reply]) -> AsyncIterator[str]:
    """An HTTP server whose connection i gets ``replies[i]`` (the last one again after); its
    URL."""
    count = 0

    async def handle(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        nonlocal count
        reply = replies[min(count, len(replies) - 1)]
        count += 1
        try:
            await reader.readuntil(b"\r\n\r\n")
            step = reply.pieces or len(reply.data)
            for i in range(0, len(reply.data), step):
                writer.write(reply.data[i : i + step])
                await writer.drain()
            if not reply.close:
                while await reader.read(4096):
                    pass
        except (OSError, asyncio.IncompleteReadError):
            pass
        finally:
            writer.close()

    server = await asyncio.start_server(handle, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    try:
        yield f"http://127.0.0.1:{port}/stream?topic=/cam&type=ros_compressed"
    finally:
        server.close()


def head(boundary: str = "frame", delim: bytes = b"--frame") -> bytes:
    """A multipart reply's head and the boundary line before its first part."""
    ctype = f"multipart/x-mixed-replace;boundary={boundary}"
    return f"HTTP/1.0 200 OK\r\nContent-Type: {ctype}\r\n\r\n".encode() + delim + b"\r\n"


def part(
    body: bytes,
    stamp: str | None = None,
    *,
    length: bool = True,
    delim: bytes = b"--frame",
    extra: bytes = b"",
) -> bytes:
    """One part (headers, body, the boundary line after it), as web_video_server writes it."""
    headers = b"Content-type: image/jpeg\r\n" + extra
    if stamp is not None:
        headers += f"X-Timestamp: {stamp}\r\n".encode()
    if length:
        headers += f"Content-Length: {len(body)}\r\n".encode()
    return headers + b"\r\n" + body + b"\r\n" + delim + b"\r\n"


@pytest.mark.parametrize("length", [True, False], ids=["content-length", "no-length"])
@pytest.mark.parametrize(
    ("boundary", "delim"),
    [
        ("frame", b"--frame"),
        ('"frame"', b"--frame"),
        ("--frame", b"--frame"),  # the header's dashes used as the delimiter, as some do
        ('"--frame"', b"----frame"),  # the header's dashes, then the delimiter's own
    ],
    ids=["plain", "quoted", "dashed", "quoted-dashed"],
)
async def test_parts_with_or_without_length_and_any_boundary(
    length: bool, boundary: str, delim: bytes
) -> None:
    images = [jpeg(n, 300 + 1000 * n) for n in range(1, 5)]
    data = head(boundary, delim) + b"".join(
        part(img, f"{100 + n}.5", length=length, delim=delim) for n, img in enumerate(images)
    )
    async with served([Reply(data, pieces=97)]) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            got = await frames.until(len(images))
    assert got == [(img, 100.5 + n) for n, img in enumerate(images)]
    assert source.connects == 1 and source.malformed == source.oversize == 0


async def test_a_content_length_is_trusted_over_a_boundary_line_inside_the_picture() -> None:
    # A JPEG's bytes can be anything, a boundary line too: web_video_server sends a length.
    sneaky = jpeg(1)[:-2] + b"\r\n--frame\r\nContent-type: image/jpeg\r\n\r\n\xff\xd9"
    data = head() + part(sneaky, "1") + part(jpeg(2), "2")
    async with served([Reply(data)]) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            assert await frames.until(2) == [(sneaky, 1.0), (jpeg(2), 2.0)]
    assert source.malformed == 0


async def test_an_oversize_part_is_skipped_and_counted_and_the_next_one_arrives() -> None:
    assert MAX_FRAME_BYTES < MAX_PART_BYTES <= MAX_FRAME_BYTES + 64 * 1024  # the relay's limit
    small = [jpeg(n) for n in range(1, 4)]
    huge = jpeg(99, 3_000_000)
    data = head() + b"".join(
        [
            part(small[0], "1"),
            part(huge, "2"),  # over the limit, with a length: skipped as it streams past
            part(small[1], "3", length=False),
            part(huge, "4", length=False),  # over the limit, no length: dropped as it comes
            part(small[2], "5"),
        ]
    )
    async with served([Reply(data, pieces=4096)]) as url:
        source = MjpegCamera(url, max_bytes=10_000)
        async with running(source) as frames:
            got = await frames.until(3)
    assert got == [(small[0], 1.0), (small[1], 3.0), (small[2], 5.0)]
    assert source.oversize == 2 and source.malformed == 0 and source.connects == 1
    assert source.buffer_peak < 10_000 + 2 * 65_536  # never the 3 MB: the limit and a read


async def test_garbage_between_and_inside_parts_is_skipped() -> None:
    good = [jpeg(n) for n in range(1, 6)]
    data = head() + b"".join(
        [
            part(good[0], "nan"),  # no usable stamp: 0.0
            b"some text a broken proxy put in\r\n" + b"\x00\xff" * 1_000_000 + b"\r\n--frame\r\n",
            part(good[1], "2", extra=b"X-Other: yes\r\n"),
            b"this is no header line\r\n\r\n" + b"junk\r\n--frame\r\n",  # a part without headers
            part(good[2], "3", extra=b"Content-Length: twelve\r\n", length=False),  # bad length
            b"\r\n--frame\r\n",  # an empty part
            b"Content-type: image/jpeg\r\n--frame\r\n",  # headers cut short by a boundary
            part(good[3]),  # no stamp at all: 0.0
            part(good[4], "5"),
        ]
    )
    async with served([Reply(data)]) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            got = await frames.until(5)
    assert got == [(good[0], 0.0), (good[1], 2.0), (good[2], 3.0), (good[3], 0.0), (good[4], 5.0)]
    assert source.malformed == 4 and source.oversize == 0 and source.connects == 1
    assert source.buffer_peak < 100_000  # not the 2 MB line of junk


async def test_a_404_a_page_and_an_empty_stream_are_failures_retried_until_frames_come(
    monkeypatch: pytest.MonkeyPatch, caplog: pytest.LogCaptureFixture
) -> None:
    monkeypatch.setattr(camera_retry, "RETRY_FIRST", 0.1)  # 0.1, 0.2, 0.4 s, not 0.5, 1, 2
    caplog.set_level(logging.INFO, logger=camera_retry.__name__)
    page = b"<html><body><h1>404 Not Found</h1></body></html>"
    not_found = b"HTTP/1.0 404 Not Found\r\nContent-Type: text/html\r\n\r\n" + page
    html = b"HTTP/1.0 200 OK\r\nContent-Type: text/html\r\n\r\n<html>a viewer page</html>"
    replies = [
        Reply(not_found, close=True),  # web_video_server: no such topic
        Reply(html, close=True),  # not a stream
        Reply(head(), close=True),  # a stream, ended before its first frame
        Reply(head() + part(jpeg(1))),
    ]
    async with served(replies) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            assert await frames.until(1) == [(jpeg(1), 0.0)]
    assert source.connects == 4
    said = [r.getMessage() for r in caplog.records]
    assert len(said) == 3 and "HTTP 404 Not Found" in said[0] and "text/html" in said[1]
    assert "before its first frame" in said[2]
    # Each failure doubles the pause: the three are failures, not streams that ended.
    assert [m.rsplit(" again in ", 1)[1] for m in said] == ["0.1 s", "0.2 s", "0.4 s"]


async def test_a_server_that_hangs_up_mid_part_is_reconnected() -> None:
    first, second = jpeg(1, 2000), jpeg(2, 2000)
    cut = b"Content-type: image/jpeg\r\nContent-Length: 2000\r\n\r\n" + second[:700]
    replies = [
        Reply(head() + part(first, "1") + cut, close=True),  # web_video_server killed
        Reply(head() + part(second, "2")),  # and started again
    ]
    async with served(replies) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            got = await frames.until(2)
    assert got == [(first, 1.0), (second, 2.0)]  # never the half picture
    assert source.connects == 2 and source.malformed == 0


async def test_the_closing_boundary_ends_the_stream_and_it_is_opened_again() -> None:
    data = head() + part(jpeg(1), "1").removesuffix(b"\r\n") + b"--\r\n"  # "--frame--"
    async with served([Reply(data, close=True)]) as url:
        source = MjpegCamera(url)
        async with running(source) as frames:
            assert await frames.until(2) == [(jpeg(1), 1.0), (jpeg(1), 1.0)]
    assert source.connects == 2


def test_boundaries_and_addresses() -> None:
    assert boundary_of("multipart/x-mixed-replace;boundary=boundarydonotcross") == (
        b"boundarydonotcross"
    )
    assert boundary_of('Multipart/X-Mixed-Replace; charset=x; Boundary="--my frame"') == (
        b"my frame"
    )
    for no in ("image/jpeg", "multipart/x-mixed-replace", "multipart/mixed; boundary=--", ""):
        assert boundary_of(no) is None
    for bad in ("ws://robot:9090", "rtsp://robot/cam", "http:///stream"):
        with pytest.raises(ValueError):
            MjpegCamera(bad)
