"""ui.js ``KeyedList``, the one way the pages draw a list that live updates change (issue 27,
item 6), in Chromium: a row is built again only when its signature changed, rows keep their
nodes and follow the records' order, the empty note comes and goes, a language change rebuilds
every row, and a rebuilt row keeps the keyboard's place (``data-focus-key``, ``lostFocus``).

The site is answered from memory (``StaticSite``, the server's own files and its made status
table) through playwright's routing: no server, no network.
"""

from __future__ import annotations

from typing import Any

import pytest

from serveur.web.static import WEB_ROOT, StaticSite, generated
from tests.web.conftest import needs_browser

ORIGIN = "http://serveur.test"

# Each step's list as [text, is the same node as the step before] per row; builds counted.
SCENARIO = """async () => {
  const { KeyedList } = await import("/js/ui.js");
  const ul = document.createElement("ul");
  document.body.append(ul);
  let builds = 0;
  const list = new KeyedList(ul, {
    key: (r) => r.id,
    signature: (r) => [r.text],
    build: (r) => {
      builds += 1;
      const li = document.createElement("li");
      li.textContent = r.text;
      return li;
    },
    empty: () => Object.assign(document.createElement("li"), { textContent: "none" }),
  });
  const steps = [];
  let before = new Map();
  const look = (name) => {
    const now = new Map([...list.rows].map(([k, row]) => [k, row.node]));
    steps.push({
      name,
      rows: [...ul.children].map((li) => [li.textContent, [...before.values()].includes(li)]),
      builds,
    });
    before = now;
    builds = 0;
  };
  list.update([]);
  look("empty");
  list.update([{ id: 1, text: "a" }, { id: 2, text: "b" }, { id: 3, text: "c" }]);
  look("three");
  list.update([{ id: 1, text: "a" }, { id: 2, text: "B" }, { id: 3, text: "c" }]);
  look("one changed");
  list.update([{ id: 3, text: "c" }, { id: 1, text: "a" }]);
  look("reordered, one gone");
  list.invalidate();
  list.update([{ id: 3, text: "c" }, { id: 1, text: "a" }]);
  look("new words");
  list.update([]);
  look("empty again");
  list.clear();
  look("cleared");
  return steps;
}"""

FOCUS = """async () => {
  const { KeyedList } = await import("/js/ui.js");
  const ul = document.createElement("ul");
  document.body.append(ul);
  let pressed = null;
  const list = new KeyedList(ul, {
    key: (r) => r.id,
    signature: (r) => r.state,
    build: (r) => {
      const li = document.createElement("li");
      for (const key of r.buttons) {
        const b = document.createElement("button");
        b.textContent = `${key} ${r.state}`;
        b.dataset.focusKey = key;
        li.append(b);
      }
      return li;
    },
    lostFocus: (r) => (pressed && pressed.id === r.id ? pressed.key : null),
  });
  const out = [];
  const focused = () => (document.activeElement ? document.activeElement.textContent : null);
  list.update([{ id: 1, state: 1, buttons: ["go", "stop"] }]);
  ul.querySelector('[data-focus-key="stop"]').focus();
  list.update([{ id: 1, state: 2, buttons: ["go", "stop"] }]);
  out.push(focused()); // the same control, rebuilt
  list.update([{ id: 1, state: 3, buttons: ["go"] }]);
  out.push(focused()); // that control gone: the row's first
  document.activeElement.blur();
  pressed = { id: 1, key: "go" };
  list.update([{ id: 1, state: 4, buttons: ["stop", "go"] }]);
  out.push(focused()); // focus had dropped to <body> while a request ran: lostFocus names it
  pressed = null;
  document.activeElement.blur();
  list.update([{ id: 1, state: 5, buttons: ["stop", "go"] }]);
  out.push(document.activeElement === document.body ? "body" : focused()); // nothing taken
  return out;
}"""


async def _page(browser: Any) -> Any:
    site = StaticSite.load(WEB_ROOT, generated())
    page = await browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)

    async def answer(route: Any) -> None:
        path = route.request.url.removeprefix(ORIGIN)
        asset = site.resolve(path)
        if asset is None:
            await route.fulfill(status=404, body="not found")
        else:
            await route.fulfill(status=200, body=asset.body, content_type=asset.content_type)

    await page.route(f"{ORIGIN}/**", answer)
    # A blank page of the site's origin (no page script: nothing connects anywhere).
    await page.goto(f"{ORIGIN}/i18n/en.json")
    page.errors = errors
    return page


@needs_browser
@pytest.mark.asyncio(loop_scope="module")
async def test_a_row_is_built_again_only_when_it_changed(browser: Any) -> None:
    page = await _page(browser)
    steps = {s["name"]: s for s in await page.evaluate(SCENARIO)}
    await page.close()
    assert steps["empty"]["rows"] == [["none", False]]
    assert steps["three"] == {
        "name": "three",
        "rows": [["a", False], ["b", False], ["c", False]],
        "builds": 3,
    }
    # Only the changed row is a new node; the others are the very nodes drawn before.
    assert steps["one changed"]["rows"] == [["a", True], ["B", False], ["c", True]]
    assert steps["one changed"]["builds"] == 1
    # Order follows the records, nothing built; a record gone takes its row.
    assert steps["reordered, one gone"]["rows"] == [["c", True], ["a", True]]
    assert steps["reordered, one gone"]["builds"] == 0
    # A language change: every row again.
    assert steps["new words"]["rows"] == [["c", False], ["a", False]]
    assert steps["new words"]["builds"] == 2
    assert steps["empty again"]["rows"] == [["none", False]]
    assert steps["cleared"]["rows"] == []
    assert page.errors == []


@needs_browser
@pytest.mark.asyncio(loop_scope="module")
async def test_a_rebuilt_row_keeps_the_keyboards_place(browser: Any) -> None:
    page = await _page(browser)
    got = await page.evaluate(FOCUS)
    await page.close()
    assert got == ["stop 2", "go 3", "go 4", "body"]


# The scripts that still replace an element's children, and why none of them is a live list:
# each draws a fixed set of options again in a new language, a one-off report, or one view.
# A new list a live update changes is drawn with KeyedList, not added here.
REPLACED = {
    "i18n.js": 1,  # the language picker's options (a new language)
    "robot.js": 5,  # the robot screen: one view, drawn again when its model changed; the staff
    # bar (signed in or not), drawn on signing in and out
    "setup.js": 1,  # the default language's options (the languages ticked), not live data
    "staff/accounts.js": 5,  # the role and kind options; a password or the codes just made
    "staff/programs.js": 2,  # a program's token, shown once when it is made, and cleared
    "staff/cartrays.js": 2,  # the tray numbers for the one dish tapped (or none), not a list
    "staff/restaurant/buttons.js": 4,  # the kind and table options; a button's address, shown
    # once when it is made, and cleared
    "staff/log.js": 3,  # the filters' options; the people the server names on a search
    "staff/restaurant/settings.js": 1,  # the default language's options (the languages ticked)
    "staff/restaurant/zones.js": 1,  # an import's report, cleared for the next file
    "staff/stats.js": 8,  # the range's options; a report drawn whole from one reply
    "staff/stats/forecast.js": 4,  # the forecast, drawn whole from one reply
}


def test_no_script_draws_a_live_list_by_hand() -> None:
    found: dict[str, int] = {}
    for path in sorted((WEB_ROOT / "js").rglob("*.js")):
        name = path.relative_to(WEB_ROOT / "js").as_posix()
        text = path.read_text("utf-8")
        if name != "ui.js" and "replaceChildren(" in text:
            found[name] = text.count("replaceChildren(")
        # A hand-kept map of rows (what KeyedList is) outside ui.js.
        assert "rows = new Map()" not in text or name == "ui.js", name
    assert found == REPLACED, "draw a list that live updates change with ui.js KeyedList"
