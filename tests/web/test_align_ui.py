"""The owner lays the floor plan under the robot's map in Chromium on a tablet (issue 29): the
same spots tapped on the plan and on the map, the fit checked (a few centimetres), the plan laid
over the map to see it, then used — the staff map draws it under the robot's map."""

from __future__ import annotations

import asyncio
import math
from pathlib import Path
from typing import Any

import numpy as np
from PIL import Image

from serveur.maps.navigation import load_demo
from tests.test_align_map import SPOTS, TRUE, plan_pixel
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    owner_tab,
    pytestmark,  # noqa: F401
    ui_restaurant,
)

PLAN_SIZE = (820, 600)


def plan_of_the_demo_room(path: Path) -> None:
    """The demo restaurant's map drawn as a floor plan would be: at 3 cm per pixel, turned and
    shifted by ``TRUE`` (walls black on white)."""
    grid, _ = load_demo()
    cells = np.asarray(grid.grid)
    room = np.where(cells >= 50, 0, 255).astype(np.uint8)[::-1]  # image rows go down
    ox, oy, res, h = grid.origin[0], grid.origin[1], grid.resolution, grid.height
    s, c, n = TRUE.scale, math.cos(TRUE.rotation), math.sin(TRUE.rotation)
    # The map cell under plan pixel (col, row): world = TRUE(col, -row), then the cell.
    a, b, c0 = s * c / res, s * n / res, (TRUE.tx - ox) / res
    d, e, f0 = -s * n / res, s * c / res, h - (TRUE.ty - oy) / res
    plan = Image.fromarray(room).transform(
        PLAN_SIZE, Image.Transform.AFFINE, (a, b, c0, d, e, f0), fillcolor=255
    )
    plan.save(path)


async def tap(canvas: Any, x: float, y: float) -> None:
    """Tap ``canvas`` at its own pixel (x, y)."""
    await canvas.scroll_into_view_if_needed()
    box = await canvas.bounding_box()
    size = await canvas.evaluate("c => [c.width, c.height]")
    await canvas.click(position={"x": x * box["width"] / size[0], "y": y * box["height"] / size[1]})


async def test_the_owner_lays_the_floor_plan_under_the_map(tmp_path: Path, browser: Any) -> None:
    await asyncio.to_thread(plan_of_the_demo_room, tmp_path / "plan.png")
    grid, _ = load_demo()
    async with (
        ui_restaurant(tmp_path) as r,
        owner_tab(browser, r, "Restaurant") as (owner, errors),
    ):
        section = owner.get_by_role("region", name="Floor plan under the map")
        said = section.get_by_role("status")
        await section.get_by_label("Floor plan (PNG or JPEG)").set_input_files(
            str(tmp_path / "plan.png")
        )
        plan = section.get_by_role("img", name="The floor plan: tap a spot")
        room = section.get_by_role("img", name="The robot's map: tap the same spot")
        await expect(said).to_have_text("Spot 1: tap it on the floor plan.")
        # The map first: nothing happens but a word.
        await tap(room, 10, 10)
        await expect(said).to_have_text("Tap the spot on the floor plan first.")
        for x, y in SPOTS[:4]:
            await tap(plan, *plan_pixel(x, y))
            await expect(said).to_have_text("Now tap the same spot on the robot's map.")
            col = (x - grid.origin[0]) / grid.resolution
            row = grid.height - (y - grid.origin[1]) / grid.resolution
            await tap(room, col, row)
        await expect(room).to_have_attribute("data-spots", "4")
        await section.get_by_role("button", name="Check the fit").click()
        # Taps land on whole CSS pixels: a plan pixel is ~1.5 cm, a map cell 5 cm on screen.
        await expect(said).to_contain_text("The plan fits the map within")
        words = await said.text_content() or ""
        average = int(words.split("within ")[1].split(" cm")[0])
        assert average <= 6, words
        await expect(room).to_have_attribute("data-fitted", "true")
        await section.screenshot(path=str(SHOTS / "align-tablet.png"))
        assert await violations(owner) == []

        await section.get_by_role("button", name="Use this plan under the map").click()
        await expect(said).to_contain_text("Every screen now shows the floor plan under the map.")
        stored = await r.app.store.site_backdrop.get()
        assert stored is not None and math.isclose(stored.scale, TRUE.scale, rel_tol=0.03)
        assert abs(math.remainder(stored.rotation - TRUE.rotation, math.tau)) < math.radians(1)
        await owner.get_by_role("tab", name="Map & robots").click()
        await expect(owner.locator("#map")).to_have_attribute("data-backdrop", "true")
        await owner.locator("#map").screenshot(path=str(SHOTS / "map-with-plan-tablet.png"))
        assert errors == [], errors
