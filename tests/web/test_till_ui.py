"""Orders straight from the restaurant's till (issue 33), in Chromium against the real server:
the owner opens serveur's printer port in the Restaurant tab's Till section on a phone (390 px
wide, a touch screen), the till prints three kitchen tickets of one layout to it over a real TCP
socket (ESC/POS made by python-escpos, as a till sends it), the owner shows serveur how to read
them on one ticket (the table line and which table, the ticket's number, a dish line), Propose
previews how the other two read, Save makes the waiting tickets orders; the Kitchen tab shows
them on one card per ticket and the cook starts one dish; a garbled job shows as it printed,
"not understood", and "Done by hand" closes it. The `tickets` topic streams only while the
Kitchen tab is shown.

Same harness as tests/web/test_modes_staff.py (Debian's /usr/bin/chromium driven by playwright,
a real server, the simulator and SQLite; no sleeps: every wait is on the page or the server's
state, with a timeout). Each new view is checked with axe-core.
"""

from __future__ import annotations

import asyncio
import functools
import re
import socket
from pathlib import Path
from typing import Any

from escpos.printer import Dummy

from serveur.core.engine import CoreConfig
from tests.conftest import Client, make_app, served_by
from tests.web.conftest import sideways, too_small
from tests.web.test_a11y import need_axe
from tests.web.test_modes_staff import PHONE, TABLET, TouchBrowser, no_violations, sent
from tests.web.test_service_ui import (
    SERVICE,
    TIMES,
    expect,
    pytestmark,  # noqa: F401
)
from tests.web.test_ui import Screens, http_base, log_in

till_app = functools.partial(make_app, config=CoreConfig(**SERVICE))  # type: ignore[arg-type]

#: The till's kitchen tickets: (number, table, guests, [(quantity, dish, notes)]).
TICKETS: list[tuple[int, int, int, list[Any]]] = [
    (1042, 12, 3, [(2, "Nasi Lemak", ["no chilli"]), (1, "Teh Tarik", [])]),
    (1043, 5, 2, [(1, "Laksa", []), (2, "Roti Canai Telur", ["extra curry"])]),
    (1044, 7, 4, [(3, "Satay", [])]),
]


def kitchen_ticket(number: int, table: int, guests: int, dishes: list[Any]) -> bytes:
    """One kitchen ticket as a till prints it: a large heading, the order's number, the table,
    the dishes with their notes indented under them, then the cut."""
    p = Dummy()
    p.set(align="center", double_height=True, double_width=True)
    p.text("KITCHEN\n")
    p.set(align="left", normal_textsize=True)
    p.text(f"Order #{number}\n")
    p.text(f"Table: {table}   Guests: {guests}\n")
    p.text("-" * 32 + "\n")
    for quantity, dish, notes in dishes:
        p.set(bold=True)
        p.text(f"{quantity} x {dish}\n")
        p.set(bold=False)
        for note in notes:
            p.text(f"   - {note}\n")
    p.text("-" * 32 + "\n")
    p.cut()
    return bytes(p.output)


def garbled_job() -> bytes:
    """A job nothing reads: a printer's test page, not a kitchen ticket."""
    p = Dummy()
    p.text("~~ PRINTER TEST ~~\n")
    p.text("#$%&'()*+,-./:;<=>?\n")
    p.text("ABCDEFGHIJKLMNOPQRSTUVWXYZ\n")
    p.cut()
    return bytes(p.output)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def print_job(port: int, job: bytes) -> None:
    """The till prints one job: it connects to the printer port, sends the bytes, hangs up."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(job)
    await writer.drain()
    writer.write_eof()
    await reader.read()  # the printer's side closes once it took the job
    writer.close()
    await writer.wait_closed()


def tickets(c: Client) -> dict[int, dict[str, Any]]:
    """The `tickets` topic as ``c`` saw it: each ticket's latest record, by id."""
    seen: dict[int, dict[str, Any]] = {}
    for frame in c.frames:
        if frame.get("servermsg") == "update" and frame.get("topic") == "tickets":
            seen[frame["data"]["id"]] = frame["data"]
        elif frame.get("servermsg") == "ok" and isinstance(frame.get("data"), dict):
            for ticket in frame["data"].get("tickets") or []:
                seen[ticket["id"]] = ticket
    return seen


def orders_of(c: Client, ticket: int) -> list[dict[str, Any]]:
    return [o for o in c.records.get("orders", {}).values() if o.get("ticket") == ticket]


async def phone_checks(page: Any, selector: str) -> None:
    """Nothing scrolls sideways on the phone, and every control of ``selector`` takes a finger."""
    width, inner = await sideways(page)
    assert width <= inner, (width, inner)
    assert await too_small(page, f"{selector} button, {selector} select, {selector} summary") == []


async def test_tickets_from_the_till_become_orders_on_the_kitchen_tab(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with served_by(tmp_path, till_app, "till ui tests") as r:
        c = await r.client()
        await c.subscribe("orders", "tickets", "till")
        screens = Screens(TouchBrowser(browser), http_base(r), "")
        owner = await screens.open("/", online=False, viewport=PHONE, bypass_csp=True)
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        await owner.get_by_role("tab", name="Restaurant").click()
        till = owner.locator("section.rest-till")
        await till.scroll_into_view_if_needed()
        state = owner.get_by_test_id("till-state")
        await expect(state).to_contain_text("Off: serveur takes no tickets from the till.")

        # The printer port, set on the phone: serveur is a second printer (no kitchen printer).
        port = free_port()
        await till.get_by_label("Printer port (0: off)").fill(str(port))
        await till.get_by_role("button", name="Save the printer").tap()
        await expect(state).to_contain_text(f"Taking tickets from the till on port {port}.")
        await expect(state).to_contain_text("serveur is a second printer")
        assert (await c.ok("till", action="state"))["till"]["port"] == port

        # The till prints three tickets, each its own job on its own connection.
        for number, table, guests, dishes in TICKETS:
            await print_job(port, kitchen_ticket(number, table, guests, dishes))
        await c.until(lambda: len(tickets(c)) == 3, what="three tickets kept")
        kept = sorted(tickets(c).values(), key=lambda x: x["id"])
        assert all(x["status"] == "unread" for x in kept), kept
        assert "Table: 12   Guests: 3" in kept[0]["lines"], kept[0]["lines"]
        assert not c.records.get("orders")  # nothing ordered before serveur can read them

        # The pattern, shown on the first ticket.
        await till.get_by_role("button", name="Look for new tickets").tap()
        listed = till.get_by_role("list", name="Tickets kept")
        await expect(listed.get_by_role("listitem")).to_have_count(3)
        await expect(listed.get_by_role("listitem").first).to_contain_text("Not understood")
        first = kept[0]
        await (
            listed.locator(f'[data-ticket="{first["id"]}"]')
            .get_by_role("button", name=re.compile(r"^Use this ticket"))
            .tap()
        )
        lines = till.locator("ol.till-lines")
        await expect(
            lines.get_by_role("button", name="Line 3: Table: 12 Guests: 3")
        ).to_be_visible()
        await phone_checks(owner, "section.rest-till")

        # The table line (by touch): it is the table T12.
        await lines.get_by_role("button", name="Line 3: Table: 12 Guests: 3").tap()
        kind = till.get_by_role("group", name="What is line 3?")
        await kind.get_by_label("The table").check()
        which = kind.get_by_label("Which table is it?")
        await expect(which).to_have_value("T12")  # the number the line holds first
        await which.select_option("T12")
        await kind.get_by_role("button", name="Done").tap()
        await expect(
            lines.get_by_role("button", name="Line 3: Table: 12 Guests: 3 — The table: T12")
        ).to_be_visible()
        # The ticket's number, by keyboard.
        await lines.get_by_role("button", name="Line 2: Order #1042").focus()
        await owner.keyboard.press("Enter")
        kind = till.get_by_role("group", name="What is line 2?")
        await kind.get_by_label("The ticket number").focus()
        await owner.keyboard.press("Space")
        await expect(kind.get_by_label("The ticket number")).to_be_checked()
        # One dish line.
        await lines.get_by_role("button", name="Line 5: 2 x Nasi Lemak").tap()
        await (
            till.get_by_role("group", name="What is line 5?")
            .get_by_label("A dish", exact=True)
            .check()
        )
        await expect(
            lines.get_by_role("button", name="Line 5: 2 x Nasi Lemak — A dish")
        ).to_be_visible()
        # The dashes under the last dish are no note of it.
        dashes = "-" * 32
        await lines.get_by_role("button", name=f"Line 8: {dashes}").tap()
        await (
            till.get_by_role("group", name="What is line 8?")
            .get_by_label("Ignore this line")
            .check()
        )
        await expect(
            lines.get_by_role("button", name=f"Line 8: {dashes} — Ignore this line")
        ).to_be_visible()
        await no_violations(owner)
        await phone_checks(owner, "section.rest-till")

        # Propose: this ticket as read, and every kept ticket previewed.
        await till.get_by_role("button", name="Propose").tap()
        await expect(till.get_by_test_id("till-reads")).to_have_text(
            f"This ticket reads: T12, ticket 1042: Nasi Lemak {TIMES}2 (no chilli), Teh Tarik"
        )
        preview = till.get_by_role("list", name="3 of 3 kept tickets understood")
        await expect(preview.get_by_role("listitem")).to_have_count(3)
        second, third = kept[1]["id"], kept[2]["id"]
        await expect(preview.locator(f'[data-ticket="{second}"]')).to_contain_text(
            f"T5, ticket 1043: Laksa, Roti Canai Telur {TIMES}2 (extra curry)"
        )
        await expect(preview.locator(f'[data-ticket="{third}"]')).to_contain_text(
            f"T7, ticket 1044: Satay {TIMES}3"
        )
        await no_violations(owner)
        # Save: the three waiting tickets become orders.
        await till.get_by_role("button", name="Save", exact=True).tap()
        await expect(till.get_by_role("status").filter(has_text="Saved")).to_have_text(
            "Saved: tickets are read this way from now on. 3 waiting tickets became orders."
        )
        await c.until(lambda: all(orders_of(c, x["id"]) for x in kept), what="orders made")
        assert sorted(
            (o["table"], o["dish"], o["quantity"], o.get("note") or "")
            for x in kept
            for o in orders_of(c, x["id"])
        ) == [  # as the menu spells each dish
            ("T12", "Nasi lemak", 2, "no chilli"),
            ("T12", "Teh tarik", 1, ""),
            ("T5", "Laksa", 1, ""),
            ("T5", "Roti Canai Telur", 2, "extra curry"),  # not on the menu
            ("T7", "Satay", 3, ""),
        ]
        assert (await c.ok("till", action="state"))["till"]["pattern"] is not None

        # The till's menu, imported as CSV: a name the menu spells alike is matched, one like a
        # dish comes with it to choose, one like none is left to pick from the whole menu.
        # A name the tickets printed that is not on the menu, with the dish it likely is.
        names = owner.get_by_role("group", name="The till's names for your dishes")
        unmapped = names.get_by_role("list", name="Names on tickets that are not on your menu")
        await expect(unmapped.get_by_role("listitem")).to_have_count(1)
        await expect(unmapped.locator('[data-till-name="Roti Canai Telur"]')).to_contain_text(
            "Which dish is it?"
        )
        await names.get_by_role("button", name="Match Roti Canai Telur to Roti canai").tap()
        await expect(unmapped).to_have_text("Every name the tickets printed is on your menu.")
        assert sent(screens, "till", action="map")[-1]["names"] == {
            "Roti Canai Telur": "Roti canai"
        }
        await names.get_by_label("The till's menu (CSV file)").set_input_files(
            files=[
                {
                    "name": "till-menu.csv",
                    "mimeType": "text/csv",
                    "buffer": b"till,price\nNASI LEMAK,12.50\nTeh Tarik Kurang Manis,3.00\n"
                    b"Iced Milo,4.00\n",
                }
            ]
        )
        await names.get_by_role("button", name="Import the till's menu").tap()
        imported = names.get_by_role("list", name="The till's menu")
        await expect(imported.get_by_role("listitem")).to_have_count(3)
        await expect(imported.locator('[data-till-name="NASI LEMAK"]')).to_contain_text(
            "is Nasi lemak"
        )
        await expect(imported.locator('[data-till-name="Iced Milo"]')).to_contain_text(
            "Not on your menu"
        )
        await no_violations(owner)
        await phone_checks(owner, "section.rest-till")
        await names.get_by_role("button", name="Match Teh Tarik Kurang Manis to Teh tarik").tap()
        await expect(imported.locator('[data-till-name="Teh Tarik Kurang Manis"]')).to_contain_text(
            "is Teh tarik"
        )
        assert sent(screens, "till", action="map")[-1]["names"] == {
            "Teh Tarik Kurang Manis": "Teh tarik"
        }
        # Any dish of the menu, for a name like none.
        await names.get_by_label("Another dish for Iced Milo").select_option("Cendol")
        await names.get_by_role("button", name="Match Iced Milo to the dish chosen").tap()
        await expect(imported.locator('[data-till-name="Iced Milo"]')).to_contain_text("is Cendol")

        # The owner's phone shows the tickets on its Kitchen tab too, nothing sideways.
        await owner.get_by_role("tab", name="Kitchen").tap()
        on_phone = owner.get_by_role("list", name="Tickets from the till, by ticket")
        await expect(on_phone.get_by_role("heading")).to_have_count(3)
        await phone_checks(owner, "#panel-kitchen")
        await no_violations(owner)

        # The kitchen's tablet: one card per ticket, oldest first; the cook starts a dish.
        kitchen_screens = Screens(browser, http_base(r), r.token)
        kitchen = await kitchen_screens.open("/", viewport=TABLET, bypass_csp=True)
        await kitchen.get_by_role("tab", name="Kitchen").click()
        cards = kitchen.get_by_role("list", name="Tickets from the till, by ticket")
        await expect(cards.get_by_role("heading")).to_have_text(
            ["T12 · ticket 1042", "T5 · ticket 1043", "T7 · ticket 1044"]
        )
        card = cards.locator(f'[data-ticket="{first["id"]}"]')
        await expect(card.get_by_role("listitem")).to_have_count(2)
        await expect(card).to_contain_text(f"Nasi lemak {TIMES}2 (no chilli)")
        # Dishes from the till are on their cards, not in the lists of staff's own orders.
        await expect(kitchen.get_by_role("list", name="To cook")).to_have_text("Nothing to start.")
        nasi = next(o for o in orders_of(c, first["id"]) if o["dish"] == "Nasi lemak")
        await card.get_by_role(
            "button", name=f"Start cooking Nasi lemak {TIMES}2 (no chilli) for T12"
        ).click()
        await c.until(lambda: c.order(nasi["id"]).get("status") == "cooking", what="cooking")
        await expect(
            card.get_by_role("button", name=re.compile("^Start cooking Nasi"))
        ).to_have_count(0)
        await expect(
            card.get_by_role("button", name=f"Ready: Nasi lemak {TIMES}2 (no chilli) for T12")
        ).to_be_visible()
        await no_violations(kitchen)

        # A garbled job: kept, not understood, shown as it printed on the Kitchen tab.
        await print_job(port, garbled_job())
        garbled = await c.until(
            lambda: next((x for x in tickets(c).values() if x["id"] > kept[-1]["id"]), None),
            what="the garbled job kept",
        )
        await c.until(lambda: tickets(c)[garbled["id"]]["status"] == "unread", what="unread")
        unread = kitchen.get_by_role("list", name="Tickets not understood")
        item = unread.locator(f'[data-ticket="{garbled["id"]}"]')
        await expect(item).to_contain_text(
            "Ticket not understood: add its dishes by hand, or fix the pattern"
        )
        await expect(item.locator("pre.ticket-printed")).to_contain_text("~~ PRINTER TEST ~~")
        await expect(item.locator("pre.ticket-printed")).to_contain_text(
            "ABCDEFGHIJKLMNOPQRSTUVWXYZ"
        )
        await no_violations(kitchen)
        # Its dishes by hand: New order opens.
        await item.get_by_role("button", name=re.compile(r"^Add a dish by hand")).click()
        await expect(kitchen.get_by_role("tab", name="New order")).to_have_attribute(
            "aria-selected", "true"
        )
        await expect(kitchen.get_by_label("Dish", exact=True)).to_be_focused()
        await kitchen.get_by_role("tab", name="Kitchen").click()
        await item.get_by_role("button", name=re.compile(r"^Done by hand")).click()
        await expect(item).to_have_count(0)
        await c.until(lambda: tickets(c)[garbled["id"]]["status"] == "by_hand", what="by hand")
        await expect(cards.get_by_role("heading")).to_have_count(3)  # the orders are unchanged
        # The tickets streamed to the kitchen's tablet only while its Kitchen tab was shown:
        # followed when it opened, left for New order, followed again on the way back.
        follows = [
            "off" if m.get("unsubscribe") else "on"
            for m in sent(kitchen_screens, "data")
            if "tickets" in m["topics"]
        ]
        assert follows == ["on", "off", "on"], follows

        screens.assert_no_errors()
        kitchen_screens.assert_no_errors()
