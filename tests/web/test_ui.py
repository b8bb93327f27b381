"""The web UI in a real Chromium, driven only by clicks, drags and keys, against the real server,
simulated robots and SQLite (conftest's ``restaurant()`` harness, with a looser heartbeat).

Chromium is Debian's ``/usr/bin/chromium`` (``.ci/run`` installs it), driven by the playwright
package; playwright's own browser download is never used. No sleeps: every wait is one of
playwright's auto-retrying ``expect`` assertions or ``Client.until`` on the server's updates.
Screenshots for the README are written to ``docs/screenshots/`` when SERVEUR_SCREENSHOTS says so.
"""

from __future__ import annotations

import asyncio
import base64
import contextlib
import json
import math
import os
import re
import tempfile
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from serveur.app import App, RobotSpec
from serveur.clock import ScaledClock
from serveur.core.engine import CoreConfig
from serveur.maps.navigation import demo_map_path, load_demo
from serveur.robot_sim import start_simulation
from tests.conftest import TIME_SCALE, Client, Restaurant, make_app
from tests.web.conftest import import_playwright, needs_browser

playwright_api = import_playwright()
Browser = playwright_api.Browser
Page = playwright_api.Page
expect = playwright_api.expect

TABLET = {"width": 1280, "height": 800}  # a 10-inch tablet in landscape
# Screenshots are always taken (that exercises rendering) but only land in docs/screenshots when
# asked: `SERVEUR_SCREENSHOTS=docs/screenshots python3 -m pytest tests/web/test_ui.py`, so a test
# run does not rewrite tracked files.
SHOTS = Path(os.environ.get("SERVEUR_SCREENSHOTS") or tempfile.mkdtemp(prefix="serveur-shots-"))
_, WAYPOINTS = load_demo()

# One browser for the module (each test opens its own windows), so every test runs on the
# module's event loop. Without Debian's chromium each test is skipped, the reason naming what
# to install (in CI each fails instead). The other modules of browser tests import this.
pytestmark = [needs_browser, pytest.mark.asyncio(loop_scope="module")]
expect.set_options(timeout=20_000)


class Screens:
    """Pages of one browser context, each recording its console errors and uncaught exceptions."""

    def __init__(self, browser: Any, base: str, token: str = "") -> None:
        self.browser = browser
        self.base = base
        self.token = token  # given to each page by its setup link (#token=...), as on a device
        self.errors: list[str] = []
        self.sent: list[dict[str, Any]] = []  # every message the pages sent on their websockets

    async def open(
        self,
        path: str,
        ws_route: Any = None,
        *,
        online: bool = True,
        token: str | None = None,
        viewport: dict[str, int] | None = None,
        bypass_csp: bool = False,
    ) -> Any:
        """The page at ``path``, online unless told otherwise. ``bypass_csp`` lets a test
        inject axe (as tests/web/test_a11y.py does); without it a CSP violation is an error."""
        # One context (window) per screen, as on separate devices: a second tab in the same
        # window would be a hidden tab, whose animation frames Chromium pauses.
        context = await self.browser.new_context(viewport=viewport or TABLET, bypass_csp=bypass_csp)
        page = await context.new_page()
        if ws_route is not None:
            await page.route_web_socket(re.compile(r"/ws$"), ws_route)
        page.on(
            "console",
            lambda m: (
                self.errors.append(f"{path}: console {m.text}") if m.type == "error" else None
            ),
        )
        page.on("pageerror", lambda e: self.errors.append(f"{path}: exception {e}"))
        page.on(
            "websocket", lambda ws: ws.on("framesent", lambda f: self.sent.append(json.loads(f)))
        )
        token = self.token if token is None else token
        await page.goto(self.base + path + (f"#token={token}" if token else ""))
        if online:
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        return page

    def assert_no_errors(self, allowed: re.Pattern[str] | None = None) -> None:
        errors = [e for e in self.errors if not (allowed and allowed.search(e))]
        assert errors == [], errors


def ui_app(r_db: Path, clock: ScaledClock, specs: list[RobotSpec], port: int = 0) -> App:
    """The harness's app (conftest.make_app) with a heartbeat a loaded machine can keep: the
    browser shares the 2 CI cores with the server and the robots, and a stalled sim tick must
    not turn the robot Offline in the middle of a click-through."""
    cfg = CoreConfig(heartbeat=10.0, ack_timeout=5.0, auto_depart=True)
    return make_app(r_db, clock, specs, port, config=cfg, backups=r_db.parent / "backups")


@contextlib.asynccontextmanager
async def ui_restaurant(
    tmp_path: Path, robots: int = 1, link: dict[str, str] | None = None
) -> AsyncIterator[Restaurant]:
    """conftest.restaurant() with ui_app; ``link``: more link options for every robot."""
    clock = ScaledClock(TIME_SCALE)
    sim = await start_simulation(
        robots, port=0, map_path=demo_map_path(), time_scale=TIME_SCALE, clock=clock
    )
    specs = [
        RobotSpec(rb.name, url, f"home{i + 1}", link=dict(link or {}))
        for i, (rb, url) in enumerate(zip(sim.robots, sim.urls, strict=True))
    ]
    db = tmp_path / "serveur.db"
    r = Restaurant(ui_app(db, clock, specs), sim, clock, db, specs, [], make=ui_app)
    try:
        await r.app.start()
        r.token = await r.app.issue_token("staff", label="ui tests")
        yield r
    finally:
        for c in r.clients:
            await c.close()
        await r.app.close()
        await sim.close()


def http_base(r: Restaurant) -> str:
    return r.http_base


async def staff_client(r: Restaurant) -> Client:
    """A staff connection subscribed to what the pages show, once every robot's link is up:
    the server starts its links as it starts, and a command before one answers is refused
    (not allowed while the robot is Offline)."""
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "waypoints", "pose:r1")
    for spec in r.specs:
        await c.until(
            lambda name=spec.name: c.robot(name).get("status") not in (None, "Offline"),
            what=f"{spec.name}'s link up",
        )
    return c


def near(p: dict[str, Any], x: float, y: float, tol: float) -> bool:
    return p is not None and math.hypot(p["x"] - x, p["y"] - y) <= tol


def angle_diff(a: float, b: float) -> float:
    return abs((a - b + math.pi) % (2 * math.pi) - math.pi)


async def log_in(page: Any, user: str, password: str) -> Any:
    """Fill the page's login dialog and press "Log in"; the dialog."""
    form = page.get_by_role("dialog").filter(has_text="Log in to serveur")
    await form.get_by_label("Login").fill(user)
    await form.get_by_label("Password").fill(password)
    await form.get_by_role("button", name="Log in").click()
    return form


@contextlib.asynccontextmanager
async def owner_tab(
    browser: Any, r: Restaurant, tab: str, **options: Any
) -> AsyncIterator[tuple[Any, list[str]]]:
    """The console on a tablet, logged in as the owner, on ``tab``: the page and the errors
    it logged (a test asserts there are none). ``bypass_csp``: axe is injected at the end (as
    tests/web/test_a11y.py does); ``options`` go to the browser context."""
    context = await browser.new_context(viewport=TABLET, bypass_csp=True, **options)
    page = await context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    try:
        await page.goto(f"{http_base(r)}/")
        await log_in(page, "owner", r.app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await page.get_by_role("tab", name=tab).click()
        yield page, errors
    finally:
        await context.close()


def lagging(held: dict[str, bool]) -> Callable[[Any], None]:
    """A websocket route for a lagging tablet: the server's updates are dropped on their way to
    the page while ``held["on"]`` (its requests and their replies still pass)."""

    def relay(ws: Any) -> None:
        server = ws.connect_to_server()

        def down(frame: str | bytes) -> None:
            if held["on"] and json.loads(frame).get("servermsg") == "update":
                return
            ws.send(frame)

        server.on_message(down)
        ws.on_message(server.send)

    return relay


async def dismiss_toasts(page: Any) -> None:
    for button in await page.get_by_role("button", name="Dismiss").all():
        await button.click()
    await expect(page.locator(".toast")).to_have_count(0)


async def test_a_whole_delivery_by_clicking(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        # Other dishes already waiting at the pass; they stay pending throughout.
        for dish, tbl in [("Satay", "T7"), ("Teh tarik", "T3"), ("Rendang", "T12")]:
            await c.ok("create", type="order", dish=dish, table=tbl)
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        # The robot's and the table's screens run on their own device tokens, as deployed.
        robot_token = await r.app.issue_token("robot-screen", robot="r1")
        robot = await screens.open("/robot/r1", token=robot_token)
        table = await screens.open(
            "/table/T3", token=await r.app.issue_token("table-screen", table="T3")
        )
        await expect(
            robot.get_by_text(
                "Not taking deliveries. Staff start me from their phones, or sign in here."
            )
        ).to_be_visible()
        await expect(table.get_by_role("list", name="Ready in the kitchen")).to_have_text(
            "Teh tarik"
        )

        # New order: table T3, one Laksa from the menu, sent to the kitchen, which marks it
        # ready: it waits at the pass.
        await staff.get_by_role("tab", name="New order").click()
        await staff.get_by_role("button", name="Table T3").click()
        await staff.get_by_role("button", name="Add Laksa").click()
        await staff.get_by_role("button", name="Send to the kitchen").click()
        await expect(staff.get_by_text("Sent to the kitchen: Laksa (T3)")).to_be_visible()
        await dismiss_toasts(staff)
        await staff.get_by_role("tab", name="Kitchen").click()
        await staff.get_by_role("button", name="Ready: Laksa for T3").click()
        await expect(table.get_by_role("list", name="Ready in the kitchen")).to_contain_text(
            "Laksa"
        )

        # Send food: the dish is pending with its table and waiting time; into the cart; send.
        await staff.get_by_role("tab", name="Send food").click()
        row = staff.get_by_role("row").filter(has_text="Laksa")
        await expect(row).to_contain_text("T3")
        await expect(row.locator("td.waiting")).to_have_text(re.compile(r"\d+ (s|min)"))
        await staff.get_by_role("button", name="Add to cart: Laksa for T3").click()
        cart = staff.get_by_role("list", name="Cart")
        await expect(cart).to_contain_text("Laksa")
        await expect(staff.get_by_role("row")).to_have_count(4)  # header + the 3 others
        await staff.screenshot(path=str(SHOTS / "staff-issue-task.png"))
        await staff.get_by_role("button", name=re.compile(r"^Send 1 dish")).click()
        await expect(staff.get_by_text("Sent: 1 trip (T3)")).to_be_visible()
        await expect(staff.get_by_role("list", name="Trips")).to_contain_text("T3")
        [oid] = [o["id"] for o in c.records["orders"].values() if o["dish"] == "Laksa"]
        await c.until(lambda: c.order(oid).get("status") == "assigned", what="order assigned")

        # Start delivering: the robot takes the trip and leaves.
        await staff.get_by_role("tab", name="Map & robots").click()
        await staff.get_by_role("button", name="Start delivering r1").click()
        await expect(robot.locator(".destination")).to_have_text("Table T3")
        home = WAYPOINTS["home1"]
        await c.until(
            lambda: not near(c.streams.get("pose:r1"), home.x, home.y, 0.5), what="robot leaves"
        )
        await dismiss_toasts(staff)
        await staff.screenshot(path=str(SHOTS / "staff-map.png"))

        # At the table: the robot screen shows this table's dishes; the guest confirms.
        collected = robot.get_by_role("button", name="Food collected")
        await expect(collected).to_be_visible()
        await expect(robot.get_by_role("list", name="Your dishes")).to_have_text("Laksa")
        await robot.screenshot(path=str(SHOTS / "robot-delivered.png"))
        await collected.click()
        await expect(robot.get_by_text("Awaiting orders")).to_be_visible()
        rb = await c.status("r1", "Awaiting")
        assert near(rb, home.x, home.y, 0.4)

        # The table screen shows the dish served; the store agrees.
        await expect(table.get_by_role("list", name="Served")).to_contain_text("Laksa")
        await expect(table.get_by_role("list", name="On the way")).to_contain_text("Nothing")
        await table.screenshot(path=str(SHOTS / "table.png"))
        orders = {o.dish: (o.table, o.status.value) for o in await r.app.store.orders.list_orders()}
        assert orders["Laksa"] == ("T3", "delivered")
        assert {o[1] for d, o in orders.items() if d != "Laksa"} == {"pending"}
        await expect(staff.get_by_role("listitem").filter(has_text="r1")).to_contain_text("Free")
        screens.assert_no_errors()


async def test_stop_then_cancel_with_confirmation(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        await c.ok("control", robot="r1", action="auto")
        oid = (await c.ok("create", type="order", dish="Curry", table="T16"))["order"]["id"]
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        robot = await screens.open("/robot.html?robot=r1")
        await c.ok("create", type="task", orders=[oid])

        # Stop from the robot's own screen while it drives to the far table.
        await expect(robot.locator(".destination")).to_have_text("Table T16")
        await robot.get_by_role("button", name="Stop").click()
        await expect(robot.get_by_role("heading", name="Stopped")).to_be_visible()
        await c.status("r1", "Stopped")

        # The console offers only what Stopped allows (skip: on a trip, leave this table).
        actions = staff.get_by_role("group", name="Actions for r1")
        await expect(actions.get_by_role("button")).to_have_text(
            ["Continue", "Skip table", "Cancel trip", "Take control"]
        )
        # Take control is one step, but with a trip under way it asks first.
        await actions.get_by_role("button", name="Take control r1").click()
        take = staff.get_by_role("dialog", name="Take control of r1?")
        await expect(take).to_contain_text("the dishes for T16 not served yet go back")
        await take.get_by_role("button", name="No, let it carry on").click()
        await expect(take).to_have_count(0)
        assert c.robot("r1")["status"] == "Stopped"

        # Cancel asks first; "No" keeps the trip.
        await staff.get_by_role("button", name="Cancel trip r1").click()
        dialog = staff.get_by_role("dialog", name="Cancel r1's trip?")
        await expect(dialog).to_be_visible()
        await dialog.get_by_role("button", name="No, keep it").click()
        await expect(dialog).to_have_count(0)
        assert (await c.ok("order", robot="r1"))["orders"][0]["status"] == "assigned"
        assert c.robot("r1")["status"] == "Stopped"

        # From the robot screen, "Yes" cancels: the dish is pending again, the robot goes home.
        await robot.get_by_role("button", name="Cancel").click()
        await (
            robot.get_by_role("dialog")
            .get_by_role("button", name="Yes, cancel the delivery")
            .click()
        )
        await expect(robot.get_by_text("Awaiting orders")).to_be_visible()
        await c.until(lambda: c.order(oid).get("status") == "pending", what="order pending")
        await staff.get_by_role("tab", name="Send food").click()
        await expect(staff.get_by_role("button", name="Add to cart: Curry for T16")).to_be_visible()
        # Free at home: Take control in one press, no "Pause deliveries" first, nothing asked.
        await c.status("r1", "Awaiting")
        await staff.get_by_role("tab", name="Map & robots").click()
        await actions.get_by_role("button", name="Take control r1").click()
        await c.status("r1", "Manual")
        await expect(actions.get_by_role("button")).to_have_text(["Done driving"])
        screens.assert_no_errors()


def map_cells(
    m: dict[str, Any], centre: tuple[float, float], within: float
) -> tuple[tuple[float, float], tuple[float, float]]:
    """The centres of a solidly occupied and a solidly free cell near `centre`, off waypoints."""
    grid = np.frombuffer(base64.b64decode(m["data"]), np.int8).reshape(m["height"], m["width"])
    res, (ox, oy, _) = m["resolution"], m["origin"]
    k = 4  # a 9x9 block of the same kind, so rounding cannot land on an edge

    def find(pred: Any) -> tuple[float, float]:
        for j in range(k, m["height"] - k, 3):
            for i in range(k, m["width"] - k, 3):
                if pred(grid[j - k : j + k + 1, i - k : i + k + 1]).all():
                    x, y = ox + (i + 0.5) * res, oy + (j + 0.5) * res
                    if math.hypot(x - centre[0], y - centre[1]) > within:
                        continue
                    if all(math.hypot(w.x - x, w.y - y) > 1.0 for w in WAYPOINTS.values()):
                        return x, y
        raise AssertionError("no such cell")

    return find(lambda b: b >= 90), find(lambda b: b == 0)


async def to_screen(page: Any, x: float, y: float) -> tuple[float, float]:
    """Page coordinates of a map position, from the view the canvas publishes."""
    canvas = page.locator("#map")
    box = await canvas.bounding_box()
    scale = float(await canvas.get_attribute("data-scale"))
    ox = float(await canvas.get_attribute("data-origin-x"))
    oy = float(await canvas.get_attribute("data-origin-y"))
    sx, sy = ox + x * scale, oy - y * scale
    assert 0 < sx < box["width"] and 0 < sy < box["height"], (x, y, "off the visible map")
    return box["x"] + sx, box["y"] + sy


async def drag(page: Any, start: tuple[float, float], heading: float, length: float = 60) -> None:
    x, y = start
    await page.mouse.move(x, y)
    await page.mouse.down()
    end = (x + length * math.cos(heading), y - length * math.sin(heading))  # screen y is down
    await page.mouse.move(*end, steps=6)
    await page.mouse.up()


async def pixel(page: Any, px: float, py: float) -> list[int]:
    box = await page.locator("#map").bounding_box()
    return list(
        await page.locator("#map").evaluate(
            """(c, [x, y]) => {
                const d = window.devicePixelRatio || 1;
                const at = (v) => Math.round(v * d);
                return [...c.getContext("2d").getImageData(at(x), at(y), 1, 1).data];
            }""",
            [px - box["x"], py - box["y"]],
        )
    )


async def test_calibrate_move_here_teleop_and_waypoints(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        m = (await c.ok("data", topics=["map"]))["data"]["map"]
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        await expect(staff.get_by_role("button", name="Take control r1")).to_be_visible()
        await staff.get_by_role("button", name="Take control r1").click()
        await c.status("r1", "Manual")
        calibrate = staff.get_by_role("button", name="Set where the robot is")
        await expect(calibrate).to_be_enabled()

        # Zoom in and pan: the conversion must follow the view.
        await staff.get_by_role("button", name="Zoom in").click()
        await staff.get_by_role("button", name="Zoom in").click()
        box = await staff.locator("#map").bounding_box()
        centre = (box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        before = float(await staff.locator("#map").get_attribute("data-origin-x"))
        await drag(staff, centre, math.pi, 40)  # pan right-to-left by 40 px
        after = float(await staff.locator("#map").get_attribute("data-origin-x"))
        assert after == pytest.approx(before - 40, abs=1.5)

        # What is drawn at a map position is the map there: a wall is dark, a floor cell white.
        wall, floor = map_cells(m, (8.0, 6.0), 3.0)
        assert max((await pixel(staff, *await to_screen(staff, *wall)))[:3]) < 90
        assert min((await pixel(staff, *await to_screen(staff, *floor)))[:3]) > 230

        # Set where the robot is: press where it "really" is, drag toward its heading (east).
        await calibrate.click()
        await expect(calibrate).to_have_attribute("aria-pressed", "true")
        await drag(staff, await to_screen(staff, 4.5, 9.0), 0.0)
        await c.until(
            lambda: (
                near(c.streams.get("pose:r1"), 4.5, 9.0, 0.15)
                and angle_diff(c.streams["pose:r1"]["yaw"], 0.0) < 0.2
            ),
            what="relocalised at (4.5, 9.0) facing east",
        )
        await expect(calibrate).to_have_attribute("aria-pressed", "false")

        # Move here: press on the destination, drag toward north.
        await staff.get_by_role("button", name="Move here").click()
        await drag(staff, await to_screen(staff, 8.0, 8.5), math.pi / 2)
        await c.until(
            lambda: (
                near(c.streams.get("pose:r1"), 8.0, 8.5, 0.3)
                and angle_diff(c.streams["pose:r1"]["yaw"], math.pi / 2) < 0.35
            ),
            what="robot reached (8.0, 8.5) facing north",
        )

        # Teleop from the keyboard: held W drives forward (north now), re-sent at 5 Hz while held,
        # and one zero twist on release.
        def twists() -> list[tuple[float, float, float]]:
            return [
                (m["vx"], m["vy"], m["wz"]) for m in screens.sent if m.get("action") == "teleop"
            ]

        y0 = c.streams["pose:r1"]["y"]
        await staff.locator("#map").click(position={"x": 5, "y": 5})  # focus the page, not a field
        await staff.keyboard.down("w")
        await c.until(lambda: c.streams["pose:r1"]["y"] > y0 + 0.1, what="teleop forward")
        await c.until(lambda: len(twists()) >= 3, what="the command repeated while held")
        assert set(twists()) == {(0.5, 0.0, 0.0)}
        await staff.keyboard.up("w")
        await c.until(lambda: twists()[-1] == (0.0, 0.0, 0.0), what="zero twist on release")

        # The joystick: pushing it right moves an omni robot to its right (east when facing north).
        x0 = c.streams["pose:r1"]["x"]
        pad = await staff.get_by_role("group", name="Joystick: drag to drive").bounding_box()
        cx, cy = pad["x"] + pad["width"] / 2, pad["y"] + pad["height"] / 2
        await staff.mouse.move(cx, cy)
        await staff.mouse.down()
        await staff.mouse.move(cx + pad["width"] / 2, cy, steps=3)
        await c.until(lambda: c.streams["pose:r1"]["x"] > x0 + 0.1, what="joystick sideways")
        assert twists()[-1][1] < 0 and twists()[-1][0] == pytest.approx(0, abs=0.05)
        await staff.mouse.up()
        await c.until(lambda: twists()[-1] == (0.0, 0.0, 0.0), what="zero twist on release")
        released = len(twists())

        # Waypoints: save the pose under a name; go to a waypoint by clicking it.
        await staff.get_by_label("Name", exact=True).fill("bar")
        await staff.get_by_role("button", name="Save this place").click()
        await expect(staff.get_by_role("button", name="Go to bar")).to_be_visible()
        pose = c.streams["pose:r1"]
        bar = await c.until(lambda: c.records["waypoints"].get("bar"), what="waypoint bar")
        assert near(bar, pose["x"], pose["y"], 0.2)
        t7 = WAYPOINTS["T7"]
        await staff.get_by_role("button", name="Go to T7").click()
        await c.until(
            lambda: near(c.streams.get("pose:r1"), t7.x, t7.y, 0.3), what="go-to reaches T7"
        )
        assert len(twists()) == released  # nothing was sent after the release
        await staff.get_by_role("button", name="Done driving r1").click()
        await c.status("r1", "Ready")
        await expect(calibrate).to_be_disabled()
        screens.assert_no_errors()


async def test_pages_reconnect_after_a_server_restart(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        robot = await screens.open("/robot/r1")
        table = await screens.open("/table/T5")
        await expect(robot.get_by_role("button", name="Activate this robot")).to_be_visible()

        await r.restart_server()
        c = await staff_client(r)
        await c.status("r1", "Ready")
        # Without a reload, every page is live again: a new order shows up...
        await c.ok("create", type="order", dish="Soup", table="T5")
        await staff.get_by_role("tab", name="Send food").click()
        await expect(staff.get_by_role("button", name="Add to cart: Soup for T5")).to_be_visible()
        await expect(table.get_by_role("list", name="Ready in the kitchen")).to_contain_text("Soup")
        # ...and a click on one page reaches the new server and shows on the others (once
        # that page is back online: a click while offline is refused, and says so).
        await expect(robot.locator("body")).to_have_attribute("data-connection", "online")
        await robot.get_by_role("button", name="Activate this robot").click()
        await expect(robot.get_by_text("Awaiting orders")).to_be_visible()
        await staff.get_by_role("tab", name="Map & robots").click()
        await expect(staff.get_by_role("button", name="Pause deliveries r1")).to_be_visible()
        for page in (staff, robot, table):
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        # The only errors allowed are the browser's own notes of refused connection attempts.
        screens.assert_no_errors(re.compile(r"WebSocket connection to .* failed"))


async def test_server_refusals_are_shown_and_gaps_resync(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        screens = Screens(browser, http_base(r), r.token)
        # A lagging tablet: the page's websocket goes through a relay that can drop updates.
        held = {"on": False}
        staff = await screens.open("/", ws_route=lagging(held))
        start = staff.get_by_role("button", name="Start delivering r1")
        await expect(start).to_be_visible()
        held["on"] = True
        await c.ok("control", robot="r1", action="manual")  # another tablet, unseen by this page
        await start.click()
        # The server refuses (r1 is under staff control now) and the person is told why,
        # in words, from the error's details: the robot's name and its status as staff say it.
        alert = staff.get_by_role("alert").filter(
            has_text="r1 now shows “Staff control”, so that cannot be done."
        )
        await expect(alert).to_be_visible()
        await expect(alert).not_to_contain_text("not_allowed_in_status")
        # Updates flow again; the next one (a new order) shows a seq gap, the page subscribes
        # again, and the fresh snapshot shows what the server has.
        held["on"] = False
        await c.ok("create", type="order", dish="Tea", table="T2")
        await expect(staff.get_by_role("button", name="Done driving r1")).to_be_visible()
        await expect(start).to_have_count(0)

        # Saving a waypoint under a taken name asks before replacing it.
        await staff.get_by_label("Name", exact=True).fill("T1")
        await staff.get_by_role("button", name="Save this place").click()
        dialog = staff.get_by_role("dialog", name="Replace the place T1?")
        await expect(dialog).to_be_visible()
        await dialog.get_by_role("button", name="No").click()
        await expect(dialog).to_have_count(0)
        assert c.records["waypoints"]["T1"]["x"] == WAYPOINTS["T1"].x
        screens.assert_no_errors()


async def test_logging_in_and_out_and_screen_setup_links(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        password = r.app.first_owner_password
        assert password
        screens = Screens(browser, http_base(r))  # a fresh device: no token yet
        staff = await screens.open("/", online=False)
        form = staff.get_by_role("dialog").filter(has_text="Log in to serveur")
        await expect(form).to_be_visible()
        await log_in(staff, "owner", "not the password")
        await expect(form.get_by_role("alert")).to_have_text("Wrong user name, password or token.")
        await log_in(staff, "owner", password)
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        await expect(form).to_be_hidden()
        await expect(staff.get_by_test_id("who")).to_have_text("owner (owner)")
        await expect(staff.get_by_role("button", name="Take control r1")).to_be_visible()
        # The session survives a reload (kept in this browser), and ends with "Log out".
        await staff.reload()
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        await staff.get_by_role("button", name="Log out").click()
        await expect(form).to_be_visible()
        await staff.reload()
        await expect(form).to_be_visible()

        # A robot screen set up by its link: the token leaves the address at once, and the
        # screen offers only what a robot screen may do.
        screens.token = await r.app.issue_token("robot-screen", robot="r1")
        robot = await screens.open("/robot/r1")
        assert "token" not in robot.url
        await expect(
            robot.get_by_text(
                "Not taking deliveries. Staff start me from their phones, or sign in here."
            )
        ).to_be_visible()
        await expect(robot.get_by_role("button", name="Activate this robot")).to_have_count(0)
        screens.token = await r.app.issue_token("table-screen", table="T3")
        table = await screens.open("/table/T3")
        assert "token" not in table.url
        screens.assert_no_errors(re.compile("401|4001|Unauthorized", re.I))


@pytest.mark.cuts_links  # its simulated robot stops before the server
async def test_the_owner_registers_a_robot_staff_cannot(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        # A robot the server does not know yet, on its own rosbridge port.
        extra = await start_simulation(
            1, port=0, map_path=demo_map_path(), time_scale=TIME_SCALE, clock=r.clock
        )
        try:
            screens = Screens(browser, http_base(r), r.token)
            staff = await screens.open("/")  # a staff device token: no form
            await expect(staff.get_by_role("button", name="Take control r1")).to_be_visible()
            await expect(staff.get_by_text("Register a robot")).to_be_hidden()

            screens.token = ""
            owner = await screens.open("/", online=False)
            await log_in(owner, "owner", r.app.first_owner_password or "")
            await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
            await owner.get_by_text("Register a robot").click()
            form = owner.get_by_role("form", name="Register a robot")
            # the free home spots are offered, home1 (r1's) is not
            await expect(form.get_by_label("Home spot")).to_have_value("home2")
            assert "home1" not in await form.get_by_label("Home spot").inner_text()

            # A name in use with another address: the server's refusal is shown.
            await form.get_by_label("Robot name").fill("r1")
            await form.get_by_label("Rosbridge address").fill(extra.urls[0])
            await form.get_by_role("button", name="Register robot").click()
            await expect(
                owner.get_by_role("alert").filter(has_text="There is already a robot called r1")
            ).to_be_visible()
            await dismiss_toasts(owner)

            await form.get_by_label("Robot name").fill("r2")
            await form.get_by_label("Drive").select_option("diff")
            await form.get_by_role("button", name="Register robot").click()
            await expect(owner.get_by_text("Registered r2")).to_be_visible()
            # the server reached it: Paused (not taking trips yet), in both consoles' lists
            for page in (owner, staff):
                await expect(page.get_by_role("listitem").filter(has_text="r2")).to_contain_text(
                    "Paused"
                )
            robot = await r.app.store.robots.get_robot("r2")
            assert (robot.url, robot.home, robot.kinematics) == (
                extra.urls[0],
                "home2",
                "diff",
            )
            await expect(form.get_by_label("Home spot")).not_to_have_value("home2")  # taken now
            screens.assert_no_errors(re.compile("401|4001|Unauthorized", re.I))
        finally:
            await extra.close()


async def test_a_stalled_tablet_shows_it_and_its_late_food_collected_is_refused(
    tmp_path: Path, browser: Any
) -> None:
    """Wi-Fi stalls with the socket open: within seconds the page says the connection is lost
    (its own heartbeat), and the "Food collected" pressed into the stall, delivered when the
    network comes back after another tablet moved the robot on, is refused as stale: the robot
    does not leave the second table with its food."""
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.ok("control", robot="r1", action="auto")
        ids = [
            (await c.ok("create", type="order", dish=d, table=t))["order"]["id"]
            for d, t in (("Pho", "T1"), ("Satay", "T12"))
        ]
        [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
        await c.status("r1", "Delivered")
        screens = Screens(browser, http_base(r), r.token)
        stalled = {"on": False}
        held: list[tuple[Any, str | bytes]] = []  # frames the stalled path holds, to the server
        replies: list[dict[str, Any]] = []  # what the server said to them
        stale = asyncio.Event()  # set by the relay: c's own updates need not come meanwhile

        def relay(ws: Any) -> None:
            server = ws.connect_to_server()

            def up(frame: str | bytes) -> None:
                if stalled["on"]:
                    held.append((server, frame))
                else:
                    server.send(frame)

            def down(frame: str | bytes) -> None:
                if held and not stalled["on"]:
                    replies.append(json.loads(frame))
                    if replies[-1].get("code") == "stale":
                        stale.set()
                if not stalled["on"]:
                    ws.send(frame)

            server.on_message(down)
            ws.on_message(up)
            ws.on_close(lambda *_: None)  # the page giving up does not close the server side

        staff = await screens.open("/", ws_route=relay)
        collected = staff.get_by_role("button", name="Food collected r1")
        await expect(collected).to_be_visible()
        stalled["on"] = True
        await collected.click()  # into the stall: the frame waits in the network
        await c.ok("next", robot="r1", task=task["id"], stop=0)  # another tablet, in time
        await c.status("r1", "Delivering")
        banner = staff.get_by_role("status").filter(has_text="Connection to the server lost")
        await expect(banner).to_be_visible(timeout=8_000)  # heartbeat: 5 s of silence
        stalled["on"] = False
        for server, frame in held:  # the network is back: what was sent arrives, late
            server.send(frame)
        late = [json.loads(f) for _, f in held if json.loads(f).get("clientmsg") == "next"]
        assert late and late[0]["stop"] == 0 and late[0]["task"] == task["id"], held
        await asyncio.wait_for(stale.wait(), 20)
        # Nothing changed: the robot is on its way to (or at) T12 with the dish still aboard.
        second = c.task(task["id"])["stops"][1]
        assert c.task(task["id"])["current_stop"] == 1 and second["status"] != "done"
        assert c.order(ids[1])["status"] == "assigned"
        # The page reconnects and shows the truth; it sent nothing it was not asked to.
        await expect(banner).to_have_count(0, timeout=20_000)
        row = staff.get_by_role("listitem").filter(has_text="r1")
        await expect(row).to_contain_text("now T12")
        nexts = [m for m in screens.sent if m.get("clientmsg") == "next"]
        assert len(nexts) == 1, nexts
        screens.assert_no_errors(re.compile("stale|did not answer|connection dropped", re.I))
