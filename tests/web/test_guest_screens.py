"""The robot and table screens through a dinner service (issue 18), in Chromium, against the real
server and simulated robots, on a site as shipped: a trip waits at the pass (Loading) until
staff press Go (``auto_depart=False``).

The robot screen tells staff what goes on which tray for which table and sends the trip with
Go; at a table, the table's own screen says "your robot is here, take tray N" and its "Food
collected" completes the stop, while another table's screen cannot; a robot in Error asks for
staff in the guest's words and never shows its raw navigation error. Chinese and Malay render
the new words. Harness and rules as in tests/web/test_ui.py: Debian's /usr/bin/chromium, no
sleeps (playwright's ``expect`` and ``Client.until`` wait on the pages and the server).
"""

from __future__ import annotations

import contextlib
import functools
import re
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur.core.engine import CoreConfig
from tests.conftest import Client, Restaurant, make_app, served_by
from tests.test_e2e import activate
from tests.web.conftest import needs_browser
from tests.web.test_i18n import tr
from tests.web.test_ui import Screens, http_base

playwright_api = pytest.importorskip("playwright.async_api")
expect = playwright_api.expect

pytestmark = [needs_browser, pytest.mark.asyncio(loop_scope="module")]
expect.set_options(timeout=20_000)


#: test_ui's app (a heartbeat a loaded machine keeps) with trips waiting for Go.
service_app = functools.partial(
    make_app, config=CoreConfig(heartbeat=10.0, ack_timeout=5.0, auto_depart=False)
)


def service(tmp_path: Path) -> contextlib.AbstractAsyncContextManager[Restaurant]:
    """One simulated robot and a server whose trips are loaded at the pass, then sent."""
    return served_by(tmp_path, service_app, "guest screen tests")


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks")
    return c


async def device(r: Restaurant, role: str, **bound: str) -> Client:
    """A websocket client logged in with a screen's own token, as the page would be."""
    c = Client(await connect(r.app.url))
    r.clients.append(c)
    await c.ok("login", token=await r.app.issue_token(role, **bound))
    return c


async def loaded_trip(c: Client, *dishes: dict[str, Any]) -> dict[str, Any]:
    """Staff send these dishes to the pass and put them in one cart: r1 takes it (Loading)."""
    await activate(c, "r1")
    ids = [(await c.ok("create", type="order", **d))["order"]["id"] for d in dishes]
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    await c.status("r1", "Loading")
    await c.until(lambda: c.task(task["id"]).get("status") == "active", what="trip taken")
    return c.task(task["id"])


async def test_load_go_and_food_collected_at_the_table(tmp_path: Path, browser: Any) -> None:
    async with service(tmp_path) as r:
        c = await staff(r)
        screens = Screens(browser, http_base(r))
        robot = await screens.open(
            "/robot/r1", token=await r.app.issue_token("robot-screen", robot="r1")
        )
        # The two tables' own screens (T1's in Chinese), and a third table's.
        tables = {
            "T2": await screens.open(
                "/table/T2?lang=en", token=await r.app.issue_token("table-screen", table="T2")
            ),
            "T1": await screens.open(
                "/table/T1?lang=zh", token=await r.app.issue_token("table-screen", table="T1")
            ),
        }
        lang = {"T2": "en", "T1": "zh"}
        other = await screens.open(
            "/table/T9", token=await r.app.issue_token("table-screen", table="T9")
        )
        task = await loaded_trip(
            c,
            dict(dish="Laksa", table="T2", quantity=2, note="no chilli"),
            dict(dish="Satay", table="T1"),
        )
        first, second = task["stops"]  # visiting order: tray 1, then tray 2
        label = {"T2": "Laksa \N{MULTIPLICATION SIGN}2 — no chilli", "T1": "Satay"}

        # Loading: staff read what goes on which tray for which table, then press Go.
        await expect(robot.get_by_role("heading", name="Loading dishes")).to_be_visible()
        trays = robot.get_by_role("list", name="What goes on each tray")
        await expect(trays.locator(".tray-head")).to_have_text(
            [f"Tray 1 → {first['table']}", f"Tray 2 → {second['table']}"]
        )
        for n, stop in ((1, first), (2, second)):
            dishes = robot.get_by_role("list", name=f"Dishes on tray {n}")
            await expect(dishes).to_have_text(label[stop["table"]])
        await robot.screenshot(path=str(tmp_path / "robot-loading.png"))
        # Still at the pass: nothing moves before Go.
        assert c.robot("r1")["status"] == "Loading"
        await robot.get_by_role("button", name="Go", exact=True).click()
        await c.status("r1", "Delivering")
        gos = [m for m in screens.sent if m.get("clientmsg") == "go"]
        assert [(m["robot"], m["task"]) for m in gos] == [("r1", task["id"])]

        for n, stop in ((1, first), (2, second)):
            here, code = tables[stop["table"]], lang[stop["table"]]
            await c.until(
                lambda s=stop: c.task(task["id"])["stops"][s["seq"]]["status"] == "arrived",
                what=f"at {stop['table']}",
            )
            # The table's screen: the robot is here, which tray, its dishes, Food collected.
            panel = here.locator(".here")
            await expect(panel.get_by_role("heading")).to_have_text(tr(code, "guest.table.here"))
            await expect(panel.locator(".take-tray")).to_have_text(
                tr(code, "guest.takeTray", tray=n)
            )
            await expect(
                panel.get_by_role("list", name=tr(code, "guest.trayDishes", tray=n))
            ).to_have_text(label[stop["table"]])
            # The robot's screen names the same tray.
            await expect(robot.locator(".take-tray")).to_have_text(f"Please take tray {n}")
            await expect(robot.get_by_role("list", name="Your dishes")).to_have_text(
                label[stop["table"]]
            )
            # Another table's screen gets no such button, and the server refuses it anyway.
            await expect(other.locator(".here")).to_have_count(0)
            await expect(other.get_by_role("button", name="Food collected")).to_have_count(0)
            intruder = await device(r, "table-screen", table="T9")
            await intruder.error("next", "forbidden", robot="r1", task=task["id"], stop=n - 1)
            if n == 1:
                await here.screenshot(path=str(tmp_path / "table-here.png"))
                await robot.screenshot(path=str(tmp_path / "robot-at-table.png"))

            await panel.get_by_role("button", name=tr(code, "robot.collected")).click()
            await c.until(
                lambda s=stop: c.task(task["id"])["stops"][s["seq"]]["status"] == "done",
                what=f"{stop['table']} served",
            )
            [oid] = stop["orders"]
            await c.until(lambda o=oid: c.order(o).get("status") == "delivered")
            await expect(here.locator(".here")).to_have_count(0)
            await expect(here.get_by_text(tr(code, "guest.table.enjoy"))).to_be_visible()
            served = here.get_by_role("list", name=tr(code, "table.served"))
            await expect(served).to_have_text(label[stop["table"]])
            await expect(
                here.get_by_role("list", name=tr(code, "table.coming"), exact=True)
            ).to_have_text(tr(code, "table.comingEmpty"))

        # Both stops done: the robot goes home; the nexts were the tables' own.
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        nexts = [m for m in screens.sent if m.get("clientmsg") == "next"]
        assert [(m["task"], m["stop"]) for m in nexts] == [(task["id"], 0), (task["id"], 1)]
        screens.assert_no_errors()


async def test_a_stuck_robot_asks_for_staff_in_the_guests_words(
    tmp_path: Path, browser: Any
) -> None:
    async with service(tmp_path) as r:
        c = await staff(r)
        screens = Screens(browser, http_base(r))
        robot = await screens.open(
            "/robot/r1?lang=ms", token=await r.app.issue_token("robot-screen", robot="r1")
        )
        task = await loaded_trip(c, dict(dish="Teh tarik", table="T12", note="kurang manis"))
        # Malay at the pass: the tray and its table, the dish with its note, and Go.
        await expect(robot.locator(".tray-head")).to_have_text(
            tr("ms", "guest.robot.trayTo", tray=1, table="T12")
        )
        await expect(
            robot.get_by_role("list", name=tr("ms", "guest.trayDishes", tray=1))
        ).to_have_text("Teh tarik — kurang manis")
        await expect(robot.get_by_text(tr("ms", "guest.robot.goHint"))).to_be_visible()

        r.sim.robots[0].block_path(True)  # the aisle to T12 is blocked: the goal aborts
        await robot.get_by_role("button", name=tr("ms", "guest.robot.go"), exact=True).click()
        err = await c.status("r1", "Error")
        assert err["last_error"], err
        await expect(robot.get_by_text(tr("ms", "guest.robot.needHelp"))).to_be_visible()
        await expect(robot.get_by_role("heading", level=1)).to_have_text(tr("ms", "robot.stuck"))
        # No big button invites a guest: the ways out are staff's, small and set apart.
        await expect(robot.locator("button.big")).to_have_count(0)
        for_staff = robot.get_by_role("group", name=tr("ms", "guest.robot.forStaff"))
        await expect(for_staff.get_by_role("button")).to_have_text(
            [tr("ms", key) for key in ("robot.continue", "robot.cancel", "guest.robot.skip")]
        )
        # The robot's own words never reach the guest.
        text = await robot.locator("body").inner_text()
        assert err["last_error"] not in text and "ABORTED" not in text.upper(), text
        assert not re.search(r"move_base|no path", text, re.I), text
        await robot.screenshot(path=str(tmp_path / "robot-error.png"))
        # Staff logged in on a robot screen do read the cause, below the guests' words.
        staffed = await screens.open("/robot/r1?lang=en", token=r.token)
        await expect(
            staffed.get_by_text("I need help from the staff — please wait")
        ).to_be_visible()
        # In staff's words; the robot's own under "For the technician", opened on demand.
        detail = staffed.locator(".detail")
        await expect(detail).to_contain_text("Could not get to T12: check nothing blocks the way")
        await expect(detail).not_to_contain_text(err["last_error"], use_inner_text=True)
        await detail.get_by_text("For the technician").click()
        await expect(detail).to_contain_text(err["last_error"], use_inner_text=True)

        # Staff leave the table from the screen: Skip asks first, the dish goes back to the pass.
        r.sim.robots[0].block_path(False)
        await for_staff.get_by_role("button", name=tr("ms", "guest.robot.skip")).click()
        dialog = robot.get_by_role("dialog", name=tr("ms", "guest.robot.skipQuestion", table="T12"))
        await dialog.get_by_role("button", name=tr("ms", "guest.robot.skipYes")).click()
        [oid] = task["stops"][0]["orders"]
        await c.until(lambda: c.order(oid).get("status") == "returned", what="dish returned")
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        skips = [m for m in screens.sent if m.get("clientmsg") == "skip"]
        assert [(m["task"], m["stop"]) for m in skips] == [(task["id"], 0)]
        screens.assert_no_errors()


async def test_guest_screens_speak_the_sites_language(tmp_path: Path, browser: Any) -> None:
    """The owner's settings choose the languages offered and the one a screen with no choice of
    its own starts in: a new table screen and a robot screen open in Malay and offer only
    Malay and English; a screen told ?lang=en keeps English."""
    async with service(tmp_path) as r:
        owner = Client(await connect(r.app.url))
        r.clients.append(owner)
        await owner.ok("login", username="owner", password=r.app.first_owner_password)
        await owner.ok("site", action="set_settings", languages=["ms", "en"], language="ms")
        screens = Screens(browser, http_base(r))
        table = await screens.open(
            "/table/T3", token=await r.app.issue_token("table-screen", table="T3")
        )
        robot = await screens.open(
            "/robot/r1", token=await r.app.issue_token("robot-screen", robot="r1")
        )
        told = await screens.open(
            "/table/T4?lang=en", token=await r.app.issue_token("table-screen", table="T4")
        )
        for page in (table, robot):
            await expect(page.locator("html")).to_have_attribute("data-site-langs", "ms en")
            await expect(page.locator("html")).to_have_attribute("lang", "ms")
            options = page.locator("#lang-picker option")
            await expect(options).to_have_count(2)
            assert sorted(await options.evaluate_all("os => os.map(o => o.value)")) == ["en", "ms"]
        await expect(told.locator("html")).to_have_attribute("data-site-langs", "ms en")
        await expect(told.locator("html")).to_have_attribute("lang", "en")
        screens.assert_no_errors()
