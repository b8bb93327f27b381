"""The joystick's dead man's switch, the same for every robot driver.

A joystick sends twists several times a second; a robot base keeps its last velocity. If no
twist comes for ``timeout`` wall seconds (the tablet slept, the Wi-Fi went), the driver stops
the robot itself with ``stop`` (a zero twist), whatever ROS the robot runs.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable

from serveur.clock import Clock

__all__ = ["DeadManSwitch"]

log = logging.getLogger(__name__)


class DeadManSwitch:
    """Armed by each non-zero joystick twist; fires ``stop`` once the twists stop coming."""

    def __init__(
        self, name: str, clock: Clock, timeout: float, stop: Callable[[], Awaitable[None]]
    ) -> None:
        """``timeout`` is wall seconds (scaled to the clock); ``stop`` sends the zero twist."""
        self._name = name
        self._clock = clock
        self._timeout = timeout
        self._stop = stop
        self._last = 0.0  # clock time of the last non-zero twist
        self._task: asyncio.Task[None] | None = None
        #: Steering now: a non-zero twist was sent and no stop since.
        self.held = False

    def twist(self, moving: bool) -> None:
        """A twist was sent: a non-zero one (re)arms the switch, a zero one disarms it."""
        self.held = moving
        if not moving:
            self.release()
            return
        self._last = self._clock.now()
        if self._task is None or self._task.done():
            self._task = asyncio.create_task(self._watch(), name=f"teleop-failsafe-{self._name}")

    def release(self) -> None:
        """Disarm without stopping the robot (a zero twist was sent, or shutting down)."""
        self.held = False
        task, self._task = self._task, None
        if task is not None and task is not asyncio.current_task():
            task.cancel()

    async def _watch(self) -> None:
        timeout = self._timeout * self._clock.time_scale  # wall seconds on the clock
        while self.held:
            left = self._last + timeout - self._clock.now()
            if left > 0:
                await self._clock.sleep(left)
                continue
            self.held = False
            log.warning("%s: no joystick command for %.1fs, stopping", self._name, self._timeout)
            await self._stop()
