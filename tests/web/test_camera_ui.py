"""The robot's camera beside the joystick, in Chromium (issue 28).

Staff take control of r1 (whose ``camera`` option names the simulator's CompressedImage topic):
the picture appears beside the joystick, says it is live and how old it is; the robot drives
from the keyboard. The camera stalls (the simulator stops sending): within half a second the
page says the picture is too old and the robot is stopped (a zero twist), and holding the key
does not drive it; the camera comes back and driving works again. Control handed back: the
page stops watching and the robot's camera subscription goes. On a 390 px phone the picture
sits above the pads, nothing scrolls sideways; axe finds nothing serious; screenshots of the
phone and the tablet are saved (SERVEUR_SCREENSHOTS).
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from serveur.sim.sensors import CAMERA_TOPIC
from tests.conftest import poll_until, subscribers
from tests.test_camera import CAMERA
from tests.web.conftest import sideways
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    TABLET,
    expect,
    http_base,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

PHONE = {"width": 390, "height": 844}


def speed(r: Any) -> float:
    vx, vy, wz = r.sim.robots[0].velocity
    return math.hypot(vx, vy) + abs(wz)


def camera_subs(r: Any) -> int:
    return subscribers(r.sim, CAMERA_TOPIC)


async def test_the_camera_beside_the_joystick_and_a_stale_picture_stops_the_robot(
    tmp_path: Path, browser: Any
) -> None:
    async with ui_restaurant(tmp_path, link=CAMERA) as r:
        c = await staff_client(r)
        # bypass_csp: axe is injected into the page at the end (as tests/web/test_a11y.py).
        context = await browser.new_context(viewport=TABLET, bypass_csp=True)
        staff = await context.new_page()
        errors: list[str] = []
        staff.on("pageerror", lambda e: errors.append(str(e)))
        staff.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        await staff.goto(f"{http_base(r)}/#token={r.token}")
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        assert camera_subs(r) == 0  # nobody drives: nothing watched
        await staff.get_by_role("button", name="Take control r1").click()
        await c.status("r1", "Manual")

        picture = staff.get_by_role("img", name="What r1's camera sees")
        state = staff.locator(".camera-state [role=status]")
        await expect(picture).to_be_visible()
        await expect(state).to_have_text("Camera: live.")
        age = re.compile(r"^Picture 0\.\d s old\.$")
        await expect(staff.locator(".camera-age")).to_have_text(age)
        size = "(img) => [img.naturalWidth, img.naturalHeight]"
        shown = f"() => ({size})(document.querySelector('.camera-picture'))[0] > 0"
        await staff.wait_for_function(shown)
        assert await picture.evaluate(size) == [640, 480]
        assert camera_subs(r) == 1

        # Drive forward from the keyboard: the robot moves.
        await staff.keyboard.down("q")  # turn on the spot: no wall in the way
        await poll_until(lambda: speed(r) > 0.1, 10.0, "the robot turning")

        # The camera stalls: the picture goes stale, the robot is stopped, the page says why.
        r.sim.robots[0].sensors.camera_on = False
        await expect(state).to_have_text(
            "The picture is too old to drive on: the robot stopped. Wait for a fresh picture."
        )
        await expect(staff.locator(".teleop-note")).to_have_text(
            "The camera picture is too old: driving stopped."
        )
        await poll_until(lambda: speed(r) < 0.01, 10.0, "the robot stopped")
        await staff.keyboard.up("q")
        await staff.keyboard.down("q")  # held again on the stale picture: no twist goes out
        await expect(state).to_contain_text("too old")
        assert speed(r) < 0.01
        await staff.keyboard.up("q")

        # The camera is back: live again, and the robot drives.
        r.sim.robots[0].sensors.camera_on = True
        await expect(state).to_have_text("Camera: live.")
        await staff.keyboard.down("q")
        await poll_until(lambda: speed(r) > 0.1, 10.0, "the robot turning again")
        await staff.keyboard.up("q")
        await poll_until(lambda: speed(r) < 0.01, 10.0, "the robot stopped on release")

        # Tablet and phone: the picture beside / above the pads, nothing sideways, axe clean.
        assert await violations(staff) == []
        await staff.locator(".teleop").screenshot(path=str(SHOTS / "camera-tablet.png"))
        await staff.set_viewport_size(PHONE)
        await staff.locator(".teleop").scroll_into_view_if_needed()
        wide, inner = await sideways(staff)
        assert wide <= inner, (wide, inner)
        pic = await picture.bounding_box()
        pads = await staff.locator(".teleop .pads").bounding_box()
        assert pic is not None and pads is not None and pic["y"] + pic["height"] <= pads["y"]
        assert pic["width"] <= PHONE["width"]
        await staff.locator(".teleop").screenshot(path=str(SHOTS / "camera-phone.png"))

        # Control handed back: the page stops watching; the robot's camera is closed.
        await c.ok("ready", robot="r1")
        await expect(staff.locator(".camera")).to_be_hidden()
        await poll_until(lambda: camera_subs(r) == 0, 10.0, "the camera closed")
        assert errors == []
        await context.close()
