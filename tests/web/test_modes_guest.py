"""The robot and table screens for what robots do besides delivering (issue 32), in Chromium
against the real server and simulated robot (tests/web/test_guest_screens.py's harness; trips
wait at the pass for Go, bussing trips and cruises leave at once).

- A table's screen calls a waiter: the call reaches the server (the staff's connection sees
  it), the screen says a waiter is on the way and the button shows it is called; a second tap
  is merged and said to be already called, not an error; a call staff answer leaves it; a
  refused call is worded. The bill is called from a tablet in Chinese, by keyboard.
- Used plates: the table calls for a robot; it comes ("Coming to take the plates at T16"), can
  be stopped and sent on; at the table both screens ask for the plates and Done moves it on;
  at the dish return it asks staff to empty it, and Done finishes the trip.
- A special delivery (a birthday): at the pass each dish is shown on the tray staff chose,
  else its stop's (two stops' dishes share one); at the table its message is shown large and
  "Happy Birthday to You" starts (the oscillators the page started, counted by an init
  script's hook on Web Audio), once; "Play the song again" plays it again; Done serves it.
- A cruise: its screen is a face saying "Help yourself"; a tap (phone) or a key (tablet)
  stops the robot, once per touch; stopped, it says it goes on in a moment and offers a guest
  nothing to press; staff signed in may send it on.
- Charging: "Charging — 45 %" (its battery), nothing to press.

Each new state is axe-core clean on a phone (390x844, touch) or a tablet (1024x768), with no
sideways scroll and finger-sized buttons. No sleeps: playwright's ``expect`` and
``Client.until`` wait on the pages and the server.
"""

from __future__ import annotations

import contextlib
import functools
import json
import re
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur.core.engine import CoreConfig
from tests.conftest import Client, Restaurant, make_app, served_by
from tests.test_e2e import activate
from tests.web.conftest import needs_browser, sideways, too_small
from tests.web.test_a11y import need_axe, violations
from tests.web.test_i18n import tr
from tests.web.test_robot_screen_sound import SPEECH_SPY
from tests.web.test_ui import WAYPOINTS, Screens, http_base

playwright_api = pytest.importorskip("playwright.async_api")
expect = playwright_api.expect

pytestmark = [needs_browser, pytest.mark.asyncio(loop_scope="module")]
expect.set_options(timeout=20_000)

PHONE = {"width": 390, "height": 844}
TABLET = {"width": 1024, "height": 768}

#: Every oscillator the page starts, by its pitch (Hz), in window.__tones: what it played.
TONES = """(() => {
  window.__tones = [];
  const start = OscillatorNode.prototype.start;
  OscillatorNode.prototype.start = function (...args) {
    window.__tones.push(Math.round(this.frequency.value * 100) / 100);
    return start.apply(this, args);
  };
})();"""

#: "Happy Birthday to You" as sound.js plays it: its pitches (MIDI notes), in order.
BIRTHDAY_NOTES = [67, 67, 69, 67, 72, 71, 67, 67, 69, 67, 74, 72]
BIRTHDAY_NOTES += [67, 67, 79, 76, 72, 71, 69, 77, 77, 76, 72, 74, 72]


def pitch(note: int) -> float:
    return round(440 * 2 ** ((note - 69) / 12), 2)


#: Trips wait at the pass for Go; a robot waits at a table for its plates until Done (600 s of
#: the site's time), pauses 2 s at a cruise's place and, stopped, waits 600 s before going on.
modes_app = functools.partial(
    make_app,
    config=CoreConfig(
        heartbeat=10.0,
        ack_timeout=5.0,
        auto_depart=False,
        bussing_wait=600.0,
        cruise_pause=2.0,
        cruise_resume=600.0,
    ),
)


def modes(tmp_path: Path) -> contextlib.AbstractAsyncContextManager[Restaurant]:
    """One simulated robot (r1, at home1) and the server of ``modes_app``."""
    return served_by(tmp_path, modes_app, "modes screen tests")


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "calls")
    return c


async def owner(r: Restaurant) -> Client:
    c = Client(await connect(r.app.url))
    r.clients.append(c)
    await c.ok("login", username="owner", password=r.app.first_owner_password)
    return c


class Guests(Screens):
    """Screens of their own size, touch or not, each with the speech stand-in of
    test_robot_screen_sound (this Chromium has no voice) and the oscillator count (``TONES``),
    recording console errors and every frame sent; axe may be injected (CSP bypassed)."""

    async def screen(
        self,
        path: str,
        token: str,
        viewport: dict[str, int],
        *,
        touch: bool = False,
        route: Any = None,
    ) -> Any:
        context = await self.browser.new_context(
            viewport=viewport, has_touch=touch, bypass_csp=True
        )
        await context.add_init_script(SPEECH_SPY)
        await context.add_init_script(TONES)
        page = await context.new_page()
        if route is not None:
            await page.route_web_socket(re.compile(r"/ws$"), route)
        page.on(
            "console",
            lambda m: (
                self.errors.append(f"{path}: console {m.text}") if m.type == "error" else None
            ),
        )
        page.on("pageerror", lambda e: self.errors.append(f"{path}: exception {e}"))
        page.on(
            "websocket", lambda ws: ws.on("framesent", lambda f: self.sent.append(json.loads(f)))
        )
        await page.goto(f"{self.base}{path}#token={token}")
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        return page

    def sent_of(self, verb: str) -> list[dict[str, Any]]:
        return [m for m in self.sent if m.get("clientmsg") == verb]


#: The cruise's face covers the whole window, the footer's corner too.
COVERS_THE_SCREEN = """() => {
  const face = document.querySelector(".cruise-face");
  if (!face) return false;
  const r = face.getBoundingClientRect();
  const corner = document.elementFromPoint(innerWidth - 2, innerHeight - 2);
  return r.x === 0 && r.y === 0 && r.width === innerWidth && r.height === innerHeight
    && Boolean(corner && corner.closest(".cruise-face"));
}"""


def refusing_calls(ws: Any) -> None:
    """A websocket route that answers every ``call`` as a server over its rate limit would."""
    server = ws.connect_to_server()

    def up(frame: str | bytes) -> None:
        msg = json.loads(frame)
        if msg.get("clientmsg") != "call":
            server.send(frame)
            return
        refusal = {
            "servermsg": "error",
            "id": msg["id"],
            "code": "rate_limited",
            "message": "too many requests",
            "details": {"retry_after": 2.5},
        }
        ws.send(json.dumps(refusal))

    ws.on_message(up)


async def clean(page: Any, what: str, shots: Path | None = None) -> None:
    """axe-core finds nothing serious; nothing sideways; every button a finger's size. The
    page's picture goes to ``shots`` (the test's tmp_path), named after ``what``."""
    if shots is not None:
        name = re.sub(r"[^a-z0-9]+", "-", what.lower()).strip("-")
        await page.screenshot(path=str(shots / f"{name}.png"))
    assert await violations(page) == [], what
    width, inner = await sideways(page)
    assert width <= inner, (what, width, inner)
    assert await too_small(page, "main button, footer button") == [], what


async def sound_on(page: Any) -> None:
    """Touch the screen's "Tap here to turn the sound on" if the browser still holds it back."""
    body = page.locator("body")
    if await body.get_attribute("data-sound") == "blocked":
        await page.locator(".sound-prompt").click()
    await expect(body).to_have_attribute("data-sound", "on")


async def tones(page: Any) -> list[float]:
    found: list[float] = await page.evaluate("() => window.__tones")
    return found


def open_calls(c: Client, table: str, kind: str) -> list[dict[str, Any]]:
    return [
        x
        for x in c.records.get("calls", {}).values()
        if x["table"] == table
        and x["kind"] == kind
        and x["answered_at"] is None
        and x["cancelled_at"] is None
    ]


async def test_a_table_calls_a_waiter_and_a_second_tap_is_already_called(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes(tmp_path) as r:
        c = await staff(r)
        g = Guests(browser, http_base(r))
        token = await r.app.issue_token("table-screen", table="T3")
        phone = await g.screen("/table/T3?lang=en", token, PHONE, touch=True)
        calls = phone.get_by_role("region", name="Need anything?")
        await expect(calls.get_by_role("button")).to_have_text(
            ["Take our plates", "Call a waiter", "The bill, please"]
        )
        await clean(phone, "table phone, nothing called", tmp_path)

        waiter = calls.get_by_role("button", name="Call a waiter")
        await waiter.tap()
        [call] = await c.until(lambda: open_calls(c, "T3", "waiter"), what="the waiter's call")
        assert call["source"] == "table" and call["presses"] == 1
        states = phone.get_by_role("list", name="Your calls")
        await expect(states.get_by_role("listitem")).to_have_text(["A waiter is on the way"])
        await expect(waiter).to_have_attribute("data-called", "true")
        await expect(waiter).to_contain_text("Called")
        await expect(phone.locator(".call-said")).to_have_text("")
        await clean(phone, "table phone, a waiter called", tmp_path)

        # A second tap: merged into the same call, and said to be already called.
        await waiter.tap()
        await c.until(lambda: c.records["calls"][call["id"]]["presses"] == 2, what="merged")
        said = phone.locator(".call-said")
        await expect(said).to_have_text("Already called: a waiter is on the way.")
        assert await said.get_attribute("role") == "status"
        await expect(states.get_by_role("listitem")).to_have_count(1)
        await expect(phone.locator(".toast-error")).to_have_count(0)
        await clean(phone, "table phone, already called", tmp_path)
        assert [m["kind"] for m in g.sent_of("call")] == ["waiter", "waiter"]
        assert all(m["action"] == "open" and m["table"] == "T3" for m in g.sent_of("call"))

        # The same table's tablet, in Chinese: it shows the call, and calls the bill by keyboard.
        tablet = await g.screen("/table/T3?lang=zh", token, TABLET)
        listed = tablet.get_by_role("list", name=tr("zh", "guest.call.states"))
        await expect(listed.get_by_role("listitem")).to_have_text(
            [tr("zh", "guest.call.waiterComing")]
        )
        bill = tablet.get_by_role("button", name=tr("zh", "guest.call.bill"))
        await bill.focus()
        await tablet.keyboard.press("Enter")
        await c.until(lambda: open_calls(c, "T3", "bill"), what="the bill's call")
        await expect(listed.get_by_role("listitem")).to_have_text(
            [tr("zh", "guest.call.waiterComing"), tr("zh", "guest.call.billComing")]
        )
        await expect(bill).to_be_focused()
        await expect(states.get_by_role("listitem")).to_have_text(
            ["A waiter is on the way", "Your bill is on its way"]
        )
        await clean(tablet, "table tablet, two calls, zh", tmp_path)

        # Staff answer the waiter's call: it leaves the screen, its button is free again.
        await c.ok("call", action="answer", call=call["id"])
        await expect(states.get_by_role("listitem")).to_have_text(["Your bill is on its way"])
        await expect(waiter).to_have_attribute("data-called", "false")
        await expect(said).to_have_text("")

        # A refused call is said in words (errors.js): here the connection's rate limit.
        busy = await g.screen("/table/T3?lang=en", token, PHONE, touch=True, route=refusing_calls)
        await expect(busy.get_by_role("list", name="Your calls")).to_have_text(
            "Your bill is on its way"
        )
        await busy.get_by_role("button", name="Call a waiter").tap()
        await expect(busy.locator(".toast-error .toast-text")).to_have_text(
            "Too many presses at once: wait 3 s and try again."
        )
        await expect(busy.get_by_role("button", name="Call a waiter")).to_have_attribute(
            "data-called", "false"
        )
        await expect(busy.locator(".call-said")).to_have_text("")
        g.assert_no_errors()


async def test_a_robot_comes_for_the_plates_and_done_moves_it_on(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with modes(tmp_path) as r:
        c = await staff(r)
        await c.ok("create", type="waypoint", name="dish return", x=9.0, y=10.8, kind="dish_return")
        await activate(c, "r1")
        g = Guests(browser, http_base(r))
        robot_token = await r.app.issue_token("robot-screen", robot="r1")
        robot = await g.screen("/robot/r1?lang=en", robot_token, PHONE, touch=True)
        back = await g.screen("/robot/r1?lang=ms", robot_token, TABLET)
        table = await g.screen(
            "/table/T16?lang=en", await r.app.issue_token("table-screen", table="T16"), TABLET
        )
        await expect(robot.get_by_role("heading", name="Awaiting orders")).to_be_visible()

        # The guests ask for a robot to take their plates: one leaves at once.
        await table.get_by_role("button", name="Take our plates").click()
        [call] = await c.until(lambda: open_calls(c, "T16", "plates"), what="the plates call")
        assert call["task_id"] is not None
        task_id = call["task_id"]
        await expect(table.get_by_role("list", name="Your calls")).to_have_text(
            "A robot is coming for your plates"
        )
        coming = robot.get_by_role("heading", name="Coming to take the plates at T16")
        await expect(coming).to_be_visible()
        assert c.task(task_id)["kind"] == "bussing"
        # Stopped on the way (its big Stop), it says where it was going and goes on.
        await robot.get_by_role("button", name="Stop", exact=True).tap()
        await c.status("r1", "Stopped")
        await expect(robot.get_by_role("heading", name="Stopped")).to_be_visible()
        await expect(robot.get_by_text("Coming to take the plates at T16")).to_be_visible()
        await clean(robot, "robot phone, stopped on its way for the plates", tmp_path)
        await robot.get_by_role("button", name="Continue").tap()

        # At the table: both screens ask for the plates; the call was answered by the robot.
        await c.until(lambda: c.task(task_id)["stops"][0]["status"] == "arrived", what="at T16")
        put = robot.get_by_role("heading", name="Please put your used plates on my trays")
        await expect(put).to_be_visible()
        # Not a delivery's words: no "Your order has arrived", no Food collected.
        await expect(robot.get_by_text("Your order has arrived")).to_have_count(0)
        await expect(robot.get_by_role("button", name="Food collected")).to_have_count(0)
        panel = table.locator(".here.plates")
        await expect(panel.get_by_role("heading")).to_have_text("A robot has come for your plates")
        await expect(panel).to_contain_text("Please put your used plates on its trays")
        await expect(table.locator(".here .take-tray")).to_have_count(0)
        await c.until(lambda: c.records["calls"][call["id"]]["answered_by"] == "robot:r1")
        await expect(
            table.get_by_role("list", name="Your calls").get_by_role("listitem")
        ).to_have_count(0)
        await expect(
            back.get_by_role("heading", name=tr("ms", "guest.robot.putPlates"))
        ).to_be_visible()
        await clean(robot, "robot phone, at a table for the plates", tmp_path)
        await clean(table, "table tablet, a robot for the plates", tmp_path)
        await clean(back, "robot tablet, at a table for the plates, ms", tmp_path)
        assert c.robot("r1")["status"] == "Delivered"

        # Done on the robot's screen: on to the dish return, where staff empty it.
        await robot.get_by_role("button", name="Done", exact=True).tap()
        await c.until(lambda: c.task(task_id)["current_stop"] == 1, what="on to the dish return")
        [done] = g.sent_of("next")
        assert (done["robot"], done["task"], done["stop"]) == ("r1", task_id, 0)
        await expect(table.locator(".here")).to_have_count(0)
        await c.until(lambda: c.task(task_id)["stops"][1]["status"] == "arrived", what="returned")
        empty = back.get_by_role("heading", name=tr("ms", "guest.robot.emptyTrays"))
        await expect(empty).to_be_visible()
        await expect(robot.get_by_role("heading", name="Please empty my trays")).to_be_visible()
        await clean(back, "robot tablet, at the dish return, ms", tmp_path)
        await clean(robot, "robot phone, at the dish return", tmp_path)
        finish = back.get_by_role("button", name=tr("ms", "guest.robot.done"), exact=True)
        await finish.focus()
        await back.keyboard.press("Enter")
        await c.until(lambda: c.task(task_id)["status"] == "done", what="the trip done")
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        assert [(m["task"], m["stop"]) for m in g.sent_of("next")] == [(task_id, 0), (task_id, 1)]
        g.assert_no_errors()


def arrived(c: Client, task_id: int, seq: int) -> bool:
    """The robot on trip ``task_id`` stands at its stop ``seq``."""
    return bool(c.task(task_id)["stops"][seq]["status"] == "arrived")


def trays_of(task: dict[str, Any], c: Client) -> dict[int, list[tuple[str, str]]]:
    """Each tray's dishes (dish, table): the tray staff chose, else the stop's (seq + 1)."""
    trays: dict[int, list[tuple[str, str]]] = {}
    for stop in sorted(task["stops"], key=lambda s: s["seq"]):
        for oid in stop["orders"]:
            o = c.order(oid)
            tray = o["tray"] if o.get("tray") is not None else stop["seq"] + 1
            trays.setdefault(tray, []).append((o["dish"], stop["table"]))
    return dict(sorted(trays.items()))


async def test_a_birthday_shows_its_message_and_sings(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with modes(tmp_path) as r:
        c = await staff(r)
        await activate(c, "r1")
        g = Guests(browser, http_base(r))
        robot_token = await r.app.issue_token("robot-screen", robot="r1")
        robot = await g.screen("/robot/r1?lang=en", robot_token, TABLET, touch=True)
        phone = await g.screen("/robot/r1?lang=zh", robot_token, PHONE, touch=True)
        for page in (robot, phone):
            await sound_on(page)

        laksa = (await c.ok("create", type="order", dish="Laksa", table="T2"))["order"]["id"]
        satay = (await c.ok("create", type="order", dish="Satay", table="T2"))["order"]["id"]
        message = "Happy birthday, Ana!"
        made = await c.ok("create", type="order", dish="Cake", table="T4", special=message)
        cake = made["order"]["id"]
        # Staff put the satay and the cake on tray 2, whichever table comes first: two stops'
        # dishes share it; the laksa stays on its stop's tray.
        chosen = [{"order": satay, "tray": 2}, {"order": cake, "tray": 2}]
        [task] = (await c.ok("create", type="task", orders=[laksa, satay, cake], trays=chosen))[
            "tasks"
        ]
        await c.status("r1", "Loading")
        await c.until(lambda: c.order(cake).get("tray") == 2, what="the trays staff chose")
        trays = trays_of(task, c)
        assert {t for _, t in trays[2]} == {"T2", "T4"}, trays

        # At the pass: each tray, its tables, and each dish named with its table when shared.
        heads = [
            f"Tray {n} → {' and '.join(dict.fromkeys(t for _, t in d))}" for n, d in trays.items()
        ]
        await expect(robot.locator(".tray-head")).to_have_text(heads)
        for n, dishes in trays.items():
            shared = len({t for _, t in dishes}) > 1
            on_tray = robot.get_by_role("list", name=f"Dishes on tray {n}")
            await expect(on_tray.get_by_role("listitem")).to_have_text(
                [f"{d} → {t}" if shared else d for d, t in dishes]
            )
        await clean(robot, "robot tablet, loading trays staff chose", tmp_path)
        await robot.get_by_role("button", name="Go", exact=True).tap()

        chimes = 0
        for stop in task["stops"]:
            played = len(await tones(robot))  # before the robot is there
            await c.until(functools.partial(arrived, c, task["id"], stop["seq"]), what="there")
            mine = {n: [d for d, t in ds if t == stop["table"]] for n, ds in trays.items()}
            mine = {n: ds for n, ds in mine.items() if ds}
            several = len(mine) > 1
            take = (
                f"Please take trays {' and '.join(map(str, mine))}"
                if several
                else f"Please take tray {next(iter(mine))}"
            )
            labels = [f"Tray {n}: {d}" if several else d for n, ds in mine.items() for d in ds]
            body = robot.locator("body")
            await expect(robot.locator(".take-tray")).to_have_text(take)
            yours = robot.get_by_role("list", name="Your dishes").get_by_role("listitem")
            await expect(yours).to_have_text(labels)
            if stop["table"] == "T2":
                # A plain stop rings and speaks; no song.
                chimes += 1
                await expect(body).to_have_attribute("data-chimes", str(chimes))
                await expect(body).to_have_attribute("data-arrival-sound", "spoken")
                assert await body.get_attribute("data-songs") is None
                await robot.get_by_role("button", name="Food collected").tap()
                continue
            # The birthday: its message large, the song started once, Done and "again".
            await expect(robot.get_by_role("heading", level=1)).to_have_text(message)
            await expect(robot.get_by_text("Something special for table T4")).to_be_visible()
            await expect(body).to_have_attribute("data-arrival-sound", "song")
            await expect(body).to_have_attribute("data-songs", "1")
            song = (await tones(robot))[played:]
            assert song == [pitch(n) for n in BIRTHDAY_NOTES], song
            assert await body.get_attribute("data-chimes") == (str(chimes) if chimes else None)
            await expect(phone.locator("h1.special-message")).to_have_text(message)
            await expect(phone.locator("body")).to_have_attribute("data-songs", "1")
            await clean(robot, "robot tablet, a birthday", tmp_path)
            await clean(phone, "robot phone, a birthday, zh", tmp_path)
            # A redraw (another language and back) does not sing again; the button does.
            await robot.locator("#lang-picker").select_option("ms")
            await robot.locator("#lang-picker").select_option("en")
            await expect(robot.get_by_role("heading", level=1)).to_have_text(message)
            assert await body.get_attribute("data-songs") == "1"
            await robot.get_by_role("button", name="Play the song again").tap()
            await expect(body).to_have_attribute("data-songs", "2")
            assert len(await tones(robot)) == played + 2 * len(BIRTHDAY_NOTES)
            await phone.get_by_role("button", name=tr("zh", "guest.robot.done"), exact=True).tap()
            await c.until(lambda: c.order(cake).get("status") == "delivered", what="served")
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        g.assert_no_errors()


async def test_touching_a_cruising_robot_stops_it(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with modes(tmp_path) as r:
        c = await staff(r)
        await activate(c, "r1")
        g = Guests(browser, http_base(r))
        token = await r.app.issue_token("robot-screen", robot="r1")
        phone = await g.screen("/robot/r1?lang=en", token, PHONE, touch=True)
        tablet = await g.screen("/robot/r1?lang=zh", token, TABLET)
        await c.ok("cruise", robot="r1", route=["T1", "T5", "T9"])
        await c.until(lambda: c.robot("r1").get("current_task") is not None, what="cruising")
        task_id = c.robot("r1")["current_task"]
        assert c.task(task_id)["kind"] == "cruise"

        # The whole screen is a face saying "Help yourself", on a phone and a tablet.
        face = phone.get_by_role("button", name="Help yourself Touch me to stop")
        zh_face = tablet.get_by_role(
            "button",
            name=f"{tr('zh', 'guest.robot.helpYourself')} {tr('zh', 'guest.robot.touchToStop')}",
        )
        for page, shown in ((phone, face), (tablet, zh_face)):
            await expect(shown).to_be_visible()
            await page.wait_for_function(COVERS_THE_SCREEN)
            await expect(page.get_by_text("Delivering")).to_have_count(0)
        await clean(phone, "robot phone, cruising", tmp_path)
        await clean(tablet, "robot tablet, cruising, zh", tmp_path)

        # A tap stops it, once; it says it goes on soon and offers a guest nothing to press.
        await face.tap()
        await c.status("r1", "Stopped")
        await expect(phone.get_by_role("heading", name="I'll go on in a moment")).to_be_visible()
        await expect(phone.locator("#screen button")).to_have_count(0)
        await expect(
            tablet.get_by_role("heading", name=tr("zh", "guest.robot.goOnSoon"))
        ).to_be_visible()
        await expect(tablet.locator("#screen button")).to_have_count(0)
        assert [m["robot"] for m in g.sent_of("stop")] == ["r1"]
        await clean(phone, "robot phone, a cruise stopped", tmp_path)
        await clean(tablet, "robot tablet, a cruise stopped, zh", tmp_path)

        # Staff signed in on the screen may send it on now.
        staffed = await g.screen("/robot/r1?lang=en", r.token, TABLET)
        for_staff = staffed.get_by_role("group", name="For staff")
        await expect(for_staff.get_by_role("button")).to_have_text(["Go on now", "End the cruise"])
        await clean(staffed, "robot tablet, a cruise stopped, staff", tmp_path)
        await for_staff.get_by_role("button", name="Go on now").click()
        await c.until(
            lambda: c.robot("r1")["status"] in ("Delivering", "Delivered"), what="going on"
        )
        assert len(g.sent_of("stop")) == 1  # staff's click stopped nothing

        # Any key on the tablet stops it again.
        await expect(zh_face).to_be_visible()
        await tablet.keyboard.press("Space")
        await c.status("r1", "Stopped")
        assert len(g.sent_of("stop")) == 2
        await expect(zh_face).to_have_count(0)

        # Staff end the cruise from the screen: home, and deliveries again.
        await staffed.get_by_role("button", name="End the cruise").click()
        dialog = staffed.get_by_role("dialog", name="End the cruise?")
        await dialog.get_by_role("button", name="Yes, end it").click()
        await c.until(lambda: c.task(task_id).get("status") == "cancelled", what="ended")
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        await expect(face).to_have_count(0)
        g.assert_no_errors()


async def test_a_charging_robot_says_how_full_it_is(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with modes(tmp_path) as r:
        c = await staff(r)
        o = await owner(r)
        # Its charger across the room (where T16's guests sit: a spot it can reach).
        far = WAYPOINTS["T16"]
        await c.ok("create", type="waypoint", name="dock1", x=far.x, y=far.y, kind="dock")
        await o.ok("site", action="edit_robot", robot="r1", dock="dock1")
        r.sim.robots[0].battery = 0.45
        await c.until(
            lambda: abs((c.robot("r1").get("battery") or 0) - 0.45) < 0.004, what="at 45 %"
        )
        await activate(c, "r1")
        g = Guests(browser, http_base(r))
        token = await r.app.issue_token("robot-screen", robot="r1")
        phone = await g.screen("/robot/r1?lang=en", token, PHONE, touch=True)
        tablet = await g.screen("/robot/r1?lang=zh", token, TABLET)

        await c.ok("charge", robot="r1")
        # On its way, it says where to (not home).
        await expect(phone.get_by_role("heading", name="Going to my charger")).to_be_visible()
        await expect(
            tablet.get_by_role("heading", name=tr("zh", "guest.robot.toCharge"))
        ).to_be_visible()
        await c.status("r1", "Charging", timeout=60)
        await expect(phone.get_by_role("heading", level=1)).to_have_text("Charging — 45 %")
        await expect(tablet.get_by_role("heading", level=1)).to_have_text(
            tr("zh", "guest.robot.charging", percent=45)
        )
        for page in (phone, tablet):
            await expect(page.locator("#screen button")).to_have_count(0)
        await expect(phone.locator("#robot-status")).to_have_text("Charging")
        await clean(phone, "robot phone, charging", tmp_path)
        await clean(tablet, "robot tablet, charging, zh", tmp_path)

        # Its battery rises: the words follow.
        r.sim.robots[0].battery = 0.62
        await expect(phone.get_by_role("heading", level=1)).to_have_text(
            re.compile(r"^Charging — 6[23] %$")
        )
        # Back to work: home, free for deliveries.
        await c.ok("work", robot="r1")
        await c.status("r1", "Awaiting", timeout=60)
        await expect(phone.get_by_role("heading", name="Awaiting orders")).to_be_visible()
        g.assert_no_errors()
