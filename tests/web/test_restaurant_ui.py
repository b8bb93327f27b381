"""The owner's Restaurant and Activity tabs, end to end in Chromium (issue 20, item 1).

Same harness as tests/web/test_ui.py (Debian's /usr/bin/chromium driven by playwright, a real
server and a simulated robot, no sleeps: every wait is an ``expect`` or ``Client.until``).
The owner fixes a robot's wrong address (its link error changes with it), is refused removing
a robot on a trip and removes one without; renames a table (the map's list follows), moves a
place, is told why a table with an open dish cannot go and removes one with nothing open;
changes the settings (the server applies them, the language picker offers what was kept, a
device with no choice of its own speaks the default); then filters and pages the activity log.
"""

from __future__ import annotations

import datetime as dt
import math
import re
from pathlib import Path
from typing import Any

from tests.web.test_ui import (
    Screens,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)


async def confirm(page: Any, yes: str) -> None:
    dialog = page.get_by_role("dialog")
    await dialog.get_by_role("button", name=yes, exact=True).click()
    await expect(dialog).to_have_count(0)


async def test_the_owner_edits_the_restaurant_and_reads_the_activity(
    tmp_path: Path,
    browser: Any,
) -> None:
    async with ui_restaurant(tmp_path) as r:
        assert r.app.core is not None
        c = await staff_client(r)
        owner_c = await r.client()
        await owner_c.ok("login", username="owner", password=r.app.first_owner_password)
        # r1 on a trip to T3 that waits there for ever, another dish for T3 in the kitchen; r9 at
        # an address nothing listens on.
        await owner_c.ok("site", action="set_settings", table_timeout=None)
        await c.ok("control", robot="r1", action="auto")
        await c.status("r1", "Awaiting")
        order = await c.ok("create", type="order", dish="Laksa", table="T3")
        await c.ok("create", type="task", orders=[order["order"]["id"]])
        await c.until(lambda: c.robot("r1").get("current_task") is not None, what="r1's trip")
        await c.ok("create", type="order", dish="Pho", table="T3", status="ordered")  # cooking
        await owner_c.ok("create", type="robot", name="r9", url="ws://127.0.0.1:9")
        # Refusals to find in the activity log, more than one page of them (50 a page).
        for _ in range(55):
            assert (await c.call("site", action="settings"))["code"] == "forbidden"

        screens = Screens(browser, http_base(r))
        page = await screens.open("/", online=False)
        await log_in(page, "owner", r.app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await page.get_by_role("tab", name="Restaurant").click()

        # -- robots: the link's error in words, fixed address, ROS 2 and trays.
        robots = page.get_by_role("list", name="Robots")
        r9 = robots.locator('li[data-robot="r9"]')
        await expect(r9.get_by_test_id("link-error")).to_contain_text(
            re.compile(r"^Cannot reach the robot: .*\b9\b")
        )
        await r9.get_by_role("button", name="Edit r9", exact=True).click()
        form = page.get_by_role("dialog", name="Edit robot r9")
        await form.get_by_label("Address").fill("ws://127.0.0.1:10")
        await form.get_by_label("ROS", exact=True).select_option("2")
        await form.get_by_label("Trays").select_option("2")
        await form.get_by_label("Home").select_option("home2")
        await form.get_by_role("button", name="Save").click()
        await expect(form).to_have_count(0)
        await expect(r9.get_by_test_id("link-error")).to_contain_text(re.compile(r"\b10\b"))
        await expect(r9).to_contain_text("ws://127.0.0.1:10")
        await expect(r9).to_contain_text("ROS 2")
        await expect(r9).to_contain_text("home2")
        robot = r.app.core._robots["r9"]
        assert (robot.url, robot.link, robot.trays, robot.home) == (
            "ws://127.0.0.1:10",
            {"ros": "2"},
            2,
            "home2",
        )

        # r1 is on a trip: the server refuses, the owner reads why.
        await robots.get_by_role("button", name="Remove r1", exact=True).click()
        await confirm(page, "Remove")
        await expect(
            page.get_by_role("alert").filter(has_text="r1 is on a trip: wait until it is back.")
        ).to_be_visible()
        await expect(robots.locator('li[data-robot="r1"]')).to_be_visible()
        # r9 has none: removed, gone here and from the map's robot list.
        await robots.get_by_role("button", name="Remove r9", exact=True).click()
        await confirm(page, "Remove")
        await expect(r9).to_have_count(0)
        await page.get_by_role("tab", name="Map").click()
        await expect(page.get_by_role("button", name="Select r1")).to_be_visible()
        await expect(page.get_by_role("button", name="Select r9")).to_have_count(0)
        await page.get_by_role("tab", name="Restaurant").click()

        # -- tables and places: rename (the map's go-to list follows), move.
        places = page.get_by_role("list", name="Tables and places")
        await places.get_by_role("button", name="Rename T5", exact=True).click()
        form = page.get_by_role("dialog", name="Rename T5")
        await form.get_by_label("New name").fill("Patio 5")
        await form.get_by_role("button", name="Rename").click()
        await expect(form).to_have_count(0)
        await expect(places.locator('li[data-waypoint="Patio 5"]')).to_be_visible()
        await expect(places.locator('li[data-waypoint="T5"]')).to_have_count(0)
        await page.get_by_role("tab", name="Map").click()
        await expect(page.get_by_role("button", name="Go to Patio 5")).to_be_attached()
        await expect(page.get_by_role("button", name="Go to T5")).to_have_count(0)
        await page.get_by_role("tab", name="Restaurant").click()

        await places.get_by_role("button", name="Move T7", exact=True).click()
        form = page.get_by_role("dialog", name="Move T7")
        await form.get_by_label("x (metres)").fill("3")  # free floor (2.5 is a table's edge)
        await form.get_by_label("y (metres)").fill("1.25")
        await form.get_by_label("Facing (degrees)").fill("90")
        await form.get_by_role("button", name="Move").click()
        await expect(form).to_have_count(0)
        await expect(places.locator('li[data-waypoint="T7"]')).to_contain_text(
            "x 3.00 m, y 1.25 m, facing 90°"
        )
        t7 = r.app.core.places.waypoint("T7")
        assert (t7.x, t7.y, round(t7.yaw, 3)) == (3.0, 1.25, round(math.pi / 2, 3))

        # -- remove: T3 has an open dish and a trip, so the owner is told why not.
        await places.get_by_role("button", name="Remove T3", exact=True).click()
        dialog = page.get_by_role("dialog", name="Remove T3?")
        await expect(dialog.get_by_test_id("dependents")).to_contain_text(
            "1 open dish for this table"
        )
        await expect(dialog.get_by_test_id("dependents")).to_contain_text("1 trip stopping here")
        await expect(dialog).to_contain_text("T3 cannot be removed yet")
        await expect(dialog.get_by_role("button", name="Remove T3", exact=True)).to_have_count(0)
        await dialog.get_by_role("button", name="Close").click()
        await expect(dialog).to_have_count(0)
        await places.get_by_role("button", name="Remove Patio 5", exact=True).click()
        dialog = page.get_by_role("dialog", name="Remove Patio 5?")
        await expect(dialog.get_by_test_id("dependents")).to_have_text(
            "Nothing: it can be removed."
        )
        await dialog.get_by_role("button", name="Remove Patio 5", exact=True).click()
        await expect(dialog).to_have_count(0)
        await expect(places.locator('li[data-waypoint="Patio 5"]')).to_have_count(0)
        assert r.app.core.places.waypoint("T3").name == "T3"  # still there

        # -- settings: applied by the server; the picker offers the languages kept.
        settings = page.get_by_role("form", name="Restaurant settings")
        await expect(settings.get_by_label("Wait for ever")).to_be_checked()
        await settings.get_by_label("Wait for ever").uncheck()
        await settings.get_by_label("Wait at a table (seconds)").fill("60")
        await settings.get_by_label("Bahasa Melayu").uncheck()
        await settings.get_by_role("button", name="Save settings").click()
        await expect(page.get_by_text("Settings saved: they apply now")).to_be_visible()
        assert r.app.core.config.table_timeout == 60.0
        assert r.app.core.languages == ["en", "zh"]
        picker = page.locator("#lang-picker option")
        await expect(picker).to_have_count(2)
        assert await picker.evaluate_all("os => os.map((o) => o.value)") == ["en", "zh"]

        # -- the activity log: newest first, filtered, paged.
        await page.get_by_role("tab", name="Activity").click()
        logp = page.locator("#panel-log")
        log = logp.get_by_role("list", name="Activity")
        rows = log.get_by_role("listitem")
        await expect(rows).to_have_count(50)
        await expect(rows.first).to_contain_text("Changed the settings")
        await expect(rows.first).to_contain_text("owner (owner)")
        await expect(rows.first).to_contain_text("Done")
        older = page.get_by_role("button", name="Load older")
        await older.click()  # the rest: fewer than a page, so that is all
        await expect(page.get_by_text(re.compile(r"^\d+ entries: that is all$"))).to_be_visible()
        await expect(older).to_be_hidden()
        assert 50 < await rows.count() < 100
        ids = [int(i) for i in await rows.evaluate_all("ls => ls.map((l) => l.dataset.audit)")]
        assert ids == sorted(set(ids), reverse=True)  # newest first, no record twice

        await logp.get_by_label("Person", exact=True).fill("owner")
        await logp.get_by_label("Action", exact=True).select_option("site")
        await logp.get_by_label("Result", exact=True).select_option("ok")
        await logp.get_by_role("button", name="Show", exact=True).click()
        await expect(rows.filter(has_text="Removed a place")).to_have_count(1)
        await expect(rows.filter(has_text="Renamed a place")).to_have_count(1)
        await expect(rows.filter(has_text="Edited a robot")).to_have_count(1)
        assert "Patio 5" in (await rows.filter(has_text="Removed a place").text_content() or "")
        await expect(rows.filter(has_text="staff")).to_have_count(0)
        await expect(older).to_be_hidden()

        # Refusals, of anyone: the owner's conflict and staff's 55 forbidden asks, paged.
        await logp.get_by_label("Person", exact=True).fill("")
        await logp.get_by_label("Action", exact=True).select_option("")
        await logp.get_by_label("Result", exact=True).select_option("refused")
        await logp.get_by_role("button", name="Show", exact=True).click()
        await expect(rows.first).to_contain_text("Refused: something depends on it")
        await expect(rows.first).to_contain_text("Removed a robot")
        await expect(rows.nth(1)).to_contain_text("Refused: not allowed")
        await expect(rows.nth(1)).to_contain_text("(staff)")
        count = await rows.count()
        assert count >= 25, count
        if await older.is_visible():  # the refusals are spread over the pages read
            await older.click()
        await expect(older).to_be_hidden()
        await expect(rows).to_have_count(56)  # 55 forbidden + the owner's refused removal
        await expect(rows.filter(has_text="Refused: something depends on it")).to_have_count(1)
        await expect(rows.filter(has_text="Done")).to_have_count(0)

        # Dates: up to yesterday, nothing; from today, the same refusals.
        today = dt.datetime.fromtimestamp(r.clock.epoch()).date()
        await logp.get_by_label("To", exact=True).fill((today - dt.timedelta(days=1)).isoformat())
        await logp.get_by_role("button", name="Show", exact=True).click()
        await expect(page.get_by_text("Nothing found.")).to_be_visible()
        await logp.get_by_label("To", exact=True).fill("")
        await logp.get_by_label("From", exact=True).fill(today.isoformat())
        await logp.get_by_role("button", name="Show", exact=True).click()
        await expect(rows.first).to_contain_text("Refused")

        # -- the default language: a device that chose nothing speaks it at once; its own
        # choice then wins (and is kept).
        await page.get_by_role("tab", name="Restaurant").click()
        await settings.get_by_label("Default language").select_option("zh")
        await settings.get_by_label("Wait for ever").check()
        await settings.get_by_role("button", name="Save settings").click()
        await expect(page.locator("html")).to_have_attribute("lang", "zh-Hans")
        await expect(page.get_by_role("tab", name="餐厅")).to_be_visible()
        assert r.app.core.config.table_timeout is None
        # Another tablet (staff) with nothing chosen: Chinese too; one whose address names Malay
        # keeps Malay although the site no longer offers it.
        fresh = await screens.open("/", token=r.token)
        await expect(fresh.locator("html")).to_have_attribute("lang", "zh-Hans")
        await expect(fresh.locator("#lang-picker option")).to_have_count(2)
        malay = await screens.open("/?lang=ms", token=r.token)
        await expect(malay.locator("html")).to_have_attribute("data-site-langs", "en zh")
        await expect(malay.get_by_role("tab", name="Peta & robot")).to_be_visible()
        await expect(malay.locator("html")).to_have_attribute("lang", "ms")
        await page.locator("#lang-picker").select_option("en")
        await expect(page.locator("html")).to_have_attribute("lang", "en")
        await page.reload()
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await expect(page.get_by_role("tab", name="Restaurant")).to_be_visible()
        await expect(page.locator("html")).to_have_attribute("lang", "en")
        screens.assert_no_errors()
