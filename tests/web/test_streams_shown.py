"""Stream only what is shown (issue 30, point 9): the selected robot's laser scan streams to the
console while the map is on screen, stops when another tab is opened or the page is hidden (a
tablet put to sleep), and comes back with the map — counted on the socket, in Chromium."""

from __future__ import annotations

import asyncio
import json
from collections.abc import Callable
from pathlib import Path
from typing import Any

from tests.web.test_ui import (
    TABLET,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    ui_restaurant,
)

HIDE = (
    "Object.defineProperty(document, 'visibilityState', {value: 'hidden', configurable: true});"
    "document.dispatchEvent(new Event('visibilitychange'))"
)


class Socket:
    """The page's websocket frames, both ways, and a wait on them."""

    def __init__(self) -> None:
        self.received: list[dict[str, Any]] = []
        self.sent: list[dict[str, Any]] = []
        self._changed = asyncio.Event()

    def attach(self, ws: Any) -> None:
        ws.on("framereceived", lambda f: self._add(self.received, f))
        ws.on("framesent", lambda f: self._add(self.sent, f))

    def _add(self, into: list[dict[str, Any]], frame: Any) -> None:
        if isinstance(frame, str):
            into.append(json.loads(frame))
            self._changed.set()

    def count(self, topic: str) -> int:
        return sum(1 for f in self.received if f.get("topic") == topic)

    def unsubscribed(self, topic: str) -> int:
        return sum(1 for m in self.sent if m.get("unsubscribe") and topic in m.get("topics", []))

    async def until(self, cond: Callable[[], bool], what: str) -> None:
        async def wait() -> None:
            while not cond():
                self._changed.clear()
                await self._changed.wait()

        try:
            await asyncio.wait_for(wait(), 20)
        except TimeoutError:
            raise AssertionError(f"timed out waiting for {what}") from None


async def test_the_scan_streams_only_while_the_map_is_shown(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        context = await browser.new_context(viewport=TABLET)
        page = await context.new_page()
        sock = Socket()
        page.on("websocket", sock.attach)
        await page.goto(f"{http_base(r)}/")
        await log_in(page, "owner", r.app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await page.get_by_role("button", name="Select r1").click()
        await sock.until(lambda: sock.count("scan:r1") > 2, "scans on the map")
        assert r.app.core is not None and r.app.core.hub.watched("scan:r1")

        hub = r.app.core.hub  # type: ignore[union-attr]

        async def stopped(times: int) -> None:
            """Unsubscribed (the ``times``-th time) and answered: the server streams no more
            scans to anyone (the robot's scan is not even asked of it any more)."""
            await sock.until(lambda: sock.unsubscribed("scan:r1") == times, "the unsubscribe")
            request = [m for m in sock.sent if m.get("unsubscribe")][-1]["id"]
            await sock.until(
                lambda: any(f.get("id") == request for f in sock.received), "its reply"
            )
            assert not hub.watched("scan:r1")

        # Another tab: the scan stops.
        await page.get_by_role("tab", name="Kitchen").click()
        await stopped(1)
        # Back on the map: it streams again.
        scans = sock.count("scan:r1")
        await page.get_by_role("tab", name="Map & robots").click()
        await sock.until(lambda: sock.count("scan:r1") > scans + 3, "scans again")
        # The page hidden (a tablet asleep): stopped too.
        await page.evaluate(HIDE)
        await stopped(2)
        await context.close()
