"""Fewer taps and nothing lost (issue 30, points 5 and 6), on a phone in Chromium: one tap sends
one table's ready dishes, one tap sends everything ready (no "Add to cart" per dish); a reload
keeps the new order's draft (table, quantities, notes), the cart at the pass and the open tab.
Same harness as tests/web/test_service_ui.py (robots wait at the pass for Go)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.web.test_service_ui import (
    TIMES,
    activate,
    expect,
    pytestmark,  # noqa: F401
    service_restaurant,
    staff_client,
)
from tests.web.test_ui import Screens, http_base

PHONE = {"width": 390, "height": 844}


async def test_one_tap_sends_a_tables_dishes_then_everything_ready(
    tmp_path: Path, browser: Any
) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        ids = {}
        for dish, table in (("Laksa", "T1"), ("Satay", "T1"), ("Tea", "T5"), ("Soup", "T9")):
            made = await c.ok("create", type="order", dish=dish, table=table)
            ids[dish] = made["order"]["id"]
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE)
        await page.get_by_role("tab", name="Send food").click()
        send_all = page.get_by_role("button", name="Send all ready: 4 dishes for 3 tables")
        await expect(send_all).to_be_visible()
        # One table: T1's two dishes leave in one press, the others stay.
        await page.get_by_role("button", name="Send T1's 2 dishes now").click()
        await c.until(
            lambda: {c.order(ids[d])["status"] for d in ("Laksa", "Satay")} == {"assigned"},
            what="T1 sent",
        )
        assert c.order(ids["Tea"])["status"] == "pending"
        # The rest in one press: both tables on trips, nothing left ready.
        await expect(
            page.get_by_role("button", name="Send all ready: 2 dishes for 2 tables")
        ).to_be_visible()
        await page.get_by_role("button", name="Send all ready: 2 dishes for 2 tables").click()
        await c.until(
            lambda: all(c.order(i)["status"] == "assigned" for i in ids.values()),
            what="all sent",
        )
        await expect(page.locator(".send-ready")).to_be_hidden()
        tasks = [
            m for m in screens.sent if m.get("clientmsg") == "create" and m.get("type") == "task"
        ]
        assert [sorted(m["orders"]) for m in tasks] == [
            sorted([ids["Laksa"], ids["Satay"]]),
            sorted([ids["Tea"], ids["Soup"]]),
        ]
        screens.assert_no_errors()


async def test_a_reload_keeps_the_draft_the_cart_and_the_tab(tmp_path: Path, browser: Any) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        tea = (await c.ok("create", type="order", dish="Tea", table="T5"))["order"]["id"]
        await c.ok("create", type="order", dish="Soup", table="T9")
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE)

        # A cart at the pass: Tea in it.
        await page.get_by_role("tab", name="Send food").click()
        await page.get_by_role("button", name="Add to cart: Tea for T5").click()
        cart = page.get_by_role("list", name="Cart")
        await expect(cart).to_contain_text("Tea")

        # A new order half-written: two Laksa for T1 with a note, a Satay for T12.
        await page.get_by_role("tab", name="New order").click()
        await page.get_by_role("button", name="Table T1", exact=True).click()
        await page.get_by_role("button", name="Add Laksa").click()
        await page.get_by_role("button", name="One more Laksa").click()
        await page.get_by_role("textbox", name="Note for Laksa (T1)").fill("no chilli")
        await page.get_by_role("button", name="Table T12").click()
        await page.get_by_role("button", name="Add Satay").click()

        await page.reload()
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        # The tab, the draft with its quantities and note, the table picked.
        await expect(page.get_by_role("tab", name="New order")).to_have_attribute(
            "aria-selected", "true"
        )
        lines = page.get_by_role("list", name="Order")
        await expect(lines.get_by_role("listitem")).to_have_count(2)
        await expect(lines).to_contain_text(f"{TIMES}2")
        await expect(page.get_by_role("textbox", name="Note for Laksa (T1)")).to_have_value(
            "no chilli"
        )
        await expect(page.get_by_role("button", name="Table T12")).to_have_attribute(
            "aria-pressed", "true"
        )
        # Sent, the draft is gone for good (a second reload shows none).
        await page.get_by_role("button", name="Send to the kitchen").click()
        await c.until(
            lambda: sum(1 for o in c.records["orders"].values() if o["dish"] == "Laksa") == 1,
            what="Laksa ordered",
        )
        await expect(lines).to_contain_text("Pick a table, then dishes.")
        # The cart, still holding Tea (and only it), sent with its kept key.
        await page.get_by_role("tab", name="Send food").click()
        await expect(cart).to_contain_text("Tea")
        await expect(cart).not_to_contain_text("Soup")
        await page.reload()
        await expect(page.get_by_role("tab", name="Send food")).to_have_attribute(
            "aria-selected", "true"
        )
        await expect(cart).to_contain_text("Tea")
        await page.get_by_role("button", name="Send 1 dish (1 table)").click()
        await c.until(lambda: c.order(tea)["status"] == "assigned", what="the cart sent")
        screens.assert_no_errors()
