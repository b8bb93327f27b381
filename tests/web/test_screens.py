"""Every screen size (issue 20): a 390 px phone, portrait and landscape tablets, a desktop.

At each size, in Chromium: no horizontal scroll on any staff tab nor the guest screens, Log out
on screen, the main action buttons at least 44 px tall and wide (a finger), and on the tablets
the map and the teleop joystick in view together. Screenshots land in docs/screenshots/ when
asked: ``SERVEUR_SCREENSHOTS=docs/screenshots python3 -m pytest tests/web/test_screens.py``.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from tests.web.conftest import sideways, too_small
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
    "tablet-portrait": {"width": 768, "height": 1024},
    "tablet-landscape": {"width": 1024, "height": 768},
    "desktop": {"width": 1440, "height": 900},
}

TOPBAR = """() => [...document.querySelectorAll(".topbar > *, .tabs > *")]
  // Shown (not for screen readers only: a 1 px clipped box is not on screen to overlap).
  .filter((e) => e.offsetParent !== null && !e.classList.contains("tabs"))
  .filter((e) => e.getBoundingClientRect().width > 1)
  .map((e) => {
    const r = e.getBoundingClientRect();
    return [e.textContent.trim().slice(0, 20), [r.left, r.top, r.right, r.bottom]];
  })"""
# Visible controls whose words do not fit in them (cut off by their box).
CLIPPED = """(sel) => [...document.querySelectorAll(sel)]
  .filter((e) => e.offsetParent !== null && e.scrollWidth > e.clientWidth + 1)
  .map((e) => e.textContent.trim())"""
MAIN_BUTTONS = (
    '[role="tab"], .logout, .actions button, .robot-name, .map-toolbar button, '
    ".goto-list button, .alert-mute, button.go"
)


def in_view(box: dict[str, float] | None, size: dict[str, int]) -> bool:
    return (
        box is not None
        and box["x"] >= 0
        and box["y"] >= 0
        and box["x"] + box["width"] <= size["width"] + 0.5
        and box["y"] + box["height"] <= size["height"] + 0.5
    )


@pytest.mark.parametrize("name", list(SIZES))
async def test_every_screen_size(tmp_path: Path, browser: Any, name: str) -> None:
    size = SIZES[name]
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.ok("control", robot="r1", action="manual")
        await c.status("r1", "Manual")
        context = await browser.new_context(viewport=size)
        page = await context.new_page()
        await page.goto(f"{http_base(r)}/#token={r.token}")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await expect(page.get_by_role("button", name="Done driving r1")).to_be_visible()

        for tab in ("Map", "Send food", "New order", "Kitchen"):
            await page.get_by_role("tab", name=tab).click()
            width, inner = await sideways(page)
            assert width <= inner, f"{name} {tab}: page {width} px wide in {inner}"
            tab_box = await page.get_by_role("tab", name=tab).bounding_box()
            assert tab_box and tab_box["height"] < 70, f"{name}: tab label wraps ({tab_box})"
        await page.get_by_role("tab", name="Map").click()
        logout = page.get_by_role("button", name="Log out")
        assert in_view(await logout.bounding_box(), size), f"{name}: Log out off screen"
        # Nothing in the top bar wraps its words or covers its neighbour.
        boxes = await page.evaluate(TOPBAR)
        for i, (a, ra) in enumerate(boxes):
            assert ra[3] - ra[1] <= 52, f"{name}: {a!r} on two lines"
            for b, rb in boxes[i + 1 :]:
                apart = ra[2] <= rb[0] or rb[2] <= ra[0] or ra[3] <= rb[1] or rb[3] <= ra[1]
                assert apart, f"{name}: {a!r} and {b!r} overlap"

        small = await too_small(page, MAIN_BUTTONS)
        assert small == [], f"{name}: touch targets under 44 px: {small}"
        # No tool's words cut off: every map tool shows its whole label.
        clipped = await page.evaluate(CLIPPED, ".map-toolbar button")
        assert clipped == [], f"{name}: map tools clipped: {clipped}"

        if name.startswith("tablet"):
            # Teleop open (the robot is Manual): the map and the joystick on screen together.
            joystick = page.get_by_role("group", name="Joystick: drag to drive")
            await expect(joystick).to_be_visible()
            await page.evaluate("() => window.scrollTo(0, 0)")
            map_box = await page.locator("#map").bounding_box()
            pad_box = await joystick.bounding_box()
            visible_map = map_box is not None and map_box["height"] >= 200
            assert visible_map and in_view(map_box, size), f"{name}: map {map_box}"
            assert in_view(pad_box, size), f"{name}: joystick {pad_box} not with the map"
        await page.screenshot(path=str(SHOTS / f"size-staff-{name}.png"))

        for path in ("/robot/r1", "/table/T3"):
            role = "robot-screen" if path.startswith("/robot") else "table-screen"
            bound = {"robot": "r1"} if role == "robot-screen" else {"table": "T3"}
            token = await r.app.issue_token(role, **bound)
            await page.goto(f"{http_base(r)}{path}#token={token}")
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
            width, inner = await sideways(page)
            assert width <= inner, f"{name} {path}: page {width} px wide in {inner}"
            await page.screenshot(path=str(SHOTS / f"size-{role}-{name}.png"))

        if name == "phone":
            # The owner, on a fresh phone: a longer "who", one more tab (the menu).
            await context.close()
            context = await browser.new_context(viewport=size)
            page = await context.new_page()
            await page.goto(f"{http_base(r)}/")
            await log_in(page, "owner", r.app.first_owner_password or "")
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
            for tab in ("Map", "Send food", "New order", "Kitchen", "Menu"):
                await page.get_by_role("tab", name=tab).click()
                width, inner = await sideways(page)
                assert width <= inner, f"owner's {tab}: page {width} px wide in {inner}"
            logout = page.get_by_role("button", name="Log out")
            assert in_view(await logout.bounding_box(), size), "owner: Log out off screen"
        await context.close()
