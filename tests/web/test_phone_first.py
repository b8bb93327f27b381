"""The console on every size, the phone first (issue 30, points 1 and 4): on a 390 px phone the
header, tabs and map tools took ~300 px and the robot list was below the fold, the Kitchen tab
off-screen, the map out of view while driving; on a 1024 px tablet the map tools were cut off
and an armed tool's instruction sat in the hidden overflow.

Checked in Chromium at 390x844, 768x1024, 1024x768 and 1440x900, logged in as the owner (all
nine tabs) with two robots and an alert up: every tab whole on screen; on each tab that shows
robots, the first robot's card and its first action on screen without scrolling; the map tools
whole, and an armed tool's instruction on screen on a touch device; no visible text clipped."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest

from tests.web.conftest import sideways
from tests.web.test_ui import (
    SHOTS,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

SIZES = {
    "phone": {"width": 390, "height": 844},
    "portrait": {"width": 768, "height": 1024},
    "tablet": {"width": 1024, "height": 768},
    "desktop": {"width": 1440, "height": 900},
}

# Visible elements whose text does not fit their box and is cut (overflow not visible), or that
# stick out of the window: [what, why]. Scrolling lists are not clipping (their content scrolls).
CLIPPED = """(root) => {
  const out = [];
  const inner = window.innerWidth;
  const texts = "button, a, label, summary, h1, h2, h3, [role=tab], span, p, li, td, th, output";
  for (const e of root.querySelectorAll(texts)) {
    if (!e.checkVisibility()) continue;
    const r = e.getBoundingClientRect();
    if (r.width <= 1 || r.height <= 1) continue; // none, or for screen readers only
    let shown = true; // inside a box kept for screen readers (1 px, clipped): not on screen
    for (let p = e.parentElement; p && shown; p = p.parentElement) {
      const pr = p.getBoundingClientRect();
      if (pr.width <= 1 && pr.height <= 1) shown = false;
    }
    if (!shown) continue;
    const text = (e.innerText || "").trim();
    if (!text) continue;
    const s = getComputedStyle(e);
    const cuts = s.overflowX !== "visible" || s.textOverflow === "ellipsis";
    const scrolls = s.overflowX === "auto" || s.overflowX === "scroll";
    if (cuts && !scrolls && e.scrollWidth > e.clientWidth + 1) {
      out.push([text.slice(0, 40), `cut: ${e.scrollWidth} > ${e.clientWidth}`]);
    }
    if (r.right > inner + 1 || r.left < -1) {
      out.push([text.slice(0, 40), `outside the window: ${r.left}..${r.right}`]);
    }
    // Inside a box that scrolls sideways and scrolled out of it: hidden from whoever looks.
    for (let p = e.parentElement; p; p = p.parentElement) {
      const ps = getComputedStyle(p);
      if (ps.overflowX === "auto" || ps.overflowX === "scroll" || ps.overflowX === "hidden") {
        const pr = p.getBoundingClientRect();
        if (p.scrollWidth > p.clientWidth + 1 && (r.right > pr.right + 1 || r.left < pr.left - 1)) {
          out.push([text.slice(0, 40), `scrolled out of ${p.className || p.tagName}`]);
        }
        break;
      }
    }
  }
  return out;
}"""


def on_screen(box: dict[str, float] | None, size: dict[str, int]) -> bool:
    return (
        box is not None
        and box["x"] >= -1
        and box["y"] >= -1
        and box["x"] + box["width"] <= size["width"] + 1
        and box["y"] + box["height"] <= size["height"] + 1
    )


async def clipped(page: Any, selector: str = "body") -> list[list[str]]:
    return await page.locator(selector).first.evaluate(CLIPPED)  # type: ignore[no-any-return]


@pytest.mark.parametrize("size", list(SIZES))
async def test_robots_first_tools_whole_nothing_clipped(
    tmp_path: Path, browser: Any, size: str
) -> None:
    view = SIZES[size]
    async with ui_restaurant(tmp_path, robots=2) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        await c.status("r2", "Ready")
        assert r.app.core is not None
        # Alerts up: the banner must not push the robots off a phone's screen.
        for table in ("T5", "T7", "T9"):
            await r.app.core.service.block(table, f"r1: no way to {table}", "r1")
        # A long dish name and note, in the lists at the pass: wrapped, never cut.
        long = "Nasi lemak ayam goreng berempah with extra sambal and telur"
        await c.ok("create", type="order", dish=long, table="T2", note="no peanuts " * 8)
        await c.ok("create", type="order", dish="Teh tarik", table="T3")
        context = await browser.new_context(
            viewport=view, has_touch=True, is_mobile=size == "phone"
        )
        page = await context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        await page.goto(f"{http_base(r)}/")
        await log_in(page, "owner", r.app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await expect(page.get_by_role("region", name="Alerts")).to_contain_text("T9")
        await expect(page.get_by_role("tab", name="Activity")).to_be_visible()

        # Every tab whole on screen: none hidden in a scrolled row.
        for tab in await page.get_by_role("tab").all():
            assert on_screen(await tab.bounding_box(), view), (size, await tab.inner_text())

        # The robots first: r1's card and its first action, without scrolling.
        first = page.locator("#robots > li").first
        await expect(first).to_contain_text("r1")
        action = first.locator(".actions button").first
        await expect(action).to_be_visible()
        assert on_screen(await first.locator(".robot-name").bounding_box(), view), size
        assert on_screen(await action.bounding_box(), view), (size, await action.inner_text())
        await page.screenshot(path=str(SHOTS / f"phone-first-{size}.png"))

        # The map tools, whole (a phone scrolls down to them); nothing clipped on the tab.
        for tool in await page.locator(".map-toolbar button:visible").all():
            box = await tool.bounding_box()
            assert box is not None and box["x"] >= 0 and box["x"] + box["width"] <= view["width"]
        assert await clipped(page) == [], size
        assert (await sideways(page))[0] <= view["width"]

        # An armed tool says what to do, on screen, on a touch device.
        await first.get_by_role("button", name="Take control r1").tap()
        goal = page.get_by_role("button", name="Move here")
        await expect(goal).to_be_enabled()
        await goal.tap()
        hint = page.locator("#tool-hint")
        await expect(hint).to_contain_text("Press where the robot should go")
        assert on_screen(await hint.bounding_box(), view), size
        assert await clipped(page, "#tool-hint") == []
        # Driving on a phone: the map and the joystick on screen together.
        await expect(page.locator(".pad.joystick")).to_be_visible()
        if size in ("phone", "portrait"):
            canvas = await page.locator("#map").bounding_box()
            pad = await page.locator(".pad.joystick").bounding_box()
            assert canvas is not None and pad is not None
            assert canvas["y"] + canvas["height"] * 0.5 >= 0 and on_screen(pad, view), (canvas, pad)
        await page.screenshot(path=str(SHOTS / f"phone-first-{size}-driving.png"))
        # The way out is beside the pads; after it the robots come first again.
        await page.get_by_role("button", name="Finish driving r1").tap()
        await c.status("r1", "Ready")
        await expect(page.locator("body")).to_have_attribute("data-driving", "false")
        await expect(first.get_by_role("button", name="Take control r1")).to_be_visible()

        # The other tabs: whole, nothing clipped; where robots are shown, the first one first.
        tabs = ("Send food", "New order", "Kitchen", "Menu", "Accounts", "Restaurant", "Statistics")
        for name in (*tabs, "Activity"):
            await page.get_by_role("tab", name=name, exact=True).tap()
            panel = page.locator("[role=tabpanel]:visible")
            await expect(panel).to_have_count(1)
            if name == "Send food":
                await page.get_by_role("button", name=re.compile(f"^Add to cart: {long}")).tap()
                await expect(page.get_by_role("list", name="Cart")).to_contain_text(long)
            assert await clipped(page) == [], (size, name)
            assert (await sideways(page))[0] <= view["width"], (size, name)
        assert errors == []
        await context.close()
