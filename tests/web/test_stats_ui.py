"""The owner's Statistics tab in Chromium (issue 20, item 2).

Same harness as tests/web/test_ui.py (Debian's /usr/bin/chromium through playwright, a real
server, no sleeps). The server's database holds tests/stats/events.py's hand-made service
twice, an hour apart (2026-01-01, 08:00 and 09:00 in Kuala Lumpur, the browser's time zone).
The owner opens Statistics, picks that day by the hour, and sees the server's figures: the
dishes delivered, one bar per hour in the SVG chart (and its text alternative), each robot;
opens a trip from the keyboard onto its stops and dishes; downloads both CSV files, which
are exactly what ``serveur stats --csv`` writes for the same range and offset. On a 390 px
phone the tab does not scroll sideways and its controls are 44 px targets.

The CSV files are compared with the command itself, run on the server's database file.
"""

from __future__ import annotations

import asyncio
import contextlib
import re
import shutil
import sys
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

from serveur.app import App
from serveur.clock import ScaledClock
from serveur.core.engine import CoreConfig
from serveur.domain import EventRecord
from serveur.maps.navigation import load_demo
from serveur.stats.compute import read_events, table
from serveur.stats.document import trips_in
from serveur.stats.load import load_events
from serveur.stats.periods import parse_offset, parse_when
from tests.stats.events import service, with_calls
from tests.web.conftest import sideways, too_small
from tests.web.test_a11y import need_axe, violations
from tests.web.test_ui import (
    TABLET,
    expect,
    log_in,
    pytestmark,  # noqa: F401
)

#: How long the Statistics tab may say "Adding up the figures…": the server computes them in
#: two `serveur stats` children (figures, trips) and gives them up to 120 s; here ~3 s alone, but
#: over 20 s on CI's two cores beside two other workers and Chromium (three runs, 2026-11-29).
FIGURES_MS = 90_000

ZONE = "Asia/Kuala_Lumpur"  # +08:00, no daylight saving
OFFSET = "+08:00"
DAY = "2026-01-01"
PHONE = {"width": 390, "height": 844}


@contextlib.asynccontextmanager
async def stats_server(
    db: Path, events: Callable[[], list[EventRecord]] = service, hours: tuple[int, ...] = (0, 1)
) -> AsyncIterator[App]:
    """A server (no robots) whose database holds two services (``events``, an hour apart)."""
    nav_map, waypoints = load_demo()
    app = App(
        db,
        port=0,
        clock=ScaledClock(1.0),
        nav_map=nav_map,
        waypoints=waypoints,
        config=CoreConfig(auto_depart=True),
    )
    await app.start()
    try:
        for hour in hours:
            for e in events():
                await app.store.events.add_event(
                    e.kind,
                    robot=e.robot,
                    task_id=None if e.task_id is None else e.task_id + 10 * hour,
                    order_id=None if e.order_id is None else e.order_id + 10 * hour,
                    data=later(dict(e.data), hour),
                    now=e.ts + 3600 * hour,
                )
        yield app
    finally:
        await app.close()


def later(data: dict[str, Any], hour: int) -> dict[str, Any]:
    """An event's data in the second service: an hour later, its orders and trips numbered
    from 11 (so both services' dishes and trips are told apart)."""
    if hour == 0:
        return data
    if isinstance(data.get("ready_at"), float):
        data["ready_at"] += 3600.0
    if isinstance(data.get("orders"), list):
        data["orders"] = [o + 10 for o in data["orders"]]
    if isinstance(data.get("stops"), list):
        data["stops"] = [
            {**s, "orders": [o + 10 for o in s["orders"]]} if isinstance(s, dict) else s
            for s in data["stops"]
        ]
    return data


async def expected(app: App) -> tuple[Any, Any]:
    """The server's figures of that day by the hour (serveur/stats/compute.py)."""
    tz = parse_offset(OFFSET)
    start, end = parse_when(DAY, tz), parse_when(DAY, tz, end=True)
    log = read_events(await load_events(app.store))
    assert len(trips_in(log, start, end)) == 4
    return table(log, "hour", tz, start=start, end=end)


async def command_csv(db: Path, *args: str) -> str:
    """What ``serveur stats --csv -`` prints for that day at that offset."""
    exe = shutil.which("serveur")
    head = [exe] if exe else [sys.executable, "-m", "serveur.cli"]
    proc = await asyncio.create_subprocess_exec(
        *head, "stats", "--db", str(db), "--from", DAY, "--to", DAY,
        "--utc-offset", OFFSET, "--csv", "-", *args,
        stdout=asyncio.subprocess.PIPE, stderr=asyncio.subprocess.PIPE,
    )  # fmt: skip
    out, err = await proc.communicate()
    assert proc.returncode == 0, err.decode()
    return out.decode("utf-8")


async def download(page: Any, button: str) -> tuple[str, str]:
    async with page.expect_download() as info:
        await page.get_by_role("button", name=button).click()
    d = await info.value
    path = await d.path()
    text = await asyncio.to_thread(Path(path).read_text, "utf-8")
    return d.suggested_filename, text


async def show_the_day(page: Any, app: App) -> Any:
    """Log in as the owner, open Statistics, show the service day by the hour; the panel."""
    base = app.url.replace("ws://", "http://").removesuffix("/ws")
    await page.goto(base + "/")
    await log_in(page, "owner", app.first_owner_password or "")
    await expect(page.locator("body")).to_have_attribute("data-connection", "online")
    # The tab loads when opened (today's: no service); then the day chosen by hand.
    await page.get_by_role("tab", name="Statistics").click()
    panel = page.locator("#panel-stats")
    await expect(page.get_by_role("tabpanel", name="Statistics")).to_be_visible()
    await expect(panel).not_to_have_attribute("aria-busy", "true", timeout=FIGURES_MS)
    await panel.get_by_label("Dates", exact=True).select_option(label="Choose dates…")
    await panel.get_by_label("From", exact=True).fill(DAY)
    await panel.get_by_label("To", exact=True).fill(DAY)
    await panel.get_by_label("Show per", exact=True).select_option("hour")
    await panel.get_by_role("button", name="Show").click()
    await expect(panel.get_by_role("heading", name="Service of Thu, Jan 1")).to_be_visible()
    return panel


async def test_the_owner_reads_the_statistics_and_downloads_them(
    tmp_path: Path, browser: Any
) -> None:
    db = tmp_path / "serveur.db"
    async with stats_server(db) as app:
        rows, total = await expected(app)
        assert [f.period.label for f in rows] == ["2026-01-01 08:00", "2026-01-01 09:00"]
        assert total.delivered == 6

        context = await browser.new_context(
            viewport=TABLET, timezone_id=ZONE, accept_downloads=True
        )
        page = await context.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        panel = await show_the_day(page, app)

        # The headline figures are the server's.
        await expect(panel.get_by_test_id("stats-delivered")).to_have_text(str(total.delivered))
        await expect(panel.get_by_test_id("stats-trips")).to_have_text(str(total.trips))
        await expect(panel.get_by_test_id("stats-returned")).to_have_text(
            f"{total.returned} / {total.voided}"
        )
        wait = f"{total.wait_mean / 60:.1f} min"
        await expect(panel.get_by_test_id("stats-wait-mean")).to_have_text(wait)

        # One bar per hour, as tall as its count; the chart's words say what it shows.
        chart = panel.get_by_role("img", name="Bar chart: 6 dishes delivered over 2 periods")
        await expect(chart).to_be_visible()
        bars = chart.locator("rect.bar")
        await expect(bars).to_have_count(len(rows))
        assert [await b.get_attribute("data-value") for b in await bars.all()] == [
            str(f.delivered) for f in rows
        ]
        await expect(panel.locator("svg.chart-line .dot")).to_have_count(len(rows))
        # The same figures as a table (the charts' text alternative), behind a disclosure.
        await panel.get_by_text("Show the figures as a table").click()
        figures_table = panel.get_by_role("table", name="Figures for each period")
        await expect(figures_table.get_by_role("row")).to_have_count(1 + len(rows) + 1)
        await expect(figures_table.get_by_role("row").last).to_contain_text(
            f"Total{total.delivered}"
        )
        # Each robot: its trips and errors.
        robots = panel.get_by_role("table", name="Each robot")
        r2 = next(r for r in total.robots if r.robot == "r2")
        await expect(robots.get_by_role("row", name="r2")).to_contain_text(str(r2.trips))
        assert r2.errors == 2

        # The trip history, newest first; a trip opened from the keyboard: stops and dishes.
        trips = panel.get_by_role("list", name="Trips")
        await expect(trips.locator(":scope > li")).to_have_count(4)
        first = trips.locator("details").filter(has_text=re.compile(r"Trip 1 "))
        await first.locator("summary").focus()
        await page.keyboard.press("Enter")
        await expect(first).to_have_attribute("open", "")
        await expect(first.get_by_role("listitem")).to_have_count(2)
        await expect(first).to_contain_text("skipped by ana")
        await expect(first).to_contain_text("#1 Laksa, #2 Satay")
        await expect(first).to_contain_text("food collected 08:02")

        # Both CSV files, exactly what `serveur stats --csv` writes for this range.
        name, text = await download(page, "Download figures (CSV)")
        assert name == f"serveur-figures-hour-{DAY}.csv"
        assert text == await command_csv(db, "--by", "hour")
        assert [r.split(",")[0] for r in text.splitlines()] == [
            "period", "2026-01-01 08:00", "2026-01-01 09:00", "total",
        ]  # fmt: skip
        name, text = await download(page, "Download trips (CSV)")
        assert name == f"serveur-trips-{DAY}.csv"
        assert text == await command_csv(db, "--trips")
        assert len(text.splitlines()) == 1 + 6  # a row per stop: 2 + 1 per service

        # In Chinese: the words change, the numbers stay the server's.
        await page.locator("#lang-picker").select_option("zh")
        await expect(page.get_by_role("tab", name="统计")).to_be_visible()
        await expect(panel.get_by_test_id("stats-delivered")).to_have_text("6")
        await expect(panel.get_by_role("img", name=re.compile("^柱状图"))).to_be_visible()
        await expect(panel.locator("svg.chart-bars rect.bar")).to_have_count(len(rows))
        await expect(panel.locator("details.trip-row[open]")).to_contain_text("第 1 趟")
        await page.locator("#lang-picker").select_option("en")

        # A 390 px phone: nothing wider than the screen, every control a finger's size.
        await page.set_viewport_size(PHONE)
        # The charts are drawn again to the phone's width.
        await page.wait_for_function(
            "() => [...document.querySelectorAll('#panel-stats svg.chart')]"
            ".every((s) => Number(s.getAttribute('width')) <= 390)"
        )
        wide, inner = await sideways(page)
        assert wide <= inner == PHONE["width"], wide
        small = await too_small(page, "#panel-stats :is(button, select, input, summary)")
        assert small == [], small
        assert errors == [], errors
        await context.close()


async def test_the_statistics_tab_passes_axe(tmp_path: Path, browser: Any) -> None:
    """axe-core (as tests/web/test_a11y.py runs it) on the tab with everything shown: the
    figures, both charts, the table of periods, the robots, a trip opened; on a tablet and
    on a phone."""
    need_axe()
    async with stats_server(tmp_path / "serveur.db") as app:
        context = await browser.new_context(viewport=TABLET, timezone_id=ZONE, bypass_csp=True)
        page = await context.new_page()
        panel = await show_the_day(page, app)
        await panel.get_by_text("Show the figures as a table").click()
        await panel.locator("details.trip-row summary").first.click()
        await expect(panel.locator("details.trip-row[open]")).to_have_count(1)
        found = {"tablet": await violations(page)}
        await page.set_viewport_size(PHONE)  # the tables now scroll sideways in their boxes
        await page.wait_for_function(
            "() => document.querySelector('#panel-stats .table-scroll').scrollWidth"
            " > document.querySelector('#panel-stats .table-scroll').clientWidth"
        )
        found["phone"] = await violations(page)
        assert found == {"tablet": [], "phone": []}, found
        await context.close()


async def test_the_owner_reads_the_guests_calls(tmp_path: Path, browser: Any) -> None:
    """tests/stats/events.py's service with six calls and two bussing trips: the calls table
    counts each kind with its times to answer, then what waited too long, was cancelled, and
    the robots sent for plates; axe-clean on a phone."""
    need_axe()
    async with stats_server(tmp_path / "serveur.db", with_calls, (0,)) as app:
        context = await browser.new_context(viewport=PHONE, timezone_id=ZONE, bypass_csp=True)
        page = await context.new_page()
        panel = await show_the_day(page, app)
        calls = panel.get_by_role("region", name="Guests' calls")
        rows = calls.locator("tbody tr")
        await expect(rows).to_have_count(4)
        # Plates 3 (answered in 20 s and 200 s), a waiter 2 (150 s), the bill 1 (30 s).
        await expect(rows.nth(0)).to_have_text(re.compile(r"Take the plates\s*3\s*20 sec\s*3"))
        await expect(rows.nth(1)).to_have_text(re.compile(r"A waiter\s*2\s*2"))
        await expect(rows.nth(3)).to_have_text(re.compile(r"Total\s*6\s*30 sec"))
        more = panel.get_by_test_id("stats-calls-more")
        await expect(more).to_contain_text("2 waited too long · 2 cancelled · 2 robot trips")
        await expect(more).to_contain_text("within 20 sec (half)")
        assert await violations(page) == []
        await context.close()
