"""The owner's backups in Chromium on a tablet (issue 29): "Back up now" saves a checked copy on
the tablet; a copy from elsewhere that is not one is refused in the owner's words; a listed copy
restored after being told what it holds and what is lost — the server restarts on it, the page
reconnects by itself, and the restaurant is as it was."""

from __future__ import annotations

import asyncio
import re
from pathlib import Path
from typing import Any

from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    owner_tab,
    pytestmark,  # noqa: F401
    ui_restaurant,
)


async def test_the_owner_backs_up_and_restores_from_the_console(
    tmp_path: Path, browser: Any
) -> None:
    (tmp_path / "photo.db").write_bytes(b"\x89PNG\r\n\x1a\n" + bytes(500))
    async with (
        ui_restaurant(tmp_path) as r,
        owner_tab(browser, r, "Restaurant", accept_downloads=True) as (owner, errors),
    ):
        store = r.app.store
        await store.service.put_settings({"name": "Chez Avant"}, now=0.0)
        section = owner.get_by_role("region", name="Backups")
        said = section.get_by_role("status")
        await expect(section.get_by_text("No backup yet")).to_be_visible()

        async with owner.expect_download() as saving:
            await section.get_by_role("button", name="Back up now").click()
        saved = Path(await (await saving.value).path())
        assert (await asyncio.to_thread(saved.read_bytes)).startswith(b"SQLite format 3\x00")
        await expect(said).to_have_text(
            "Done: the copy is checked and is being saved on this device."
        )
        rows = section.get_by_role("listitem")
        await expect(rows).to_have_count(1)
        await expect(rows.first).to_contain_text("Made by hand")
        await expect(rows.first).to_contain_text("checked")

        # Not a backup: refused in words, nothing restarts.
        await section.get_by_label("A copy saved elsewhere (.db)").set_input_files(
            str(tmp_path / "photo.db")
        )
        await section.get_by_role("button", name="Restore from this file…").click()
        await expect(said).to_have_text(
            "Not restored: this file is not a copy of a serveur restaurant."
        )

        # The restaurant moves on; then the owner restores the copy.
        await store.service.put_settings({"name": "Chez Après"}, now=0.0)
        await rows.first.get_by_role("button", name="Restore").click()
        dialog = owner.get_by_role("dialog")
        await expect(dialog).to_contain_text("Put the restaurant back as it was on")
        await expect(dialog).to_contain_text("Lost: the 0 dishes and 0 trips made since.")
        await expect(dialog).to_contain_text("Today's state is kept as a copy first.")
        assert await violations(owner) == []
        await dialog.screenshot(path=str(SHOTS / "restore-tablet.png"))
        assert r.app.server is not None and r.app.server.backups is not None
        desk = r.app.server.backups
        await dialog.get_by_role("button", name="Restore").click()
        # The server restarts on the copy; the page comes back by itself.
        await expect(said).to_have_text(
            "Restoring: the server restarts on the copy, this page reconnects by itself."
        )
        assert desk.restarting is not None  # set before the reply the page just showed
        await asyncio.wait_for(desk.restarting, 30)
        await expect(owner.locator("body")).to_have_attribute(
            "data-connection", "online", timeout=30_000
        )
        settings = await r.app.store.service.get_settings()
        assert settings.get("name") == "Chez Avant", settings
        await owner.get_by_role("tab", name="Map & robots").click()
        await owner.get_by_role("tab", name="Restaurant").click()
        await expect(said).to_contain_text("Restored: the restaurant is as it was on")
        await expect(section.get_by_role("listitem")).to_have_count(2)
        await expect(section.get_by_text("Before a restore")).to_be_visible()
        await section.screenshot(path=str(SHOTS / "backups-tablet.png"))
        # The only errors allowed: the browser's own notes of connection attempts refused
        # while the server was restarting (as tests/web/test_ui.py's restart test allows).
        refused = re.compile(r"WebSocket connection to .* failed")
        assert [e for e in errors if not refused.search(e)] == [], errors
