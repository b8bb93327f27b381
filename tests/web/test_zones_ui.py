"""Zones in the staff console, end to end in Chromium (issue 21, item 2, and "staff can see and
break a lease").

Same harness as tests/web/test_ui.py (Debian's /usr/bin/chromium driven by playwright, no
sleeps: every wait is an ``expect``, ``wait_for_function`` or a poll of the server's state), on
the narrow room of tests/core/test_zone_leases.py: two halves joined by an aisle one robot wide,
two simulated robots that see each other, leases on.

The owner draws the aisle with the mouse and a second zone from the keyboard (a drawing begun
and cancelled with Escape stores nothing), both stored by the server and drawn on the map;
imports a file of zones (the bad one reported), draws one again from the Restaurant tab's list
(its name kept, `replace`); removes a zone. A robot parked in the aisle
holds it (the map and the lists say so); staff release its lease after a confirm that says the
robot must be out of the zone first. Then two robots sent head-on through the aisle: the one that
asked second reads "Waiting for aisle (held by r1)" (or r2) in the robots list until the aisle
is free.
Axe finds nothing on the Restaurant tab's zones nor on the map's side panel with a lease shown,
and neither scrolls sideways on a 390 px phone, their buttons 44 px.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

from serveur.app import App
from tests.conftest import Client, poll_until
from tests.core.test_zone_leases import AISLE, narrow_restaurant
from tests.web.conftest import sideways, too_small
from tests.web.test_a11y import need_axe, open_page, violations
from tests.web.test_ui import (
    TABLET,
    expect,
    log_in,
    pytestmark,  # noqa: F401
)

PHONE = {"width": 390, "height": 844}
SCALE = 5.0
WAIT = 30.0
PASS_ZONE = [[0.2, 0.2], [0.6, 0.2], [0.6, 0.6]]

# The map position (x, y) in page pixels, from the view the canvas publishes (view.js).
TO_PAGE = """([x, y]) => {
  const c = document.getElementById("map");
  const d = c.dataset;
  const r = c.getBoundingClientRect();
  const s = Number(d.scale);
  return [r.left + Number(d.originX) + x * s, r.top + Number(d.originY) - y * s];
}"""
ZONES_DRAWN = """(want) => {
  const drawn = JSON.parse(document.getElementById("map").dataset.zones || "{}");
  return JSON.stringify(drawn) === JSON.stringify(want);
}"""
ZONE_STATE = """([zone, state]) =>
  JSON.parse(document.getElementById("map").dataset.zones || "{}")[zone] === state"""


@contextlib.asynccontextmanager
async def narrow_console(tmp: Path) -> AsyncIterator[tuple[App, Any, Client, str]]:
    """The narrow room of tests/core/test_zone_leases.py (leases on, two robots that see each
    other); a staff client subscribed to the robots, zones and leases; the console's address."""
    async with narrow_restaurant(
        tmp, leases=True, scale=SCALE, heartbeat=10.0, ack_timeout=5.0
    ) as (app, sim, c):
        token = await app.issue_token("staff", label="zones ui")
        await c.subscribe("robots", "zones", "leases")
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        yield app, sim, c, f"{base}|{token}"


def watch(page: Any, errors: list[str]) -> Any:
    page.on("pageerror", lambda e: errors.append(f"exception {e}"))
    page.on("console", lambda m: errors.append(f"console {m.text}") if m.type == "error" else None)
    return page


async def on_a_phone(page: Any, selector: str, size: dict[str, int] = PHONE) -> None:
    """At a phone's width: nothing scrolls sideways, the buttons are finger-sized."""
    await page.set_viewport_size(size)
    wide, inner = await sideways(page)
    assert wide <= inner, wide
    assert await too_small(page, selector) == []
    await page.set_viewport_size(TABLET)


async def click_map(page: Any, x: float, y: float) -> None:
    px, py = await page.evaluate(TO_PAGE, [x, y])
    await page.mouse.click(px, py)


async def confirm(page: Any, yes: str) -> Any:
    dialog = page.get_by_role("dialog")
    await dialog.get_by_role("button", name=yes, exact=True).click()
    await expect(dialog).to_have_count(0)


def lease(app: App, zone: str) -> list[str]:
    assert app.core is not None
    return app.core.leases.holders(zone)


async def test_zones_drawn_imported_leased_released_and_removed(
    tmp_path: Path, browser: Any
) -> None:
    async with narrow_console(tmp_path) as (app, sim, c, where):
        base, token = where.split("|")
        core = app.core
        assert core is not None
        need_axe()
        errors: list[str] = []
        owner = watch(await open_page(browser, f"{base}/", online=False), errors)
        await log_in(owner, "owner", app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        canvas = owner.locator("#map")
        draw = owner.get_by_role("button", name="Draw zone")
        hint = owner.locator("#tool-hint")

        # -- a drawing begun and cancelled with Escape stores nothing.
        await draw.click()
        await expect(draw).to_have_attribute("aria-pressed", "true")
        await click_map(owner, 3.0, 2.7)
        await expect(canvas).to_have_attribute("data-draft", "[[3,2.7]]")
        await expect(hint).to_contain_text("1 corner so far")
        # The toolbar with Draw zone and Finish fits a phone and a portrait tablet.
        await expect(owner.get_by_role("button", name="Finish")).to_be_visible()
        await on_a_phone(owner, ".map-toolbar button", {"width": 768, "height": 1024})
        await on_a_phone(owner, ".map-toolbar button")
        await owner.keyboard.press("Escape")
        await expect(draw).to_have_attribute("aria-pressed", "false")
        await expect(canvas).not_to_have_attribute("data-draft", re.compile(".*"))

        # -- the aisle with the mouse: four corners, Finish, its name; capacity 1 by default.
        await draw.click()
        for x, y in AISLE:
            await click_map(owner, x, y)
        await expect(hint).to_contain_text("4 corners so far")
        await owner.get_by_role("button", name="Finish").click()
        form = owner.get_by_role("dialog", name="New zone")
        await expect(form.get_by_label("Robots allowed in it at once")).to_have_value("1")
        await form.get_by_label("Name").fill("aisle")
        # Its waiting point: a robot stopped in the aisle that cannot go on waits at L.
        await form.get_by_label("Where robots wait to enter").select_option("L")
        await form.get_by_role("button", name="Save zone").click()
        await expect(form).to_have_count(0)
        await poll_until(lambda: "aisle" in core.zone_records, WAIT, "aisle stored")
        assert core.zone_records["aisle"].wait_at == "L"
        stored = [list(p) for p in core.zone_records["aisle"].points]
        assert all(math.dist(p, q) < 0.05 for p, q in zip(stored, AISLE, strict=True)), stored
        assert core.zone_records["aisle"].capacity == 1
        await owner.wait_for_function(ZONES_DRAWN, arg={"aisle": "free"})
        await expect(draw).to_be_focused()

        # -- a zone from the keyboard: Enter on the tool puts a cross on the map; arrow keys
        # move it (Shift: 0.5 m), Enter adds a corner, Enter again on the last one closes it.
        await draw.focus()
        await owner.keyboard.press("Enter")
        await expect(canvas).to_be_focused()
        x0, y0, _ = map(float, (await canvas.get_attribute("data-cursor") or "").split(","))
        for _ in range(6):
            await owner.keyboard.press("Shift+ArrowRight")  # 3 m east
        for _ in range(2):
            await owner.keyboard.press("Shift+ArrowDown")  # 1 m south
        corners = [(x0 + 3.0, y0 - 1.0)]
        await owner.keyboard.press("Enter")
        for key, n, (dx, dy) in [("ArrowRight", 4, (0.4, 0)), ("ArrowUp", 3, (0, 0.3))]:
            for _ in range(n):
                await owner.keyboard.press(key)
            corners.append((corners[-1][0] + dx, corners[-1][1] + dy))
            await owner.keyboard.press("Enter")
        await expect(hint).to_contain_text("3 corners so far")
        await owner.keyboard.press("Enter")  # on the last corner: closed
        form = owner.get_by_role("dialog", name="New zone")
        await form.get_by_label("Name").fill("corner")
        await form.get_by_label("Robots allowed in it at once").fill("2")
        await form.get_by_role("button", name="Save zone").click()
        await expect(form).to_have_count(0)
        await poll_until(lambda: "corner" in core.zone_records, WAIT, "corner stored")
        got = core.zone_records["corner"]
        assert got.capacity == 2 and got.wait_at is None
        assert all(math.dist(p, q) < 0.02 for p, q in zip(got.points, corners, strict=True)), (
            got.points,
            corners,
        )
        await owner.wait_for_function(ZONES_DRAWN, arg={"aisle": "free", "corner": "free"})

        # -- the Restaurant tab: import a file (one good zone, one refused), remove a zone.
        await owner.get_by_role("tab", name="Restaurant").click()
        zones = owner.get_by_role("list", name="Zones")
        await expect(zones.locator("li[data-zone]")).to_have_count(2)
        bad = {"name": "line", "points": [[0, 0], [1, 1]], "capacity": 1}
        good = {"name": "pass", "points": PASS_ZONE, "capacity": 1}
        path = tmp_path / "zones.json"
        path.write_text(json.dumps({"zones": [good, bad]}))
        await owner.get_by_label("Import zones from a file").set_input_files(path)
        report = owner.get_by_test_id("zone-import")
        await expect(report).to_contain_text("1 zone imported: pass")
        await expect(report).to_contain_text(re.compile(r"1 zone not imported:\s*line: "))
        await poll_until(lambda: "pass" in core.zone_records, WAIT, "pass imported")
        assert "line" not in core.zone_records
        await expect(zones.locator("li[data-zone]")).to_have_count(3)
        await zones.get_by_role("button", name="Remove zone corner").click()
        await confirm(owner, "Remove")
        await poll_until(lambda: "corner" not in core.zone_records, WAIT, "corner removed")
        await expect(zones.locator("li[data-zone]")).to_have_count(2)
        # Draw "pass" again from its row: the map's tool, a new shape, its name kept (replace).
        await zones.get_by_role("button", name="Draw again: pass").click()
        await expect(draw).to_have_attribute("aria-pressed", "true")
        await expect(hint).to_contain_text("Draw pass again")
        moved = [[0.3, 0.3], [0.9, 0.3], [0.9, 0.8], [0.3, 0.8]]
        for x, y in moved:
            await click_map(owner, x, y)
        await click_map(owner, *moved[0])  # the first corner again closes it
        form = owner.get_by_role("dialog", name="Zone pass: its new shape")
        await expect(form.get_by_label("Name")).to_have_value("pass")
        await form.get_by_role("button", name="Save zone").click()
        await expect(form).to_have_count(0)
        await poll_until(
            lambda: [list(p) for p in core.zone_records["pass"].points] == moved, WAIT, "redrawn"
        )
        await owner.wait_for_function(ZONES_DRAWN, arg={"aisle": "free", "pass": "free"})
        await owner.get_by_role("tab", name="Restaurant").click()
        await expect(report).to_be_visible()
        assert await violations(owner) == []
        await on_a_phone(owner, "#panel-restaurant button, #zone-file")
        await owner.get_by_role("tab", name="Map").click()

        # -- r1 parked in the aisle holds it: the map tints it, the lists say who is in it.
        staff = watch(await open_page(browser, f"{base}/#token={token}"), errors)
        for name in ("r1", "r2"):
            await c.until(lambda n=name: c.robot(n).get("status") == "Ready", WAIT, f"{name} up")
            await c.ok("control", robot=name, action="manual")
        await c.ok("control", robot="r1", action="goal", x=4.0, y=1.5, yaw=0.0)
        await poll_until(lambda: lease(app, "aisle") == ["r1"], WAIT, "r1 holds the aisle")
        await poll_until(
            lambda: math.dist(sim.robots[0].pose[:2], (4.0, 1.5)) < 0.3, WAIT, "r1 in the aisle"
        )
        await staff.wait_for_function(ZONE_STATE, arg=["aisle", "used"])
        row = staff.locator('.zone-row[data-zone="aisle"]')
        await expect(row.get_by_test_id("zone-lease")).to_have_text("In use by r1")
        assert await violations(staff) == []
        await on_a_phone(staff, ".zone-row button")

        # -- staff release it, after a confirm that says the robot must be out first.
        await row.get_by_role("button", name="Release aisle from r1").click()
        dialog = staff.get_by_role("dialog")
        await expect(dialog).to_contain_text("Only when r1 is out of aisle")
        await confirm(staff, "It is out: release")
        await poll_until(lambda: lease(app, "aisle") == [], WAIT, "lease broken")
        await expect(row.get_by_test_id("zone-lease")).to_have_text("Free")
        await staff.wait_for_function(ZONE_STATE, arg=["aisle", "free"])
        # r1 leaves the aisle (asking for it again: it stands in it), home, in line with the
        # aisle as tests/core/test_zone_leases.py starts (and away from L, where r2 may go).
        await c.ok("control", robot="r1", action="goto", waypoint="home1")
        await poll_until(lambda: math.dist(sim.robots[0].pose[:2], (1.0, 1.5)) < 0.3, WAIT, "out")
        await poll_until(lambda: lease(app, "aisle") == [], WAIT, "aisle left")

        # -- head-on: r1 to the right half and r2 to the left at once, both through the aisle.
        # (Go to a table: the server asks for the zones on the planned path between places.)
        await c.ok("control", robot="r1", action="goto", waypoint="R")
        await c.ok("control", robot="r2", action="goto", waypoint="L")
        # Which of the two asked first is the server's (each leg is planned first): the other
        # one waits, and its row says for what and behind whom.
        shown = await staff.wait_for_function(
            """() => {
              const e = document.querySelector('.robot [data-testid="waiting-for"]');
              const row = e && e.closest(".robot");
              return e && [row.querySelector(".robot-name").textContent, e.textContent];
            }"""
        )
        waiter, text = await shown.json_value()
        other = {"r1": "r2", "r2": "r1"}[waiter]
        assert text == f"Waiting for aisle (held by {other})", text
        await c.until(lambda: c.robot(waiter).get("waiting_for") is None, WAIT, "waiter goes")
        await expect(staff.get_by_test_id("waiting-for")).to_have_count(0)
        for robot, goal in (("r1", (6.5, 2.4)), ("r2", (1.5, 2.4))):
            body = sim.robots[int(robot[1]) - 1]
            there = f"{robot} there"
            await poll_until(lambda b=body, g=goal: math.dist(b.pose[:2], g) < 0.3, WAIT, there)
        assert c.robot("r1").get("last_error") is None and c.robot("r2").get("last_error") is None
        await staff.wait_for_function(ZONE_STATE, arg=["aisle", "free"])

        # -- the owner removes the aisle: gone from the server, the lists and the map.
        await owner.get_by_role("tab", name="Restaurant").click()
        await zones.get_by_role("button", name="Remove zone aisle").click()
        await confirm(owner, "Remove")
        await poll_until(lambda: "aisle" not in core.zone_records, WAIT, "aisle removed")
        await staff.wait_for_function(ZONES_DRAWN, arg={"pass": "free"})
        await expect(staff.locator('.zone-row[data-zone="aisle"]')).to_have_count(0)
        assert errors == []
