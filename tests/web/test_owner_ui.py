"""The owner's Accounts tab, end to end in Chromium (issue 20): people and screens' tokens.

Same harness as tests/web/test_ui.py (Debian's /usr/bin/chromium driven by playwright, a real
server and a simulated robot, no sleeps). The owner adds a staff person, who logs in on a second
device; resets their password (their session ends, the new one works); removes them. Then makes
a table screen's token: its QR code and setup link show, the link opened on a second device is
the table's screen logged in; revoked, that screen is refused and asks to log in.
"""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

from tests.web.test_ui import (
    Screens,
    expect,
    http_base,
    log_in,
    pytestmark,  # noqa: F401
    ui_restaurant,
)

LOGIN = "Log in to serveur"


async def confirm(page: Any, yes: str) -> None:
    dialog = page.get_by_role("dialog")
    await dialog.get_by_role("button", name=yes, exact=True).click()
    await expect(dialog).to_have_count(0)


async def test_the_owner_manages_people_and_screens(
    tmp_path: Path,
    browser: Any,
) -> None:
    async with ui_restaurant(tmp_path) as r:
        screens = Screens(browser, http_base(r))
        owner = await screens.open("/", online=False)
        await log_in(owner, "owner", r.app.first_owner_password or "")
        await expect(owner.locator("body")).to_have_attribute("data-connection", "online")
        await owner.get_by_role("tab", name="Accounts").click()
        people = owner.get_by_role("list", name="People")
        await expect(people.get_by_role("listitem").filter(has_text="owner")).to_be_visible()

        # A staff person added: the password is shown once, and works on another device.
        await owner.get_by_label("User name").fill("sam")
        await owner.get_by_label("Role", exact=True).select_option("staff")
        await owner.get_by_role("button", name="Add person").click()
        first = (await owner.get_by_test_id("password").text_content() or "").strip()
        assert len(first) >= 12
        await expect(people.get_by_role("combobox", name="Role of sam")).to_have_value("staff")
        sam = await screens.open("/", online=False, token="")
        sam_login = await log_in(sam, "sam", first)
        await expect(sam.locator("body")).to_have_attribute("data-connection", "online")
        await expect(sam.get_by_test_id("who")).to_have_text("sam (staff)")
        await expect(sam.get_by_role("tab", name="Accounts")).to_be_hidden()

        # Reset (after a confirmation): sam's tablet is logged out, the new password works.
        await owner.get_by_role("button", name="Reset password of sam").click()
        await confirm(owner, "Reset password")
        await expect(owner.get_by_test_id("password")).not_to_have_text(first)
        second = (await owner.get_by_test_id("password").text_content() or "").strip()
        await expect(sam_login).to_be_visible()
        await log_in(sam, "sam", second)
        await expect(sam.locator("body")).to_have_attribute("data-connection", "online")

        # Removed: logged out at once, and gone from the list.
        await owner.get_by_role("button", name="Remove sam").click()
        await confirm(owner, "Remove")
        await expect(sam_login).to_be_visible()
        await expect(people.get_by_role("listitem").filter(has_text="sam")).to_have_count(0)

        # A table screen's token: QR code and link shown once; the link sets the screen up.
        await owner.get_by_label("Screen of").select_option("table-screen")
        await owner.get_by_label("Which", exact=True).select_option("T3")
        await owner.get_by_role("button", name="Make QR code").click()
        await expect(owner.get_by_role("img", name="QR code for Table T3")).to_be_visible()
        link = owner.locator(".acc-made a.setup-link")
        href = await link.get_attribute("href") or ""
        assert re.fullmatch(re.escape(http_base(r)) + r"/table/T3#token=srv_[\w-]+", href), href
        table = await screens.open(href.removeprefix(http_base(r)), token="")
        assert "token" not in table.url
        await expect(table.get_by_role("dialog").filter(has_text=LOGIN)).to_have_count(0)
        screen_list = owner.get_by_role("list", name="Screens")
        await expect(
            screen_list.get_by_role("listitem").filter(has_text="Table T3")
        ).to_be_visible()

        # The print sheet holds the code made here, with the table's name.
        await owner.emulate_media(media="print")
        await expect(owner.locator(".print-sheet li").filter(has_text="Table T3")).to_be_visible()
        await owner.emulate_media(media="screen")

        # Revoked (after a confirmation): that screen is refused and asks to log in.
        await screen_list.get_by_role("button", name=re.compile(r"^Revoke Table T3")).click()
        await confirm(owner, "Revoke")
        await expect(table.get_by_role("dialog").filter(has_text=LOGIN)).to_be_visible()
        await expect(screen_list.get_by_text("No screen tokens yet.")).to_be_visible()
        screens.assert_no_errors(re.compile("401|4001|Unauthorized", re.I))
