"""Accessibility: axe-core finds no serious or critical violation on any page (issue 20).

axe-core comes from the npm registry (tests/node/package.json, installed by ``npm ci`` into the
git-ignored tests/node/node_modules, as .ci/run does); the test skips without it locally and
fails without it in CI (``$CI`` set). The pages' Content-Security-Policy forbids an inline
script, so the browser context bypasses it to inject axe.

Checked: the staff console after login on each of its tabs (the owner's, so the menu and
accounts tabs too, the latter also showing a new password and a screen's QR code),
a robot's screen and a table's screen, with a trip under way so status badges and buttons show.
The first-run setup page is checked with ``violations`` where its tests reach each state:
tests/web/test_setup_ui.py (each step on a phone, the places step with and without a map) and
tests/web/test_first_service.py (the places placed and the test trip at its table, on a tablet).
The WCAG 2.1 A/AA rules and best practices run, with ``label-content-name-mismatch`` (an
experimental rule: a button whose accessible name does not contain its visible words).
"""

from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

import pytest

from tests.web.test_ui import (
    TABLET,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

AXE = Path(__file__).parents[1] / "node" / "node_modules" / "axe-core" / "axe.min.js"

RUN_AXE = """async () => {
  const r = await axe.run(document, {
    runOnly: { type: "tag", values: ["wcag2a", "wcag2aa", "wcag21a", "wcag21aa", "best-practice"] },
    rules: { "label-content-name-mismatch": { enabled: true } },
  });
  return r.violations
    .filter((v) => v.impact === "serious" || v.impact === "critical")
    .map((v) => ({
      id: v.id,
      impact: v.impact,
      help: v.help,
      nodes: v.nodes.slice(0, 5).map((n) => n.target.join(" ") + " :: " + n.failureSummary),
    }));
}"""


def need_axe() -> None:
    if not AXE.is_file():
        msg = "tests/node has no node_modules/axe-core: run `npm ci` in tests/node"
        if os.environ.get("CI"):
            pytest.fail(msg)
        pytest.skip(msg)


async def open_page(b: Any, url: str, *, online: bool = True) -> Any:
    context = await b.new_context(viewport=TABLET, bypass_csp=True)
    page = await context.new_page()
    await page.goto(url)
    # The page's words are in (i18n.js marks <html data-lang> once its catalogs are applied):
    # axe must not judge the bare markup of a page still fetching its catalogs.
    await expect(page.locator("html")).to_have_attribute("data-lang", re.compile(r"^\w+$"))
    if online:
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
    return page


async def violations(page: Any) -> list[dict[str, Any]]:
    if not await page.evaluate("() => typeof axe !== 'undefined'"):
        await page.add_script_tag(path=str(AXE))
    result: list[dict[str, Any]] = await page.evaluate(RUN_AXE)
    return result


async def test_no_serious_or_critical_violation_on_any_page(
    tmp_path: Path,
    browser: Any,
) -> None:
    need_axe()
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.ok("control", robot="r1", action="auto")
        ids = [
            (await c.ok("create", type="order", dish=d, table=t))["order"]["id"]
            for d, t in (("Laksa", "T3"), ("Satay", "T5"))
        ]
        await c.ok("create", type="order", dish="Pho", table="T7")  # left waiting in the kitchen
        await c.ok("create", type="task", orders=ids)
        base = http_base(r)
        found: dict[str, list[dict[str, Any]]] = {}

        staff = await open_page(browser, f"{base}/", online=False)
        found["login"] = await violations(staff)
        await log_in(staff, "owner", r.app.first_owner_password or "")
        await expect(staff.get_by_role("button", name="Select r1")).to_be_visible()
        tabs = ("Map", "Send food", "New order", "Kitchen", "Menu", "Restaurant", "Activity")
        tabs += ("Statistics",)
        for tab in (*tabs, "Accounts"):  # Accounts last: what it shows once is checked next
            await staff.get_by_role("tab", name=tab).click()
            await expect(staff.get_by_role("tab", name=tab)).to_have_attribute(
                "aria-selected", "true"
            )
            found[f"staff {tab}"] = await violations(staff)
        # The owner's Accounts tab with what it shows once: a password and a screen's QR code.
        await staff.get_by_label("User name").fill("sam")
        await staff.get_by_role("button", name="Add person").click()
        await expect(staff.get_by_test_id("password")).to_be_visible()
        await staff.get_by_role("button", name="Make QR code").click()
        await expect(staff.locator("img.qr").first).to_be_visible()
        found["staff Accounts, shown once"] = await violations(staff)

        robot = await open_page(
            browser, f"{base}/robot/r1#token={await r.app.issue_token('robot-screen', robot='r1')}"
        )
        found["robot screen"] = await violations(robot)
        table = await open_page(
            browser, f"{base}/table/T3#token={await r.app.issue_token('table-screen', table='T3')}"
        )
        found["table screen"] = await violations(table)
        bad = {page: v for page, v in found.items() if v}
        assert bad == {}, bad


def contrast(a: str, b: str) -> float:
    """WCAG 2 contrast ratio of two #rrggbb colours."""

    def lum(h: str) -> float:
        c = [int(h[i : i + 2], 16) / 255 for i in (1, 3, 5)]
        c = [x / 12.92 if x <= 0.03928 else ((x + 0.055) / 1.055) ** 2.4 for x in c]
        return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]

    hi, lo = sorted((lum(a), lum(b)), reverse=True)
    return (hi + 0.05) / (lo + 0.05)


async def test_every_status_colour_reads_at_4_5_to_1() -> None:
    """Each status, whichever the page shows now: white words on the colour (the robot
    screen's badge) and the colour on the page's background (the console's dots and names)."""
    import re

    site = Path(__file__).parents[2] / "serveur" / "web" / "site"
    js = (site / "js" / "status.js").read_text()
    block = js.split("STATUS_COLOURS = {")[1].split("}")[0]
    colours = dict(re.findall(r'(\w+): "(#[0-9a-fA-F]{6})"', block))
    assert len(colours) == 11, colours
    bg = re.search(r"--bg: (#[0-9a-fA-F]{6})", (site / "css" / "base.css").read_text())
    assert bg is not None
    low = {
        status: (round(contrast(c, "#ffffff"), 2), round(contrast(c, bg.group(1)), 2))
        for status, c in colours.items()
        if min(contrast(c, "#ffffff"), contrast(c, bg.group(1))) < 4.5
    }
    assert low == {}, low
