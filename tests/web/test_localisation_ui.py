"""A robot that is not sure where it is, in Chromium on a phone (issue 28).

The simulated robot loses its localisation: its card says "Not sure where it is: set where the
robot is", the alert banner names it, and the map shows where it may be (its particle cloud,
pulled from the robot only while shown: the robot's cloud subscription opens with it). Staff
set where it is: the card and the alert clear, the cloud is no longer shown and the robot's
subscription closes. "Where it may be" also shows a sure robot's cloud on demand. Nothing
scrolls sideways at 390 px; axe finds nothing serious; a screenshot is saved.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from serveur.sim.sensors import CLOUD_TOPICS
from tests.conftest import poll_until, subscribers
from tests.web.conftest import sideways
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    http_base,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

PHONE = {"width": 390, "height": 844}


async def test_a_lost_robot_on_a_phone_and_its_cloud_only_while_shown(
    tmp_path: Path, browser: Any
) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        topic = CLOUD_TOPICS[r.sim.robots[0].ros]
        context = await browser.new_context(viewport=PHONE, bypass_csp=True)
        staff = await context.new_page()
        errors: list[str] = []
        staff.on("pageerror", lambda e: errors.append(str(e)))
        staff.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        await staff.goto(f"{http_base(r)}/#token={r.token}")
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        where = staff.locator("#tool-cloud")
        canvas = staff.locator("#map")
        await expect(where).to_have_attribute("aria-pressed", "false")
        assert subscribers(r.sim, topic) == 0

        # Shown on demand for a robot that is sure: a tight knot where it is.
        await where.click()
        await expect(where).to_have_attribute("aria-pressed", "true")
        await poll_until(lambda: subscribers(r.sim, topic) == 1, 10.0, "the cloud subscribed")
        await expect(canvas).not_to_have_attribute("data-cloud", "0")
        await where.click()
        await expect(where).to_have_attribute("aria-pressed", "false")
        await expect(canvas).to_have_attribute("data-cloud", "0")
        await poll_until(lambda: subscribers(r.sim, topic) == 0, 10.0, "the cloud unsubscribed")

        # Lost: said on the card and in the alerts, and the cloud shown by itself.
        r.sim.robots[0].lose_localisation()
        lost = staff.get_by_test_id("lost")
        await expect(lost).to_have_text(
            "Not sure where it is: set where the robot is (Manual, then Set where the robot is"
            " on the map)"
        )
        await expect(staff.locator("#alerts")).to_contain_text("r1 is not sure where it is")
        await expect(where).to_have_attribute("aria-pressed", "true")
        await expect(canvas).not_to_have_attribute("data-cloud", "0")
        assert subscribers(r.sim, topic) == 1
        wide, inner = await sideways(staff)
        assert wide <= inner, (wide, inner)
        assert await violations(staff) == []
        await staff.screenshot(path=str(SHOTS / "lost-phone.png"), full_page=True)

        # Staff set where it is: sure again, nothing more to show, the robot's cloud closed.
        await c.ok("control", robot="r1", action="manual")
        x, y, yaw = r.sim.robots[0].pose
        await c.ok("control", robot="r1", action="initialpose", x=x, y=y, yaw=yaw)
        await expect(lost).to_have_count(0)
        await expect(staff.locator("#alerts")).not_to_contain_text("not sure where it is")
        await expect(where).to_have_attribute("aria-pressed", "false")
        await poll_until(lambda: subscribers(r.sim, topic) == 0, 10.0, "the cloud closed")
        assert errors == []
        await context.close()
