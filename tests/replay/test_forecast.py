""" "How many robots do I need?" over the protocol: a recorded day replayed with other fleets.

A real server on a database holding a short service day (its dishes stored with their ready
times, as a service records them); the owner asks for a forecast with 1 and 2 robots, and each
fleet's replay — a real ``serveur replay`` child, on the site's own map and waypoints — reports
its waits on the ``forecast`` topic. Refusals: a day without dishes, a second forecast while
one runs, staff.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

from websockets.asyncio.client import ClientConnection, connect

from serveur.clock import FakeClock
from serveur.maps.navigation import load_demo
from tests.security.test_security import bare_server, login, request

DAY = "2023-11-14"  # FakeClock's epoch 1_700_000_000 is 2023-11-14 22:13 UTC
WAIT = 120.0


async def _until(ws: ClientConnection, pred: Any) -> dict[str, Any]:
    async def wait() -> dict[str, Any]:
        while True:
            msg = json.loads(await ws.recv())
            if msg.get("topic") == "forecast" and pred(msg["data"]):
                return msg["data"]  # type: ignore[no-any-return]

    return await asyncio.wait_for(wait(), WAIT)


async def record_day(ws: ClientConnection, clock: FakeClock) -> None:
    """A recorded service day: six dishes for five tables, ready at the pass a minute apart
    (on DAY, by the FakeClock), created by ``ws``'s owner session."""
    for i, table in enumerate(["T1", "T2", "T5", "T9", "T1", "T12"]):
        made = await request(
            ws, {"clientmsg": "create", "type": "order", "dish": "Laksa", "table": table}
        )
        assert made["servermsg"] == "ok", made
        await clock.advance(60.0 if i < 5 else 1.0)


async def test_a_recorded_day_replayed_with_one_and_two_robots(tmp_path: Path) -> None:
    grid, _ = load_demo()
    async with bare_server(tmp_path, app={"nav_map": grid, "plan_in_child": False}) as app:
        ws = await connect(app.url)
        await login(ws, username="owner", password=app.first_owner_password)
        empty = await request(
            ws, {"clientmsg": "stats", "action": "forecast", "day": "2020-01-01", "robots": [1]}
        )
        assert empty["code"] == "not_found", empty
        assert isinstance(app.clock, FakeClock)
        await record_day(ws, app.clock)
        await request(ws, {"clientmsg": "data", "topics": ["forecast"]})
        started = await request(
            ws, {"clientmsg": "stats", "action": "forecast", "day": DAY, "robots": [1, 2]}
        )
        assert started["servermsg"] == "ok", started
        fc = started["forecast"]
        assert (fc["dishes"], fc["state"]) == (6, "running")
        again = await request(
            ws, {"clientmsg": "stats", "action": "forecast", "day": DAY, "robots": [3]}
        )
        assert again["code"] == "conflict"
        done = await _until(ws, lambda d: d["state"] != "running")
        assert done["state"] == "done", done
        one, two = done["fleets"]
        assert (one["robots"], two["robots"]) == (1, 2)
        for fleet in (one, two):
            assert fleet["state"] == "done" and fleet["delivered"] == 6, fleet
            assert fleet["wait_mean"] > 0
        # Two robots never make the day's waits longer than one.
        assert two["wait_mean"] <= one["wait_mean"] + 1.0
        snap = await request(ws, {"clientmsg": "data", "topics": ["forecast"]})
        assert snap["data"]["forecast"]["id"] == fc["id"]
        none = await request(ws, {"clientmsg": "stats", "action": "forecast_cancel"})
        assert none["code"] == "not_found"
        # Cancelled while its first replay runs: that child is stopped, nothing is left running.
        await request(
            ws, {"clientmsg": "stats", "action": "forecast", "day": DAY, "robots": [1, 2, 3]}
        )
        await _until(ws, lambda d: d["fleets"][0]["state"] == "running")
        stopped = await request(ws, {"clientmsg": "stats", "action": "forecast_cancel"})
        assert stopped["forecast"]["state"] == "cancelled", stopped
        assert [f["state"] for f in stopped["forecast"]["fleets"]] == ["cancelled"] * 3
        staff = await connect(app.url)
        await login(staff, token=await app.issue_token("staff"))
        refused = await request(
            staff, {"clientmsg": "stats", "action": "forecast", "day": DAY, "robots": [1]}
        )
        assert refused["code"] == "forbidden"
        await staff.close()
        await ws.close()
