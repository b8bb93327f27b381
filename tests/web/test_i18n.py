"""The pages' words come from catalogs (serveur/web/site/i18n/*.json, applied by js/i18n.js).

Two sets of catalogs, merged per language by i18n.js: the main one (``i18n/<lang>.json``: staff
and shared words) and the guests' (``i18n/guest/<lang>.json``: the robot and table screens'
service words). Static checks: in each set every catalog has exactly the English one's keys (and
each text the same placeholders), no key is in both sets, every key the site names exists in
their union, every key is used, and no HTML file carries words of its own.
In Chromium (as tests/web/test_ui.py runs it: Debian's /usr/bin/chromium, a real server, no
sleeps): each page opened with ``?lang=zh`` and ``?lang=ms`` shows that language and sets
``<html lang>``, and the page's language picker switches at once, without reloading the page
or its connection.
"""

from __future__ import annotations

import json
import re
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest

from serveur.domain import WaypointKind
from serveur.status import RobotStatus
from serveur.web.static import StaticSite
from tests.web.conftest import needs_browser

SITE = Path(__file__).resolve().parents[2] / "serveur" / "web" / "site"
LANGS = ("en", "zh", "ms")


def _load(folder: Path) -> dict[str, dict[str, Any]]:
    return {lang: json.loads((folder / f"{lang}.json").read_text("utf-8")) for lang in LANGS}


MAIN = _load(SITE / "i18n")
# The other sets, each in its folder and namespace (its keys start with "<folder>.").
NAMED = ("guest", "owner", "stats")
SETS = {"main": MAIN, **{name: _load(SITE / "i18n" / name) for name in NAMED}}
GUEST = SETS["guest"]
# What a page holds per language: the sets merged (i18n.js), as the tests below read it.
CATALOGS = {lang: {k: v for c in SETS.values() for k, v in c[lang].items()} for lang in LANGS}
EN = CATALOGS["en"]
HTML_FILES = sorted(SITE.glob("*.html"))
JS_FILES = sorted((SITE / "js").rglob("*.js"))

# Keys the scripts build from wire values (`status.${s}`, ...): each family is checked in full.
# From the server's own enums: a status or a kind of place added there must be worded here.
STATUSES = [s.value for s in RobotStatus]
DYNAMIC = {
    "status": STATUSES,
    "role": ["owner", "staff", "robot-screen", "table-screen", "integration"],
    "lang": list(LANGS),
    "wp.kind": [k.value for k in WaypointKind],
}
PLURAL_FORMS = {"zero", "one", "two", "few", "many", "other"}  # Intl.PluralRules' categories
# Attributes a person sees or hears: in the HTML they only ever come from data-i18n-<attr>.
WORDY_ATTRS = ("aria-label", "title", "placeholder", "alt")

try:
    from playwright.async_api import expect

    from tests.web.test_ui import (
        Screens,
        http_base,
        staff_client,
        ui_restaurant,
    )
except (ImportError, pytest.skip.Exception):  # no browser here: the static checks still run
    expect = None


def texts(value: Any) -> list[str]:
    """A catalog value's texts: a plain text, or each form of a plural."""
    return list(value.values()) if isinstance(value, dict) else [value]


def placeholders(value: Any) -> set[str]:
    return {p for text in texts(value) for p in re.findall(r"\{(\w+)\}", text)}


@pytest.mark.parametrize("name", sorted(SETS))
def test_every_catalog_has_the_same_keys_and_placeholders(name: str) -> None:
    catalogs = SETS[name]
    en = catalogs["en"]
    assert en, f"the {name} catalogs are empty"
    for lang, catalog in catalogs.items():
        assert set(catalog) == set(en), (name, lang, set(catalog) ^ set(en))
        for key, value in catalog.items():
            assert all(isinstance(t, str) and t for t in texts(value)), (name, lang, key)
            if isinstance(value, dict):
                assert "other" in value and set(value) <= PLURAL_FORMS, (name, lang, key)
                assert "count" in placeholders(value), (name, lang, key)
            # A translation may reorder the placeholders, never drop or invent one.
            assert placeholders(value) == placeholders(en[key]), (name, lang, key)


def test_no_key_is_in_both_catalog_sets() -> None:
    # i18n.js merges the sets: a key in both would have one text silently replace the other.
    assert sum(len(c["en"]) for c in SETS.values()) == len(CATALOGS["en"])
    # Each set has its own namespace, so it is plain which file holds a key.
    for name in NAMED:
        assert all(key.startswith(f"{name}.") for key in SETS[name]["en"]), name
        assert not any(key.startswith(f"{name}.") for key in MAIN["en"]), name


def keys_named_in_site() -> set[str]:
    """Every catalog key the HTML and scripts name literally."""
    spaces = {key.split(".")[0] for key in EN}
    found: set[str] = set()
    for path in HTML_FILES:
        found |= set(re.findall(r'data-i18n(?:-[\w-]+)?="([^"]+)"', path.read_text("utf-8")))
    for path in JS_FILES:
        # Any "namespace.key" string, wherever it sits: t("..."), data-i18n attributes, tables
        # of label keys. A typo in a key is a string in a known namespace that is not a key.
        for literal in re.findall(r'"([a-z][\w-]*(?:\.[\w-]+)+)"', path.read_text("utf-8")):
            if literal.split(".")[0] in spaces:
                found.add(literal)
    return found


def test_every_key_the_site_names_exists_and_every_key_is_used() -> None:
    named = keys_named_in_site()
    assert named, "no key found: the scan is broken"
    assert sorted(named - set(EN)) == []
    dynamic = {f"{family}.{v}" for family, values in DYNAMIC.items() for v in values}
    assert sorted(dynamic - set(EN)) == []
    assert sorted(set(EN) - named - dynamic) == [], "keys nothing uses"
    # The dynamic families are built with template literals in these files.
    scripts = "\n".join(p.read_text("utf-8") for p in JS_FILES)
    for family in DYNAMIC:
        assert f"`{family}.${{" in scripts, family


class _Words(HTMLParser):
    """The text and the wordy attributes of an HTML file, outside <title>, <script>, <style>."""

    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.words: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        for name, value in attrs:
            if name in WORDY_ATTRS:
                self.words.append(f"<{tag} {name}={value!r}>")
        if tag not in ("meta", "link", "br", "img", "input"):
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if tag in self.stack:
            while self.stack.pop() != tag:
                pass

    def handle_data(self, data: str) -> None:
        if data.strip() and not {"title", "script", "style"} & set(self.stack[-1:]):
            self.words.append(data.strip())


@pytest.mark.parametrize("page", [p.name for p in HTML_FILES])
def test_html_files_hold_no_words_of_their_own(page: str) -> None:
    parser = _Words()
    parser.feed((SITE / page).read_text("utf-8"))
    assert parser.words == []


def test_catalogs_are_served_as_json() -> None:
    site = StaticSite.load(SITE)
    for folder, catalogs in (("/i18n/", MAIN), *((f"/i18n/{n}/", SETS[n]) for n in NAMED)):
        for lang in LANGS:
            asset = site.resolve(f"{folder}{lang}.json")
            assert asset is not None and asset.content_type.startswith("application/json")
            assert json.loads(asset.body.decode("utf-8")) == catalogs[lang]
    # i18n.js fetches every set, by these very paths.
    script = (SITE / "js" / "i18n.js").read_text("utf-8")
    assert "SETS = " + json.dumps(["", *(n + "/" for n in NAMED)]) in script


# --- in Chromium -----------------------------------------------------------------------------

chromium = [needs_browser, pytest.mark.asyncio(loop_scope="module")]


def in_chromium(f: Any) -> Any:
    for mark in chromium:
        f = mark(f)
    return f


def tr(lang: str, key: str, **params: Any) -> str:
    """The catalog's text as i18n.js fills it (plurals: en, zh and ms only have one/other)."""
    text = CATALOGS[lang][key]
    if isinstance(text, dict):
        text = text.get("one" if params.get("count") == 1 else "other", text["other"])
    return re.sub(r"\{(\w+)\}", lambda m: str(params.get(m.group(1), m.group(0))), text)


HTML_LANG = {"en": "en", "zh": "zh-Hans", "ms": "ms"}


async def expect_lang(page: Any, lang: str) -> None:
    await expect(page.locator("html")).to_have_attribute("lang", HTML_LANG[lang])
    await expect(page.locator("#lang-picker")).to_have_value(lang)


async def switch(page: Any, screens: Any, lang: str) -> None:
    """Pick `lang` in the page's picker; the page is neither reloaded nor reconnected."""
    await page.evaluate("window.__sameDocument = true")
    logins = sum(1 for m in screens.sent if m.get("clientmsg") == "login")
    picker = page.get_by_role("combobox", name=tr(await current_lang(page), "lang.label"))
    await picker.select_option(lang)
    await expect_lang(page, lang)
    assert await page.evaluate("window.__sameDocument === true")
    await expect(page.locator("body")).to_have_attribute("data-connection", "online")
    assert sum(1 for m in screens.sent if m.get("clientmsg") == "login") == logins


async def current_lang(page: Any) -> str:
    return str(await page.locator("html").get_attribute("data-lang"))


@in_chromium
async def test_the_staff_console_in_chinese_and_malay(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        await c.ok("create", type="order", dish="Laksa", table="T3")
        screens = Screens(browser, http_base(r))  # a fresh tablet: log in by hand, in Chinese
        staff = await screens.open("/?lang=zh", online=False)
        await expect_lang(staff, "zh")
        form = staff.get_by_role("dialog").filter(has_text=tr("zh", "login.title"))
        await form.get_by_label(tr("zh", "login.user")).fill("owner")
        await form.get_by_label(tr("zh", "login.password")).fill(r.app.first_owner_password or "")
        await form.get_by_role("button", name=tr("zh", "login.submit")).click()
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        await expect(staff).to_have_title(tr("zh", "staff.docTitle"))
        who = tr("zh", "staff.who", user="owner", role=tr("zh", "role.owner"))
        await expect(staff.get_by_test_id("who")).to_have_text(who)
        await expect(staff.get_by_role("tab", name="地图和机器人")).to_be_visible()
        row = staff.get_by_role("listitem").filter(has_text="r1")
        await expect(row.locator(".status-badge")).to_have_text(tr("zh", "status.Ready"))
        await expect(staff.get_by_role("button", name="接管 r1")).to_be_visible()

        # Plural forms through Intl.PluralRules: one form in Chinese.
        await staff.get_by_role("tab", name=tr("zh", "staff.tab.issue")).click()
        await staff.get_by_role(
            "button", name=tr("zh", "issue.addFor", dish="Laksa", table="T3")
        ).click()
        dishes, tables = tr("zh", "count.dishes", count=1), tr("zh", "count.tables", count=1)
        assert (dishes, tables) == ("1 道菜", "1 桌")
        send = staff.get_by_role(
            "button", name=tr("zh", "issue.sendCount", dishes=dishes, tables=tables)
        )
        await expect(send).to_be_enabled()

        # The picker: Malay at once, the same page and connection, the cart kept.
        await switch(staff, screens, "ms")
        await expect(staff.get_by_role("button", name="Hantar 1 hidangan (1 meja)")).to_be_enabled()
        await expect(staff.get_by_role("tab", name="Peta & robot")).to_be_visible()
        await expect(staff.get_by_role("list", name=tr("ms", "issue.cart"))).to_contain_text(
            "Laksa"
        )
        await staff.get_by_role("tab", name="Peta & robot").click()
        await expect(row.locator(".status-badge")).to_have_text(tr("ms", "status.Ready"))
        await expect(staff.get_by_role("button", name="Ambil alih r1")).to_be_visible()
        await expect(staff.get_by_test_id("who")).to_have_text("owner (pemilik)")
        # The choice replaced the address's and is kept on this device for staff pages.
        assert "lang=ms" in staff.url
        await staff.goto(http_base(r) + "/")
        await expect(staff.locator("body")).to_have_attribute("data-connection", "online")
        await expect_lang(staff, "ms")
        await expect(staff.get_by_role("button", name="Ambil alih r1")).to_be_visible()
        # Back to English: the texts the other UI tests rely on.
        await switch(staff, screens, "en")
        await expect(staff.get_by_role("button", name="Take control r1")).to_be_visible()
        await expect(staff.get_by_role("tab", name="Map & robots")).to_be_visible()
        screens.assert_no_errors()


@in_chromium
async def test_the_robot_screen_in_malay_and_chinese(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        token = await r.app.issue_token("robot-screen", robot="r1")
        screens = Screens(browser, http_base(r), token)
        robot = await screens.open("/robot/r1?lang=ms")
        await expect_lang(robot, "ms")
        await expect(robot.get_by_text(tr("ms", "robot.staffActivate"))).to_be_visible()
        await expect(robot.get_by_text(tr("ms", "robot.hello", name="r1"))).to_be_visible()
        await expect(robot.locator("#robot-status")).to_have_text(tr("ms", "status.Ready"))
        await expect(robot).to_have_title("serveur · r1")

        await switch(robot, screens, "zh")
        await expect(robot.get_by_text(tr("zh", "robot.staffActivate"))).to_be_visible()
        await expect(robot.locator("#robot-status")).to_have_text(tr("zh", "status.Ready"))
        # A status change after the switch is drawn in the new language.
        await c.ok("control", robot="r1", action="auto")
        await expect(robot.get_by_role("heading", name=tr("zh", "robot.awaiting"))).to_be_visible()
        await expect(robot.locator("#robot-status")).to_have_text(tr("zh", "status.Awaiting"))
        screens.assert_no_errors()


@in_chromium
async def test_the_table_screen_in_chinese_and_malay(tmp_path: Path, browser: Any) -> None:
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.ok("create", type="order", dish="Teh tarik", table="T3")
        token = await r.app.issue_token("table-screen", table="T3")
        screens = Screens(browser, http_base(r), token)
        table = await screens.open("/table/T3?lang=zh")
        await expect_lang(table, "zh")
        await expect(table.get_by_role("heading", level=1)).to_have_text("T3 号桌")
        await expect(table).to_have_title("serveur · T3 号桌")
        await expect(table.get_by_role("list", name=tr("zh", "table.pass"))).to_have_text(
            "Teh tarik"
        )
        await expect(table.get_by_role("list", name=tr("zh", "table.served"))).to_have_text(
            tr("zh", "table.servedEmpty")
        )

        await switch(table, screens, "ms")
        await expect(table.get_by_role("heading", level=1)).to_have_text("Meja T3")
        await expect(table).to_have_title("serveur · Meja T3")
        await expect(table.get_by_role("list", name=tr("ms", "table.pass"))).to_have_text(
            "Teh tarik"
        )
        await expect(table.get_by_role("list", name=tr("ms", "table.served"))).to_have_text(
            tr("ms", "table.servedEmpty")
        )
        # Opened with ?lang=ms from the start, another device shows Malay at once.
        other = await screens.open("/table/T3?lang=ms")
        await expect_lang(other, "ms")
        await expect(other.get_by_role("heading", name=tr("ms", "table.coming"))).to_be_visible()
        screens.assert_no_errors()
