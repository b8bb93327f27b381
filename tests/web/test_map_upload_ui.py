"""The owner replaces the restaurant's map with a robot's map files, in Chromium (issue 29): the
two files chosen on a tablet, sent in parts, the map replaced on every screen, the places now
in a wall named; a YAML pointing outside its folder refused in the owner's words."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from serveur.maps.distances import MapData
from serveur.maps.mapfiles import map_files
from tests.test_site_map import walled_demo
from tests.web.test_a11y import violations
from tests.web.test_ui import (
    SHOTS,
    expect,
    owner_tab,
    pytestmark,  # noqa: F401
    ui_restaurant,
)


async def test_the_owner_uploads_a_robot_map(tmp_path: Path, browser: Any) -> None:
    new = walled_demo()
    text, pgm = map_files(new, "room")
    (tmp_path / "room.yaml").write_bytes(text)
    (tmp_path / "room.pgm").write_bytes(pgm)
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "room.yaml").write_bytes(text.replace(b"image: room.pgm", b"image: ../maps/room.pgm"))
    async with (
        ui_restaurant(tmp_path) as r,
        owner_tab(browser, r, "Restaurant") as (owner, errors),
    ):
        section = owner.get_by_role("region", name="The map", exact=True)
        result = section.get_by_role("status")

        await section.get_by_label("Map file (.yaml)").set_input_files(str(bad / "room.yaml"))
        await section.get_by_label("Map image (.pgm or .png)").set_input_files(
            str(tmp_path / "room.pgm")
        )
        await section.get_by_role("button", name="Use this map").click()
        await expect(result).to_have_text(
            "This map was not used: the .yaml file points to an image in another folder;"
            " choose the .yaml saved beside its image."
        )
        assert await r.app.store.site_map.get() is None

        await section.get_by_label("Map file (.yaml)").set_input_files(str(tmp_path / "room.yaml"))
        await section.get_by_role("button", name="Use this map").click()
        await expect(result).to_contain_text("The map is replaced: 17.3 m by 13.3 m, 5 cm squares.")
        await expect(result).to_contain_text("move them: T3.")
        stored = await r.app.store.site_map.get()
        assert stored is not None and stored.cells == MapData.from_occupancy(new).data
        assert await violations(owner) == []
        await section.screenshot(path=str(SHOTS / "map-upload.png"))
        assert errors == []
