"""The owner connects a program from the Accounts tab (a till's bridge: docs/till.md, "For
integrators"), on a phone, in Chromium (same harness as tests/web/test_ui.py: Debian's
/usr/bin/chromium, a real server, no sleeps).

The owner names the program and keeps "send orders" (and adds "read the restaurant"); the token
is shown once, with a Copy button (the clipboard then holds it) and where the program sends its
orders; after Done it is nowhere on the page. The token works: an order POSTed with it to the
order-intake API (the App started with ``intake_port=0``, as tests/test_till.py's ``till_site``)
is taken (201), and the list then says the program was used. Revoked in the list (after a
confirmation), the same POST is refused (401). The form refuses to make a token that may do
nothing, every control is a finger's size, nothing scrolls sideways and axe finds no serious or
critical violation with the token shown.
"""

from __future__ import annotations

import asyncio
import re
from pathlib import Path
from typing import Any

from tests.conftest import intake_app
from tests.test_till import post
from tests.web.conftest import sideways, too_small
from tests.web.test_a11y import need_axe, violations
from tests.web.test_owner_ui import confirm
from tests.web.test_ui import (
    SHOTS,
    Screens,
    expect,
    log_in,
    pytestmark,  # noqa: F401
)

PHONE = {"width": 390, "height": 844}
ORDER = {"key": "pos-7-1", "table": "T12", "ticket": "7", "dishes": [{"dish": "Laksa"}]}
SHOWN = """(token) => document.body.innerText.includes(token)
  || [...document.querySelectorAll("input")].some((i) => i.value === token)"""


async def test_the_owner_connects_a_program_and_revokes_it(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with intake_app(tmp_path) as app:
        assert app.intake is not None
        api = f"http://127.0.0.1:{app.intake.port}/api/orders"
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        screens = Screens(browser, base)
        page = await screens.open("/", online=False, viewport=PHONE, bypass_csp=True)
        await page.context.grant_permissions(["clipboard-read", "clipboard-write"], origin=base)
        await log_in(page, "owner", app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await page.get_by_role("tab", name="Accounts").click()
        card = page.get_by_role("region", name="Programs")
        programs = card.get_by_role("list", name="Programs")
        await expect(programs.get_by_text("No programs yet.")).to_be_visible()

        # What it may do: "send orders" by default, "read the restaurant" not.
        orders = card.get_by_role("checkbox", name="send orders")
        read = card.get_by_role("checkbox", name="read the restaurant")
        await expect(orders).to_be_checked()
        await expect(read).not_to_be_checked()
        # Neither: the form says so and sends nothing.
        await card.get_by_label("Name of the program").fill("till bridge")
        await orders.press("Space")  # the keyboard, as a tablet's or a desk's
        await expect(orders).not_to_be_checked()
        await card.get_by_role("button", name="Create token").click()
        why = "Choose at least one thing it may do."
        await expect(orders).to_have_js_property("validationMessage", why)
        assert not [m for m in screens.sent if m.get("action") == "create_token"]

        # Orders, and reading the restaurant: the token is shown once.
        await orders.press("Space")
        await read.check()
        assert await too_small(page, "#panel-accounts button, .prog-may label") == []
        await card.get_by_role("button", name="Create token").press("Enter")
        made = card.get_by_test_id("program-made")
        await expect(made.get_by_role("heading", name="Token for till bridge")).to_be_visible()
        await expect(made).to_contain_text("Shown only this once")
        await expect(made).to_contain_text("the order-intake address your installer set up")
        box = made.get_by_role("textbox", name="Token")
        await expect(box).to_have_value(re.compile(r"^srv_[\w-]{20,}$"))
        await expect(box).to_be_focused()
        token = await box.input_value()
        sent = [m for m in screens.sent if m.get("action") == "create_token"]
        assert [(m["role"], sorted(m["scopes"]), m["label"]) for m in sent] == [
            ("integration", ["orders", "read"], "till bridge")
        ]
        await made.get_by_role("button", name="Copy").click()
        await expect(page.get_by_text("Token copied")).to_be_visible()
        assert await page.evaluate("() => navigator.clipboard.readText()") == token
        row = programs.get_by_role("listitem").filter(has_text="till bridge")
        await expect(row).to_contain_text("sends orders and reads the restaurant")
        await expect(row).to_contain_text("never used")
        await expect(card.get_by_label("Name of the program")).to_have_value("")
        assert await too_small(page, "#panel-accounts button, .prog-may label") == []
        assert (await sideways(page))[0] <= PHONE["width"]
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "program-token-phone.png"), full_page=True)

        # Done: the token is gone from the page, for good.
        await made.get_by_role("button", name="Done").click()
        await expect(made).to_be_hidden()
        await expect(card.get_by_label("Name of the program")).to_be_focused()
        assert not await page.evaluate(SHOWN, token)

        # The token works: the till bridge's order is taken; the list says it was used.
        status, reply = await asyncio.to_thread(post, api, ORDER, token)
        assert status == 201, reply
        assert [(o["dish"], o["table"]) for o in reply["orders"]] == [("Laksa", "T12")]
        await page.get_by_role("tab", name="Kitchen").click()
        await page.get_by_role("tab", name="Accounts").click()
        await expect(row).to_contain_text("last used")
        assert not await page.evaluate(SHOWN, token)

        # Revoked from the list (after a confirmation): the same order is refused.
        revoke = re.compile(r"^Revoke till bridge \(token \d+\)$")
        await row.get_by_role("button", name=revoke).click()
        await expect(page.get_by_role("dialog")).to_contain_text("Revoke the token of till bridge?")
        await confirm(page, "Revoke")
        await expect(programs.get_by_text("No programs yet.")).to_be_visible()
        status, reply = await asyncio.to_thread(post, api, {**ORDER, "key": "pos-7-2"}, token)
        assert status == 401, reply
        assert reply["code"] == "unauthorized", reply
        assert len(await app.store.orders.list_orders()) == 1
        screens.assert_no_errors()
