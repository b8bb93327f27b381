"""The reconnect loop every camera source runs, written once.

A camera source (:class:`~serveur.core.camera.CameraSource`) must keep its stream up by
itself until the relay cancels it: the relay opens it for the first viewer and has no one to
tell if it dies. Whatever the wire (rosbridge's CompressedImage in
:mod:`serveur.robots.camera`, web_video_server's MJPEG in :mod:`serveur.robots.mjpeg`), that
loop is the same: run a session until it ends, say why if it failed, wait, open it again. The
pause doubles from :data:`RETRY_FIRST` to :data:`RETRY_MAX` while sessions keep failing, so a
robot switched off is not hammered, and falls back to :data:`RETRY_FIRST` after a session that
ended without an error (the robot closed a stream that worked: it is back soon).

Not the robot link's loop (:mod:`serveur.robots.reconnect`): a camera has no tracker, no goals
and no one to report its liveness to, so it needs none of that.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from typing import Final, NoReturn

__all__ = ["RETRY_FIRST", "RETRY_MAX", "keep_streaming"]

log = logging.getLogger(__name__)

#: The first pause before a camera connection is opened again (seconds), and the longest.
RETRY_FIRST: Final = 0.5
RETRY_MAX: Final = 5.0


async def keep_streaming(
    session: Callable[[], Awaitable[object]],
    failures: tuple[type[Exception], ...],
    what: str,
) -> NoReturn:
    """Run ``session`` again and again until cancelled, pausing between two runs.

    ``failures`` are the exceptions that mean "the robot or the network failed, try again"
    (each is logged with ``what``, the camera's address); anything else is a bug and ends the
    loop (the relay logs it).
    """
    pause = RETRY_FIRST
    while True:
        try:
            await session()
            pause = RETRY_FIRST
        except failures as exc:
            why = str(exc) or type(exc).__name__  # TimeoutError() says nothing
            log.info("camera %s: %s; again in %.1f s", what, why, pause)
        await asyncio.sleep(pause)
        pause = min(pause * 2, RETRY_MAX)
