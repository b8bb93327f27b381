"""The owner draws the restaurant's map from its floor plan, in Chromium on a tablet (issue 29):
the plan picked, the walls kept by the darkness slider (a live preview on the page), a table
rubbed out, one distance measured across and one along by tapping their ends, the map checked
(its size said), used (stored, the places now in a wall named), and downloaded for the robot as
map_server's PGM and YAML; the map's measured depth is within 2 % of the plan's truth."""

from __future__ import annotations

import asyncio
import io
import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from PIL import Image

from tests.maps.plans import ROOM, plan
from tests.maps.test_floorplan import free_run
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    owner_tab,
    pytestmark,  # noqa: F401
    ui_restaurant,
)


async def tap(page: Any, canvas: Any, x: float, y: float, size: tuple[int, int]) -> None:
    """Tap the plan at its own pixel (x, y)."""
    box = await canvas.bounding_box()
    await page.mouse.click(
        box["x"] + x * box["width"] / size[0], box["y"] + y * box["height"] / size[1]
    )


async def test_the_owner_draws_the_map_from_the_floor_plan(tmp_path: Path, browser: Any) -> None:
    p = plan(px_per_m=37.0)
    (tmp_path / "plan.png").write_bytes(p.data)

    size = Image.open(io.BytesIO(p.data)).size
    mid_x, mid_y = (p.left + p.partition_x) / 2, (p.top + p.bottom) / 2
    async with (
        ui_restaurant(tmp_path) as r,
        owner_tab(browser, r, "Restaurant", accept_downloads=True) as (owner, errors),
    ):
        section = owner.get_by_role("region", name="Map from the floor plan")
        status = section.get_by_role("status")
        await section.get_by_label("Floor plan (PNG or JPEG)").set_input_files(
            str(tmp_path / "plan.png")
        )
        canvas = section.get_by_role("img", name="The floor plan: dark is wall")
        await expect(canvas).to_be_visible()
        await canvas.scroll_into_view_if_needed()
        # The walls only: the tables, labels and dimension line are lighter than them.
        slider = section.get_by_label("Darkness of the walls")
        await slider.evaluate("(s) => { s.value = 50; s.dispatchEvent(new Event('input')); }")
        # No tool yet: a touch on the plan changes nothing.
        await tap(owner, canvas, p.left + 2.0 * 37, p.top + 3.0 * 37, size)
        await expect(canvas).to_have_attribute("data-strokes", "0")
        # Rub out the first table (already gone at this darkness: the stroke is kept anyway),
        # take it back, and rub it out again.
        await section.get_by_role("button", name="Erase").click()
        await tap(owner, canvas, p.left + 2.0 * 37, p.top + 3.0 * 37, size)
        await expect(canvas).to_have_attribute("data-strokes", "1")
        await section.get_by_role("button", name="Undo").click()
        await expect(canvas).to_have_attribute("data-strokes", "0")
        await tap(owner, canvas, p.left + 2.0 * 37, p.top + 3.0 * 37, size)
        await expect(canvas).to_have_attribute("data-strokes", "1")

        await section.get_by_role("button", name="Measure across").click()
        await tap(owner, canvas, p.left, mid_y + 40, size)
        await tap(owner, canvas, p.right, mid_y + 40, size)
        await section.get_by_label("Measured across (m)").fill(str(ROOM[0]))
        await section.get_by_role("button", name="Measure along").click()
        await tap(owner, canvas, mid_x, p.top, size)
        await tap(owner, canvas, mid_x, p.bottom, size)
        await section.get_by_label("Measured along (m)").fill(str(ROOM[1]))
        await expect(canvas).to_have_attribute("data-measures", "2")

        await section.get_by_role("button", name="Check the map").click()
        await expect(status).to_contain_text("The map will be 17.")
        # The map as the robot will have it, drawn before "Use".
        preview = section.get_by_role("img", name="The map made from the floor plan")
        await expect(preview).to_be_visible()
        await expect(preview).to_have_attribute("data-cells", re.compile(r"^\d+x\d+$"))
        assert await r.app.store.site_map.get() is None  # a preview changes nothing
        assert await violations(owner) == []
        await section.scroll_into_view_if_needed()
        await owner.screenshot(path=str(SHOTS / "plan-tablet.png"))

        await section.get_by_role("button", name="Use this map").click()
        await expect(status).to_contain_text("The map is replaced")
        stored = await r.app.store.site_map.get()
        assert stored is not None and stored.source == "floor plan (plan.png)"
        grid = np.frombuffer(stored.cells, dtype=np.int8).reshape(stored.height, stored.width)
        col = int(((mid_x - 30) / 37.0) / 0.05)
        assert free_run(grid[:, col], stored.height // 2) * 0.05 == pytest.approx(ROOM[1], rel=0.02)

        async with owner.expect_download() as first:
            await section.get_by_role("button", name="Download for the robot").click()
        saved = await (await first.value).path()
        text = await asyncio.to_thread(Path(saved).read_bytes)
        assert b"image: restaurant.pgm" in text
        assert errors == []
