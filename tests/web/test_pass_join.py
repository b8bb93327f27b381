"""One more plate for the robot being loaded, from a waiter's phone in Chromium: a dish that
comes out while its table's trip is still at the pass (its robot Loading) goes on that trip, at
its table's stop, instead of making a trip of its own (``create task`` with ``task``,
docs/protocol.md); the pending list says so before the press and the toast after it. Once the
robot has left (Go), a dish for that table makes a new trip, also when the phone had not seen
it leave (the join refused as ``stale`` becomes an ordinary cart, without an error).

Same harness as tests/web/test_service_ui.py (robots wait at the pass for Go, as shipped); every
check of where a dish went is made on the server's state, not only on the page.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.conftest import Client
from tests.web.test_a11y import violations
from tests.web.test_service_ui import (
    activate,
    expect,
    pytestmark,  # noqa: F401
    service_restaurant,
    staff_client,
)
from tests.web.test_ui import Screens, http_base, lagging

PHONE = {"width": 390, "height": 844}


async def dish(c: Client, name: str, table: str) -> int:
    """A dish ready at the pass (pending), by its id."""
    return int((await c.ok("create", type="order", dish=name, table=table))["order"]["id"])


async def loading_for(c: Client, table: str) -> dict[str, Any]:
    """A trip for ``table`` given to r1, which waits at the pass, Loading, for Go."""
    first = await dish(c, "Laksa", table)
    [trip] = (await c.ok("create", type="task", orders=[first]))["tasks"]
    await c.until(
        lambda: (
            c.robot("r1").get("status") == "Loading"
            and c.robot("r1").get("current_task") == trip["id"]
        ),
        what="r1 loading the trip",
    )
    return trip


def creates(screens: Screens) -> list[dict[str, Any]]:
    """The `create task` requests the pages sent."""
    return [m for m in screens.sent if m.get("clientmsg") == "create" and m.get("type") == "task"]


def stop_of(c: Client, task_id: int, table: str) -> dict[str, Any]:
    return next(s for s in c.task(task_id).get("stops", []) if s["table"] == table)


async def test_a_dish_for_the_table_being_loaded_goes_on_its_trays_until_it_leaves(
    tmp_path: Path, browser: Any
) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        trip = await loading_for(c, "T3")
        tea = await dish(c, "Tea", "T3")
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/", viewport=PHONE, bypass_csp=True)  # axe is injected
        await page.get_by_role("tab", name="Send food").click()
        toasts = page.locator(".toast-text")

        def said(text: str) -> Any:
            return toasts.get_by_text(text, exact=True)

        # The row says where the dish goes before anyone presses.
        row = page.get_by_role("row").filter(has_text="Tea")
        await expect(row).to_contain_text("Goes on r1's trays (loading now)")
        await page.get_by_role("button", name="Send all ready: 1 dish for 1 table").click()
        await expect(said("Added to r1's trays: T3")).to_be_visible()
        # On r1's trip, at T3's stop, and no other trip made.
        await c.until(lambda: tea in stop_of(c, trip["id"], "T3")["orders"], what="Tea aboard")
        assert c.order(tea)["status"] == "assigned"
        assert c.order(tea)["task_id"] == trip["id"]
        assert set(c.records["tasks"]) == {trip["id"]}
        assert c.robot("r1")["status"] == "Loading"
        [join] = creates(screens)
        assert (join["task"], join["orders"]) == (trip["id"], [tea])
        loading = page.get_by_role("list", name="Loading at the pass")
        await expect(loading.get_by_role("list", name="Trays")).to_contain_text("Tea")

        # Two tables ready: T3's button says it adds to r1, T5's still sends; one press does both.
        rice = await dish(c, "Rice", "T3")
        soup = await dish(c, "Soup", "T5")
        add = page.get_by_role("button", name="Add T3 to r1 now: 1 dish on its trays")
        await expect(add).to_have_text("Add T3 to r1 (1)")
        await expect(page.get_by_role("button", name="Send T5's 1 dish now")).to_be_visible()
        await expect(page.get_by_role("row").filter(has_text="Soup")).not_to_contain_text("Goes on")
        assert await violations(page) == []
        await page.get_by_role("button", name="Send all ready: 2 dishes for 2 tables").click()
        await expect(said("Added to r1's trays: T3 · Sent: 1 trip (T5)")).to_be_visible()
        await c.until(lambda: c.order(soup).get("task_id") is not None, what="Soup sent")
        assert rice in stop_of(c, trip["id"], "T3")["orders"]
        assert c.order(rice)["task_id"] == trip["id"]
        [five] = set(c.records["tasks"]) - {trip["id"]}
        assert [s["table"] for s in c.task(five)["stops"]] == ["T5"]
        assert c.order(soup)["task_id"] == five

        # Go: r1 leaves with its trays. A dish for T3 now makes a trip of its own.
        await loading.get_by_role("button", name="Go r1").click()
        await c.until(lambda: c.robot("r1")["status"] != "Loading", what="r1 left")
        cake = await dish(c, "Cake", "T3")
        cake_row = page.get_by_role("row").filter(has_text="Cake")
        await expect(cake_row).to_be_visible()
        await expect(cake_row).not_to_contain_text("Goes on")
        await page.get_by_role("button", name="Send all ready: 1 dish for 1 table").click()
        await expect(said("Sent: 1 trip (T3)")).to_be_visible()
        await c.until(lambda: c.order(cake).get("task_id") is not None, what="Cake sent")
        [new] = set(c.records["tasks"]) - {trip["id"], five}
        assert c.order(cake)["task_id"] == new
        assert [s["table"] for s in c.task(new)["stops"]] == ["T3"]
        assert cake not in stop_of(c, trip["id"], "T3")["orders"]
        assert "task" not in creates(screens)[-1]
        screens.assert_no_errors()


async def test_a_robot_that_left_unseen_takes_no_more_the_dish_goes_on_a_new_trip(
    tmp_path: Path, browser: Any
) -> None:
    async with service_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await activate(c)
        trip = await loading_for(c, "T3")
        tea = await dish(c, "Tea", "T3")
        soup = await dish(c, "Soup", "T5")
        screens = Screens(browser, http_base(r), r.token)
        held = {"on": False}  # a lagging phone: the server's updates held back while "on"
        page = await screens.open("/", ws_route=lagging(held), viewport=PHONE)
        await page.get_by_role("tab", name="Send food").click()
        add = page.get_by_role("button", name="Add T3 to r1 now: 1 dish on its trays")
        await expect(add).to_have_text("Add T3 to r1 (1)")

        # Another tablet presses Go; this phone has not seen r1 leave and adds Tea to it.
        held["on"] = True
        await c.ok("go", robot="r1", task=trip["id"])
        await c.until(lambda: c.robot("r1")["status"] != "Loading", what="r1 left")
        await add.click()
        # Refused as stale, sent as a cart of its own instead: said as sent, no error shown.
        await expect(page.locator(".toast-text")).to_have_text(["Sent: 1 trip (T3)"])
        await expect(page.locator(".toast-error")).to_have_count(0)
        await c.until(lambda: c.order(tea).get("task_id") is not None, what="Tea sent")
        [new] = set(c.records["tasks"]) - {trip["id"]}
        assert c.order(tea)["task_id"] == new
        assert [s["table"] for s in c.task(new)["stops"]] == ["T3"]
        assert tea not in stop_of(c, trip["id"], "T3")["orders"]
        assert c.order(soup)["status"] == "pending"
        join, cart = creates(screens)
        assert (join["task"], join["orders"]) == (trip["id"], [tea])
        assert ("task" not in cart, cart["orders"]) == (True, [tea])
        held["on"] = False
        screens.assert_no_errors()
