""" "How many robots do I need?" in the owner's Statistics tab, in Chromium (issue 20, item 3).

Same harness as tests/web/test_stats_ui.py (Debian's /usr/bin/chromium through playwright, a
real server, no sleeps). The server's database holds a short recorded day, as
tests/replay/test_forecast.py makes it: six dishes ordered a minute apart on a FakeClock on the
demo map (2023-11-14 22:13 UTC, i.e. the service day 2023-11-15 in Kuala Lumpur, the browser's
time zone: the request must name the browser's UTC offset). The site has two robots (never
reachable: the frozen clock keeps them quietly Offline), so the fleet now is 2.

The owner opens Statistics; the day offered is the recorded day (the last with a service, not
yesterday: issue 30), the fleet sizes offered by default are 1..4 (the fleet -1, same,
+1, +2) with 2 marked "now". A day without dishes is refused in plain words; then the recorded
day with 1 and 2 robots: each fleet's step shows while the real ``serveur replay`` children
run, and at the end both rows of the table hold the server's forecast record's numbers, the
sentences say them in words and the bar chart has two bars, the current fleet's marked; below,
that the record has no delivered dish to compare with (the robots were never reachable). Axe
finds nothing serious on the results; on a 390 px phone nothing scrolls sideways and every
control is a 44 px target. In Chinese the words change and the numbers stay; last, a
forecast cancelled while it runs.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur.app import RobotSpec
from serveur.clock import FakeClock
from serveur.maps.navigation import load_demo
from tests.replay.test_forecast import record_day
from tests.security.test_security import bare_server, login
from tests.web.conftest import sideways, too_small
from tests.web.test_a11y import AXE, violations
from tests.web.test_stats_ui import FIGURES_MS
from tests.web.test_ui import (
    SHOTS,
    TABLET,
    expect,
    log_in,
    pytestmark,  # noqa: F401
)

ZONE = "Asia/Kuala_Lumpur"  # +08:00, no daylight saving
DAY = "2023-11-15"  # FakeClock's epoch 1_700_000_000 is 2023-11-14 22:13 UTC = 06:13 here
EMPTY_DAY = "2023-11-16"
PHONE = {"width": 390, "height": 844}
# Two replays of six dishes take ~5 s alone; each is a `serveur replay` child, CPU-bound, and
# on CI's two cores beside two other workers and Chromium one took over 60 s (2026-11-29).
REPLAY_MS = 120_000


def minutes(seconds: float) -> str:
    """As the page writes a wait (Intl, en, at most one decimal): "2.1 min", "3 min"."""
    return f"{seconds / 60:.1f}".removesuffix(".0") + " min"


@pytest.mark.timeout(400)  # two replays, each given REPLAY_MS on a loaded machine
async def test_the_owner_asks_how_many_robots_a_recorded_day_needed(
    tmp_path: Path, browser: Any
) -> None:
    grid, _ = load_demo()
    dead = [RobotSpec(f"r{i}", "ws://127.0.0.1:9", f"home{i}") for i in (1, 2)]
    app_options = {"nav_map": grid, "robots": dead, "plan_in_child": False}
    async with bare_server(tmp_path, app=app_options) as app:
        ws = await connect(app.url)
        await login(ws, username="owner", password=app.first_owner_password)
        assert isinstance(app.clock, FakeClock)
        await record_day(ws, app.clock)
        await ws.close()

        context = await browser.new_context(viewport=TABLET, timezone_id=ZONE, bypass_csp=True)
        page = await context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        base = app.url.replace("ws://", "http://").removesuffix("/ws")
        await page.goto(base + "/")
        await log_in(page, "owner", app.first_owner_password or "")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        await page.get_by_role("tab", name="Statistics").click()
        panel = page.locator("#panel-stats")
        await expect(panel).not_to_have_attribute("aria-busy", "true", timeout=FIGURES_MS)

        section = panel.get_by_role("region", name="How many robots do I need?")
        await expect(section).to_be_visible()
        await expect(section).to_contain_text("replays that day's real orders in a simulation")
        # The fleet now is 2: 1, 2, 3 and 4 are offered, 2 marked "now".
        fleets = section.get_by_role("group", name="Numbers of robots to try")
        boxes = {n: fleets.get_by_role("checkbox", name=re.compile(f"^{n}")) for n in range(1, 7)}
        for n, box in boxes.items():
            if n <= 4:
                await expect(box).to_be_checked()
            else:
                await expect(box).not_to_be_checked()
        await expect(boxes[2]).to_have_accessible_name(re.compile(r"^2\s*now$"))

        # The day offered: the last one with a service.
        day = section.get_by_label("Service day", exact=True)
        await expect(day).to_have_value(DAY)
        # A day without a dish: refused, in words.
        await day.fill(EMPTY_DAY)
        await section.get_by_role("button", name="Start").click()
        await expect(section.get_by_role("status")).to_have_text(
            "No dish was ready at the pass on Thu, Nov 16: there is nothing to replay."
            " Choose another day."
        )

        # The recorded day with 1 and 2 robots.
        await day.fill(DAY)
        await boxes[3].uncheck()
        await boxes[4].uncheck()
        await section.get_by_role("button", name="Start").click()
        await expect(
            section.get_by_role("heading", name="Wed, Nov 15: 6 dishes replayed")
        ).to_be_visible()
        # While it runs: Cancel, and each fleet's step (the first replaying, or already past it).
        steps = section.locator("ol.fc-progress > li")
        await expect(steps).to_have_count(2)
        await expect(steps.first).to_have_text(
            re.compile(r"^1 robot: (replaying…|done)$"), timeout=REPLAY_MS
        )
        await expect(section.get_by_role("status")).to_have_text("Finished.", timeout=REPLAY_MS)
        await expect(section.get_by_role("button", name="Cancel")).to_be_hidden()

        # The server's record, number for number.
        fc = app.server.forecaster.current if app.server else None
        assert fc is not None and fc.state == "done" and fc.dishes == 6, fc
        record = fc.as_dict()
        assert [f["robots"] for f in record["fleets"]] == [1, 2]
        table = section.get_by_role("table", name="The replayed day's waits with each number")
        await expect(table.get_by_role("row")).to_have_count(3)
        for f in record["fleets"]:
            assert f["state"] == "done" and f["delivered"] == 6, f
            row = table.locator(f'tr[data-robots="{f["robots"]}"]')
            await expect(row.locator('[data-col="delivered"]')).to_have_text(
                f"{f['delivered']} of 6"
            )
            await expect(row.locator('[data-col="wait-mean"]')).to_have_text(
                minutes(f["wait_mean"])
            )
            await expect(row.locator('[data-col="wait-p95"]')).to_have_text(minutes(f["wait_p95"]))
            word = "robot" if f["robots"] == 1 else "robots"
            await expect(
                section.locator(f'ul.fc-sentences li[data-robots="{f["robots"]}"]')
            ).to_have_text(
                f"With {f['robots']} {word}, 95 % of dishes reached the table within"
                f" {minutes(f['wait_p95'])}; on average {minutes(f['wait_mean'])}."
            )
        await expect(table.locator("tr.now th")).to_have_text("2 robots now")
        # The bar chart: a bar per fleet, as tall as its 95 % wait, the fleet now marked.
        chart = section.get_by_role("img", name=re.compile(r"^Bar chart of the wait"))
        bars = chart.locator("rect.bar")
        await expect(bars).to_have_count(2)
        values = [float(await b.get_attribute("data-value") or "nan") for b in await bars.all()]
        assert values == [f["wait_p95"] for f in record["fleets"]]
        await expect(chart.locator("rect.bar.now")).to_have_attribute("data-robots", "2")
        heights = [float(await b.get_attribute("height") or 0) for b in await bars.all()]
        p95 = [f["wait_p95"] for f in record["fleets"]]
        assert (heights[0] > heights[1]) == (p95[0] > p95[1]), (heights, p95)
        await expect(chart).to_have_accessible_name(
            f"Bar chart of the wait within which 95 % of dishes reached the table:"
            f" 1 robot: {minutes(record['fleets'][0]['wait_p95'])},"
            f" 2 robots: {minutes(record['fleets'][1]['wait_p95'])}."
        )
        await expect(section.get_by_role("button", name="Start")).to_be_enabled()
        # Nothing was delivered that day: no recorded wait to set beside the replay's.
        await expect(section.locator(".fc-why .fc-recorded")).to_have_text(
            "No dish was recorded as delivered on Wed, Nov 15: there is no recorded wait to"
            " compare with."
        )

        await section.screenshot(path=str(SHOTS / "forecast-tablet.png"))
        # In Chinese: the words change at once, the numbers stay the server's.
        await page.locator("#lang-picker").select_option("zh")
        zh = panel.get_by_role("region", name=re.compile("^我需要几台机器人"))
        await expect(zh.locator('ul.fc-sentences li[data-robots="2"]')).to_contain_text(
            "用 2 台机器人"
        )
        await expect(
            zh.get_by_role("img", name=re.compile("^柱状图")).locator("rect.bar")
        ).to_have_count(2)
        await zh.screenshot(path=str(SHOTS / "forecast-tablet-zh.png"))
        await page.locator("#lang-picker").select_option("en")
        await expect(section.get_by_role("status")).to_have_text("Finished.")
        if AXE.is_file():  # as tests/web/test_a11y.py (which skips without it)
            assert await violations(page) == []
        # A 390 px phone: nothing wider than the screen, every control a finger's size.
        await page.set_viewport_size(PHONE)
        await page.wait_for_function(
            "() => Number(document.querySelector('#panel-stats svg.chart-fleets')"
            ".getAttribute('width')) <= 390"
        )
        wide, inner = await sideways(page)
        assert wide <= inner == PHONE["width"], wide
        small = await too_small(
            page, "#panel-stats .stats-forecast :is(button, select, input, summary)"
        )
        assert small == [], small
        await section.screenshot(path=str(SHOTS / "forecast-phone.png"))

        # Cancelled while it runs: each fleet left says so, the finished ones stay.
        await boxes[3].check()
        await section.get_by_role("button", name="Start").click()
        await section.get_by_role("button", name="Cancel").click()
        await expect(section.get_by_role("status")).to_have_text("Cancelled.")
        await expect(steps.last).to_have_text("3 robots: cancelled")
        await expect(section.get_by_role("button", name="Cancel")).to_be_hidden()
        await expect(section.get_by_role("button", name="Start")).to_be_enabled()
        assert errors == [], errors
        await context.close()
