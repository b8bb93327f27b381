"""Map labels that never cover each other or a table's name (issue 30, point 7: a robot's "→ T5"
lay over table T1, which then read as T5; labels overlapped tables and homes).

A crowded dining room on the real server and simulator: tables 0.6 m apart (one each side of T1
and of T5), robots parked on tables (T18, T19, T2), r1 on a trip to T5 standing next to T1 (as
loaded, not yet gone). On a phone, a portrait and a landscape tablet and a desktop, at the map's
whole view and zoomed in on T1: no two labels overlap, none covers a place's marker, a robot,
the ring of r1's destination or the legend over the map, every table in view is named (its name
beside its own marker), and each robot's label — its name and where it goes, "r1 → T5" — is
beside that robot or on a line from it; no label but T5's own reads "T5". The canvas publishes
what it placed as data-label-info (js/map/view.js).

The placer itself (js/map/labels.js) is tested on plain values under Node
(tests/node/map_labels.mjs).
"""

from __future__ import annotations

import asyncio
import math
import os
import shutil
from pathlib import Path
from typing import Any

import pytest

from tests.web.conftest import needs_browser
from tests.web.test_ui import expect, http_base, staff_client, ui_restaurant

pytestmark = [pytest.mark.asyncio(loop_scope="module")]

NODE_TEST = Path(__file__).resolve().parents[1] / "node" / "map_labels.mjs"
SIZES = [
    {"width": 390, "height": 844},
    {"width": 768, "height": 1024},
    {"width": 1024, "height": 768},
    {"width": 1440, "height": 900},
]
# The crowded tables: one 0.6 m each side of T1 (2.4, 9.7) and of T5 (2.4, 7.5).
CROWD = {"T17": (1.8, 9.7), "T18": (3.0, 9.7), "T19": (1.8, 7.5), "T20": (3.0, 7.5)}
# Where each robot stands: r1 next to T1 (headed to T5), the others parked on tables.
PARKED = {"r1": (2.1, 9.25), "r2": (3.0, 9.7), "r3": (1.8, 7.5), "r4": (6.1, 9.8)}
ROBOT_RADIUS_M = 0.25  # js/map/draw.js
MARKER_PX = 6  # a place's diamond, corner to centre
RING_PX = 11.5  # the destination's ring with half its line

# The map as the page drew it: the view, the labels placed, the legend's box on the canvas.
STATE = """() => {
  const c = document.getElementById("map");
  const d = c.dataset;
  const r = c.getBoundingClientRect();
  const left = r.left + c.clientLeft;
  const top = r.top + c.clientTop;
  const legend = document.getElementById("map-legend").getBoundingClientRect();
  return {
    scale: Number(d.scale), ox: Number(d.originX), oy: Number(d.originY),
    width: c.clientWidth, height: c.clientHeight, left, top,
    legend: [legend.left - left, legend.top - top, legend.right - left, legend.bottom - top],
    info: JSON.parse(d.labelInfo || "null"),
  };
}"""
# Whether the labels drawn are those of the current view with every robot where it stands and
# r1's trip known: each robot's label anchored at it (within 0.1 m).
DRAWN = """(robots) => {
  const c = document.getElementById("map");
  const d = c.dataset;
  if (!d.labelInfo) return false;
  const info = JSON.parse(d.labelInfo);
  const s = Number(d.scale);
  return Object.entries(robots).every(([name, [x, y, text]]) => {
    const l = info.placed.find((p) => p.kind === "robot" && p.of === name);
    const sx = Number(d.originX) + x * s;
    const sy = Number(d.originY) - y * s;
    return l && l.text === text && Math.hypot(l.anchor[0] - sx, l.anchor[1] - sy) <= 0.1 * s;
  });
}"""


def apart(a: list[float], b: list[float]) -> bool:
    return a[2] <= b[0] or b[2] <= a[0] or a[3] <= b[1] or b[3] <= a[1]


def covers_circle(box: list[float], x: float, y: float, r: float) -> bool:
    nx = max(box[0], min(x, box[2]))
    ny = max(box[1], min(y, box[3]))
    return math.hypot(nx - x, ny - y) < r - 0.2  # boxes are published to 0.1 px


def attached(label: dict[str, Any]) -> bool:
    """Beside its anchor's edge (2 px, labels.js RINGS[0]), or on a line that starts on that edge
    and ends on the label."""
    ax, ay, ar = label["anchor"]
    box = label["box"]
    nx, ny = max(box[0], min(ax, box[2])), max(box[1], min(ay, box[3]))
    gap = math.hypot(nx - ax, ny - ay) - ar
    line = label["leader"]
    if line is None:
        return gap <= 2.3
    starts = abs(math.hypot(line[0] - ax, line[1] - ay) - ar) <= 0.3
    ends = math.hypot(line[2] - nx, line[3] - ny) <= 0.3
    return starts and ends


def check(state: dict[str, Any], places: dict[str, tuple[float, float, str]], where: str) -> None:
    """Every rule of the module's docstring on one frame drawn."""
    info = state["info"]
    scale, ox, oy = state["scale"], state["ox"], state["oy"]

    def screen(x: float, y: float) -> tuple[float, float]:
        return ox + x * scale, oy - y * scale

    placed = info["placed"]
    boxes = [p["box"] for p in placed]
    assert placed, where
    for i, a in enumerate(placed):
        for b in placed[i + 1 :]:
            assert apart(a["box"], b["box"]), f"{where}: {a['text']!r} covers {b['text']!r}"
        assert attached(a), f"{where}: {a['text']!r} is not beside its mark: {a}"
    # Nothing covers a place's marker, a robot or r1's destination ring.
    marks = [(*screen(x, y), MARKER_PX, name) for name, (x, y, _) in places.items()]
    robot_px = max(8.0, ROBOT_RADIUS_M * scale)
    marks += [(*screen(x, y), robot_px, name) for name, (x, y) in PARKED.items()]
    marks.append((*screen(2.4, 7.5), RING_PX, "r1's destination"))
    for box, label in zip(boxes, placed, strict=True):
        for x, y, r, name in marks:
            assert not covers_circle(box, x, y, r), f"{where}: {label['text']!r} covers {name}"
    # None under the legend laid over the map's corner.
    legend = state["legend"]
    for label in placed:
        assert apart(label["box"], legend), f"{where}: {label['text']!r} is under the legend"
    # Every table in view named, beside its own marker; no other label reads as a table's name.
    for name, (x, y, kind) in places.items():
        sx, sy = screen(x, y)
        seen = 0 <= sx <= state["width"] and 0 <= sy <= state["height"]
        under = legend[0] <= sx <= legend[2] and legend[1] <= sy <= legend[3]
        named = [p for p in placed if p["text"] == name]
        if kind == "table" and seen and not under:
            assert len(named) == 1, f"{where}: {name} is not named ({info['dropped']})"
        for p in named:
            assert p["of"] == name and p["kind"] == kind, f"{where}: {p}"
            assert math.hypot(p["anchor"][0] - sx, p["anchor"][1] - sy) <= 0.2, f"{where}: {p}"
    # Each robot's label: its name and where it goes, on it.
    for name, (x, y) in PARKED.items():
        [label] = [p for p in placed if p["kind"] == "robot" and p["of"] == name]
        assert label["text"] == ("r1 → T5" if name == "r1" else name), f"{where}: {label}"
        sx, sy = screen(x, y)
        assert math.hypot(label["anchor"][0] - sx, label["anchor"][1] - sy) <= 0.1 * scale


async def until_drawn(page: Any, robots: dict[str, list[Any]], where: str) -> None:
    """Wait for a frame with every robot where it stands and r1's trip known; on a timeout, say
    what the last frame drew."""
    try:
        await page.wait_for_function(DRAWN, arg=robots)
    except Exception:
        state = await page.evaluate(STATE)
        info = state["info"] or {}
        robots_drawn = [p for p in info.get("placed", []) if p["kind"] == "robot"]
        view = {k: state[k] for k in ("scale", "ox", "oy", "width", "height")}
        raise AssertionError(
            f"{where}: robots' labels {robots_drawn}, left out {info.get('dropped')}, view {view}"
        ) from None


@needs_browser
async def test_labels_in_a_crowded_room(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path, robots=len(PARKED)) as r:
        c = await staff_client(r)
        await c.subscribe("waypoints")
        for name, (x, y) in CROWD.items():
            await c.ok("create", type="waypoint", name=name, x=x, y=y, yaw=-1.5708, kind="table")
        places = {
            w["name"]: (w["x"], w["y"], w["kind"])
            for w in c.records["waypoints"].values()
            if not w.get("removed")
        }
        assert set(CROWD) <= set(places)
        # r1 loaded for T5: its trip taken, not yet gone (no automatic departure).
        assert r.app.core is not None
        r.app.core.config.auto_depart = False
        await c.status("r1", "Ready")
        await c.ok("control", robot="r1", action="auto")
        order = (await c.ok("create", type="order", dish="Laksa", table="T5"))["order"]["id"]
        [task] = (await c.ok("create", type="task", orders=[order]))["tasks"]
        await c.status("r1", "Loading")  # the only robot taking trips took it
        assert c.robot("r1")["current_task"] == task["id"]
        # Then each robot is put where it stands (as if pushed there): r1 beside T1.
        for sim_robot in r.sim.robots:
            x, y = PARKED[sim_robot.name]
            sim_robot.teleport(x, y, -1.5708)
        robots = {
            name: [x, y, "r1 → T5" if name == "r1" else name] for name, (x, y) in PARKED.items()
        }

        for size in SIZES:
            where = f"{size['width']}x{size['height']}"
            context = await browser.new_context(viewport=size)
            page = await context.new_page()
            errors: list[str] = []
            page.on("pageerror", lambda e, errors=errors: errors.append(str(e)))
            await page.goto(f"{http_base(r)}/#token={r.token}")
            await expect(page.locator("body")).to_have_attribute("data-connection", "online")
            await until_drawn(page, robots, where)
            check(await page.evaluate(STATE), places, f"{where}, whole map")

            # Zoomed in twice over on T1 (the wheel keeps the point under the pointer).
            canvas = page.locator("#map")
            await canvas.scroll_into_view_if_needed()
            state = await page.evaluate(STATE)
            x = state["left"] + state["ox"] + 2.4 * state["scale"]
            y = state["top"] + state["oy"] - 9.7 * state["scale"]
            await page.mouse.move(x, y)
            await page.mouse.wheel(0, -462)  # exp(462 * 0.0015) = 2
            zoomed = "(s) => Number(document.getElementById('map').dataset.scale) > 1.9 * s"
            await page.wait_for_function(zoomed, arg=state["scale"])
            await until_drawn(page, robots, f"{where}, zoomed in")
            check(await page.evaluate(STATE), places, f"{where}, zoomed in")
            assert errors == [], errors
            await context.close()


@pytest.fixture(scope="module")
def node() -> str:
    """The ``node`` binary (the placer's test needs no package of tests/node)."""
    exe = shutil.which("node")
    if exe is None:
        what = "node not found: the label placer's test needs Debian's nodejs package"
        if os.environ.get("CI"):
            pytest.fail(f"the Node test must run in CI: {what} (.ci/run installs nodejs)")
        pytest.skip(what)
    return exe


async def test_the_label_placer_under_node(node: str) -> None:
    proc = await asyncio.create_subprocess_exec(
        node,
        str(NODE_TEST),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    out, err = await asyncio.wait_for(proc.communicate(), 60)
    assert proc.returncode == 0, (out.decode(), err.decode())
    assert out.decode().strip() == "ok"
