"""The one reconnect loop every MQTT client of serveur runs (call buttons, a chain site's
shipper, the chain's centre).

A session is opened, used until the broker goes, and opened again after a pause that grows
(:data:`BACKOFF`, the last one repeating). The broker's reachability is logged once down and
once up, as Home Assistant logs a device's availability — not at every retry, which would fill
a Pi's log during a night without internet.
"""

from __future__ import annotations

import asyncio
import logging
from collections.abc import Awaitable, Callable
from contextlib import AbstractAsyncContextManager
from typing import Any

__all__ = ["BACKOFF", "keep_session"]

#: Seconds between reconnection attempts (doubling, then the last one repeats).
BACKOFF = (1.0, 2.0, 5.0, 10.0, 30.0)


async def keep_session(
    what: str,
    client: Callable[[], AbstractAsyncContextManager[Any]],
    setup: Callable[[Any], Awaitable[None]],
    session: Callable[[Any], Awaitable[None]],
    *,
    connected: asyncio.Event,
    log: logging.Logger,
    backoff: tuple[float, ...] = BACKOFF,
    on_down: Callable[[], None] | None = None,
) -> None:
    """On each connection ``client()`` opens, ``setup(c)`` (subscribe) then ``session(c)``,
    forever (cancel to stop). ``connected`` is set from the end of ``setup`` (subscribed:
    a test or a caller may publish then) until the session ends; then ``on_down``."""
    import aiomqtt  # only where a broker is configured

    tries = 0
    down_logged = False
    while True:
        try:
            async with client() as c:
                await setup(c)
                if down_logged or tries == 0:
                    log.info("%s: connected", what)
                down_logged, tries = False, 0
                connected.set()
                await session(c)
        except aiomqtt.MqttError as exc:
            connected.clear()
            if on_down is not None:
                on_down()
            if not down_logged:
                log.warning("%s: broker unreachable: %s", what, exc)
                down_logged = True
            await asyncio.sleep(backoff[min(tries, len(backoff) - 1)])
            tries += 1
