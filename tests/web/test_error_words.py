"""Every error the server answers is read as a sentence in the page's language (issue 30, point 2:
"r1 has moved on: you saw trip 1 stop 2, it is on no trip (Transit) (stale)" and server messages
in English on the Chinese page).

The words are chosen in the page (js/errors.js) from the error's stable code and its details,
never from the server's English message: a test walks docs/protocol.md's error table in every
language, then real refusals from a real server are worded in each language, then one is seen
on a phone in Chinese."""

from __future__ import annotations

import json
import re
from pathlib import Path
from typing import Any

from tests.test_protocol_doc import _error_table
from tests.web.test_ui import (
    Screens,
    expect,
    http_base,
    lagging,
    pytestmark,  # noqa: F401
    staff_client,
    ui_restaurant,
)

LANGS = ("en", "zh", "ms")
PHONE = {"width": 390, "height": 844}
CJK = re.compile(r"[\u4e00-\u9fff]")
# What a waiter must never read: a number with decimals (a coordinate), ROS words, a status
# code as the server spells it.
ENGINEERS = re.compile(r"\d+\.\d+|move_base|navigate_to_pose|ROS|Nav2|rosbridge|ABORTED|_")

WORD = """async ([errors, lang]) => {
  const i18n = await import("/js/i18n.js");
  const ui = await import("/js/ui.js");
  const ws = await import("/js/ws.js");
  i18n.setLang(lang);
  return errors.map(([code, message, details, request]) =>
    ui.describeError(new ws.ServerError(code, message, details, { request })));
}"""


async def _catalogs_loaded(page: Any) -> None:
    await expect(page.locator("html")).to_have_attribute("data-lang", "en")


async def test_every_code_of_the_error_table_has_a_sentence_in_every_language(
    tmp_path: Path, browser: Any
) -> None:
    codes = _error_table()
    async with ui_restaurant(tmp_path) as r:
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/")
        await _catalogs_loaded(page)
        worded = await page.evaluate("async () => (await import('/js/errors.js')).WORDED_CODES")
        assert sorted(worded) == sorted(codes), "errors.js words exactly the table's codes"
        said: dict[str, list[str]] = {}
        for lang in LANGS:
            errors = [[code, "the server's English words", {}, None] for code in codes]
            said[lang] = await page.evaluate(WORD, [errors, lang])
        for i, code in enumerate(codes):
            for lang in LANGS:
                text = said[lang][i]
                assert text and "{" not in text and "errors." not in text, (code, lang, text)
                assert code not in text and "English words" not in text, (code, lang, text)
            assert CJK.search(said["zh"][i]), (code, said["zh"][i])
            assert said["ms"][i] != said["en"][i], (code, said["ms"][i])
        screens.assert_no_errors()


async def test_real_refusals_are_worded_from_their_details(tmp_path: Path, browser: Any) -> None:
    """Refusals the server really sends, each worded in three languages: the robot's or the
    table's name and what it is now, in staff's words; nothing of the server's message."""
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        got: list[tuple[dict[str, Any], dict[str, Any]]] = []

        async def refused(verb: str, code: str, **fields: Any) -> None:
            reply = await c.error(verb, code, **fields)
            got.append(({"clientmsg": verb, **fields}, reply))

        await refused("go", "not_allowed_in_status", robot="r1")
        await refused("next", "stale", robot="r1", task=41, stop=0)
        off = {"type": "waypoint", "kind": "table", "replace": True, "name": "T16"}
        await refused("create", "unreachable", **off, x=9999.0, y=-50.0)
        await refused("create", "unreachable", **off, x=0.05, y=5.0)
        await refused("control", "not_found", robot="r9", action="auto")
        await refused("clear", "not_found", table="T99")
        await refused("ack", "not_found", alert=12345)
        await refused("site", "forbidden", action="settings")
        await refused("create", "invalid_field", type="order", dish="Tea", table="T1", quantity=0)
        await refused("fly", "unknown_message")
        t1 = c.records["waypoints"]["T1"]
        moved = {"x": t1["x"] + 0.1, "y": t1["y"], "kind": "table"}
        await refused("create", "conflict", type="waypoint", name="T1", **moved)
        want_en = [
            "r1 now shows “Paused”, so that cannot be done. The screen is up to date.",
            "r1 has moved on since your screen showed it: it now shows “Paused”."
            " Look again before pressing.",
            "That spot is outside the restaurant's map: choose a spot on the floor.",
            "That spot is in a wall or furniture: choose a spot on open floor.",
            "There is no robot called r9 (any more).",
            "There is no table or place called T99 (any more).",
            "That alert is already over.",
            "Your account may not do that: ask the owner.",
            "Something in the form is not right: check it and try again.",
            "This page is older than the server: reload it.",
            "There is already a place called T1: choose another name.",
        ]
        errors = [[rep["code"], rep["message"], rep.get("details"), req] for req, rep in got]
        screens = Screens(browser, http_base(r), r.token)
        page = await screens.open("/")
        await _catalogs_loaded(page)
        said = {lang: await page.evaluate(WORD, [errors, lang]) for lang in LANGS}
        assert said["en"] == want_en, json.dumps(said["en"], indent=1)
        for lang in LANGS:
            for (_req, rep), text in zip(got, said[lang], strict=True):
                assert rep["message"] not in text, (lang, text)
                assert not ENGINEERS.search(text), (lang, rep["code"], text)
        assert all(CJK.search(text) for text in said["zh"]), said["zh"]
        # Names stay as the restaurant wrote them, in every language.
        assert "r1" in said["zh"][0] and "T99" in said["ms"][5]
        assert "暂停" in said["zh"][1], said["zh"][1]  # r1's status, in Chinese
        screens.assert_no_errors()


async def test_a_refusal_on_a_chinese_phone_is_in_chinese(tmp_path: Path, browser: Any) -> None:
    """A phone set to Chinese: a press refused because another tablet changed the robot meanwhile
    reads in Chinese, with the robot's name and its status, and no code."""
    async with ui_restaurant(tmp_path) as r:
        c = await staff_client(r)
        await c.status("r1", "Ready")
        screens = Screens(browser, http_base(r), r.token)
        held = {"on": False}  # a lagging phone: the server's updates held back while "on"
        page = await screens.open("/?lang=zh", ws_route=lagging(held), viewport=PHONE)
        await expect(page.locator("html")).to_have_attribute("data-lang", "zh")
        start = page.get_by_role("button", name="开始送餐 r1")
        await expect(start).to_be_visible()
        held["on"] = True
        await c.ok("control", robot="r1", action="manual")  # another tablet, unseen here
        await start.click()
        alert = page.get_by_role("alert").filter(has_text="r1")
        await expect(alert).to_be_visible()
        text = await alert.inner_text()
        assert CJK.search(text) and "员工操控" in text, text  # r1 is under staff control
        assert "not_allowed" not in text and "Manual" not in text, text
        held["on"] = False
        screens.assert_no_errors()
