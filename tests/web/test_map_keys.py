"""The map from the keyboard, focus after actions, and drawing only on change (issue 20).

Calibrate and Move here: the tool's button pressed with Enter puts a cursor on the selected
robot; arrow keys move it, [ and ] turn it, Enter confirms and Escape cancels, focus going back
to the tool's button. A robot action pressed from the keyboard leaves focus on the robot's row,
not on <body>. With every robot parked, the map draws no frame.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

from tests.web.test_ui import (
    Screens,
    angle_diff,
    expect,
    http_base,
    near,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

# Counts the map's frames over `n` animation frames (events, not a sleep).
DRAWS_OVER_FRAMES = """async (n) => {
  const canvas = document.getElementById("map");
  const before = Number(canvas.dataset.draws || 0);
  for (let i = 0; i < n; i++) await new Promise((r) => requestAnimationFrame(r));
  return Number(canvas.dataset.draws || 0) - before;
}"""

FOCUSED = """() => {
  const a = document.activeElement;
  if (a === document.body || !a) return "body";
  return a.id || a.getAttribute("aria-label") || a.textContent;
}"""


async def test_calibrate_and_move_here_from_the_keyboard(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        screens = Screens(browser, http_base(r), r.token)
        staff = await screens.open("/")
        take = staff.get_by_role("button", name="Take control r1")
        await take.focus()
        await staff.keyboard.press("Enter")
        await c.status("r1", "Manual")
        # Focus kept on r1's row (its new first action), not dropped to <body>.
        await expect(staff.locator(".robot:focus-within")).to_have_count(1)
        assert await staff.evaluate(FOCUSED) != "body"

        # Parked, nothing changing: no frame drawn over ~30 animation frames.
        await c.until(lambda: c.streams.get("pose:r1"), what="a pose")
        assert await staff.evaluate(DRAWS_OVER_FRAMES, 30) <= 2

        p0 = await c.until(lambda: c.streams.get("pose:r1"), what="pose")
        calibrate = staff.get_by_role("button", name="Set where the robot is")
        await expect(calibrate).to_be_enabled()
        await calibrate.focus()
        await staff.keyboard.press("Enter")
        canvas = staff.locator("#map")
        await expect(canvas).to_be_focused()
        assert await canvas.get_attribute("data-cursor")
        for _ in range(5):
            await staff.keyboard.press("ArrowRight")  # 5 x 0.1 m east
        for _ in range(6):
            await staff.keyboard.press("[")  # 6 x 15 degrees to the left
        x1, y1, yaw1 = p0["x"] + 0.5, p0["y"], p0["yaw"] + math.pi / 2
        # The hint (a live region) says where the mark is, for a screen reader: near which
        # place and which way on the map, never coordinates.
        where = re.compile(r"The mark is (at \w+|about \d+(\.5)? m from \w+), facing [a-z ]+\.")
        await expect(staff.locator("#tool-hint")).to_contain_text(where)
        await expect(staff.locator("#tool-hint")).not_to_contain_text(re.compile(r"\d\.\d\d|°"))
        await staff.keyboard.press("Enter")
        await c.until(
            lambda: (
                near(c.streams.get("pose:r1"), x1, y1, 0.15)
                and angle_diff(c.streams["pose:r1"]["yaw"], yaw1) < 0.2
            ),
            what="relocalised by the keyboard",
        )
        await expect(calibrate).to_be_focused()
        await expect(calibrate).to_have_attribute("aria-pressed", "false")
        # The arrows moved the mark only: the robot (Manual) was not driven by them.
        assert not [m for m in screens.sent if m.get("action") == "teleop"]

        # Escape cancels: nothing sent, focus back on the tool.
        goal = staff.get_by_role("button", name="Move here")
        await goal.focus()
        await staff.keyboard.press("Enter")
        await expect(canvas).to_be_focused()
        await staff.keyboard.press("ArrowUp")
        await staff.keyboard.press("Escape")
        await expect(goal).to_be_focused()
        await expect(goal).to_have_attribute("aria-pressed", "false")
        assert not [m for m in screens.sent if m.get("action") == "goal"]

        # A tool turned on by a click: Escape turns it off too, wherever the focus is.
        await goal.click()
        await expect(goal).to_have_attribute("aria-pressed", "true")
        await staff.keyboard.press("Escape")
        await expect(goal).to_have_attribute("aria-pressed", "false")
        await expect(goal).to_be_focused()

        # Move here: Shift+arrows take 0.5 m steps (south, into the dining room).
        await staff.keyboard.press("Enter")
        await staff.keyboard.press("Shift+ArrowDown")
        await staff.keyboard.press("Shift+ArrowDown")
        await staff.keyboard.press("Enter")
        sent = [m for m in screens.sent if m.get("action") == "goal"]
        await c.until(
            lambda: near(c.streams.get("pose:r1"), x1, y1 - 1.0, 0.3), what="moved 1 m south"
        )
        assert len(sent) <= 1
        await expect(goal).to_be_focused()

        # Labels never overlap one another.
        boxes = await staff.evaluate(
            "() => JSON.parse(document.getElementById('map').dataset.labels)"
        )
        assert boxes
        for i, a in enumerate(boxes):
            for b in boxes[i + 1 :]:
                assert not (a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]), (a, b)
        screens.assert_no_errors()
