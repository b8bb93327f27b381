"""The allowed-actions table the pages use is the server's (issue 27, item 6): the real server
serves ``/js/status-table.js``, written from ``serveur.status.ALLOWED`` at start, and the page's
``status.js`` answers from it. Checked in Chromium, for every status and every action, against
the Python table itself, so a change in ``status.py`` that the pages missed fails here.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

from serveur.status import ALLOWED, Action, RobotStatus
from serveur.web.static import STATUS_TABLE, StaticSite
from tests.web.conftest import needs_browser
from tests.web.test_ui import http_base, ui_restaurant

# Every (status, action) the page's allowed() accepts, as "Status action" strings.
ANSWERS = """async ([statuses, actions]) => {
  const status = await import("/js/status.js");
  const yes = [];
  for (const s of statuses) {
    for (const a of actions) if (status.allowed(s, a)) yes.push(`${s} ${a}`);
  }
  return { yes, statuses: status.STATUSES };
}"""


@needs_browser
@pytest.mark.asyncio(loop_scope="module")
async def test_the_page_allows_what_status_py_allows(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        page = await browser.new_page()
        errors: list[str] = []
        page.on("pageerror", lambda e: errors.append(str(e)))
        page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
        got: list[str] = []
        page.on("response", lambda resp: got.append(resp.url))
        await page.goto(http_base(r) + "/")
        statuses = [s.value for s in RobotStatus]
        answers = await page.evaluate(ANSWERS, [statuses, [a.value for a in Action]])
        await page.close()
    want = sorted(f"{s.value} {a.value}" for s in RobotStatus for a in ALLOWED[s])
    assert sorted(answers["yes"]) == want
    assert answers["statuses"] == statuses
    # The staff page itself loaded the table from the server (its map tools and buttons use it).
    assert any(url.endswith(STATUS_TABLE) for url in got), got
    assert errors == []


def test_a_made_file_cannot_shadow_a_file_of_the_site(tmp_path: Path) -> None:
    (tmp_path / "js").mkdir()
    (tmp_path / "js" / "status-table.js").write_text("export const ALLOWED = {};")
    with pytest.raises(ValueError, match=r"status-table\.js"):
        StaticSite.load(tmp_path, {STATUS_TABLE: b"export const ALLOWED = {};"})
    site = StaticSite.load(tmp_path / "js", {STATUS_TABLE: b"x"})
    assert sorted(site.assets) == ["/js/status-table.js", "/status-table.js"]
