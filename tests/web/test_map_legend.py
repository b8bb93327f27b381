"""The map's legend, Follow robot, and each trip's tables drawn (issue 20, items 5-6).

The legend is HTML (a <details>): opened and closed from the keyboard, every symbol named in the
page's language, its swatches in the colours the map draws with, inside the map at a phone's and
a tablet's size without covering the toolbar. Follow robot keeps the selected robot in the middle
as it drives (the zoom kept, no frame drawn while it is parked) and stops when the map is moved by
hand, zoomed, or on Escape. A robot on a trip has its current table and its later ones drawn, in
visiting order (the canvas publishes what it drew as data-routes), and a blocked table is drawn
crossed (data-blocked).
"""

from __future__ import annotations

import json
import math
import re
from pathlib import Path
from typing import Any

from tests.web.test_a11y import AXE, violations
from tests.web.test_map_keys import DRAWS_OVER_FRAMES
from tests.web.test_ui import (
    TABLET,
    Screens,
    expect,
    http_base,
    near,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

SITE = Path(__file__).resolve().parents[2] / "serveur" / "web" / "site"
EN = json.loads((SITE / "i18n" / "en.json").read_text("utf-8"))
STATUS_COLOURS = dict(
    re.findall(r'^\s+(\w+): "(#[0-9a-f]{6})"', (SITE / "js" / "status.js").read_text(), re.M)
)
PHONE = {"width": 390, "height": 844}

# The map position at the middle of the canvas, and the zoom, from the view it publishes.
CENTRE = """() => {
  const c = document.getElementById("map");
  const d = c.dataset;
  const s = Number(d.scale);
  const x = (c.clientWidth / 2 - Number(d.originX)) / s;
  return [x, (Number(d.originY) - c.clientHeight / 2) / s, s];
}"""
CENTRED_NEAR = f"""([x, y, tol]) => {{
  const [cx, cy] = ({CENTRE})();
  return Math.hypot(cx - x, cy - y) <= tol;
}}"""
ROUTE_IS = """([robot, want]) => {
  const routes = JSON.parse(document.getElementById("map").dataset.routes || "{}");
  return JSON.stringify(routes[robot] || []) === JSON.stringify(want);
}"""
BOX = """(e) => {
  const r = e.getBoundingClientRect();
  return [r.left, r.top, r.right, r.bottom];
}"""
TOOLBAR_BOXES = """() => [...document.querySelectorAll(".map-toolbar button")]
  .filter((b) => b.offsetParent !== null)
  .map((b) => {
    const r = b.getBoundingClientRect();
    return [b.id, [r.left, r.top, r.right, r.bottom]];
  })"""


def rgb(hex_colour: str) -> str:
    n = int(hex_colour[1:], 16)
    return f"rgb({n >> 16 & 255}, {n >> 8 & 255}, {n & 255})"


def apart(a: list[float], b: list[float]) -> bool:
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


async def test_the_legend_on_a_phone_and_a_tablet(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        await staff_client(r)
        for size in (PHONE, TABLET):
            context = await browser.new_context(viewport=size, bypass_csp=True)
            page = await context.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e, errors=errors: errors.append(str(e)))
            await page.goto(f"{http_base(r)}/#token={r.token}")
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
            legend = page.locator("#map-legend")
            summary = legend.locator("summary")
            await expect(summary).to_have_text(EN["map.legend.title"])
            await expect(legend).not_to_have_attribute("open", "")
            for key in [k for k in EN if k.startswith("map.legend.")][1:]:
                await expect(legend.get_by_text(EN[key], exact=True)).to_be_hidden()

            # From the keyboard: Enter on the summary opens it, every symbol is named.
            await summary.focus()
            await page.keyboard.press("Enter")
            await expect(legend).to_have_attribute("open", "")
            for key in [k for k in EN if k.startswith("map.legend.")][1:]:
                await expect(legend.get_by_text(EN[key], exact=True)).to_be_visible()
            for status, colour in STATUS_COLOURS.items():
                await expect(legend.get_by_text(EN[f"status.{status}"], exact=True)).to_be_visible()
                swatch = legend.locator(f'[data-status="{status}"]')
                await expect(swatch).to_have_css("background-color", rgb(colour))
            await expect(legend.locator('[data-kind="table"]')).to_have_css(
                "background-color", rgb("#8b5a2b")
            )

            # Inside the map, never over the toolbar; a finger-sized summary; no sideways scroll.
            await page.evaluate("() => window.scrollTo(0, 0)")
            box = await legend.evaluate(BOX)
            canvas = await page.locator("#map").evaluate(BOX)
            assert canvas[0] - 1 <= box[0] and box[2] <= canvas[2] + 1, (size, box, canvas)
            assert canvas[1] - 1 <= box[1] and box[3] <= canvas[3] + 1, (size, box, canvas)
            for name, b in await page.evaluate(TOOLBAR_BOXES):
                assert apart(box, b), f"{size}: the legend covers {name}"
            s = await summary.bounding_box()
            assert s and s["height"] >= 44, s
            width, inner = await page.evaluate(
                "() => [document.scrollingElement.scrollWidth, window.innerWidth]"
            )
            assert width <= inner, (size, width, inner)
            if AXE.is_file():
                assert await violations(page) == []

            # Enter again closes it.
            await expect(summary).to_be_focused()
            await page.keyboard.press("Enter")
            await expect(legend).not_to_have_attribute("open", "")
            assert errors == []
            await context.close()


async def test_follow_robot(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.ok("control", robot="r1", action="manual")
        await c.status("r1", "Manual")
        p0 = await c.until(lambda: c.streams.get("pose:r1"), what="a pose")
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        canvas = staff.locator("#map")
        follow = staff.get_by_role("button", name=EN["map.follow"])
        await expect(follow).to_have_attribute("aria-pressed", "false")
        await expect(follow).to_be_enabled()

        # On: the robot comes to the middle, the zoom as it was.
        await staff.get_by_role("button", name="Zoom in").click()
        scale = (await staff.evaluate(CENTRE))[2]
        await follow.click()
        await expect(follow).to_have_attribute("aria-pressed", "true")
        await expect(canvas).to_have_attribute("data-follow", "on")
        await staff.wait_for_function(CENTRED_NEAR, arg=[p0["x"], p0["y"], 0.05])
        # Parked: following draws nothing.
        assert await staff.evaluate(DRAWS_OVER_FRAMES, 30) <= 2

        # The robot drives 1.1 m: the middle of the map goes with it, the zoom kept.
        gx, gy = p0["x"] + 0.5, p0["y"] - 1.0
        await c.ok("control", robot="r1", action="goal", x=gx, y=gy, yaw=p0["yaw"])
        await c.until(lambda: near(c.streams.get("pose:r1"), gx, gy, 0.3), what="at the goal")
        await staff.wait_for_function(CENTRED_NEAR, arg=[gx, gy, 0.35])
        assert (await staff.evaluate(CENTRE))[2] == scale
        await expect(canvas).to_have_attribute("data-follow", "on")

        # Moved by hand: following stops, and the map stays put while the robot drives back.
        box = await canvas.bounding_box()
        x, y = box["x"] + box["width"] * 0.3, box["y"] + box["height"] * 0.3
        await staff.mouse.move(x, y)
        await staff.mouse.down()
        await staff.mouse.move(x + 120, y + 60, steps=6)
        await staff.mouse.up()
        await expect(follow).to_have_attribute("aria-pressed", "false")
        await expect(canvas).to_have_attribute("data-follow", "off")
        after_pan = await staff.evaluate(CENTRE)
        draws = int(await canvas.get_attribute("data-draws") or 0)
        await c.ok("control", robot="r1", action="goal", x=p0["x"], y=p0["y"], yaw=p0["yaw"])
        await c.until(lambda: near(c.streams.get("pose:r1"), p0["x"], p0["y"], 0.3), what="back")
        drew = f"() => Number(document.getElementById('map').dataset.draws) > {draws}"
        await staff.wait_for_function(drew)
        await staff.evaluate(DRAWS_OVER_FRAMES, 5)
        assert await staff.evaluate(CENTRE) == after_pan
        assert math.hypot(after_pan[0] - p0["x"], after_pan[1] - p0["y"]) > 0.5

        # Escape turns it off (focus on the button), and so does a zoom.
        await follow.click()
        await expect(follow).to_have_attribute("aria-pressed", "true")
        await staff.wait_for_function(CENTRED_NEAR, arg=[p0["x"], p0["y"], 0.35])
        await staff.keyboard.press("Escape")
        await expect(follow).to_have_attribute("aria-pressed", "false")
        await follow.focus()
        await staff.keyboard.press("Enter")
        await expect(follow).to_have_attribute("aria-pressed", "true")
        await staff.get_by_role("button", name="Zoom out").click()
        await expect(follow).to_have_attribute("aria-pressed", "false")
        screens.assert_no_errors()


async def test_a_trip_draws_its_tables_in_order(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        await c.ok("control", robot="r1", action="auto")
        ids = [
            (await c.ok("create", type="order", dish=dish, table=table))["order"]["id"]
            for dish, table in (("Laksa", "T3"), ("Satay", "T7"))
        ]
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        await expect(staff.locator("#map")).to_have_attribute("data-routes", "{}")
        # A table robots cannot reach is drawn crossed (as the core records it).
        await expect(staff.locator("#map")).to_have_attribute("data-blocked", "[]")
        assert r.app.core is not None
        await r.app.core.service.block("T9", "r1 could not reach T9", "r1")
        await expect(staff.locator("#map")).to_have_attribute("data-blocked", '["T9"]')
        [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
        tables = [s["table"] for s in task["stops"]]
        assert sorted(tables) == ["T3", "T7"]

        # On the way: the current table, then the later one.
        await staff.wait_for_function(ROUTE_IS, arg=["r1", tables])
        # At the first table, then sent on: only the second is left.
        await c.status("r1", "Delivered")
        await staff.wait_for_function(ROUTE_IS, arg=["r1", tables])
        await c.ok("next", robot="r1")
        await staff.wait_for_function(ROUTE_IS, arg=["r1", tables[1:]])
        # Done with the last: going home, no table drawn.
        await c.status("r1", "Delivered")
        await c.ok("next", robot="r1")
        await staff.wait_for_function(ROUTE_IS, arg=["r1", []])
        screens.assert_no_errors()
