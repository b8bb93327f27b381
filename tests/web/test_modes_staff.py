"""The console for what robots do besides delivering (issue 32), in Chromium on a phone (390x844)
and a tablet (1024x768): guests' calls (listed, rung, counted on their tab, escalated, answered),
a robot sent for the used plates and worded by its stops, a dish put on the tray staff chose,
a birthday dish with its message, a robot sent to charge and back to work, a cruise and back to
deliveries, and the owner's Wi-Fi call buttons, places, docks and settings.

Same harness as tests/web/test_service_ui.py (Debian's /usr/bin/chromium driven by playwright, a
real server, the simulator and SQLite; no sleeps: every wait is on the page or the server's
state, with a timeout). Every check of what happened is made on the server's state too, and
each new panel is checked with axe-core.
"""

from __future__ import annotations

import contextlib
import functools
import re
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from serveur.core.engine import CoreConfig
from tests.conftest import Client, Restaurant, make_app, served_by
from tests.web.test_a11y import need_axe, violations
from tests.web.test_service_ui import (
    SERVICE,
    activate,
    expect,
    pytestmark,  # noqa: F401
)
from tests.web.test_ui import Screens, http_base, log_in

PHONE = {"width": 390, "height": 844}
TABLET = {"width": 1024, "height": 768}
DISH_RETURN = {"name": "dish return", "x": 9.0, "y": 10.8, "kind": "dish_return"}
DOCK = {"name": "dock1", "x": 5.0, "y": 10.8, "kind": "dock"}  # home2's spot: free floor


class TouchBrowser:
    """The browser, its windows made with a touch screen (a phone): `tap` works there."""

    def __init__(self, browser: Any) -> None:
        self.browser = browser

    async def new_context(self, **options: Any) -> Any:
        return await self.browser.new_context(has_touch=True, **options)


def modes_restaurant(
    tmp_path: Path, **config: Any
) -> contextlib.AbstractAsyncContextManager[Restaurant]:
    """test_service_ui's restaurant (robots wait at the pass for Go) with ``config`` on top."""
    made = functools.partial(make_app, config=CoreConfig(**{**SERVICE, **config}))
    return served_by(tmp_path, made, "modes ui tests")


async def staff_client(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "alerts", "calls", "waypoints", "settings")
    return c


async def table_screen(r: Restaurant, table: str) -> Client:
    """A second websocket client: the table's own screen, on its device token."""
    token = await r.app.issue_token("table-screen", table=table, label=f"{table} screen")
    c = Client(await connect(r.app.url, additional_headers={"Authorization": f"Bearer {token}"}))
    r.clients.append(c)
    return c


def calls(c: Client) -> dict[int, dict[str, Any]]:
    return c.records.get("calls", {})


def sent(screens: Screens, verb: str, **fields: Any) -> list[dict[str, Any]]:
    """The messages the pages sent with this verb (and these fields)."""
    return [
        m
        for m in screens.sent
        if m.get("clientmsg") == verb and all(m.get(k) == v for k, v in fields.items())
    ]


async def no_violations(page: Any) -> None:
    found = await violations(page)
    assert found == [], found


async def test_a_table_call_rings_shows_on_its_tab_and_answer_closes_it(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE, bypass_csp=True)
        tab = page.get_by_role("tab", name="Calls")
        count = page.get_by_test_id("calls-count")
        await expect(count).to_be_hidden()
        # A waiter is on another tab (a touch there lets the page make sound).
        await page.get_by_role("tab", name="Send food").click()

        t3 = await table_screen(r, "T3")
        await t3.subscribe("calls")
        first = (await t3.ok("call", action="open", table="T3", kind="waiter"))["call"]
        # Seen from the other tab: the Calls tab counts it.
        await expect(count).to_be_visible()
        await expect(count.locator(".tab-count-n")).to_have_text("1")
        await expect(tab).to_have_accessible_name(re.compile(r"^Calls\s+1 call waiting$"))
        await tab.click()
        listed = page.get_by_role("list", name="Calls from the tables")
        row = listed.get_by_role("listitem").filter(has_text="T3")
        await expect(row).to_contain_text("Waiter")
        await expect(row).to_contain_text("from the table's screen")
        await expect(row.locator(".call-ago")).to_have_text(re.compile(r"^\d+ (s|min)"))
        # It rang once.
        await expect(listed).to_have_attribute("data-chimes", "1")

        # Pressed again at the table: one call, pressed twice; no second ring.
        again = await t3.ok("call", action="open", table="T3", kind="waiter")
        assert again["merged"] is True
        await expect(row).to_contain_text("pressed 2 times")
        assert await listed.get_attribute("data-chimes") == "1"
        # A second table's bill: a new call, a new ring, counted.
        bill = (await c.ok("call", action="open", table="T5", kind="bill"))["call"]
        await expect(tab).to_have_accessible_name(re.compile(r"^Calls\s+2 calls waiting$"))
        await expect(listed).to_have_attribute("data-chimes", "2")
        await expect(listed.get_by_role("listitem")).to_have_count(2)
        await no_violations(page)

        # Answer: gone from the list, answered on the server (and on the table's screen).
        await page.get_by_role("button", name="Answer: T3 wants a waiter").click()
        await expect(row).to_have_count(0)
        await c.until(lambda: calls(c)[first["id"]].get("answered_at") is not None, what="answered")
        await t3.until(lambda: calls(t3).get(first["id"], {}).get("answered_at") is not None)
        await expect(count.locator(".tab-count-n")).to_have_text("1")
        # Cancel the other: the list is empty, the count gone.
        await page.get_by_role("button", name="Cancel the call: T5 wants the bill").click()
        await c.until(lambda: calls(c)[bill["id"]].get("cancelled_at") is not None, what="cancel")
        await expect(listed).to_contain_text("No calls: every table is looked after.")
        await expect(count).to_be_hidden()
        assert [m["call"] for m in sent(screens, "call")] == [first["id"], bill["id"]]
        screens.assert_no_errors()


async def test_a_call_nobody_answers_is_escalated_on_the_console(
    tmp_path: Path, browser: Any
) -> None:
    async with modes_restaurant(tmp_path, call_escalate=15.0) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=TABLET)
        await page.get_by_role("tab", name="Calls").click()
        opened = (await c.ok("call", action="open", table="T2", kind="bill"))["call"]
        listed = page.get_by_role("list", name="Calls from the tables")
        row = listed.get_by_role("listitem").filter(has_text="T2")
        await expect(row).to_contain_text("Bill")
        # 15 s of the server's time later (the sim's time runs faster): escalated.
        await c.until(lambda: calls(c)[opened["id"]].get("escalated_at") is not None, what="esc")
        await expect(row).to_contain_text("Waiting long")
        await expect(row).to_have_class(re.compile(r"\bescalated\b"))
        await expect(page.get_by_test_id("calls-count")).to_have_class(re.compile(r"\burgent\b"))
        # A newer call comes after it: the one waiting long stays first.
        await c.ok("call", action="open", table="T9", kind="waiter")
        await expect(listed.get_by_role("listitem")).to_have_count(2)
        await expect(listed.get_by_role("listitem").first).to_contain_text("T2")
        # The alert reads as what the table asked for, and rings as an urgent one.
        banner = page.get_by_role("region", name="Alerts")
        await expect(banner).to_contain_text("T2 asked for the bill and nobody has come")
        await expect(banner).to_contain_text("Go to the table, then press Answer in Calls.")
        await expect(banner).not_to_contain_text("T2/bill")
        await expect(banner).to_have_attribute("data-chimes", "1")
        await row.get_by_role("button", name="Answer: T2 wants the bill").click()
        await expect(banner).not_to_contain_text("T2 asked")
        screens.assert_no_errors()


async def test_staff_send_a_robot_for_plates_and_its_row_says_what_it_does(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes_restaurant(tmp_path, bussing_wait=600.0) as r:
        c = await staff_client(r)
        await activate(c)
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE, bypass_csp=True)
        send = page.get_by_role("button", name="Send a robot for plates")

        # No dish return yet: the form says so, and the server's refusal is in words.
        await send.click()
        dialog = page.get_by_role("dialog", name="Send a robot for the used plates")
        await expect(dialog.get_by_test_id("no-dish-return")).to_be_visible()
        await dialog.get_by_role("button", name="Table T3").click()
        await expect(dialog.get_by_role("button", name="Table T3")).to_have_attribute(
            "aria-pressed", "true"
        )
        await no_violations(page)
        await dialog.get_by_role("button", name="Send the robot").click()
        await expect(dialog.get_by_role("alert")).to_have_text(
            re.compile(r"^Add a dish return place first")
        )
        await dialog.get_by_role("button", name="Cancel").click()
        await expect(dialog).to_have_count(0)

        await c.ok("create", type="waypoint", **DISH_RETURN)
        await send.click()
        await dialog.get_by_role("button", name="Table T3").click()
        await dialog.get_by_role("button", name="Send the robot").click()
        await expect(dialog).to_have_count(0)
        [task] = await c.until(
            lambda: [t for t in c.records.get("tasks", {}).values() if t.get("kind") == "bussing"],
            what="a bussing trip",
        )
        assert [(s["table"], s["purpose"]) for s in task["stops"]] == [
            ("T3", "collect"),
            ("dish return", "unload"),
        ]
        refused, create = sent(screens, "create", type="bussing")
        assert refused["tables"] == create["tables"] == ["T3"]

        # The robot's row words the trip by its stops; never "At the table" or "Delivered".
        row = page.locator("#robots > li").filter(has_text="r1")
        badge = row.locator(".status-badge")
        await c.status("r1", "Delivered", timeout=60)
        await expect(row.locator(".trip")).to_have_text("Taking plates from T3")
        await expect(badge).to_have_text("Taking plates")
        done = row.get_by_role("button", name="Plates on: go on r1")
        await expect(done).to_be_visible()
        await no_violations(page)
        await done.click()
        await c.until(lambda: c.task(task["id"])["current_stop"] == 1, what="on to the return")
        await c.status("r1", "Delivered", timeout=60)
        await expect(row.locator(".trip")).to_contain_text("At the dish return")
        await expect(badge).to_have_text("At the dish return")
        for shown in (await row.inner_text(), await badge.inner_text()):
            assert "Delivered" not in shown and "At the table" not in shown, shown
        await row.get_by_role("button", name="Emptied r1").click()
        await c.until(lambda: c.task(task["id"])["status"] == "done", what="trip done")
        await expect(badge).to_have_text(re.compile(r"^(Going home|Free)$"))
        nexts = sent(screens, "next", robot="r1")
        assert [m["stop"] for m in nexts] == [0, 1] and {m["task"] for m in nexts} == {task["id"]}

        # A table asks for its plates: its call says a robot is on its way, and the robot
        # answers it when it reaches the table.
        await page.get_by_role("tab", name="Calls").click()
        t6 = await table_screen(r, "T6")
        call = (await t6.ok("call", action="open", table="T6", kind="plates"))["call"]
        assert call["task_id"] is not None
        listed = page.get_by_role("list", name="Calls from the tables")
        plates = listed.get_by_role("listitem").filter(has_text="T6")
        await expect(plates).to_contain_text("Plates")
        await expect(plates).to_contain_text("r1 is on its way for the plates")
        await c.until(
            lambda: calls(c)[call["id"]].get("answered_by") == "robot:r1", what="r1 answered"
        )
        await expect(plates).to_have_count(0)
        screens.assert_no_errors()


async def test_a_dish_put_on_tray_2_leaves_on_tray_2(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        laksa = (await c.ok("create", type="order", dish="Laksa", table="T3"))["order"]["id"]
        tea = (await c.ok("create", type="order", dish="Tea", table="T5"))["order"]["id"]
        screens = Screens(TouchBrowser(browser), http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE, bypass_csp=True)
        await page.get_by_role("tab", name="Send food").click()
        await page.get_by_role("button", name="Add to cart: Laksa for T3").click()
        await page.get_by_role("button", name="Add to cart: Tea for T5").click()
        cart = page.get_by_role("list", name="Cart")
        dish = cart.get_by_role("button", name=re.compile(r"^Laksa"))
        await expect(dish).to_contain_text("tray: automatic")

        # Tap the dish, then a tray number.
        await dish.tap()
        bar = page.get_by_role("group", name="Put Laksa (T3) on tray")
        trays = c.streams["settings"]["trays"]  # the site's: one button each, and Automatic
        await expect(bar.get_by_role("button")).to_have_count(trays + 1)
        await no_violations(page)
        await bar.get_by_role("button", name="Tray 2", exact=True).tap()
        await expect(bar).to_be_hidden()
        await expect(dish).to_contain_text("tray 2")
        await expect(cart.get_by_role("button", name=re.compile(r"^Tea"))).to_contain_text(
            "tray: automatic"
        )
        await page.get_by_role("button", name=re.compile(r"^Send 2 dishes")).tap()
        await expect(
            page.get_by_text(re.compile(r"^Sent: 1 trip \((T3, T5|T5, T3)\)$"))
        ).to_be_visible()

        # Sent with the tray chosen; one trip; the server put Laksa on tray 2.
        [create] = sent(screens, "create", type="task")
        assert create["trays"] == [{"order": laksa, "tray": 2}], create
        assert sorted(create["orders"]) == sorted([laksa, tea])
        await c.until(lambda: c.order(laksa).get("task_id") is not None, what="sent")
        assert c.order(laksa)["tray"] == 2 and c.order(tea)["tray"] is None
        assert c.order(laksa)["task_id"] == c.order(tea)["task_id"]
        trip = c.task(c.order(laksa)["task_id"])
        assert {s["table"] for s in trip["stops"]} == {"T3", "T5"}
        # Loading at the pass: the trays as staff put them.
        await c.status("r1", "Loading")
        trays = page.get_by_role("list", name="Loading at the pass").get_by_role(
            "list", name="Trays"
        )
        await expect(trays.locator('[data-tray="2"]')).to_contain_text("Laksa")
        screens.assert_no_errors()


async def test_a_birthday_dish_is_ordered_with_its_message(tmp_path: Path, browser: Any) -> None:
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=TABLET)
        await page.get_by_role("tab", name="New order").click()
        await page.get_by_role("button", name="Table T4").click()
        await page.get_by_role("button", name="Add Cendol").click()
        special = page.get_by_role(
            "checkbox", name=re.compile(r"^Special \(birthday\)\s*: Cendol for T4$")
        )
        await special.check()
        message = page.get_by_role("textbox", name="Message the robot shows with Cendol at T4")
        await expect(message).to_be_focused()
        # Ticked without a message: not sent, said so.
        await message.fill("")
        await page.get_by_role("button", name="Send to the kitchen").click()
        await expect(page.get_by_role("alert").filter(has_text="Write the message")).to_be_visible()
        assert sent(screens, "create", type="order") == []
        assert await message.get_attribute("maxlength") == "120"
        await message.fill("Happy birthday Ana!")
        await page.get_by_role("button", name="Send to the kitchen").click()
        await expect(page.get_by_text("Sent to the kitchen: Cendol (T4)")).to_be_visible()
        [create] = sent(screens, "create", type="order")
        assert create["special"] == "Happy birthday Ana!"
        [order] = await c.until(
            lambda: [o for o in c.records.get("orders", {}).values() if o["dish"] == "Cendol"]
        )
        assert order["special"] == "Happy birthday Ana!" and order["table"] == "T4"
        await page.get_by_role("tab", name="Kitchen").click()
        await expect(page.get_by_text("Cendol (birthday)")).to_be_visible()
        screens.assert_no_errors()


async def test_the_owner_gives_r1_a_dock_staff_send_it_to_charge_and_back(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        r.sim.robots[0].battery = 0.5  # above charge_below, below charge_until: it stays docked
        await c.ok("create", type="waypoint", **DOCK)
        screens = Screens(browser, http_base(r))
        owner = await screens.open("/", online=False, token="", viewport=TABLET, bypass_csp=True)
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        row = owner.locator("#robots > li").filter(has_text="r1")
        await expect(row.get_by_role("button", name="Pause deliveries r1")).to_be_visible()
        await expect(row.get_by_role("button", name="Charge r1")).to_have_count(0)  # no dock yet

        # The owner chooses r1's charger in the Restaurant tab.
        await owner.get_by_role("tab", name="Restaurant").click()
        await owner.get_by_role("button", name="Edit r1").click()
        dialog = owner.get_by_role("dialog", name="Edit robot r1")
        await dialog.get_by_label("Charger (dock)").select_option("dock1")
        await dialog.get_by_role("button", name="Save").click()
        await expect(dialog).to_have_count(0)
        await c.until(lambda: c.robot("r1").get("dock") == "dock1", what="r1's dock")
        places = owner.get_by_role("list", name="Tables and places")
        await expect(places.locator('[data-waypoint="dock1"]')).to_contain_text("charger (dock)")
        await expect(owner.locator('[data-robot="r1"]').first).to_contain_text("dock1")
        await no_violations(owner)

        # Charge: to the dock, Charging there, its battery shown.
        await owner.get_by_role("tab", name="Map & robots").click()
        await row.get_by_role("button", name="Charge r1").click()
        await c.status("r1", "Charging", timeout=60)
        await expect(row.locator(".status-badge")).to_have_text("Charging")
        await expect(row.locator(".trip")).to_have_text("On its charger (dock1)")
        await expect(row.locator(".battery")).to_have_text(re.compile(r"^battery \d+ %$"))
        back = row.get_by_role("button", name="Back to work r1")
        await expect(
            row.get_by_role("group", name="Actions for r1").get_by_role("button")
        ).to_have_text(["Back to work", "Take control"])
        await no_violations(owner)
        await back.click()
        await c.status("r1", "Awaiting", timeout=60)
        await expect(row.get_by_role("button", name="Charge r1")).to_be_visible()
        assert [m["clientmsg"] for m in screens.sent if m.get("robot") == "r1"][-2:] == [
            "charge",
            "work",
        ]
        screens.assert_no_errors()


async def test_a_cruise_round_and_back_to_deliveries(tmp_path: Path, browser: Any) -> None:
    async with modes_restaurant(tmp_path, cruise_pause=600.0) as r:
        c = await staff_client(r)
        await activate(c)
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE)
        row = page.locator("#robots > li").filter(has_text="r1")
        await row.get_by_role("button", name="Cruise… r1").click()
        dialog = page.get_by_role("dialog", name="Send r1 cruising")
        await dialog.get_by_role("button", name="pass", exact=True).click()
        await dialog.get_by_role("button", name="T2", exact=True).click()
        await expect(dialog.locator("output")).to_have_text("pass → T2")
        await dialog.get_by_role("button", name="Start cruising").click()
        await expect(dialog).to_have_count(0)
        [cruise] = sent(screens, "cruise", robot="r1")
        assert cruise["route"] == ["pass", "T2"]
        await expect(row.locator(".trip")).to_contain_text("pass → T2")
        # Paused at a place of its round (a long pause): worded as cruising, not "At the table".
        await c.status("r1", "Delivered", timeout=60)
        await expect(row.locator(".trip")).to_have_text("Cruising, at pass: pass → T2")
        await expect(row.locator(".status-badge")).to_have_text("Cruising, at a stop")
        await row.get_by_role("button", name="Back to deliveries r1").click()
        await expect(page.get_by_text("r1 is back on deliveries")).to_be_visible()
        await c.until(lambda: c.robot("r1").get("current_task") is None, what="cruise over")
        assert [m["clientmsg"] for m in screens.sent if m.get("robot") == "r1"][-3:] == [
            "next",
            "stop",
            "cancel",
        ]
        await c.status("r1", "Awaiting", timeout=60)
        await expect(row.locator(".status-badge")).to_have_text("Free")
        screens.assert_no_errors()


async def test_the_owner_adds_a_wifi_button_whose_address_calls_then_revokes_it(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r))
        owner = await screens.open("/", online=False, token="", viewport=TABLET, bypass_csp=True)
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        await owner.get_by_role("tab", name="Restaurant").click()
        form = owner.get_by_role("form", name="Add a call button")
        await form.get_by_label("Button name").fill("T7 bill")
        await form.get_by_label("Table").select_option("T7")
        await form.get_by_label("A press asks for").select_option("bill")
        await form.get_by_role("button", name="Add button").click()
        made = owner.get_by_test_id("button-made")
        await expect(made).to_be_visible()
        await expect(made).to_contain_text("it is shown only this once")
        url = await made.get_by_label("Address the button opens").input_value()
        assert url.startswith(http_base(r) + "/call/srb_"), url
        await made.get_by_text("How to set up a Shelly, Tasmota or ESPHome button").click()
        await expect(made).to_contain_text(f"WebQuery {url} GET")
        await expect(made.get_by_role("button", name="Copy")).to_be_visible()
        await no_violations(owner)

        # The address works: a plain GET opens a call for T7's bill.
        status, body, _ = await r.get(url.removeprefix(http_base(r)))
        assert status == 200 and body.startswith(b"called: bill at T7"), body
        [call] = await c.until(lambda: [x for x in calls(c).values() if x["table"] == "T7"])
        assert call["source"] == "button:T7 bill"
        # Shown once: gone with Done; the list says the button and its table.
        await made.get_by_role("button", name="Done").click()
        await expect(made).to_be_hidden()
        listed = owner.get_by_role("list", name="Call buttons")
        item = listed.locator('[data-button="T7 bill"]')
        await expect(item).to_contain_text("T7: Bill")

        # Revoked: asked first, then its address answers 404.
        await item.get_by_role("button", name="Revoke T7 bill").click()
        confirm = owner.get_by_role("dialog", name="Revoke button T7 bill?")
        await confirm.get_by_role("button", name="Revoke", exact=True).click()
        await expect(item).to_contain_text("revoked")
        status, _, _ = await r.get(url.removeprefix(http_base(r)))
        assert status == 404
        screens.assert_no_errors()


async def test_the_owner_adds_a_dish_return_and_sets_the_new_settings(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        screens = Screens(browser, http_base(r))
        owner = await screens.open("/", online=False, token="", viewport=PHONE, bypass_csp=True)
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        await owner.get_by_role("tab", name="Restaurant").click()

        # A dish return where r1 stands.
        await owner.get_by_role("button", name="Add a place").click()
        dialog = owner.get_by_role("dialog", name="Add a place where a robot stands")
        await dialog.get_by_label("Name").fill("sink")
        await expect(dialog.get_by_label("Kind")).to_have_value("dish_return")
        await dialog.get_by_role("button", name="Add a place").click()
        await expect(dialog).to_have_count(0)
        await c.until(lambda: c.records["waypoints"].get("sink", {}).get("kind") == "dish_return")
        places = owner.get_by_role("list", name="Tables and places")
        await expect(places.locator('[data-waypoint="sink"]')).to_contain_text("dish return")

        # The settings of calls, plates, charging and cruising, in words and percentages.
        settings = owner.get_by_role("form", name="Restaurant settings")
        await expect(settings.get_by_label("Go and charge below (%)")).to_have_value("25")
        await settings.get_by_label("Urgent after (seconds)").fill("60")
        await settings.get_by_label("Wait at a table for plates (seconds)").fill("90")
        await settings.get_by_label("Go and charge below (%)").fill("30")
        await settings.get_by_label("Back to work at (%)").fill("20")
        await no_violations(owner)
        await settings.get_by_role("button", name="Save settings").click()
        # Back to work below the charge level: refused by the form itself, nothing sent.
        assert sent(screens, "site", action="set_settings") == []
        await settings.get_by_label("Back to work at (%)").fill("95")
        await settings.get_by_role("button", name="Save settings").click()
        await expect(owner.get_by_text("Settings saved: they apply now")).to_be_visible()
        await c.until(lambda: (c.streams.get("settings") or {}).get("charge_until") == 0.95)
        s = c.streams["settings"]
        assert (s["call_escalate"], s["bussing_wait"], s["charge_below"]) == (60, 90, 0.3), s
        screens.assert_no_errors()
