"""How often a robot's pose reaches the screens: at most :data:`MAX_RATE` a wall second.

A robot streams its pose at AMCL's rate in *simulated* time: at the demo's time scale a moving
robot sends 50 poses a wall second, and a console has no use for more poses than it draws
(it draws at most ~10 a second). :class:`PoseGate` sits between the links' pose reports and the
``pose:<robot>`` topics:

* at most one pose per robot per ``1 / MAX_RATE`` wall seconds is published, on a beat: a
  pose arriving before the robot's next beat is held, the newer one replacing it (latest
  wins), and published when the beat comes — so the last pose after a robot stops is always
  delivered. A pose at most :data:`JITTER` of the interval early goes at once and takes that
  beat: a robot streaming at 10 Hz, each pose a few ms early or late as its link and the
  loop allow, then never has its poses held (a hold of 0-20 ms each, bench_server's fan-out
  tail), and the rate over time is still at most one a beat;
* a pose that has not moved since the last one published (a parked robot) is not published
  at all: a new subscriber gets the current pose in its subscription's snapshot. "Moved" is
  beyond AMCL's noise (:data:`MOVED_M`, :data:`MOVED_RAD`): a localised robot standing still
  reports poses a centimetre or two apart. After a robot stops, one pose inside that band is
  still published (where it came to rest), then nothing until it moves again.

Laser scans (only streamed while someone watches) are paced the same way, by dropping: at most
:data:`SCAN_RATE_MOVING` a wall second while the robot moves, :data:`SCAN_RATE_PARKED` while it
is parked (a parked robot's scan changes only when someone walks by).

Time is the event loop's (wall time, except in a replay's virtual-time loop, where nobody
watches the poses anyway).
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from dataclasses import dataclass, field

__all__ = [
    "JITTER",
    "MAX_RATE",
    "MOVED_M",
    "MOVED_RAD",
    "SCAN_RATE_MOVING",
    "SCAN_RATE_PARKED",
    "PoseGate",
]

#: Poses a robot's topic carries at most per wall second.
MAX_RATE = 10.0
#: Laser scans a robot's topic carries at most per wall second, moving and parked.
SCAN_RATE_MOVING = 5.0
SCAN_RATE_PARKED = 1.0
#: A pose this close to the last one published (metres, radians) is "not moved": several
#: times AMCL's noise (the simulator's is 1 cm and 0.005 rad, sigma), under a robot's width.
MOVED_M = 0.08
MOVED_RAD = 0.05
#: The share of the interval a pose may come early and still go at once (on its beat).
JITTER = 0.25

Pose = tuple[float, float, float]


@dataclass
class _Robot:
    sent: Pose | None = None  # the pose last published
    sent_at: float = -math.inf  # loop time it was published
    held: tuple[Pose, float] | None = None  # (pose, stamp) waiting for the interval to end
    timer: asyncio.TimerHandle | None = field(default=None, repr=False)
    settled: bool = False  # the pose last published was inside the band of the one before
    scan_at: float = -math.inf  # loop time the last scan was let through


def _moved(a: Pose, b: Pose) -> bool:
    turn = abs(math.remainder(a[2] - b[2], math.tau))
    return math.hypot(a[0] - b[0], a[1] - b[1]) >= MOVED_M or turn >= MOVED_RAD


class PoseGate:
    """Decides which of a robot's poses are published; ``publish(robot, pose, stamp)`` does it."""

    def __init__(
        self, publish: Callable[[str, Pose, float], None], *, max_rate: float = MAX_RATE
    ) -> None:
        self._publish = publish
        self._interval = 1.0 / max_rate
        self._early = JITTER * self._interval
        self._robots: dict[str, _Robot] = {}

    def offer(self, robot: str, pose: Pose, stamp: float) -> None:
        """A new pose from the robot's link (to be published now, later or not at all)."""
        st = self._robots.setdefault(robot, _Robot())
        if st.held is None and st.settled and st.sent is not None and not _moved(pose, st.sent):
            return  # parked, its resting pose already shown: nothing new
        loop = asyncio.get_running_loop()
        due = st.sent_at + self._interval
        now = loop.time()
        if now >= due - self._early and st.timer is None:
            # On time, or early by the link's jitter: it goes now and takes its beat.
            self._send(robot, st, pose, stamp, at=max(now, due))
            return
        st.held = (pose, stamp)
        if st.timer is None:
            st.timer = loop.call_at(due, self._flush, robot, due)

    def scan_due(self, robot: str) -> bool:
        """Whether a scan arriving now is let through (else dropped: the next one will be)."""
        st = self._robots.setdefault(robot, _Robot())
        now = asyncio.get_running_loop().time()
        rate = SCAN_RATE_PARKED if st.settled else SCAN_RATE_MOVING
        if now - st.scan_at < 1.0 / rate:
            return False
        st.scan_at = now
        return True

    def forget(self, robot: str) -> None:
        """Nobody watches the robot's pose: drop what is held (a watcher's snapshot has it)."""
        st = self._robots.pop(robot, None)
        if st is not None and st.timer is not None:
            st.timer.cancel()

    def close(self) -> None:
        for name in list(self._robots):
            self.forget(name)

    def _flush(self, robot: str, due: float) -> None:
        st = self._robots.get(robot)
        if st is None:
            return
        st.timer = None
        held, st.held = st.held, None
        if held is not None and not (st.settled and st.sent and not _moved(held[0], st.sent)):
            # Counted from when the interval ended, not from when this callback ran: a loop a
            # few ms late each time made the gate's beat slip behind the robot's 10 Hz, and a
            # pose then waited anywhere from 0 to 100 ms (bench_server's fan-out p99).
            self._send(robot, st, *held, at=due)

    def _send(
        self, robot: str, st: _Robot, pose: Pose, stamp: float, at: float | None = None
    ) -> None:
        st.settled = st.sent is not None and not _moved(pose, st.sent)
        st.sent = pose
        st.sent_at = asyncio.get_running_loop().time() if at is None else at
        self._publish(robot, pose, stamp)
