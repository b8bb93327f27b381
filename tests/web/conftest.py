"""The Chromium the web tests drive: Debian's /usr/bin/chromium through playwright (never
``playwright install``: no downloads here), one browser per test module (each test opens its
own windows), on the module's event loop; and the checks every screen must pass at any size
(no sideways scroll, targets a finger can hit).

On a machine without Debian's ``chromium`` package (or without the playwright Python package)
the browser tests are skipped, the reason saying what to install, so that ``python3 -m pytest``
passes on a fresh machine; with ``CI`` set in the environment they fail instead, as the MariaDB
and Node tests do: CI installs everything (``.ci/run``) and must run them all.
``SERVEUR_TEST_CHROMIUM=/some/path`` points the tests at another Chromium binary (a path that
does not exist shows what a machine without chromium does).
"""

from __future__ import annotations

import os
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio

CHROMIUM = Path(os.environ.get("SERVEUR_TEST_CHROMIUM") or "/usr/bin/chromium")
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


def _playwright_missing() -> str | None:
    try:
        import playwright.async_api  # noqa: F401
    except ImportError:
        return "the playwright Python package is not installed: pip install -e '.[test]'"
    return None


def browser_missing() -> str | None:
    """What this machine lacks to run the browser tests (and how to install it), or None."""
    if not (CHROMIUM.is_file() and os.access(CHROMIUM, os.X_OK)):
        return (
            f"no Chromium at {CHROMIUM}: the browser tests need Debian's chromium package"
            " (apt-get install chromium)"
        )
    return _playwright_missing()


def _in_ci() -> bool:
    return bool(os.environ.get("CI"))


BROWSER_MISSING = browser_missing()

#: On every browser test (each module's ``pytestmark``): skipped where the browser tests cannot
#: run, the reason saying what to install. In CI (``CI`` set) never skipped: they fail instead,
#: in the ``browser`` fixture.
needs_browser = pytest.mark.skipif(
    BROWSER_MISSING is not None and not _in_ci(), reason=BROWSER_MISSING or ""
)


def need_browser() -> None:
    """Skip the calling test when the browser tests cannot run here, saying what is missing;
    with ``CI`` set, fail it instead (CI installs everything and must run them)."""
    missing = browser_missing()
    if missing is None:
        return
    if _in_ci():
        pytest.fail(f"the browser tests must run in CI: {missing}", pytrace=False)
    pytest.skip(missing)


def import_playwright() -> Any:
    """``playwright.async_api``, for a module of browser tests to import at its top. Without
    the package the module is skipped, saying so; in CI that is a collection error."""
    missing = _playwright_missing()
    if missing is not None:
        if _in_ci():
            pytest.fail(f"the browser tests must run in CI: {missing}", pytrace=False)
        pytest.skip(missing, allow_module_level=True)
    import playwright.async_api

    return playwright.async_api


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
    need_browser()
    from playwright.async_api import async_playwright

    async with async_playwright() as p:
        b = await p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS)
        try:
            yield b
        finally:
            await b.close()
