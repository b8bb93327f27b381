"""The Chromium the web tests drive: Debian's /usr/bin/chromium through playwright (never
``playwright install``: no downloads here), one browser per test module (each test opens its
own windows), on the module's event loop; and the checks every screen must pass at any size
(no sideways scroll, targets a finger can hit)."""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest_asyncio

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]

#: The page's scrolling width and the window's: a page wider than its window scrolls sideways.
NO_SIDEWAYS_SCROLL = "() => [document.scrollingElement.scrollWidth, window.innerWidth]"

# Controls a waiter's finger aims at: their boxes (hidden ones skipped).
TARGETS = """(sel) => [...document.querySelectorAll(sel)]
  .filter((e) => e.offsetParent !== null)
  .map((e) => {
    const r = e.getBoundingClientRect();
    return [e.getAttribute("aria-label") || e.textContent.trim() || e.id, r.width, r.height];
  })"""

#: The smallest target a finger hits reliably (px, both ways).
FINGER = 44


async def sideways(page: Any) -> tuple[int, int]:
    """The page's scrolling width and the window's width."""
    width, inner = await page.evaluate(NO_SIDEWAYS_SCROLL)
    return int(width), int(inner)


async def too_small(page: Any, selector: str) -> list[tuple[str, float, float]]:
    """The visible controls of ``selector`` smaller than a finger: (label, width, height)."""
    return [
        (label, w, h)
        for label, w, h in await page.evaluate(TARGETS, selector)
        if w < FINGER or h < FINGER
    ]


@pytest_asyncio.fixture(loop_scope="module", scope="module")
async def browser() -> AsyncIterator[Any]:
    from playwright.async_api import async_playwright

    async with async_playwright() as p:
        b = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            await b.close()
