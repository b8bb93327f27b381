"""The camera relay's rules (serveur.core.camera), without sockets, on virtual time: one
upstream per robot whatever the viewers, the same bytes to all, latest frame wins per viewer,
bad frames dropped and counted."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

import pytest

from serveur.core.camera import CameraRelay, CameraViewer, jpeg_problem


def jpeg(n: int, size: int = 100) -> bytes:
    """A JPEG-shaped frame (SOI ... EOI) numbered ``n``."""
    body = n.to_bytes(4, "big") * max(1, (size - 4) // 4)
    return b"\xff\xd8" + body + b"\xff\xd9"


class Source:
    """A camera the test feeds: counts how often it was opened and closed."""

    def __init__(self) -> None:
        self.deliver: Callable[[bytes, float], None] | None = None
        self.opened = 0
        self.closed = 0
        self.fail = False
        self.changed = asyncio.Event()  # opened or closed

    async def run(self, deliver: Callable[[bytes, float], None]) -> None:
        self.opened += 1
        self.deliver = deliver
        self.changed.set()
        try:
            if self.fail:
                raise OSError("camera unplugged")
            await asyncio.Event().wait()
        finally:
            self.closed += 1
            self.deliver = None
            self.changed.set()

    async def until(self, cond: Callable[[], bool]) -> None:
        while not cond():
            self.changed.clear()
            await asyncio.wait_for(self.changed.wait(), 1.0)

    def send(self, data: bytes, captured: float = 0.0) -> None:
        assert self.deliver is not None, "nobody opened the camera"
        self.deliver(data, captured)


async def opened(source: Source) -> None:
    await source.until(lambda: source.deliver is not None)


def relay(source: Source, max_bytes: int = 10_000) -> CameraRelay:
    return CameraRelay("r1", source, asyncio.get_running_loop().time, max_bytes=max_bytes)


def test_what_is_a_jpeg() -> None:
    assert jpeg_problem(jpeg(1)) is None
    assert jpeg_problem(jpeg(1) + b"\x00\x00") is None  # padding after EOI
    assert jpeg_problem(b"\x89PNG\r\n\x1a\n" + b"\x00" * 50) == "not a JPEG"
    assert jpeg_problem(b"\xff\xd8" + b"\x00" * 50) == "not a JPEG"  # cut short: no EOI
    assert jpeg_problem(b"") == "not a JPEG"
    assert jpeg_problem(jpeg(1, 2000), max_bytes=1000) == "too large"


async def test_five_viewers_one_upstream_same_bytes_and_closed_after_the_last() -> None:
    source = Source()
    cam = relay(source)
    viewers = [cam.watch(f"tablet {i}") for i in range(5)]
    await opened(source)
    assert source.opened == 1 and cam.streaming and cam.viewers == 5
    got: dict[str, list[bytes]] = {v.name: [] for v in viewers}

    async def fast(v: CameraViewer) -> None:
        while True:
            got[v.name].append((await v.next()).jpeg)

    readers = [asyncio.create_task(fast(v)) for v in viewers]
    frames = [jpeg(n) for n in range(1, 11)]
    for f in frames:  # 10 fps
        source.send(f)
        await asyncio.sleep(0.1)
    assert all(g == frames for g in got.values())  # every frame, the very same bytes
    assert all(g[0] is frames[0] for g in got.values())  # not even copied
    assert all(v.skipped == 0 for v in viewers)
    for r in readers:
        r.cancel()
    for v in viewers[:4]:
        await cam.leave(v)
    assert source.closed == 0 and cam.streaming  # one viewer left: still open
    await cam.leave(viewers[4])
    assert source.closed == 1 and not cam.streaming
    # Watching again opens it again (once).
    again = [cam.watch("a"), cam.watch("b")]
    await opened(source)
    assert source.opened == 2 and cam.counts.upstreams_opened == 2
    for v in again:
        await cam.leave(v)
    assert source.closed == 2


async def test_a_stalled_viewer_gets_only_the_newest_frame() -> None:
    source = Source()
    cam = relay(source)
    fast, stalled = cam.watch("fast"), cam.watch("stalled")
    await opened(source)
    fast_got: list[int] = []

    async def read() -> None:
        while True:
            fast_got.append((await fast.next()).seq)

    reader = asyncio.create_task(read())
    for n in range(1, 51):  # a robot flooding 50 frames, 100 a second
        source.send(jpeg(n), captured=1000.0 + n)
        await asyncio.sleep(0.01)
    assert fast_got == list(range(1, 51))
    frame = await stalled.next()  # the stalled tablet wakes up: the newest, not the first
    assert frame.seq == 50 and frame.captured == 1050.0 and frame.jpeg == jpeg(50)
    assert stalled.skipped == 49 and stalled.taken == 1
    # Nothing is queued behind it: the next frame is the next one sent.
    source.send(jpeg(51))
    assert (await stalled.next()).seq == 51
    reader.cancel()
    await cam.close()


async def test_bad_frames_are_dropped_counted_and_never_forwarded() -> None:
    source = Source()
    cam = relay(source, max_bytes=1000)
    v = cam.watch("tablet")
    await opened(source)
    source.send(b"\x89PNG\r\n\x1a\n" + b"\x00" * 100)  # a PNG
    source.send(b"raw bytes from a misconfigured camera")
    source.send(jpeg(1, 5000))  # too large
    source.send(jpeg(2))
    frame = await asyncio.wait_for(v.next(), 1.0)
    assert frame.jpeg == jpeg(2) and frame.seq == 1 and v.skipped == 0
    assert cam.counts.frames_in == 4
    assert (cam.counts.not_jpeg, cam.counts.too_large) == (2, 1)
    await cam.close()


async def test_a_new_viewer_sees_the_current_picture_at_once() -> None:
    source = Source()
    cam = relay(source)
    first = cam.watch("first")
    await opened(source)
    source.send(jpeg(7), captured=5.0)
    late = cam.watch("late")
    frame = await asyncio.wait_for(late.next(), 0.01)
    assert frame.jpeg == jpeg(7) and source.opened == 1
    await cam.leave(first)
    await cam.leave(late)
    # The next watch starts from nothing: a picture from before is not "now".
    again = cam.watch("again")
    with pytest.raises(TimeoutError):
        await asyncio.wait_for(again.next(), 0.5)
    await cam.close()


async def test_a_failing_source_is_logged_and_the_relay_still_closes(
    caplog: pytest.LogCaptureFixture,
) -> None:
    source = Source()
    source.fail = True
    cam = relay(source)
    cam.watch("tablet")
    await source.until(lambda: source.closed > 0)
    assert "camera source failed" in caplog.text
    await cam.close()
    assert not cam.streaming
