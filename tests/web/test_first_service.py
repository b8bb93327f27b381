"""A new owner, from an empty database to a delivered trip, on a tablet and without a terminal
(issue 29): the setup link's page makes their account and names the restaurant; a simulated
robot's address is tested and the robot added; the map is made from the restaurant's floor plan
in the console (opened from the setup page in a new tab; its measured distances within 2 % of
the plan's truth); back on the setup page the pass, the robot's home and two tables are put on
the map (a tap, "Save where r1 stands", the keyboard); and the test trip is sent, loaded (Go),
delivered and collected, the robot back home. A second one, left at its table, goes on after the
site's time at a table (set in the console) and its dish is taken off the pass. A screenshot of
each step at tablet size.

The simulated robot lives in the room the plan draws (its map the plan's walls at their true
scale, as a robot that mapped the room would have), so the places tapped on the owner's map are
where the robot can drive. Waits are playwright's expectations (and the server's own state),
never sleeps."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

from serveur.app import App
from serveur.clock import ScaledClock
from serveur.core.engine import CoreConfig
from serveur.maps.floorplan import plan_to_map
from serveur.maps.mapio import save_map
from serveur.robot_sim import start_simulation
from tests.maps.plans import ROOM, plan
from tests.maps.test_floorplan import free_run, measures
from tests.web.test_a11y import violations
from tests.web.test_plan_ui import tap
from tests.web.test_ui import (
    SHOTS,
    TABLET,
    expect,
    pytestmark,  # noqa: F401
    to_screen,
)

PX_PER_M = 37.0
WALLS = 50  # the darkness the owner settles on: the walls stay, the tables and text drawn go
SPEED = 5.0  # the restaurant's clock, robots included, five times faster than life


async def test_a_new_owner_from_an_empty_database_to_a_delivered_trip(
    tmp_path: Path, browser: Any
) -> None:
    p = plan(px_per_m=PX_PER_M)
    (tmp_path / "plan.png").write_bytes(p.data)
    size = (round(p.right + p.left), round(p.bottom + p.top))  # the margins are equal
    mid_x, mid_y = (p.left + p.partition_x) / 2, (p.top + p.bottom) / 2
    # The robot's own map of the room (what its map_server serves): the plan's walls.
    room, _ = plan_to_map(p.data, WALLS, [], *measures(p, mid_y + 40, mid_x), 0.05)
    (tmp_path / "robot").mkdir()
    save_map(room, tmp_path / "robot" / "room.yaml")

    clock = ScaledClock(SPEED)
    sim = await start_simulation(
        1, port=0, map_path=tmp_path / "robot" / "room.yaml", clock=clock, ros=2
    )
    config = CoreConfig(heartbeat=10.0, ack_timeout=5.0)  # a loaded CI box's stalls
    app = await App(tmp_path / "new.db", port=0, setup=True, clock=clock, config=config).start()
    try:
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        context = await browser.new_context(viewport=TABLET, bypass_csp=True)
        page = await context.new_page()
        errors: list[str] = []
        context.on("weberror", lambda e: errors.append(str(e.error)))
        context.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        await page.goto(f"{base}/setup.html#setup={app.setup_code}")
        step = page.locator(".steps [aria-current=step]")

        # 1. The owner's account.
        await expect(step).to_have_text("You")
        await page.get_by_label("Your user name").fill("ana")
        await page.get_by_label("Password (at least 8 characters)").fill("a long pass")
        await page.get_by_label("The same password again").fill("a long pass")
        await page.screenshot(path=str(SHOTS / "first-run-1-owner.png"), full_page=True)
        await page.get_by_role("button", name="Create my account").click()

        # 2. The restaurant (the address this tablet used is kept).
        await expect(step).to_have_text("Restaurant")
        await page.get_by_label("Restaurant name").fill("Chez Ana")
        await page.screenshot(path=str(SHOTS / "first-run-2-restaurant.png"), full_page=True)
        await page.get_by_role("button", name="Save and go on").click()

        # 3. The robot: its address tested, then added.
        await expect(step).to_have_text("Robots")
        await page.get_by_label("Robot address").fill(sim.urls[0])
        await page.get_by_role("button", name="Test the address").click()
        await expect(page.locator("#robot-found")).to_have_text("Found: a ROS 2 robot (Nav2).")
        await page.screenshot(path=str(SHOTS / "first-run-3-robots.png"), full_page=True)
        await page.get_by_role("button", name="Add this robot").click()
        await expect(page.get_by_role("list", name="Robots added")).to_have_text("r1 added")
        await page.get_by_role("button", name="Done with robots").click()
        await expect(step).to_have_text("Places")

        # 4. The map from the floor plan, in the console: a new tab, logged in already.
        # (The server has r1's own map meanwhile: a robot brings it when it connects.)
        async with context.expect_page() as opened:
            await page.get_by_role("link", name="Open the console (new tab)").click()
        console = await opened.value
        await expect(console.locator("body")).to_have_attribute("data-connection", "online")
        await console.get_by_role("tab", name="Restaurant").click()
        section = console.get_by_role("region", name="Map from the floor plan")
        await section.get_by_label("Floor plan (PNG or JPEG)").set_input_files(
            str(tmp_path / "plan.png")
        )
        canvas = section.get_by_role("img", name="The floor plan: dark is wall")
        await canvas.scroll_into_view_if_needed()
        slider = section.get_by_label("Darkness of the walls")
        await slider.evaluate(
            f"(s) => {{ s.value = {WALLS}; s.dispatchEvent(new Event('input')); }}"
        )
        await section.get_by_role("button", name="Measure across").click()
        await tap(console, canvas, p.left, mid_y + 40, size)
        await tap(console, canvas, p.right, mid_y + 40, size)
        await section.get_by_label("Measured across (m)").fill(str(ROOM[0]))
        await section.get_by_role("button", name="Measure along").click()
        await tap(console, canvas, mid_x, p.top, size)
        await tap(console, canvas, mid_x, p.bottom, size)
        await section.get_by_label("Measured along (m)").fill(str(ROOM[1]))
        await section.get_by_role("button", name="Check the map").click()
        status = section.get_by_role("status")
        await expect(status).to_contain_text("The map will be 17.")
        await section.scroll_into_view_if_needed()
        await console.screenshot(path=str(SHOTS / "first-run-4-map.png"), full_page=True)
        await section.get_by_role("button", name="Use this map").click()
        await expect(status).to_contain_text("The map is replaced")
        stored = await app.store.site_map.get()
        assert stored is not None and stored.source == "floor plan (plan.png)"
        grid = np.frombuffer(stored.cells, dtype=np.int8).reshape(stored.height, stored.width)
        col = int(mid_x / PX_PER_M / 0.05)  # the dining room's middle
        row = stored.height // 2
        # Wall to partition across the dining room, wall to wall along it: the plan's truth.
        assert free_run(grid[row], col) * 0.05 == pytest.approx(10.0, rel=0.02)
        assert free_run(grid[:, col], row) * 0.05 == pytest.approx(ROOM[1], rel=0.02)

        # 5. Back on the setup page: the places, on the new map.
        await page.bring_to_front()
        check = page.get_by_role("list", name="What a trip needs")
        await expect(check).to_contain_text("The kitchen pass: not placed yet")
        await page.get_by_role("button", name="Save where r1 stands").click()
        form = page.get_by_role("group", name="What is where r1 stands?")
        await expect(form.get_by_role("radio", name="A robot's home")).to_be_checked()
        await page.get_by_role("button", name="Save this place").click()
        await expect(check).to_contain_text("r1's home: r1 home")
        home = await app.store.waypoints.get_waypoint("r1 home")
        # The pass, tapped 1.5 m above the robot; a table tapped 2.5 m to its left.
        await page.mouse.click(*await to_screen(page, home.x, home.y + 1.5))
        form = page.get_by_role("group", name="What is here?")
        await expect(form.get_by_role("radio", name="The kitchen pass")).to_be_checked()
        await page.get_by_role("button", name="Save this place").click()
        await expect(check).to_contain_text("The kitchen pass: Pass")
        await page.mouse.click(*await to_screen(page, home.x - 2.5, home.y))
        await expect(form.get_by_role("radio", name="A table")).to_be_checked()
        await expect(page.get_by_label("Table number or name")).to_have_value("T1")
        await page.get_by_role("button", name="Save this place").click()
        await expect(check).to_contain_text("1 table: T1")
        # A second table from the keyboard: the mark starts in the middle of the map (where
        # the robot stands), Shift+arrows move it half a metre, Enter picks the spot.
        await page.locator("#map").focus()
        for key in ["Shift+ArrowLeft"] * 6 + ["Shift+ArrowDown"] * 2 + ["Enter"]:
            await page.keyboard.press(key)
        await expect(page.get_by_label("Table number or name")).to_have_value("T2")
        await expect(page.get_by_role("radio", name="A table")).to_be_focused()
        await page.keyboard.press("Tab")  # to the table's name
        await page.keyboard.press("Enter")  # the form's first button: Save
        await expect(check).to_contain_text("2 tables: T1, T2")
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "first-run-5-places.png"), full_page=True)
        await page.get_by_role("button", name="Next: a test trip").click()

        # 6. The test trip: loaded at the pass (Go), at the table, collected, home again.
        await expect(step).to_have_text("Test trip")
        await expect(page.get_by_role("combobox", name="Table", exact=True)).to_have_value("T1")
        progress = page.locator("#trip-progress")
        await page.get_by_role("button", name="Send the test trip").click()
        await expect(progress).to_have_text("r1 waits to be loaded.")
        await page.get_by_role("button", name="Go", exact=True).click()
        await expect(progress).to_have_text("r1 is at T1.")
        await expect(page.locator("#trip-how")).to_contain_text("within 3 minutes")
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "first-run-6-trip.png"), full_page=True)
        await page.get_by_role("button", name="Food collected").click()
        await expect(progress).to_have_text(
            "Delivered to T1, and r1 is back home, ready for the first service."
        )
        (order,) = await app.store.orders.list_orders()
        assert (order.table, order.status.value) == ("T1", "delivered")
        await page.screenshot(path=str(SHOTS / "first-run-7-delivered.png"), full_page=True)

        # Nobody at the table: after the site's time at a table (10 s here, set in the console)
        # the robot goes on by itself, and the test dish is taken off the pass.
        await console.bring_to_front()
        await console.get_by_label("Wait at a table (seconds)").fill("10")
        await console.get_by_role("button", name="Save settings").click()
        await expect(console.get_by_text("Settings saved: they apply now")).to_be_visible()
        await page.bring_to_front()
        await page.get_by_role("button", name="Send the test trip").click()
        await page.get_by_role("button", name="Go", exact=True).click()
        await expect(progress).to_contain_text("Nobody pressed Food collected within 10 s")
        await expect(progress).to_have_attribute("data-dish", "voided")
        orders = {o.id: o.status.value for o in await app.store.orders.list_orders()}
        assert sorted(orders.values()) == ["delivered", "voided"], orders
        await page.get_by_role("link", name="Open the console").click()
        await expect(page.get_by_test_id("who")).to_contain_text("ana")
        assert errors == []
        await context.close()
    finally:
        await app.close()
        await sim.close()
