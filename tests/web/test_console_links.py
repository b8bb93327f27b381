"""A link into the console opens a tab at a section (the setup page sends the owner to
``/#restaurant/plan``): followed once the login says who it is, once only, and a link to an
owner's tab does nothing for staff."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from tests.web.test_ui import (
    TABLET,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    ui_restaurant,
)


async def test_a_link_opens_the_restaurant_tab_at_the_floor_plan(
    tmp_path: Path, browser: Any
) -> None:
    async with ui_restaurant(tmp_path) as r:
        context = await browser.new_context(viewport=TABLET)
        page = await context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        await page.goto(f"{http_base(r)}/#restaurant/plan")
        await log_in(page, "owner", r.app.first_owner_password or "")
        restaurant = page.locator("#tab-restaurant")
        await expect(restaurant).to_have_attribute("aria-selected", "true")
        plan = page.get_by_role("region", name="Map from the floor plan")
        await expect(plan).to_be_in_viewport()
        # Followed once: the owner moves on, a language change does not bring the link back.
        await page.get_by_role("tab", name="Statistics").click()
        await page.get_by_label("Language").first.select_option("ms")
        await expect(restaurant).to_have_attribute("aria-selected", "false")
        # Another link, in the same page: followed.
        await page.evaluate("window.location.hash = '#restaurant/backups'")
        await expect(restaurant).to_have_attribute("aria-selected", "true")
        await expect(page.get_by_role("region", name="Sandaran")).to_be_in_viewport()
        # Nonsense: the page stays as it is.
        await page.evaluate("window.location.hash = '#../../x/<b>'")
        await expect(restaurant).to_have_attribute("aria-selected", "true")
        assert errors == []
        await context.close()
