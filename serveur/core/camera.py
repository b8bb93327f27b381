"""One robot's camera relayed to every viewer: one upstream, the same bytes, the newest frame.

How others do it goes wrong on a Pi (../shared/notes/video.md): web_video_server opens one
subscription and one JPEG encoder per browser, so five tablets cost five encodes; rosbridge
clients that fall behind queue base64 images and show a picture 10-20 s old. So here:

* **One upstream per robot**, whatever the number of viewers: the robot's camera is opened
  when its first viewer comes and closed when its last one goes (nothing is pulled over the
  robot's Wi-Fi while nobody watches).
* **No transcoding**: the robot's own JPEG bytes go to every viewer as they came. Each frame is
  checked once (a JPEG starts with the SOI marker FF D8 and ends with EOI FF D9; at most
  ``max_bytes``): a frame that is not a JPEG or is too large is dropped and counted, never
  forwarded.
* **Latest frame wins, per viewer**: a viewer holds one slot. While its connection is still
  writing the previous frame, newer ones replace each other in the slot; when it is free it
  takes the newest. A slow tablet skips frames, never queues them, and a robot flooding frames
  costs no viewer more than its newest one.

The relay is pure asyncio (no sockets): the upstream is a :class:`CameraSource` that calls
``deliver`` per frame, and each viewer's sending is its connection's business
(:meth:`CameraViewer.next`). Tested without sockets in tests/core/test_camera.py.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Final, Protocol

__all__ = [
    "MAX_FRAME_BYTES",
    "CameraFrame",
    "CameraRelay",
    "CameraSource",
    "CameraViewer",
    "RelayCounts",
    "jpeg_problem",
]

log = logging.getLogger(__name__)

#: The largest frame relayed (bytes): a 1280x720 JPEG at quality 95 is ~250 kB; 640x480 at
#: the usual 80 is 20-50 kB (../shared/notes/video.md). A robot set to send raw or huge
#: images is refused frame by frame rather than flooding every tablet.
MAX_FRAME_BYTES: Final = 512 * 1024

_SOI: Final = b"\xff\xd8"
_EOI: Final = b"\xff\xd9"


def jpeg_problem(data: bytes, max_bytes: int = MAX_FRAME_BYTES) -> str | None:
    """Why ``data`` is not relayed ("not a JPEG", "too large"), or None if it may be."""
    if len(data) > max_bytes:
        return "too large"
    # A JPEG may carry padding after EOI (some encoders pad to an even length): look at the
    # last few bytes, not only the last two.
    if len(data) < 4 or not data.startswith(_SOI) or _EOI not in data[-8:]:
        return "not a JPEG"
    return None


@dataclass(frozen=True, slots=True)
class CameraFrame:
    """One picture as the robot sent it."""

    robot: str
    #: The relay's count of frames it accepted from this robot (viewers see gaps as skips).
    seq: int
    #: When the robot captured it (its header stamp, Unix seconds; 0 if it gave none).
    captured: float
    #: When the server received it (the server's clock, seconds), for the frame's age.
    received: float
    jpeg: bytes


class CameraSource(Protocol):
    """A robot's camera stream (rosbridge CompressedImage, web_video_server MJPEG...)."""

    async def run(self, deliver: Callable[[bytes, float], None]) -> None:
        """Connect and call ``deliver(jpeg, captured)`` per frame until cancelled; reconnect
        by itself after a failure (the relay cancels it when the last viewer goes)."""
        ...


@dataclass
class RelayCounts:
    """What one relay did since it was made (shown to the owner, read by tests and benches)."""

    frames_in: int = 0
    not_jpeg: int = 0
    too_large: int = 0
    upstreams_opened: int = 0


@dataclass(eq=False)
class CameraViewer:
    """One viewer's slot: the newest frame it has not taken yet."""

    name: str
    _slot: CameraFrame | None = None
    _ready: asyncio.Event = field(default_factory=asyncio.Event)
    #: Frames taken (sent) and frames replaced before they were taken (skipped).
    taken: int = 0
    skipped: int = 0
    closed: bool = False

    def offer(self, frame: CameraFrame) -> None:
        if self._slot is not None:
            self.skipped += 1
        self._slot = frame
        self._ready.set()

    def close(self) -> None:
        """The camera went away (the robot was removed or its camera changed): ``next``
        answers None from now on."""
        self.closed = True
        self._ready.set()

    async def next(self) -> CameraFrame | None:
        """The newest frame not taken yet, waiting for one if there is none; None once the
        viewer is closed."""
        while self._slot is None and not self.closed:
            self._ready.clear()
            await self._ready.wait()
        if self.closed:
            return None
        frame, self._slot = self._slot, None
        assert frame is not None
        self.taken += 1
        return frame


class CameraRelay:
    """One robot's camera: its viewers, its one upstream while anyone watches."""

    def __init__(
        self,
        robot: str,
        source: CameraSource,
        now: Callable[[], float],
        *,
        max_bytes: int = MAX_FRAME_BYTES,
    ) -> None:
        self.robot = robot
        self._source = source
        self._now = now
        self._max_bytes = max_bytes
        self._viewers: set[CameraViewer] = set()
        self._upstream: asyncio.Task[None] | None = None
        self.counts = RelayCounts()
        self._seq = 0
        #: The last frame relayed (a new viewer gets it at once), None before one came.
        self.last: CameraFrame | None = None

    @property
    def viewers(self) -> int:
        return len(self._viewers)

    @property
    def streaming(self) -> bool:
        """The upstream is open (someone watches)."""
        return self._upstream is not None

    def watch(self, name: str) -> CameraViewer:
        """A new viewer; the first one opens the upstream."""
        viewer = CameraViewer(name)
        self._viewers.add(viewer)
        if self._upstream is None:
            self.last = None  # a picture from the previous watch is not "now"
            self.counts.upstreams_opened += 1
            self._upstream = asyncio.get_running_loop().create_task(
                self._run_upstream(), name=f"camera-{self.robot}"
            )
        elif self.last is not None:
            viewer.offer(self.last)
        return viewer

    async def leave(self, viewer: CameraViewer) -> None:
        """A viewer goes; the last one closes the upstream."""
        self._viewers.discard(viewer)
        if not self._viewers:
            await self.close()

    async def close(self) -> None:
        """Close the upstream; every viewer still watching is told (its ``next`` is None)."""
        for viewer in self._viewers:
            viewer.close()
        self._viewers.clear()
        task, self._upstream = self._upstream, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    def deliver(self, jpeg: bytes, captured: float) -> None:
        """One frame from the upstream: checked once, then offered to every viewer."""
        self.counts.frames_in += 1
        problem = jpeg_problem(jpeg, self._max_bytes)
        if problem is not None:
            if problem == "too large":
                self.counts.too_large += 1
            else:
                self.counts.not_jpeg += 1
            if self.counts.too_large + self.counts.not_jpeg == 1:  # once, not per frame
                log.warning("%s: camera frame dropped: %s", self.robot, problem)
            return
        self._seq += 1
        frame = CameraFrame(self.robot, self._seq, captured, self._now(), jpeg)
        self.last = frame
        for viewer in self._viewers:
            viewer.offer(frame)

    async def _run_upstream(self) -> None:
        try:
            await self._source.run(self.deliver)
        except asyncio.CancelledError:
            raise
        except Exception:  # a source must reconnect by itself; if it died, say so once
            log.exception("%s: camera source failed", self.robot)
