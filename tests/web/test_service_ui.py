"""A dinner service run from the staff console in Chromium (issue 18): dishes ordered from the
menu with quantity and note, cooked and marked ready in the Kitchen tab, a trip loaded at the
pass and sent with Go, a table that times out and its dish returned then sent again, a void, an
alert raised, acknowledged and cleared, a blocked table cleared, the owner's menu, and action
buttons disabled while the connection is lost.

Same harness as tests/web/test_ui.py (Debian's /usr/bin/chromium driven by playwright, a real
server, simulated robots and SQLite, no sleeps), with a site as shipped (robots wait at the pass
for Go) and short service limits so that a timeout and an alert happen within seconds.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import re
from pathlib import Path
from typing import Any

import pytest

from serveur.core.engine import CoreConfig
from tests.conftest import Client, Restaurant, make_app, served_by
from tests.web.conftest import needs_browser
from tests.web.test_ui import Screens, dismiss_toasts, http_base, log_in

playwright_api = pytest.importorskip("playwright.async_api")
expect = playwright_api.expect

pytestmark = [needs_browser, pytest.mark.asyncio(loop_scope="module")]
expect.set_options(timeout=20_000)

#: The console writes a quantity as "Laksa", this sign, "2": a multiplication sign, not an x.
TIMES = "\u00d7"

#: Simulated seconds (the sim and the server run TIME_SCALE times faster than the wall): the
#: waiting alert comes 3 s (wall) after a robot reaches a table, the timeout 8 s after. No
#: battery or dish-at-pass alert gets in the way.
SERVICE = dict(
    heartbeat=10.0,
    ack_timeout=5.0,
    auto_depart=False,
    table_timeout=80.0,
    alert_wait_at_table=30.0,
    alert_dish_at_pass=1e6,
    alert_low_battery=0.0,
)


service_app = functools.partial(make_app, config=CoreConfig(**SERVICE))  # type: ignore[arg-type]


def service_restaurant(tmp_path: Path) -> contextlib.AbstractAsyncContextManager[Restaurant]:
    return served_by(tmp_path, service_app, "service ui tests")


async def staff_client(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "alerts", "blocks", "menu")
    return c


async def activate(c: Client) -> None:
    await c.status("r1", "Ready")
    await c.ok("control", robot="r1", action="auto")
    await c.status("r1", "Awaiting")


def alerts_of(c: Client, kind: str) -> list[dict[str, Any]]:
    return [a for a in c.records.get("alerts", {}).values() if a["kind"] == kind]


async def test_a_service_loaded_sent_timed_out_and_sent_again(tmp_path: Path, browser: Any) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")

        # New order from the menu: two Laksa without chilli for T1, a Satay for T12.
        await staff.get_by_role("tab", name="New order").click()
        menu = staff.get_by_role("group", name="Menu")
        await expect(menu.get_by_role("group", name="Drinks")).to_contain_text("Teh tarik")
        await staff.get_by_role("button", name="Table T1", exact=True).click()
        await staff.get_by_role("button", name="Add Laksa").click()
        await staff.get_by_role("button", name="One more Laksa").click()
        await staff.get_by_role("textbox", name="Note for Laksa (T1)").fill("no chilli")
        await staff.get_by_role("button", name="Table T12").click()
        await staff.get_by_role("button", name="Add Satay").click()
        await staff.get_by_role("button", name="Send to the kitchen").click()
        await expect(
            staff.get_by_text(f"Sent to the kitchen: Laksa {TIMES}2 (T1), Satay (T12)")
        ).to_be_visible()
        await dismiss_toasts(staff)
        orders = {o["dish"]: o for o in c.records["orders"].values()}
        assert (orders["Laksa"]["quantity"], orders["Laksa"]["note"]) == (2, "no chilli")
        assert {o["status"] for o in orders.values()} == {"ordered"}

        # The kitchen starts the Laksa, then marks both ready: they wait at the pass.
        await staff.get_by_role("tab", name="Kitchen").click()
        laksa = f"Laksa {TIMES}2 (no chilli)"
        await staff.get_by_role("button", name=f"Start cooking {laksa} for T1").click()
        cooking = staff.get_by_role("list", name="Cooking")
        await expect(cooking).to_contain_text(laksa)
        await staff.get_by_role("button", name=f"Ready: {laksa} for T1").click()
        await staff.get_by_role("button", name="Ready: Satay for T12").click()
        await expect(cooking).to_contain_text("Nothing cooking.")

        # Send food: both into the cart, sent; the robot takes the trip and waits at the pass.
        await staff.get_by_role("tab", name="Send food").click()
        await staff.get_by_role("button", name=f"Add to cart: {laksa} for T1").click()
        await staff.get_by_role("button", name="Add to cart: Satay for T12").click()
        await staff.get_by_role("button", name=re.compile(r"^Send 2 dishes")).click()
        rb = await c.status("r1", "Loading")
        task = c.task(rb["current_task"])
        first, second = (s["table"] for s in task["stops"])
        dishes = {"T1": laksa, "T12": "Satay"}
        loading = staff.get_by_role("list", name="Loading at the pass")
        trays = loading.get_by_role("list", name="Trays")
        await expect(trays.get_by_role("listitem")).to_have_text(
            [f"Tray 1 → {first}: {dishes[first]}", f"Tray 2 → {second}: {dishes[second]}"]
        )
        # The map tab's row says the same, with its own Go.
        await staff.get_by_role("tab", name="Map & robots").click()
        row = staff.locator("#robots > li").filter(has_text="r1")
        await expect(row.get_by_role("list", name="Trays")).to_contain_text(
            f"Tray 1 → {first}: {dishes[first]}"
        )
        await expect(row.get_by_role("button", name="Go r1")).to_be_visible()
        await staff.get_by_role("tab", name="Send food").click()
        await loading.get_by_role("button", name="Go r1").click()
        await expect(loading).to_contain_text("No robot is waiting to be loaded.")
        await c.until(lambda: c.robot("r1")["status"] in ("Delivering", "Delivered"), what="go")
        sent = [m for m in screens.sent if m.get("clientmsg") == "go"]
        assert sent and sent[0]["task"] == task["id"], sent

        # At the first table: how long it has waited, ticking; Food collected from the console.
        await staff.get_by_role("tab", name="Map & robots").click()
        at = row.locator(".at-table")
        await expect(at).to_have_text(re.compile(rf"^at {first} for 0:0\d$"))
        await expect(row.get_by_role("button", name="Skip table r1")).to_be_visible()
        shown = await at.text_content()
        await expect(at).not_to_have_text(shown or "")  # the next second
        await row.get_by_role("button", name="Food collected r1").click()

        # At the second table nobody comes: the waiting alert on every tab, acknowledged here.
        await c.until(
            lambda: c.task(task["id"])["stops"][1]["status"] == "arrived", what="at 2nd table"
        )
        banner = staff.get_by_role("region", name="Alerts")
        text = "r1 has waited long at a table"
        await expect(banner).to_contain_text(text)
        badge = staff.locator("#alert-badge")
        await expect(badge).to_have_text("1")
        await staff.get_by_role("tab", name="Kitchen").click()
        await expect(banner).to_be_visible()
        await banner.get_by_role("button", name=f"Acknowledge: {text}").click()
        await expect(banner).to_contain_text(re.compile(r"Seen by screen \d+ at"))
        await expect(badge).to_be_hidden()
        [waiting] = alerts_of(c, "waiting_at_table")
        assert waiting["acked_by"].startswith("token:")

        # The site's timeout: the robot leaves, the dish comes back, the alert is over.
        await c.until(
            lambda: c.task(task["id"])["stops"][1]["status"] == "skipped", what="timed out"
        )
        await expect(banner).to_be_hidden()
        await staff.get_by_role("tab", name="Send food").click()
        returned = staff.get_by_role("list", name="Returned dishes")
        back = dishes[second]
        await expect(returned).to_contain_text(back)
        # "Send again" sends: one press puts it on the next trip (no cart on the way).
        await returned.get_by_role("button", name=f"Send {back} for {second} again").click()
        await expect(returned).to_be_hidden()
        [oid] = task["stops"][1]["orders"]
        await c.until(lambda: c.order(oid)["status"] == "assigned", what="sent again")
        await expect(
            staff.get_by_role("button", name=f"Add to cart: {back} for {second}")
        ).to_have_count(0)
        # Home again, r1 is loaded with it at the pass.
        await c.status("r1", "Loading")
        loading = staff.get_by_role("list", name="Loading at the pass")
        await expect(loading).to_contain_text(back)
        screens.assert_no_errors()


async def test_a_blocked_table_its_alert_and_a_dish_changed(tmp_path: Path, browser: Any) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        made = await c.ok("create", type="order", dish="Laksa", table="T5")
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        await staff.get_by_role("tab", name="Send food").click()
        add = staff.get_by_role("button", name="Add to cart: Laksa for T5")
        await expect(add).to_be_enabled()

        # A robot could not reach T5 (as the core records it): no robot goes there.
        assert r.app.core is not None
        why = "r1: move_base ABORTED: no path to the goal: goal (9.20, 3.10) is occupied"
        await r.app.core.service.block("T5", why, "r1")
        blocked = staff.get_by_role("list", name="Blocked tables")
        # In staff's words; the robot's own text only for whoever opens "For the technician".
        await expect(blocked).to_contain_text("r1 could not get there.")
        await expect(blocked).not_to_contain_text("move_base", use_inner_text=True)
        await expect(staff.get_by_role("row").filter(has_text="Laksa")).to_contain_text(
            "blocked: r1 could not get there."
        )
        await blocked.get_by_text("For the technician").click()
        await expect(blocked).to_contain_text(why, use_inner_text=True)
        await expect(add).to_be_disabled()
        # A critical alert: on the banner, and a chime (WebAudio) for it.
        banner = staff.get_by_role("region", name="Alerts")
        await expect(banner).to_contain_text("Robots cannot reach T5")
        await expect(banner).to_have_attribute("data-chimes", "1")
        # Muted on this device (kept over a reload): the next critical alert is silent.
        await staff.get_by_role("button", name="Sound on").click()
        await expect(staff.get_by_role("button", name="Sound off")).to_be_visible()
        await staff.reload()
        await expect(staff.get_by_role("button", name="Sound off")).to_be_visible()
        await r.app.core.service.block("T7", "r1 could not reach T7", "r1")
        await expect(banner).to_contain_text("Robots cannot reach T7")
        await expect(staff.locator("#alert-badge")).to_have_text("2")
        assert await banner.get_attribute("data-chimes") is None  # none since the reload
        await c.ok("clear", table="T7")
        await expect(banner).not_to_contain_text("T7")
        await staff.get_by_role("tab", name="Send food").click()

        # The dish is changed while it waits: three of them, a note for the kitchen.
        await staff.get_by_role("button", name="Change Laksa for T5").click()
        dialog = staff.get_by_role("dialog", name="Change Laksa for T5")
        await dialog.get_by_label("Quantity").fill("3")
        await dialog.get_by_label("Note for the kitchen").fill("extra sambal")
        await dialog.get_by_role("button", name="Save").click()
        await expect(dialog).to_have_count(0)
        await expect(staff.get_by_role("row").filter(has_text="Laksa")).to_contain_text(
            f"Laksa {TIMES}3 (extra sambal)"
        )
        oid = made["order"]["id"]
        await c.until(lambda: c.order(oid)["quantity"] == 3, what="edited")
        assert c.order(oid)["note"] == "extra sambal"

        # Cleared: the table is served again, the alert is over, the dish can go.
        await blocked.get_by_role("button", name="Clear T5: robots may go there again").click()
        await expect(blocked).to_be_hidden()
        await expect(banner).to_be_hidden()
        await c.until(lambda: c.records["blocks"]["T5"]["reason"] == "", what="cleared")
        await expect(
            staff.get_by_role("button", name=f"Add to cart: Laksa {TIMES}3 (extra sambal) for T5")
        ).to_be_enabled()
        screens.assert_no_errors()


async def test_the_owner_edits_the_menu_new_order_offers(tmp_path: Path, browser: Any) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        await expect(staff.get_by_role("tab", name="Kitchen")).to_be_visible()
        await expect(staff.get_by_role("tab", name="Menu")).to_be_hidden()  # staff: no menu
        await staff.get_by_role("tab", name="New order").click()
        mains = staff.get_by_role("group", name="Mains")
        await expect(mains.get_by_role("button", name="Add Laksa")).to_be_visible()
        await expect(staff.get_by_role("button", name="Add Cendol")).to_be_visible()

        owner = await screens.open("/", online=False, token="")
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        await owner.get_by_role("tab", name="Menu").click()
        form = owner.get_by_role("form", name="Add or change a dish")
        await form.get_by_label("Dish name").fill("Mee goreng")
        await form.get_by_label("Category").fill("Mains")
        await form.get_by_label("Price").fill("8.50")
        await form.get_by_role("button", name="Save dish").click()
        await expect(owner.get_by_text("Mee goreng added to the menu")).to_be_visible()
        await expect(mains.get_by_role("button", name="Add Mee goreng")).to_be_visible()
        await c.until(lambda: "Mee goreng" in c.records["menu"], what="dish added")
        assert c.records["menu"]["Mee goreng"]["price_cents"] == 850

        # Cendol ran out: unticked, it leaves New order (and stays on the owner's menu).
        await owner.get_by_role("button", name="Change Cendol").click()
        await form.get_by_label("Available").uncheck()
        await form.get_by_role("button", name="Save dish").click()
        await expect(staff.get_by_role("button", name="Add Cendol")).to_have_count(0)
        await expect(
            owner.get_by_role("list", name="Menu").get_by_role("listitem").filter(has_text="Cendol")
        ).to_contain_text("not available")
        screens.assert_no_errors(re.compile("401|4001|Unauthorized", re.I))


async def test_action_buttons_are_disabled_while_the_connection_is_lost(
    tmp_path: Path, browser: Any
) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        cut = {"on": False}
        routes: list[Any] = []
        closing: list[asyncio.Future[Any]] = []

        def relay(ws: Any) -> None:
            if cut["on"]:
                closing.append(asyncio.ensure_future(ws.close()))
                return
            routes.append(ws)
            server = ws.connect_to_server()
            server.on_message(ws.send)
            ws.on_message(server.send)

        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/", ws_route=relay)
        auto = staff.get_by_role("button", name="Start delivering r1")
        await expect(auto).to_be_enabled()
        cut["on"] = True
        for ws in routes:
            await ws.close()
        await expect(staff.locator("body")).not_to_have_attribute("data-connection", "online")
        await expect(auto).to_be_disabled()
        await expect(auto).to_have_attribute("aria-disabled", "true")
        cut["on"] = False
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        await expect(auto).to_be_enabled()
        await auto.click()
        await c.status("r1", "Awaiting")
        screens.assert_no_errors(re.compile("WebSocket", re.I))
