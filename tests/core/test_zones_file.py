"""A zones file (``serveur run --zones``): read, checked, stored at start, served on ``zones``;
and the zone requests refused with a reason (a zone on a line, a name taken, staff removing)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
from websockets.asyncio.client import connect

from serveur.errors import InvalidField
from serveur.store.zones import load_zones_file
from tests.security.test_security import bare_server, login, request

AISLE = [[2.0, 1.0], [4.0, 1.0], [4.0, 1.6], [2.0, 1.6]]


def test_a_zones_file_is_read_and_checked(tmp_path: Path) -> None:
    good = tmp_path / "zones.json"
    good.write_text(json.dumps({"zones": [{"name": "aisle", "points": AISLE}]}))
    [zone] = load_zones_file(good)
    assert (zone.name, zone.capacity, zone.points[0]) == ("aisle", 1, (2.0, 1.0))
    for bad in (
        {"zones": [{"name": "line", "points": [[0, 0], [1, 1], [2, 2]]}]},  # no floor inside
        {"zones": [{"name": "two", "points": [[0, 0], [1, 0]]}]},
        {"zones": [{"name": "big", "points": AISLE, "capacity": 0}]},
        {"zones": [{"points": AISLE}]},
    ):
        path = tmp_path / "bad.json"
        path.write_text(json.dumps(bad))
        with pytest.raises(InvalidField):
            load_zones_file(path)
    # serveur run refuses to start on a bad file, with one clear line.
    out = subprocess.run(
        [sys.executable, "-m", "serveur.cli", "run", "--db", str(tmp_path / "x.db"),
         "--zones", str(tmp_path / "bad.json"), "--port", "0"],
        capture_output=True, text=True, timeout=60,
    )  # fmt: skip
    assert out.returncode == 1 and "not a zones file" in out.stderr, out.stderr


async def test_zones_given_at_start_are_served_and_edited(tmp_path: Path) -> None:
    path = tmp_path / "zones.json"
    path.write_text(json.dumps({"zones": [{"name": "aisle", "points": AISLE, "capacity": 1}]}))
    async with bare_server(tmp_path, app={"zones": load_zones_file(path)}) as app:
        ws = await connect(app.url)
        await login(ws, username="owner", password=app.first_owner_password)
        snap = await request(ws, {"clientmsg": "data", "topics": ["zones", "leases"]})
        assert [z["name"] for z in snap["data"]["zones"]] == ["aisle"]
        assert snap["data"]["leases"] == [
            {"zone": "aisle", "capacity": 1, "holders": [], "waiting": []}
        ]
        zone = {"clientmsg": "create", "type": "zone", "name": "aisle", "points": AISLE[:3]}
        assert (await request(ws, zone))["code"] == "conflict"  # taken: replace to change it
        changed = await request(ws, {**zone, "replace": True, "capacity": 2})
        assert changed["zone"]["capacity"] == 2
        flat = {**zone, "name": "flat", "points": [[0, 0], [1, 0], [2, 0]]}
        assert (await request(ws, flat))["code"] == "invalid_field"
        assert (await request(ws, {"clientmsg": "release", "zone": "nowhere"}))["code"] == (
            "not_found"
        )
        staff = await connect(app.url)
        await login(staff, token=await app.issue_token("staff"))
        # Zones are the owner's drawing: staff may not draw or remove one (they break leases).
        gone = {"clientmsg": "site", "action": "remove_zone", "zone": "aisle"}
        assert (await request(staff, gone))["code"] == "forbidden"
        assert (await request(staff, {**zone, "name": "z2"}))["code"] == "forbidden"
        released = await request(staff, {"clientmsg": "release", "zone": "aisle"})
        assert released["broken"] == [] and released["leases"][0]["zone"] == "aisle"
        await staff.close()
        removed = await request(ws, gone)
        assert removed["zone"]["removed"] is True
        await ws.close()
