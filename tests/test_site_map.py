"""The owner gives the restaurant a robot's map files from the console (issue 29), over real
sockets: uploaded in parts, checked in a child process, stored (it survives a restart and wins
over the map the server was started with), shown to every screen; places now in a wall named;
bad files refused with their reason and nothing changed."""

from __future__ import annotations

import base64
import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from websockets.asyncio.client import connect

from serveur.maps.distances import MapData
from serveur.maps.mapfiles import map_files
from serveur.maps.mapio import OccupancyMap
from serveur.maps.navigation import load_demo
from serveur.protocol import UPLOAD_PART
from tests.conftest import Client, Restaurant, restaurant
from tests.test_protocol import _server_examples


async def owner(r: Restaurant, password: str | None = None) -> Client:
    c = Client(await connect(r.app.url, max_size=2**24))
    r.clients.append(c)
    await c.ok("login", username="owner", password=password or r.app.first_owner_password)
    return c


async def upload(c: Client, kind: str, name: str, data: bytes) -> int:
    up = (await c.ok("site", action="upload", kind=kind, name=name, size=len(data)))["upload"]
    for offset in range(0, len(data), UPLOAD_PART):
        part = base64.b64encode(data[offset : offset + UPLOAD_PART]).decode()
        await c.ok("site", action="upload_part", upload=up["id"], offset=offset, data=part)
    return int(up["id"])


def walled_demo() -> OccupancyMap:
    """The demo map with a new wall where table T3 stands (a partition built since)."""
    grid, wps = load_demo()
    cells = np.array(grid.grid)
    t3 = wps["T3"]
    row, col = grid.world_to_cell(t3.x, t3.y)
    cells[row - 4 : row + 5, col - 4 : col + 5] = 100
    return OccupancyMap(cells, grid.resolution, grid.origin)


async def test_a_robot_map_uploaded_in_the_console_replaces_the_started_one(
    tmp_path: Path,
) -> None:
    new = walled_demo()
    text, pgm = map_files(new, "room")
    async with restaurant(tmp_path) as r:
        c = await owner(r)
        await c.subscribe("map")
        before = c.streams["map"]
        y = await upload(c, "map_yaml", "room.yaml", text)
        i = await upload(c, "map_image", "room.pgm", pgm)
        assert len(pgm) > UPLOAD_PART  # several parts
        got = await c.ok("site", action="set_map", yaml=y, image=i)
        assert got["outside"] == ["T3"], got
        # The doc's example of this reply (not replayed there: it needs files) is this one.
        (doc,) = [
            ex for ex in _server_examples() if ex.get("servermsg") == "ok" and "outside" in ex
        ]
        assert doc["outside"] == got["outside"] and doc["map"] == {
            **got["map"],
            "source": doc["map"]["source"],
        }
        assert (got["map"]["width"], got["map"]["height"]) == (new.width, new.height)
        shown = await c.until(lambda: c.streams["map"] != before and c.streams["map"])
        assert MapData.from_snapshot(shown) == MapData.from_occupancy(new)
        password = r.app.first_owner_password
        await r.restart_server()  # started again with the demo map: the stored one wins
        c2 = await owner(r, password)
        snap = (await c2.ok("data", topics=["map"]))["data"]["map"]
        assert MapData.from_snapshot(snap) == MapData.from_occupancy(new)


async def test_bad_map_uploads_are_refused_and_change_nothing(tmp_path: Path) -> None:
    text, pgm = map_files(load_demo()[0], "room")
    async with restaurant(tmp_path) as r:
        c = await owner(r)
        before = (await c.ok("data", topics=["map"]))["data"]["map"]
        outside = text.replace(b"image: room.pgm", b"image: ../../etc/room.pgm")
        y = await upload(c, "map_yaml", "room.yaml", outside)
        i = await upload(c, "map_image", "room.pgm", pgm)
        err = await c.error("site", "map_error", action="set_map", yaml=y, image=i)
        assert err["details"]["reason"] == "outside" and "outside its folder" in err["message"]
        # The image can be used again with a good YAML (it stays until used).
        good = await upload(c, "map_yaml", "room.yaml", text)
        wrong_kind = await c.error("site", "invalid_field", action="set_map", yaml=i, image=good)
        assert "is a map_image" in wrong_kind["message"]
        not_image = await upload(c, "map_image", "room.pgm", b"P5 not really a map")
        err = await c.error("site", "map_error", action="set_map", yaml=good, image=not_image)
        assert err["details"]["reason"] == "not_a_map"
        await c.error(
            "site", "invalid_field", action="upload", kind="map_yaml", name="a.yaml", size=10**6
        )
        up = await c.ok("site", action="upload", kind="map_yaml", name="a.yaml", size=10)
        skip = base64.b64encode(b"x").decode()
        await c.error(
            "site", "conflict", action="upload_part", upload=up["upload"]["id"], offset=5, data=skip
        )
        await c.error("site", "not_found", action="set_map", yaml=999, image=i)
        after = (await c.ok("data", topics=["map"]))["data"]["map"]
        assert after == before and await r.app.store.site_map.get() is None
        staff = await r.client()  # staff may not
        refused: Any = await staff.call(
            "site", action="upload", kind="map_yaml", name="a.yaml", size=10
        )
        assert refused["code"] == "forbidden", json.dumps(refused)


async def test_a_floor_plan_becomes_the_map_after_a_preview(tmp_path: Path) -> None:
    from tests.maps.plans import ROOM, plan
    from tests.maps.test_floorplan import free_run

    p = plan(px_per_m=37.0)
    mid_x, mid_y = (p.left + p.partition_x) / 2, (p.top + p.bottom) / 2
    across = {"a": [p.left, mid_y + 40], "b": [p.right, mid_y + 40], "metres": ROOM[0]}
    along = {"a": [mid_x, p.top], "b": [mid_x, p.bottom], "metres": ROOM[1]}
    async with restaurant(tmp_path) as r:
        c = await owner(r)
        up = await upload(c, "plan", "plan.png", p.data)
        preview = await c.ok(
            "site", action="plan_map", upload=up, threshold=50, across=across, along=along
        )
        assert "outside" not in preview and await r.app.store.site_map.get() is None
        (doc,) = [ex for ex in _server_examples() if ex.get("servermsg") == "ok" and "plan" in ex]
        assert doc.keys() == preview.keys() and doc["plan"].keys() == preview["plan"].keys()
        assert doc["map"].keys() == preview["map"].keys()
        result = preview["plan"]
        assert not result["stretched"] and result["disagreement"] < 0.01
        m = MapData.from_snapshot(result["map"])
        grid = np.frombuffer(m.data, dtype=np.int8).reshape(m.height, m.width)
        col = int(((mid_x - 30) / 37.0) / 0.05)
        depth = free_run(grid[:, col], m.height // 2) * 0.05
        assert depth == pytest.approx(ROOM[1], rel=0.02)  # measured on the map: 2 %
        applied = await c.ok(
            "site",
            action="plan_map",
            upload=up,
            threshold=50,
            across=across,
            along=along,
            apply=True,
        )
        assert applied["map"]["source"] == "floor plan (plan.png)"
        stored = await r.app.store.site_map.get()
        assert stored is not None and stored.cells == m.data
        # Bad: the upload was used; a stretched plan is said; a non-image refused.
        await c.error("site", "not_found", action="plan_map", upload=up, across=across, along=along)
        tall = plan(px_per_m=37.0, stretch=1.06)
        up2 = await upload(c, "plan", "tall.png", tall.data)
        along2 = {"a": [mid_x, tall.top], "b": [mid_x, tall.bottom], "metres": ROOM[1]}
        got = await c.ok("site", action="plan_map", upload=up2, across=across, along=along2)
        assert got["plan"]["stretched"] and got["plan"]["disagreement"] > 0.05
        junk = await upload(c, "plan", "plan.png", b"not a picture at all")
        err = await c.error(
            "site", "map_error", action="plan_map", upload=junk, across=across, along=along
        )
        assert err["details"]["reason"] == "not_an_image"
