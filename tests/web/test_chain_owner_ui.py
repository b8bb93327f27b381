"""The owner sees the chain's head office on the Restaurant tab (issue 34: "the outbox's size
and the oldest unsent event are shown to the owner"), in Chromium (same harness as
tests/web/test_ui.py: Debian's /usr/bin/chromium, a real server, no sleeps but the one that
shows nothing is asked).

A restaurant in a chain whose broker does not answer (a loopback port where nothing listens: no
broker runs here) says so in words, with the updates waiting and the time of the oldest, the
updates kept on the box, and the name the head office knows it by — never the password. As the
restaurant records more, the count grows by itself while the tab is shown; once the broker has
everything and is connected, the card says so. Another tab open, nothing is asked; the tab
shown again, it is read at once. A restaurant in no chain shows one discreet line instead.

The console reads the card every 20 s; the page's 20 s timers are made 0.3 s here (an init
script), so that the test need not wait for them.
"""

from __future__ import annotations

import asyncio
import json
import re
import socket
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from serveur.app import App
from serveur.chain.address import ChainAddress
from serveur.chain.shipper import Shipper
from tests.conftest import Client
from tests.test_chain_owner import PASSWORD, chain_site
from tests.web.test_a11y import need_axe, violations
from tests.web.test_ui import (
    SHOTS,
    TABLET,
    expect,
    log_in,
    pytestmark,  # noqa: F401
)

#: The page's refresh of the card (20 s) made short; other timers are left alone.
SHORT_REFRESH = """(() => {
  const wait = window.setTimeout;
  window.setTimeout = (f, ms, ...args) => wait(f, ms === 20000 ? 300 : ms, ...args);
})();"""


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@asynccontextmanager
async def owner_page(browser: Any, app: App) -> AsyncIterator[tuple[Any, list[dict[str, Any]]]]:
    """The console on a tablet, logged in as the owner: the page and what it sent."""
    context = await browser.new_context(viewport=TABLET, bypass_csp=True)
    await context.add_init_script(SHORT_REFRESH)
    page = await context.new_page()
    sent: list[dict[str, Any]] = []
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.on("websocket", lambda ws: ws.on("framesent", lambda f: sent.append(json.loads(f))))
    try:
        await page.goto(app.url.replace("ws://", "http://").removesuffix("/ws") + "/")
        await log_in(page, "owner", app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        yield page, sent
        assert errors == []
    finally:
        await context.close()


def asked(sent: list[dict[str, Any]]) -> int:
    return sum(1 for m in sent if m.get("clientmsg") == "chain")


async def test_the_owner_sees_the_head_office_and_what_waits(tmp_path: Path, browser: Any) -> None:
    need_axe()
    address = ChainAddress("127.0.0.1", free_port(), "lyon", PASSWORD, tls=False)
    async with chain_site(tmp_path, address) as app, owner_page(browser, app) as (page, sent):
        assert app.server is not None
        assert asked(sent) == 0  # not before the tab is opened
        await page.get_by_role("tab", name="Restaurant").click()
        card = page.get_by_role("region", name="Head office")
        line, waiting = card.get_by_test_id("chain-line"), card.get_by_test_id("chain-waiting")
        await expect(line).to_have_text("Not connected to the head office. Nothing sent yet.")
        state = await app.store.outbox.state()
        count = re.compile(r"^([\d,]+) updates? waiting, (the oldest )?from \d\d:\d\d( [AP]M)?\.$")
        await expect(waiting).to_have_text(count)
        await expect(card.get_by_test_id("chain-kept")).to_contain_text(
            "Nothing is lost: what waits is sent when the connection is back."
        )
        await expect(card.get_by_test_id("chain-kept")).to_contain_text("kept on this box")
        await expect(card).to_contain_text(
            f"The head office knows this restaurant as “lyon”, through"
            f" mqtt://lyon@127.0.0.1:{address.port}."
        )
        assert PASSWORD not in await page.evaluate("() => document.body.innerText")
        shown = int((await waiting.inner_text()).split()[0].replace(",", ""))
        assert shown >= state.unsent > 0

        # The restaurant records more (a dish ordered at the pass): the count grows while the
        # tab is shown.
        token = await app.issue_token("staff", label="pass")
        staff = Client(
            await connect(app.url, additional_headers={"Authorization": f"Bearer {token}"})
        )
        await staff.ok("create", type="order", dish="Laksa", table="T3")
        await staff.close()
        more = int((await app.store.outbox.state()).unsent)
        assert more > shown
        await expect(waiting).to_have_text(re.compile(rf"^{more:,} updates waiting"))
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "chain-not-connected.png"), full_page=True)

        # The broker has everything and is connected now (a stand-in for the shipper that
        # connected: tests/chain connects a real one): the card says so.
        head = (await app.store.outbox.state()).head
        await app.store.outbox.mark_sent(head, app.clock.epoch())
        connected = Shipper(app.store, address, app.clock)
        connected.connected.set()
        app.server.chain = connected
        await expect(line).to_have_text("Connected to the head office.")
        await expect(waiting).to_have_text("Everything sent.")
        await expect(card.get_by_test_id("chain-kept")).not_to_contain_text("Nothing is lost")

        # Another tab: nothing is asked. The tab again: read at once.
        await page.get_by_role("tab", name="Map").click()
        before = asked(sent)
        await asyncio.sleep(1.5)  # five refreshes' worth: none may come
        assert asked(sent) - before <= 1  # (one read may have been on its way)
        quiet = asked(sent)
        await asyncio.sleep(1.0)
        assert asked(sent) == quiet
        await page.get_by_role("tab", name="Restaurant").click()
        await expect(line).to_have_text("Connected to the head office.")
        for _ in range(100):
            if asked(sent) > quiet:
                break
            await asyncio.sleep(0.05)
        assert asked(sent) > quiet


async def test_a_restaurant_in_no_chain_shows_one_discreet_line(
    tmp_path: Path, browser: Any
) -> None:
    async with chain_site(tmp_path, None) as app, owner_page(browser, app) as (page, sent):
        await page.get_by_role("tab", name="Restaurant").click()
        await expect(
            page.get_by_text(
                "This restaurant is not part of a chain: nothing is sent to a head office."
            )
        ).to_be_visible()
        await expect(page.get_by_role("region", name="Head office")).to_have_count(0)
        assert asked(sent) >= 1
