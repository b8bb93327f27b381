"""The chain's dashboard (``serveur hq``, issue 34) in Chromium: a manager's read-only view of
every restaurant, on a phone and on a desk, against a real centre without a broker.

The centre: an :class:`HqStore` on a SQLite file, filled with a real service's events (a short
dinner replayed once per module, as tests/stats/test_replay_match.py makes one: two robots,
guests at T2 away so alerts are raised), moved in time so it happened this afternoon:

* ``paris`` took the whole dinner today, is connected and in sync;
* ``lyon`` took the same dinner yesterday; it is connected but 5 updates behind;
* ``nice`` took the first part of the dinner half an hour ago, with two events a site writes
  added at its end (a staff member acknowledged an alert; a robot then needed help), and went
  down: it is not connected, 20 updates behind. A test then takes the rest of the dinner into
  it (it came back): its card changes, the others' cards are the very same nodes.

The dashboard (:class:`serveur.hq.dashboard.Dashboard`) runs on the h11 listener
(:class:`IntakeServer`) on a free port; the browser's clock is put in a fixed-offset zone where
it is mid-afternoon, so "today" and "yesterday" are those services whatever the hour the test
runs. The figures the pages show are compared with :mod:`serveur.stats`'s for the same events
(the very code ``serveur stats`` runs). No sleeps: every wait is playwright's ``expect`` or
``wait_for_function``. Static checks of the dashboard's catalogs (as tests/web/test_i18n.py's
of the site's) run without a browser.
"""

from __future__ import annotations

import asyncio
import json
import math
import re
import time
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from datetime import UTC, datetime, timedelta, timezone
from html.parser import HTMLParser
from pathlib import Path
from typing import Any

import pytest
import pytest_asyncio

from serveur.domain import EventRecord
from serveur.hq.dashboard import HQ_ROOT, Dashboard
from serveur.hq.store import HqStore, open_hq_db
from serveur.replay.model import ReplayOptions
from serveur.replay.orders import parse_orders
from serveur.replay.service import replay_policy
from serveur.replay.vtime import VirtualTimeLoop
from serveur.security.auth import hash_password
from serveur.stats.compute import read_events, table
from serveur.stats.document import figures_document
from serveur.stats.load import load_events
from serveur.stats.periods import period_of
from serveur.status import RobotStatus
from serveur.store.factory import open_store
from serveur.till.intake import IntakeServer
from tests.web.conftest import needs_browser, sideways, too_small

try:
    from playwright.async_api import expect

    from tests.web.test_a11y import need_axe, violations
except (ImportError, pytest.skip.Exception):  # no browser here: the static checks still run
    expect = None

LANGS = ("en", "fr", "ms")
PHONE = {"width": 390, "height": 844}
DESK = {"width": 1280, "height": 800}
NAME, PASSWORD = "amelie", "the chain's own password"
TOUCH = "button, a, select, input, summary"  # what a finger aims at on these pages
WAIT_MS = 15_000  # a poll is every 5 s: a change shows within one or two
DASH = "\u2013"  # what the page shows for a figure with nothing to measure

LOG = """ready_at,table,dish
5.0,T2,Laksa
6.5,T2,Satay
20.0,T7,Teh tarik
"""

#: The browser tests: skipped where Chromium or playwright is missing (failed in CI), on the
#: module's event loop (the ``browser`` fixture's).
module_loop = pytest.mark.asyncio(loop_scope="module")


# -- the service, replayed once -----------------------------------------------------------------


async def _stored(db: Path) -> list[EventRecord]:
    async with open_store(str(db)) as store:
        return await load_events(store)


@pytest.fixture(scope="module")
def dinner(tmp_path_factory: pytest.TempPathFactory) -> list[EventRecord]:
    """A short dinner's events, as the site's own database holds them."""
    work = tmp_path_factory.mktemp("hq-dinner")
    opts = ReplayOptions(
        robots=2, seed=1, away=0.5, progress=False, robots_see_each_other=False, join=False
    )
    with asyncio.Runner(loop_factory=VirtualTimeLoop) as runner:
        runner.run(replay_policy(parse_orders(LOG), opts, "serveur", work))
    events = asyncio.run(_stored(work / "serveur.db"))
    kinds = {e.kind for e in events}
    assert {"alert.raised", "stop.done", "robot.status"} <= kinds, kinds
    return events


def moved(events: list[EventRecord], by: float) -> list[EventRecord]:
    """The same events ``by`` seconds later (their times, and the times their data hold)."""
    out = []
    for e in events:
        data = dict(e.data)
        if isinstance(data.get("ready_at"), int | float):
            data["ready_at"] = float(data["ready_at"]) + by  # type: ignore[arg-type]
        out.append(e.model_copy(update={"ts": e.ts + by, "data": data}))
    return out


def afternoon() -> tuple[str, timezone]:
    """A fixed-offset zone where it is now 15:xx (Chromium's name for it, and the zone)."""
    hours = (15 - datetime.now(UTC).hour + 12) % 24 - 12  # -12 .. +11
    name = "Etc/GMT" if hours == 0 else f"Etc/GMT{-hours:+d}"  # Etc/GMT-3 is UTC+3
    return name, timezone(timedelta(hours=hours))


@dataclass
class Centre:
    url: str
    hq: HqStore
    zone: str
    tz: timezone
    events: dict[str, list[EventRecord]]  # what each site holds
    rest: list[EventRecord]  # nice's events still to come
    heard: float  # when nice was last heard from
    requests: list[str] = field(default_factory=list)

    def today(self, site: str) -> dict[str, Any]:
        """Today's figures for ``site`` as serveur.stats computes them (the card's)."""
        day = period_of(time.time(), "day", self.tz, 4)
        rows, total = table(
            read_events(self.events[site]), "day", self.tz, start=day.start, end=day.end
        )
        return figures_document(rows, total)["total"]

    def days(self, site: str) -> dict[str, dict[str, Any]]:
        """Each service day's figures for ``site`` (the comparison's, the site page's)."""
        doc = figures_document(*table(read_events(self.events[site]), "day", self.tz))
        return {p["period"]: p for p in doc["periods"]}

    def clock(self, ts: float, lang: str = "en") -> re.Pattern[str]:
        """A time as the page writes it in ``lang`` ("3:05 PM", "15:05")."""
        t = datetime.fromtimestamp(ts, self.tz)
        if lang == "en":
            am_pm = "AM" if t.hour < 12 else "PM"
            return re.compile(rf"\b{t.hour % 12 or 12}:{t.minute:02d}\s{am_pm}")
        return re.compile(rf"\b{t.hour:02d}:{t.minute:02d}\b")


@pytest_asyncio.fixture(loop_scope="module")
async def centre(tmp_path: Path, dinner: list[EventRecord]) -> AsyncIterator[Centre]:
    zone, tz = afternoon()
    now = time.time()
    today = now - 120 - dinner[-1].ts  # the dinner ended two minutes ago
    paris = moved(dinner, today)
    lyon = moved(dinner, today - 86400)
    # nice: half an hour earlier, cut after the third alert; an alert was acknowledged and a
    # robot needed help just before the link went down.
    early = moved(dinner, today - 1800)
    raised = [i for i, e in enumerate(early) if e.kind == "alert.raised"]
    cut = raised[2] + 1
    first = early[raised[0]]
    ack = EventRecord(
        id=0,
        ts=early[cut - 1].ts + 5,
        kind="alert.acked",
        data={**first.data, "by": "user:sam"},
    )
    help_ = EventRecord(
        id=0,
        ts=early[cut - 1].ts + 10,
        kind="robot.status",
        robot="r2",
        data={"event": "error", "status": "Error", "last_error": "the tray sensor is blocked"},
    )
    nice = [*early[:cut], ack, help_]
    rest = early[cut:]
    hq = HqStore(open_hq_db(str(tmp_path / "hq.db")))
    await hq.db.open()
    server = None
    try:
        for site, events, behind in (("paris", paris, 0), ("lyon", lyon, 5)):
            await hq.take(site, 1, events, now)
            await hq.set_state(site, "up", now - 3600)
            await hq.heard(site, now, head=len(events) + behind, site_time=now)
        heard = help_.ts + 20
        await hq.take("nice", 1, nice, heard)
        await hq.heard("nice", heard, head=len(nice) + 20, site_time=heard)
        await hq.set_state("nice", "down", heard + 60)
        await hq.add_user(NAME, hash_password(PASSWORD), now)
        server = IntakeServer(Dashboard(hq, time.time).handle, "127.0.0.1", 0)
        await server.start()
        yield Centre(
            f"http://127.0.0.1:{server.port}",
            hq,
            zone,
            tz,
            {"paris": paris, "lyon": lyon, "nice": nice},
            rest,
            heard,
        )
    finally:
        if server is not None:
            await server.close()
        await hq.db.close()


def wait_words(seconds: float | None) -> str:
    """A wait as the page words it in English (js/format.js's ``wait``)."""
    if seconds is None:
        return DASH
    n, unit = (
        (math.floor(seconds + 0.5), "second")
        if seconds < 90
        else (math.floor(seconds / 60 + 0.5), "minute")
    )
    return f"{n} {unit}{'' if n == 1 else 's'}"


# -- pages -------------------------------------------------------------------------------------


def refused(message: Any) -> bool:
    """A console message that is an error other than a 401 (a refused login or token)."""
    return message.type == "error" and "status of 401" not in message.text


async def open_page(
    browser: Any, c: Centre, viewport: dict[str, int], *, locale: str = "en-GB", path: str = "/"
) -> Any:
    context = await browser.new_context(
        viewport=viewport,
        locale=locale,
        timezone_id=c.zone,
        bypass_csp=True,  # to inject axe; the page's own CSP is checked by a test below
        has_touch=viewport is PHONE,
        is_mobile=viewport is PHONE,
    )
    page = await context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    # A refused password is a 401 the browser logs: expected, not an error of the page.
    page.on("console", lambda m: errors.append(m.text) if refused(m) else None)
    page.on("request", lambda r: c.requests.append(r.url))
    page.errors = errors  # type: ignore[attr-defined]
    await page.goto(c.url + path)
    await expect(page.locator("html")).to_have_attribute("data-lang", re.compile(r"^\w+$"))
    return page


async def log_in(page: Any, name: str = NAME, password: str = PASSWORD) -> None:
    form = page.locator("#login-form")
    await form.locator("#login-name").fill(name)
    await form.locator("#login-password").fill(password)
    await form.locator("#login-password").press("Enter")


def card(page: Any, site: str) -> Any:
    return page.locator(f'li.site-card[data-site="{site}"]')


async def figure(page: Any, site: str, which: str) -> str:
    text: str = await card(page, site).locator(f".figure.{which} dd").inner_text()
    return text


async def assert_fits_a_phone(page: Any) -> None:
    width, inner = await sideways(page)
    assert width <= inner, f"the page scrolls sideways: {width} > {inner}"
    assert await too_small(page, TOUCH) == []


# -- a phone -----------------------------------------------------------------------------------


@needs_browser
@module_loop
async def test_a_manager_on_a_phone(centre: Centre, browser: Any) -> None:
    need_axe()
    c = centre
    page = await open_page(browser, c, PHONE)
    login = page.locator("#login")
    await expect(login).to_be_visible()
    await expect(page.locator("body")).to_have_attribute("data-view", "login")
    assert await violations(page) == []
    await assert_fits_a_phone(page)

    # A wrong password: said plainly, and nothing else shows.
    await log_in(page, NAME, "not it")
    await expect(page.get_by_role("alert")).to_have_text("Wrong name or password.")
    await expect(page.locator("#app")).to_be_hidden()
    await expect(page.locator("#login-password")).to_be_focused()

    # The right one: every restaurant's card.
    await log_in(page)
    await expect(page.locator("body")).to_have_attribute("data-view", "overview")
    token = await page.evaluate("() => sessionStorage.getItem('serveur.hq.token')")
    assert token and len(token) > 20
    await expect(page.locator("li.site-card")).to_have_count(3)
    await expect(page.locator("#overview-state")).to_have_text("3 restaurants, 1 not connected")

    # paris: connected, in sync, today's figures are serveur.stats's for its events.
    paris = c.today("paris")
    assert paris["delivered"] == 3, paris
    await expect(card(page, "paris").locator(".site-state")).to_have_text("Connected")
    await expect(card(page, "paris").locator(".site-sync")).to_have_text("In sync")
    assert await figure(page, "paris", "delivered") == str(paris["delivered"])
    assert await figure(page, "paris", "typical") == wait_words(paris["wait_p50"])
    assert await figure(page, "paris", "longest") == wait_words(paris["wait_max"])
    robots = card(page, "paris").locator("li.robot")
    await expect(robots).to_have_count(2)
    for robot in ("r1", "r2"):  # both back home, free: the site's own word
        await expect(robots.filter(has_text=robot).locator(".badge")).to_have_text("Free")
    await expect(card(page, "paris").locator(".alerts")).to_have_count(0)
    await expect(card(page, "paris")).to_contain_text("No alerts.")

    # lyon: its dinner was yesterday (nothing today), and it is catching up.
    assert c.today("lyon")["delivered"] == 0
    assert await figure(page, "lyon", "delivered") == "0"
    assert await figure(page, "lyon", "typical") == DASH
    await expect(card(page, "lyon").locator(".site-sync")).to_have_text(
        "Catching up: 5 updates to receive"
    )

    # nice: down, clearly, since when it was last heard from; what it still has to send; a
    # robot that needs help and why; its open alerts, one seen by sam.
    nice = card(page, "nice")
    await expect(nice).to_have_attribute("data-state", "down")
    state = nice.locator(".site-state")
    await expect(state).to_contain_text("Not connected")
    await expect(state).to_contain_text("not heard from since")
    await expect(state).to_contain_text(c.clock(c.heard))
    colour = await state.evaluate("(e) => getComputedStyle(e).backgroundColor")
    assert colour == "rgb(159, 18, 57)", colour  # the red band
    await expect(nice.locator(".site-sync")).to_have_text("20 updates still to receive")
    r2 = nice.locator("li.robot").filter(has_text="r2")
    await expect(r2.locator(".badge")).to_have_text("Needs help")
    await expect(r2).to_contain_text("Problem: the tray sensor is blocked")
    alerts = nice.locator("li.alert")
    await expect(alerts).to_have_count(3)
    await expect(alerts.nth(0)).to_contain_text("r1 has waited long at a table")
    await expect(alerts.nth(0)).to_contain_text("Seen by sam")
    await expect(alerts.nth(2)).to_contain_text("Dishes for T7 are waiting at the pass")
    await expect(alerts.nth(2)).to_contain_text("Nobody has acknowledged it yet")
    assert await figure(page, "nice", "delivered") == str(c.today("nice")["delivered"])
    # No machine words: no status codes, numbers of events, coordinates.
    text = await page.locator("#cards").inner_text()
    machine = r"\b(Awaiting|Error|seq|events?|waiting_at_table|stored|head|behind|null)\b"
    assert not re.findall(machine, text), re.findall(machine, text)
    await assert_fits_a_phone(page)
    assert await violations(page) == []

    # The comparison and a site's page fit a phone too (their tables scroll in their box).
    await page.get_by_role("tab", name="Compare days").tap()
    await expect(page.locator("table.compare tbody tr")).to_have_count(3)
    await assert_fits_a_phone(page)
    await page.get_by_role("tab", name="Restaurants").tap()
    figures = card(page, "paris").locator(".figures")
    await figures.scroll_into_view_if_needed()
    box = await figures.bounding_box()
    await page.touchscreen.tap(box["x"] + 10, box["y"] + 10)  # anywhere on the card
    await expect(page.locator("body")).to_have_attribute("data-view", "site")
    await expect(page.locator("#site-title")).to_have_text("paris")
    trips = read_events(c.events["paris"]).trips
    await expect(page.locator(".trips > li")).to_have_count(len(trips))
    await assert_fits_a_phone(page)
    assert await violations(page) == []

    # French: the words change at once, and stay after a reload (as does the login).
    await page.get_by_role("button", name="Back to all restaurants").tap()
    await expect(card(page, "paris").locator("a")).to_be_focused()
    await page.get_by_label("Language").select_option("fr")
    await expect(page.locator("html")).to_have_attribute("lang", "fr")
    await expect(page.locator("h1")).to_have_text("Tous les restaurants")
    await expect(nice.locator(".site-state")).to_contain_text("Non connecté")
    await expect(nice.locator(".site-state")).to_contain_text(c.clock(c.heard, "fr"))
    await expect(nice.locator(".site-sync")).to_have_text("20 informations encore à recevoir")
    await expect(r2.locator(".badge")).to_have_text("Besoin d'aide")
    await expect(card(page, "paris").locator(".figure.delivered dt")).to_have_text("Plats servis")
    await page.reload()
    await expect(page.locator("body")).to_have_attribute("data-view", "overview")
    await expect(page.locator("h1")).to_have_text("Tous les restaurants")
    await expect(page.get_by_role("tab", name="Comparer les jours")).to_be_visible()
    assert page.errors == []  # type: ignore[attr-defined]
    await page.context.close()


# -- a desk ------------------------------------------------------------------------------------


@needs_browser
@module_loop
async def test_a_manager_at_a_desk(centre: Centre, browser: Any) -> None:
    need_axe()
    c = centre
    # A French browser: the dashboard speaks French until told otherwise.
    page = await open_page(browser, c, DESK, locale="fr-FR")
    await expect(page.locator("html")).to_have_attribute("data-lang", "fr")
    await expect(page.get_by_role("button", name="Se connecter")).to_be_visible()
    await page.get_by_label("Langue").select_option("en")
    await log_in(page)
    await expect(page.locator("li.site-card")).to_have_count(3)
    # Three cards side by side.
    tops = {round(b["y"]) for b in [await card(page, s).bounding_box() for s in c.events]}
    assert len(tops) == 1, tops

    # Draw only what changed: nice comes back and sends the rest of its dinner; at the next
    # poll its card is drawn again, and paris's and lyon's are the very same nodes.
    await page.evaluate(
        "() => document.querySelectorAll('li.site-card').forEach((n) => { n.kept = true; })"
    )
    polls = int(await page.locator("body").get_attribute("data-polls") or 0)
    now = time.time()
    stored = await c.hq.take("nice", len(c.events["nice"]) + 1, c.rest, now)
    await c.hq.heard("nice", now, head=stored, site_time=now)
    await c.hq.set_state("nice", "up", now)
    c.events["nice"] = [*c.events["nice"], *c.rest]
    await page.wait_for_function(
        """() => {
          const nice = document.querySelector('li.site-card[data-site="nice"]');
          return nice && !nice.kept && nice.dataset.state === "up"
            && nice.querySelector(".site-sync").textContent === "In sync";
        }""",
        timeout=WAIT_MS,
    )
    kept = await page.evaluate(
        "() => Object.fromEntries([...document.querySelectorAll('li.site-card')]"
        ".map((n) => [n.dataset.site, n.kept === true]))"
    )
    assert kept == {"lyon": True, "nice": False, "paris": True}
    assert int(await page.locator("body").get_attribute("data-polls") or 0) > polls
    assert await figure(page, "nice", "delivered") == str(c.today("nice")["delivered"])
    await expect(page.locator("#overview-state")).to_have_text("3 restaurants")

    # The comparison is fetched only once its tab is opened: each site's days.
    assert not [u for u in c.requests if "/api/figures" in u]
    await page.get_by_role("tab", name="Restaurants").press("ArrowRight")  # the keyboard
    await expect(page.get_by_role("tab", name="Compare days")).to_have_attribute(
        "aria-selected", "true"
    )
    compare = page.locator("table.compare")
    await expect(compare.locator("tbody tr")).to_have_count(3)
    assert len([u for u in c.requests if "/api/figures" in u]) == 1
    shown_days = await compare.locator("thead th[data-day]").evaluate_all(
        "(ths) => ths.map((th) => th.dataset.day)"
    )
    every_day = sorted({d for s in c.events for d in c.days(s)}, reverse=True)
    assert shown_days == every_day and len(every_day) == 2, (shown_days, every_day)
    for site in c.events:
        days = c.days(site)
        for day in every_day:
            row = compare.locator(f'tr[data-site="{site}"]')
            p = days.get(day)
            delivered = row.locator(f'td.delivered[data-day="{day}"]')
            typical = row.locator(f'td.typical[data-day="{day}"]')
            await expect(delivered).to_have_text(str(p["delivered"]) if p else DASH)
            await expect(typical).to_have_text(wait_words(p["wait_p50"]) if p else DASH)
    assert await violations(page) == []

    # A site's page, from the keyboard: its days and its trips; Back returns to its card.
    await page.get_by_role("tab", name="Compare days").press("ArrowLeft")
    await expect(page.locator("body")).to_have_attribute("data-view", "overview")
    await card(page, "lyon").get_by_role("link", name="lyon").press("Enter")
    await expect(page.locator("body")).to_have_attribute("data-view", "site")
    await expect(page.locator("#site-title")).to_have_text("lyon")
    await expect(page.locator("#site-title")).to_be_focused()
    (day, p), *others = c.days("lyon").items()
    assert not others
    shown = page.locator(f'.days li[data-day="{day}"]')
    await expect(shown.locator("h4")).to_have_text(re.compile(r"\w+, \w+ \d+"))  # "Sat, Nov 28"
    await expect(shown.locator(".delivered dd")).to_have_text(str(p["delivered"]))
    await expect(shown.locator(".typical dd")).to_have_text(wait_words(p["wait_p50"]))
    await expect(shown.locator(".longest dd")).to_have_text(wait_words(p["wait_max"]))
    await expect(shown.locator(".trips dd")).to_have_text(str(p["trips"]))
    trips = read_events(c.events["lyon"]).trips
    listed = page.locator(".trips > li")
    await expect(listed).to_have_count(len(trips))
    newest = max(trips)
    first = listed.first
    await expect(first.locator("summary")).to_contain_text(f"Trip {newest}")
    await first.locator("summary").press("Enter")  # open it: its tables and dishes
    await expect(first.locator(".stops li").first).to_contain_text("Table T")
    await expect(page.locator("#panel-site .site-sync")).to_have_text(
        "Catching up: 5 updates to receive"
    )
    assert await violations(page) == []
    await page.get_by_role("button", name="Back to all restaurants").press("Enter")
    await expect(page.locator("body")).to_have_attribute("data-view", "overview")
    await expect(card(page, "lyon").get_by_role("link", name="lyon")).to_be_focused()
    # Browser's Back too: the site page, then the overview again.
    await page.go_back()
    await expect(page.locator("body")).to_have_attribute("data-view", "site")
    await page.go_back()
    await expect(page.locator("body")).to_have_attribute("data-view", "overview")
    assert page.errors == []  # type: ignore[attr-defined]
    await page.context.close()


@needs_browser
@module_loop
async def test_an_ended_login_returns_to_the_form(centre: Centre, browser: Any) -> None:
    c = centre
    context = await browser.new_context(viewport=PHONE, timezone_id=c.zone)
    # A token the centre does not know (it restarted, or the login ended): the next answer is
    # a 401, and the page says why it asks again.
    await context.add_init_script(
        "sessionStorage.setItem('serveur.hq.token', 'expired'); localStorage.clear()"
    )
    page = await context.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.on("console", lambda m: errors.append(m.text) if refused(m) else None)
    await page.goto(c.url + "/#/compare")
    await expect(page.locator("body")).to_have_attribute("data-view", "login")
    await expect(page.get_by_role("alert")).to_have_text(
        "You were logged out (the login lasts 12 hours). Please log in again."
    )
    await expect(page.locator("#login-name")).to_be_focused()
    await log_in(page)
    await expect(page.locator("table.compare tbody tr")).to_have_count(3)
    # Under the page's own Content-Security-Policy (no bypass here) nothing was refused.
    assert errors == []
    await context.close()


# -- the words, without a browser --------------------------------------------------------------

CATALOGS = {
    lang: json.loads((HQ_ROOT / "i18n" / f"{lang}.json").read_text("utf-8")) for lang in LANGS
}
PLURAL_FORMS = {"zero", "one", "two", "few", "many", "other"}
DYNAMIC = {"status": [s.value for s in RobotStatus], "lang": list(LANGS)}


def _texts(value: Any) -> list[str]:
    return list(value.values()) if isinstance(value, dict) else [value]


def _placeholders(value: Any) -> set[str]:
    return {p for text in _texts(value) for p in re.findall(r"\{(\w+)\}", text)}


def test_every_catalog_has_the_same_keys_and_every_key_is_used() -> None:
    en = CATALOGS["en"]
    for lang, catalog in CATALOGS.items():
        assert set(catalog) == set(en), (lang, set(catalog) ^ set(en))
        for key, value in catalog.items():
            assert all(isinstance(t, str) and t for t in _texts(value)), (lang, key)
            if isinstance(value, dict):
                assert "other" in value and set(value) <= PLURAL_FORMS, (lang, key)
            assert _placeholders(value) == _placeholders(en[key]), (lang, key)
    # Every key named by the page and its scripts exists, and every key is named somewhere.
    spaces = {key.split(".")[0] for key in en}
    named: set[str] = set()
    html = (HQ_ROOT / "index.html").read_text("utf-8")
    named |= set(re.findall(r'data-i18n(?:-[\w-]+)?="([^"]+)"', html))
    scripts = "\n".join(p.read_text("utf-8") for p in sorted((HQ_ROOT / "js").glob("*.js")))
    for literal in re.findall(r'"([a-z][\w-]*(?:\.[\w-]+)+)"', scripts):
        if literal.split(".")[0] in spaces:
            named.add(literal)
    dynamic = {f"{family}.{v}" for family, values in DYNAMIC.items() for v in values}
    assert sorted(named - set(en)) == []
    assert sorted(dynamic - set(en)) == []
    assert sorted(set(en) - named - dynamic) == [], "keys nothing uses"
    # The robots' words are the site's own (its staff read the same on their screens).
    site = json.loads((HQ_ROOT.parent / "site" / "i18n" / "en.json").read_text("utf-8"))
    assert {k: en[k] for k in en if k.startswith("status.")} == {
        k: v for k, v in site.items() if k.startswith("status.")
    }


class _Words(HTMLParser):
    def __init__(self) -> None:
        super().__init__()
        self.stack: list[str] = []
        self.words: list[str] = []

    def handle_starttag(self, tag: str, attrs: list[tuple[str, str | None]]) -> None:
        self.words += [f"<{tag} {k}>" for k, _ in attrs if k in ("aria-label", "title", "alt")]
        self.words += [f"<{tag} style>" for k, _ in attrs if k == "style" or k.startswith("on")]
        if tag not in ("meta", "link", "input"):
            self.stack.append(tag)

    def handle_endtag(self, tag: str) -> None:
        if tag in self.stack:
            while self.stack.pop() != tag:
                pass

    def handle_data(self, data: str) -> None:
        if data.strip() and not {"title", "script", "style"} & set(self.stack[-1:]):
            self.words.append(data.strip())


def test_the_page_holds_no_words_nor_inline_code_and_fetches_nothing_elsewhere() -> None:
    parser = _Words()
    html = (HQ_ROOT / "index.html").read_text("utf-8")
    parser.feed(html)
    assert parser.words == []
    assert "<script>" not in html and "<style" not in html
    for path in HQ_ROOT.rglob("*"):
        if path.suffix in (".html", ".js", ".css"):
            text = path.read_text("utf-8")
            assert "http://" not in text and "https://" not in text, path
            assert not re.search(r"innerHTML\s*=|insertAdjacentHTML", text), path
