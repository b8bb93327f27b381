"""The first-run setup page in Chromium (issue 29): a new owner opens the setup link on a phone,
chooses their password (a mismatch and a short one said in words), names the restaurant, its
languages and the address tablets use, adds a robot (its address tested live), gives it a home
where it stands on the map (the room's pass and tables are there already), reaches the test
trip and lands on the console logged in as the owner. Leaving after the first step and opening
the page again resumes at the restaurant step. Without a map, the places step says where to
make one and shows it as soon as there is one. Nothing scrolls sideways at 390 px; axe finds
nothing serious; a screenshot of each step is saved. (tests/web/test_first_service.py walks
the whole way on a tablet: the map from the floor plan, the places tapped, the trip delivered.)"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from serveur.app import App
from serveur.maps.navigation import demo_map_path, load_demo
from serveur.robot_sim import start_simulation
from tests.security.test_first_run import call
from tests.subprocess_server import free_port
from tests.web.conftest import sideways
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    pytestmark,  # noqa: F401
)

PHONE = {"width": 390, "height": 844}


async def test_a_new_owner_sets_the_restaurant_up_from_a_phone(
    tmp_path: Path, browser: Any
) -> None:
    nav_map, waypoints = load_demo()
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), ros=2)
    app = await App(
        tmp_path / "new.db", port=0, setup=True, nav_map=nav_map, waypoints=waypoints
    ).start()
    try:
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        context = await browser.new_context(viewport=PHONE, bypass_csp=True)
        page = await context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        await page.goto(f"{base}/setup.html#setup={app.setup_code}")
        # The code leaves the address bar (and the history) as the page starts.
        await page.wait_for_function("!window.location.href.includes('setup=')")

        step = page.locator(".steps [aria-current=step]")
        await expect(step).to_have_text("You")
        await page.get_by_label("Your user name").fill("ana")
        await page.get_by_label("Password (at least 8 characters)").fill("a long pass")
        await page.get_by_label("The same password again").fill("a long pas")
        await page.get_by_role("button", name="Create my account").click()
        await expect(page.get_by_role("alert")).to_have_text("The two passwords are not the same.")
        assert await app.store.accounts.count_users() == 0
        await page.get_by_label("The same password again").fill("a long pass")
        wide, inner = await sideways(page)
        assert wide <= inner, (wide, inner)
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "setup-1-owner.png"), full_page=True)
        await page.get_by_role("button", name="Create my account").click()
        await expect(step).to_have_text("Restaurant")
        assert [u.name for u in await app.store.accounts.list_users()] == ["ana"]

        # Left here and opened again (the session kept on this phone): resumes at step 2.
        await page.goto(f"{base}/setup.html")
        await expect(step).to_have_text("Restaurant")
        address = page.get_by_label("Address tablets use to reach this box")
        await expect(address).to_have_value(base)  # what this phone used
        await page.get_by_label("Restaurant name").fill("Chez Ana")
        await expect(page.get_by_role("checkbox", name="中文")).to_be_checked()  # all offered
        await page.get_by_role("checkbox", name="Bahasa Melayu").uncheck()
        await page.get_by_label("Language for screens that have no choice").select_option("zh")
        await address.fill("http://192.168.1.20:8765/")
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "setup-2-restaurant.png"), full_page=True)
        await page.get_by_role("button", name="Save and go on").click()
        await expect(step).to_have_text("Robots")

        # A robot: its address tested live (a wrong one said in words), then added.
        found = page.locator("#robot-found")
        # A bare IP is completed with rosbridge's port (nothing listens on 127.0.0.2 here).
        await page.get_by_label("Robot address").fill("127.0.0.2")
        await page.get_by_role("button", name="Test the address").click()
        await expect(page.get_by_label("Robot address")).to_have_value("ws://127.0.0.2:9090")
        await expect(found).to_contain_text("Cannot reach the robot")
        await page.get_by_label("Robot address").fill(f"ws://127.0.0.1:{free_port()}")
        await page.get_by_role("button", name="Test the address").click()
        await expect(found).to_contain_text("Cannot reach the robot: nothing listens there")
        await expect(page.get_by_role("button", name="Add this robot")).to_be_disabled()
        # Typed as a robot's label gives it: the host and port, no scheme (a bare host would
        # get rosbridge's 9090); the field shows the address as it will be used.
        await page.get_by_label("Robot address").fill(sim.urls[0].removeprefix("ws://"))
        await page.get_by_role("button", name="Test the address").click()
        await expect(found).to_have_text("Found: a ROS 2 robot (Nav2).")
        await expect(page.get_by_label("Robot address")).to_have_value(sim.urls[0])
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "setup-3-robots.png"), full_page=True)
        await page.get_by_role("button", name="Add this robot").click()
        await expect(page.get_by_role("list", name="Robots added")).to_have_text("r1 added")
        robots = await app.store.robots.list_robots()
        assert [(x.name, x.url, x.link) for x in robots] == [("r1", sim.urls[0], {"ros": "2"})]
        await expect(page.get_by_label("Robot name")).to_have_value("r2")
        await page.get_by_role("button", name="Done with robots").click()
        await expect(step).to_have_text("Places")
        assert app.core is not None
        site = app.core.site
        assert (site.name, site.public_url) == ("Chez Ana", "http://192.168.1.20:8765")
        assert site.languages == ["en", "zh"] and site.language == "zh"

        # The places: the demo room has its pass and tables, r1 no home yet.
        check = page.get_by_role("list", name="What a trip needs")
        await expect(check).to_contain_text("The kitchen pass: pass")
        await expect(check).to_contain_text("16 tables: T1, T2")
        await expect(check).to_contain_text("r1's home: not placed yet")
        await expect(page.locator("#map")).to_have_attribute("data-draws", re.compile(r"[1-9]"))
        trip = page.get_by_role("button", name="Next: a test trip")
        await expect(trip).to_be_disabled()
        await page.get_by_role("button", name="Save where r1 stands").click()
        form = page.get_by_role("group", name="What is where r1 stands?")
        await expect(form.get_by_role("radio", name="A robot's home")).to_be_checked()
        wide, inner = await sideways(page)
        assert wide <= inner, (wide, inner)
        assert await violations(page) == []
        await page.screenshot(path=str(SHOTS / "setup-4-places.png"), full_page=True)
        await page.get_by_role("button", name="Save this place").click()
        await expect(check).to_contain_text("r1's home: r1 home")
        (r1,) = await app.store.robots.list_robots()
        assert r1.home == "r1 home"
        await trip.click()
        await expect(step).to_have_text("Test trip")
        await expect(page.get_by_role("combobox", name="Table", exact=True)).to_have_value(
            "T1"
        )  # the nearest to r1's home
        wide, inner = await sideways(page)
        assert wide <= inner, (wide, inner)

        # On to the console, logged in as the owner (no login form).
        await page.get_by_role("link", name="Open the console").click()
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await expect(page.get_by_test_id("who")).to_contain_text("ana")
        assert errors == []
        await context.close()
    finally:
        await app.close()
        await sim.close()


async def test_without_the_link_the_page_says_where_to_go(tmp_path: Path, browser: Any) -> None:
    app = await App(tmp_path / "new.db", port=0, setup=True).start()
    try:
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        context = await browser.new_context(viewport=PHONE)
        page = await context.new_page()
        await page.goto(f"{base}/setup.html")
        await expect(page.get_by_role("alert")).to_contain_text("needs the setup link")
        await expect(page.locator("#owner-form")).to_be_hidden()
        await context.close()
    finally:
        await app.close()


async def test_without_a_map_the_places_step_says_where_to_make_one(
    tmp_path: Path, browser: Any
) -> None:
    """No map yet: the places step says so and where to make one (the console, in a new tab),
    then shows the map by itself once there is one (here a robot's own, which it brings when
    it is added from elsewhere). Opened again, the page resumes at the first step not done."""
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), ros=2)
    app = await App(tmp_path / "new.db", port=0, setup=True).start()
    try:
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        context = await browser.new_context(viewport=PHONE, bypass_csp=True)
        page = await context.new_page()
        await page.goto(f"{base}/setup.html#setup={app.setup_code}")
        step = page.locator(".steps [aria-current=step]")
        await page.get_by_label("Password (at least 8 characters)").fill("a long pass")
        await page.get_by_label("The same password again").fill("a long pass")
        await page.get_by_role("button", name="Create my account").click()
        await page.get_by_label("Restaurant name").fill("Chez Ana")
        await page.get_by_role("button", name="Save and go on").click()
        await page.get_by_role("button", name="Done with robots").click()
        await expect(step).to_have_text("Places")
        await expect(page.get_by_text("There is no map of the restaurant yet.")).to_be_visible()
        link = page.get_by_role("link", name="Make the map in the console (new tab)")
        await expect(link).to_have_attribute("target", "_blank")
        await expect(page.get_by_role("button", name="Next: a test trip")).to_be_disabled()
        wide, inner = await sideways(page)
        assert wide <= inner, (wide, inner)
        assert await violations(page) == []

        # The robot added in the console (another tablet): it brings its map, shown here.
        async with connect(app.url) as ws:
            await call(ws, clientmsg="login", username="owner", password="a long pass")
            made = await call(
                ws, clientmsg="create", type="robot", name="r1", url=sim.urls[0], link={"ros": "2"}
            )
            assert made["servermsg"] == "ok", made
        await expect(page.locator("#map")).to_be_visible()
        await expect(link).to_be_hidden()
        check = page.get_by_role("list", name="What a trip needs")
        await expect(check).to_contain_text("r1's home: not placed yet")
        await expect(page.get_by_role("button", name="Save where r1 stands")).to_be_enabled()

        await page.goto(f"{base}/setup.html")  # opened again: the places are not done
        await expect(step).to_have_text("Places")
        await context.close()
    finally:
        await app.close()
        await sim.close()
