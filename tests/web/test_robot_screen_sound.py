"""The robot's and the tables' screens ring and speak when the food arrives, and staff send an
idle robot from its own screen (issue 30, points 10 and 5), in Chromium against the real server
and simulated robot (tests/web/test_guest_screens.py's harness: trips wait at the pass for Go).

Sound: Chromium here holds a page's sound back until it is touched (its AudioContext starts
suspended), as a tablet's browser does, so each screen first shows "Tap here to turn the sound
on"; tapped (or Enter on it), it rings when its robot arrives at a table with food, once — not
on a redraw, not after a reload — and says the words with a voice of the device for the screen's
language. The pages' data-chimes / data-spoken / data-arrival-sound say what they played.
Chromium here has no voice at all (no speech-dispatcher), so the pages are given a recording
stand-in for ``speechSynthesis`` (a spy on the browser API, ``SPEECH_SPY``): local English and
Chinese voices, a network-only Malay one (never used: offline). A muted screen plays nothing; a
screen never touched rings once it is, if the robot is still there.

Staff: a robot-screen token alone sees no way to send its robot and the server refuses it
(`forbidden`); "Staff sign-in" opens the login dialog (Cancel and Escape close it), a staff
member's login shows "Send to a table" — every table — on the idle robot, T3 sends it there
(it drives there) and the screen is the guests' again, with the device's own token kept; "Go
home" brings it back. Sizes: the phone (390x844), the robot's tablets (768x1024, 1024x768) and
a desktop (1440x900) for a table screen; touch, mouse and keyboard; axe-core clean; no sideways
scroll; finger-sized targets.
"""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from tests.conftest import Client, Restaurant
from tests.test_e2e import activate
from tests.web.conftest import needs_browser, sideways, too_small
from tests.web.test_a11y import need_axe, violations
from tests.web.test_guest_screens import device, loaded_trip, service, staff
from tests.web.test_i18n import tr
from tests.web.test_ui import WAYPOINTS, Screens, http_base

playwright_api = pytest.importorskip("playwright.async_api")
expect = playwright_api.expect

pytestmark = [needs_browser, pytest.mark.asyncio(loop_scope="module")]
expect.set_options(timeout=20_000)

PHONE = {"width": 390, "height": 844}
PORTRAIT = {"width": 768, "height": 1024}
LANDSCAPE = {"width": 1024, "height": 768}
DESKTOP = {"width": 1440, "height": 900}

#: speechSynthesis as a device with local English and Chinese voices and a network Malay one
#: would give it, recording each sentence handed to it in window.__said.
SPEECH_SPY = """(() => {
  const voices = [
    { name: "Local English", lang: "en-GB", localService: true, default: false, voiceURI: "en" },
    { name: "Local Chinese", lang: "zh-CN", localService: true, default: false, voiceURI: "zh" },
    { name: "Online Malay", lang: "ms-MY", localService: false, default: false, voiceURI: "ms" },
  ];
  window.__said = [];
  const synth = new EventTarget();
  synth.getVoices = () => voices;
  synth.speak = (u) =>
    window.__said.push({ text: u.text, lang: u.lang, voice: u.voice && u.voice.name });
  synth.cancel = () => {};
  Object.defineProperty(window, "speechSynthesis", { value: synth, configurable: true });
  window.SpeechSynthesisUtterance = class {
    constructor(text) { this.text = text; this.lang = ""; this.voice = null; this.rate = 1; }
  };
})();"""


class Devices(Screens):
    """Screens of their own size, touch or not, each with the speech spy (Screens.open's
    recording of console errors and sent frames).

    Playwright runs its own queries in a Chromium page as if the person had touched it (user
    activation), which lets the page's sound through: a page opened here is not queried until
    it has sent its first frame, so that, like a screen nobody has touched yet, it starts with
    its sound held back. Every later query leaves it so: a suspended AudioContext runs only once
    the page resumes it, which it does on a touch, a key or its prompt.
    """

    async def device(
        self,
        path: str,
        token: str,
        viewport: dict[str, int],
        *,
        touch: bool = False,
        axe: bool = False,
    ) -> Any:
        # axe is injected as a script: only a page it checks bypasses the Content-Security-Policy.
        context = await self.browser.new_context(viewport=viewport, has_touch=touch, bypass_csp=axe)
        await context.add_init_script(SPEECH_SPY)
        page = await context.new_page()
        page.on(
            "console",
            lambda m: (
                self.errors.append(f"{path}: console {m.text}") if m.type == "error" else None
            ),
        )
        page.on("pageerror", lambda e: self.errors.append(f"{path}: exception {e}"))
        started = asyncio.get_running_loop().create_future()

        def sent(frame: str) -> None:
            self.sent.append(json.loads(frame))
            if not started.done():
                started.set_result(None)  # the page's scripts ran: its sound is set up

        page.on("websocket", lambda ws: ws.on("framesent", sent))
        await page.goto(f"{self.base}{path}#token={token}", wait_until="commit")
        await asyncio.wait_for(started, 20)
        await expect(page.locator("body")).to_have_attribute("data-connection", "online")
        return page


async def said(page: Any) -> list[dict[str, Any]]:
    result: list[dict[str, Any]] = await page.evaluate("() => window.__said")
    return result


async def press(page: Any, locator: Any, how: str) -> None:
    """A tap (touch screen), a click, or Enter on the focused control (keyboard)."""
    if how == "tap":
        await locator.tap()
    elif how == "key":
        await locator.focus()
        await page.keyboard.press("Enter")
    else:
        await locator.click()


async def fits(page: Any, what: str) -> None:
    """Nothing sideways, and every visible button a finger's size."""
    width, inner = await sideways(page)
    assert width <= inner, (what, width, inner)
    assert await too_small(page, "button") == [], what


async def owner(r: Restaurant) -> Client:
    c = Client(await connect(r.app.url))
    r.clients.append(c)
    await c.ok("login", username="owner", password=r.app.first_owner_password)
    return c


async def test_arrival_rings_and_speaks_once_in_the_screens_language(
    tmp_path: Path, browser: Any
) -> None:
    need_axe()
    async with service(tmp_path) as r:
        o = await owner(r)
        # The site speaks Chinese first: a screen with no language of its own starts in it.
        await o.ok("site", action="set_settings", languages=["zh", "en", "ms"], language="zh")
        c = await staff(r)
        d = Devices(browser, http_base(r))

        def robot_token() -> Any:
            return r.app.issue_token("robot-screen", robot="r1")

        robots = {
            "phone": await d.device(
                "/robot/r1?lang=en", await robot_token(), PHONE, touch=True, axe=True
            ),
            "portrait": await d.device("/robot/r1", await robot_token(), PORTRAIT, touch=True),
            "landscape": await d.device("/robot/r1?lang=ms", await robot_token(), LANDSCAPE),
        }
        lang = {"phone": "en", "portrait": "zh", "landscape": "ms"}

        async def table_page(name: str, query: str, viewport: dict[str, int], **kw: Any) -> Any:
            token = await r.app.issue_token("table-screen", table=name)
            return await d.device(f"/table/{name}{query}", token, viewport, **kw)

        tables = {
            "T2": await table_page("T2", "?lang=en", PHONE, touch=True, axe=True),
            "T1": await table_page("T1", "?lang=zh", DESKTOP),  # muted by staff
            "T1 untouched": await table_page("T1", "", LANDSCAPE, touch=True),  # the site's zh
        }

        # Every screen starts with its sound held back, and asks for a touch in its language.
        prompt_words = {
            "phone": "en", "portrait": "zh", "landscape": "ms",
            "T2": "en", "T1": "zh", "T1 untouched": "zh",
        }  # fmt: skip
        pages = {**robots, **tables}
        for key, page in pages.items():
            await expect(page.locator("body"), key).to_have_attribute("data-sound", "blocked")
            prompt = page.get_by_role(
                "button", name=tr(prompt_words[key], "guest.sound.turnOn"), exact=True
            )
            await expect(prompt).to_be_visible()
            await expect(prompt).to_be_in_viewport()
        await tables["T2"].screenshot(path=str(tmp_path / "table-phone-blocked.png"))
        await robots["phone"].screenshot(path=str(tmp_path / "robot-phone-blocked.png"))
        found = {"robot, sound held back": await violations(robots["phone"])}
        found["table, sound held back"] = await violations(tables["T2"])

        # Turned on by a finger, a mouse and the keyboard; one table muted; one left alone.
        for key, how in (
            ("phone", "tap"),
            ("portrait", "tap"),
            ("landscape", "key"),
            ("T2", "tap"),
        ):
            page = pages[key]
            prompt = page.get_by_role("button", name=tr(prompt_words[key], "guest.sound.turnOn"))
            await press(page, prompt, how)
            await expect(page.locator("body")).to_have_attribute("data-sound", "on")
            await expect(prompt).to_be_hidden()
        muted = tables["T1"]
        await muted.get_by_role("button", name=tr("zh", "guest.sound.on")).click()
        await expect(muted.get_by_role("button", name=tr("zh", "guest.sound.off"))).to_be_visible()
        await expect(muted.locator("body")).to_have_attribute("data-sound", "off")
        await expect(
            muted.get_by_role("button", name=tr("zh", "guest.sound.turnOn"))
        ).to_be_hidden()

        task = await loaded_trip(
            c, dict(dish="Laksa", table="T2"), dict(dish="Satay", table="T1", quantity=2)
        )
        # Loading at the pass rings nothing.
        for page in robots.values():
            await expect(page.locator(".tray")).to_have_count(2)
            assert await page.locator("body").get_attribute("data-chimes") is None
        await robots["phone"].get_by_role("button", name="Go", exact=True).tap()
        await c.status("r1", "Delivering")

        chimes = {key: 0 for key in robots}
        for n, stop in enumerate(task["stops"], start=1):
            where = stop["table"]
            told = {
                k: await p.locator("body").get_attribute("data-arrival") for k, p in tables.items()
            }
            await c.until(
                lambda s=stop: c.task(task["id"])["stops"][s["seq"]]["status"] == "arrived",
                what=f"at {where}",
            )
            # Each robot screen rings once and says it in its language; Malay has no local voice
            # (only a network one): the chime alone, the words are on the screen.
            for key, page in robots.items():
                chimes[key] += 1
                body = page.locator("body")
                await expect(body).to_have_attribute("data-chimes", str(chimes[key]))
                await expect(page.locator(".take-tray")).to_have_text(
                    tr(lang[key], "guest.takeTray", tray=n)
                )
                if lang[key] == "ms":
                    await expect(body).to_have_attribute("data-arrival-sound", "chime")
                    assert await said(page) == [], key
                    continue
                await expect(body).to_have_attribute("data-arrival-sound", "spoken")
                await expect(body).to_have_attribute("data-spoken", str(chimes[key]))
                words = tr(lang[key], "guest.arrival.spokenAt", table=where, tray=n)
                voice = {"en": ("en-GB", "Local English"), "zh": ("zh-CN", "Local Chinese")}
                lang_tag, name = voice[lang[key]]
                assert (await said(page))[-1] == {"text": words, "lang": lang_tag, "voice": name}
                assert len(await said(page)) == chimes[key], key

            if where == "T2":
                here = tables["T2"]
                await expect(here.locator("body")).to_have_attribute("data-chimes", "1")
                await expect(here.locator("body")).to_have_attribute("data-spoken", "1")
                assert await said(here) == [
                    {
                        "text": tr("en", "guest.arrival.spoken", tray=n),
                        "lang": "en-GB",
                        "voice": "Local English",
                    }
                ]
                found["table, food here"] = await violations(here)
                await here.screenshot(path=str(tmp_path / "table-phone-here.png"))
                await fits(here, "T2 phone, food here")
            else:
                # Muted: nothing rings, nothing is said, and it stays so.
                body = muted.locator("body")
                await expect(body).to_have_attribute("data-arrival-sound", "muted")
                assert await body.get_attribute("data-chimes") is None
                assert await said(muted) == []
                # Never touched: held back, the prompt still asks; a touch rings it now.
                alone = tables["T1 untouched"]
                body = alone.locator("body")
                await expect(body).to_have_attribute("data-arrival-sound", "blocked")
                assert await body.get_attribute("data-chimes") is None
                prompt = alone.get_by_role("button", name=tr("zh", "guest.sound.turnOn"))
                await expect(prompt).to_be_in_viewport()
                await prompt.tap()
                await expect(body).to_have_attribute("data-chimes", "1")
                await expect(body).to_have_attribute("data-spoken", "1")
                assert await said(alone) == [
                    {
                        "text": tr("zh", "guest.arrival.spoken", tray=n),
                        "lang": "zh-CN",
                        "voice": "Local Chinese",
                    }
                ]
                await fits(alone, "T1 landscape, food here")
                await alone.screenshot(path=str(tmp_path / "table-landscape-here.png"))

            # The other table's screens were not told of it.
            for key, page in tables.items():
                if not key.startswith(where):
                    assert await page.locator("body").get_attribute("data-arrival") == told[key]
            # Redraws ring nothing more: another language and back, on every robot screen.
            for key, page in robots.items():
                await page.locator("#lang-picker").select_option(
                    "en" if lang[key] != "en" else "zh"
                )
                await page.locator("#lang-picker").select_option(lang[key])
                await expect(page.locator("html")).to_have_attribute("data-lang", lang[key])
                await fits(page, f"robot {key}, food here")
                assert await page.locator("body").get_attribute("data-chimes") == str(chimes[key])
            if n == 1:
                found["robot, food here"] = await violations(robots["phone"])
                await robots["phone"].screenshot(path=str(tmp_path / "robot-phone-here.png"))
                # A reload does not ring the same arrival again: the device remembers it. (Chromium
                # lets a page reloaded after a touch keep its sound on.)
                phone = robots["phone"]
                await phone.reload()
                body = phone.locator("body")
                await expect(body).to_have_attribute("data-arrival-sound", "heard")
                assert await body.get_attribute("data-chimes") is None
                assert await said(phone) == []
                if await body.get_attribute("data-sound") == "blocked":
                    await phone.get_by_role("button", name="Tap here to turn the sound on").tap()
                await expect(body).to_have_attribute("data-sound", "on")
                assert await body.get_attribute("data-chimes") is None
                chimes["phone"] = 0
            # The guests take their dishes: on to the next table.
            await robots["portrait"].get_by_role("button", name=tr("zh", "robot.collected")).tap()
            await c.until(
                lambda s=stop: c.task(task["id"])["stops"][s["seq"]]["status"] == "done",
                what=f"{where} served",
            )

        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="home")
        # Going home rings nothing.
        for key, page in robots.items():
            assert await page.locator("body").get_attribute("data-chimes") == str(chimes[key])
        bad = {k: v for k, v in found.items() if v}
        assert bad == {}, bad
        d.assert_no_errors()


async def test_staff_send_an_idle_robot_from_its_screen(tmp_path: Path, browser: Any) -> None:
    need_axe()
    async with service(tmp_path) as r:
        o = await owner(r)
        sam = (await o.ok("account", action="add_user", username="sam", role="staff"))["password"]
        c = await staff(r)
        await activate(c, "r1")
        await c.status("r1", "Awaiting")
        d = Devices(browser, http_base(r))
        token = await r.app.issue_token("robot-screen", robot="r1")
        page = await d.device("/robot/r1", token, LANDSCAPE, touch=True, axe=True)

        # The robot's own token: no way to send it from here, and the server refuses it anyway.
        await expect(page.get_by_role("heading", name="Awaiting orders")).to_be_visible()
        await expect(page.get_by_role("heading", name="Send to a table")).to_have_count(0)
        await expect(page.get_by_role("button", name="T3", exact=True)).to_have_count(0)
        screen = await device(r, "robot-screen", robot="r1")
        for verb, fields in (
            ("control", {"action": "goto", "waypoint": "T3"}),
            ("control", {"action": "manual"}),
            ("control", {"action": "auto"}),
            ("ready", {}),
        ):
            await screen.error(verb, "forbidden", robot="r1", **fields)
        assert c.robot("r1")["status"] == "Awaiting"

        # "Staff sign-in": the login dialog, which a guest who pressed it can leave.
        sign_in = page.get_by_role("button", name="Staff sign-in")
        dialog = page.get_by_role("dialog").filter(has_text="Log in to serveur")
        await sign_in.tap()
        await expect(dialog).to_be_visible()
        await dialog.get_by_role("button", name="Cancel").tap()
        await expect(dialog).to_be_hidden()
        await sign_in.click()
        await expect(dialog).to_be_visible()
        await page.keyboard.press("Escape")
        await expect(dialog).to_be_hidden()
        await expect(page.get_by_role("heading", name="Send to a table")).to_have_count(0)

        # A wrong password says so and changes nothing; then sam signs in.
        await sign_in.tap()
        await dialog.get_by_label("Login").fill("sam")
        await dialog.get_by_label("Password").fill("not his password")
        await dialog.get_by_role("button", name="Log in").tap()
        await expect(dialog.get_by_text("Wrong user name, password or token.")).to_be_visible()
        assert await page.evaluate("() => localStorage.getItem('serveur.token')") == token
        await dialog.get_by_label("Password").fill(sam)
        await dialog.get_by_role("button", name="Log in").tap()
        await expect(dialog).to_be_hidden()
        send = page.get_by_role("region", name="Send to a table", exact=True)
        await expect(send.get_by_role("heading")).to_have_text("Send to a table")
        tables = sorted(
            (n for n, w in WAYPOINTS.items() if w.kind == "table"), key=lambda n: int(n[1:])
        )
        await expect(send.get_by_role("button")).to_have_text(tables)
        # Awaiting, at home: no Go home; the staff's corner has the mute and Sign out.
        await expect(page.get_by_role("button", name="Go home")).to_have_count(0)
        await expect(page.get_by_role("button", name="Sound on")).to_be_visible()
        await expect(page.get_by_role("button", name="Sign out")).to_be_visible()
        # The device keeps its own token, never the person's.
        assert await page.evaluate("() => localStorage.getItem('serveur.token')") == token
        await fits(page, "staff at an idle robot, 1024x768")
        assert await violations(page) == []
        await page.screenshot(path=str(tmp_path / "robot-staff-send.png"))

        # T3: out of deliveries, under staff control, then there.
        before = len(d.sent)
        await send.get_by_role("button", name="T3", exact=True).tap()
        t3 = WAYPOINTS["T3"]
        await c.until(
            lambda: (
                (rb := c.robot("r1"))["x"] is not None
                and math.hypot(rb["x"] - t3.x, rb["y"] - t3.y) < 0.3
            ),
            what="r1 at T3",
        )
        assert c.robot("r1")["status"] == "Manual"
        orders = [
            (m["clientmsg"], m.get("action"), m.get("waypoint"))
            for m in d.sent[before:]
            if m.get("clientmsg") in ("ready", "control")
        ]
        assert orders == [
            ("ready", None, None),
            ("control", "manual", None),
            ("control", "goto", "T3"),
        ]
        # Sent: the screen is the guests' again, on the device's token.
        await expect(sign_in).to_be_visible()
        await expect(page.get_by_role("heading", name="Send to a table")).to_have_count(0)
        await expect(page.get_by_role("button", name="Sign out")).to_have_count(0)
        await expect(page.locator("body")).to_have_attribute("data-role", "robot-screen")
        assert await page.evaluate("() => localStorage.getItem('serveur.token')") == token

        # On a phone, by keyboard: staff sign in and send it home (taking deliveries again).
        phone = await d.device("/robot/r1", token, PHONE)
        await expect(phone.get_by_role("heading", name="Staff are driving me")).to_be_visible()
        await phone.get_by_role("button", name="Staff sign-in").click()
        form = phone.get_by_role("dialog").filter(has_text="Log in to serveur")
        await form.get_by_label("Login").fill("sam")
        await form.get_by_label("Password").fill(sam)
        await phone.keyboard.press("Enter")
        home = phone.get_by_role("button", name="Go home")
        await expect(home).to_be_in_viewport()
        await fits(phone, "staff at a robot under control, phone")
        await phone.screenshot(path=str(tmp_path / "robot-staff-phone.png"))
        await press(phone, home, "key")
        await c.until(lambda: c.robot("r1")["status"] in ("Transit", "Awaiting"), what="going home")
        await c.status("r1", "Awaiting")
        await expect(phone.get_by_role("button", name="Staff sign-in")).to_be_visible()
        await expect(phone.get_by_role("button", name="Go home")).to_have_count(0)
        d.assert_no_errors()
