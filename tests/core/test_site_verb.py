"""The ``site`` verb: an owner edits and removes robots and waypoints, sets the site's settings
and searches the audit trail, over the protocol, against a real server and database.

Each refusal changes nothing: a table with an open order is not removed, a robot on a trip
keeps its address, staff may not ask at all.
"""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

from websockets.asyncio.client import ClientConnection, connect

from serveur.app import App
from serveur.clock import FakeClock
from serveur.maps.navigation import load_demo
from serveur.security.sessions import CLOSE_AUTH, SecurityConfig
from tests.security.test_security import bare_server, closed_code, login, request

WAIT = 10.0


def _site(action: str, **fields: Any) -> dict[str, Any]:
    return {"clientmsg": "site", "action": action, **fields}


async def _owner(app: App) -> ClientConnection:
    ws = await connect(app.url)
    reply = await login(ws, username="owner", password=app.first_owner_password)
    assert reply["servermsg"] == "ok", reply
    return ws


async def _robot_where(ws: ClientConnection, pred: Any) -> dict[str, Any]:
    """The first robot record satisfying ``pred``: in a fresh snapshot, else in an update."""
    snap = await request(ws, {"clientmsg": "data", "topics": ["robots"]})
    for r in snap["data"]["robots"]:
        if pred(r):
            return r  # type: ignore[no-any-return]

    async def wait() -> dict[str, Any]:
        while True:
            msg = json.loads(await ws.recv())
            if msg.get("servermsg") == "update" and msg["topic"] == "robots" and pred(msg["data"]):
                return msg["data"]  # type: ignore[no-any-return]

    return await asyncio.wait_for(wait(), WAIT)


async def test_a_robot_at_a_wrong_address_says_why_is_fixed_then_removed(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws = await _owner(app)
        await request(ws, {"clientmsg": "data", "topics": ["robots"]})
        # Port 9 on loopback: nothing listens there, the connection is refused.
        made = await request(
            ws, {"clientmsg": "create", "type": "robot", "name": "r9", "url": "ws://127.0.0.1:9"}
        )
        assert made["servermsg"] == "ok", made
        bad = await _robot_where(ws, lambda r: r["name"] == "r9" and r["link_error"])
        assert "refused" in bad["link_error"].lower() or "connect" in bad["link_error"].lower()
        # The owner corrects the address: the link starts again (still nothing there: a new
        # reason is reported for the new address).
        edited = await request(ws, _site("edit_robot", robot="r9", url="ws://127.0.0.1:10"))
        assert edited["robot"]["url"] == "ws://127.0.0.1:10", edited
        await _robot_where(ws, lambda r: r["link_error"] and "127.0.0.1', 10" in r["link_error"])
        # Home and trays change without a reconnect; null trays: the site's.
        edited = await request(ws, _site("edit_robot", robot="r9", home="home2", trays=2))
        assert (edited["robot"]["home"], edited["robot"]["trays"]) == ("home2", 2)
        edited = await request(ws, _site("edit_robot", robot="r9", trays=None))
        assert edited["robot"]["trays"] is None
        bad_home = await request(ws, _site("edit_robot", robot="r9", home="nowhere"))
        assert bad_home["code"] == "not_found"
        nothing = await request(ws, _site("edit_robot", robot="r9"))
        assert nothing["code"] == "invalid_field"
        # A robot-screen token for it ends with the robot.
        token = await app.issue_token("robot-screen", robot="r9")
        screen = await connect(app.url)
        assert (await login(screen, token=token))["servermsg"] == "ok"
        removed = await request(ws, _site("remove_robot", robot="r9"))
        assert removed["robot"]["removed"] is True and len(removed["revoked"]) == 1, removed
        assert await closed_code(screen) == CLOSE_AUTH
        gone = await request(ws, {"clientmsg": "data", "topics": ["robots"]})
        assert gone["data"]["robots"] == []
        again = await request(ws, _site("remove_robot", robot="r9"))
        assert again["code"] == "not_found"
        # The name may be registered again: a fresh robot, history kept.
        back = await request(
            ws, {"clientmsg": "create", "type": "robot", "name": "r9", "url": "ws://127.0.0.1:11"}
        )
        assert back["robot"]["url"] == "ws://127.0.0.1:11" and back["robot"]["home"] is None
        await ws.close()


async def test_a_table_with_an_open_order_moves_on_rename_and_is_not_removed(
    tmp_path: Path,
) -> None:
    async with bare_server(tmp_path) as app:
        ws = await _owner(app)
        order = await request(
            ws, {"clientmsg": "create", "type": "order", "dish": "Laksa", "table": "T3"}
        )
        oid = order["order"]["id"]
        deps = await request(ws, _site("dependents", waypoint="T3"))
        assert deps["dependents"]["orders"] == [oid] and deps["dependents"]["trips"] == []
        refused = await request(ws, _site("remove_waypoint", waypoint="T3"))
        assert refused["code"] == "conflict" and refused["details"]["orders"] == [oid]
        still = await request(ws, {"clientmsg": "data", "topics": ["waypoints"]})
        assert "T3" in [w["name"] for w in still["data"]["waypoints"]]
        taken = await request(ws, _site("rename_waypoint", waypoint="T3", name="T4"))
        assert taken["code"] == "conflict"
        renamed = await request(ws, _site("rename_waypoint", waypoint="T3", name="Patio 3"))
        assert renamed["waypoint"]["name"] == "Patio 3" and renamed["renamed"] == "T3"
        orders = await request(ws, {"clientmsg": "data", "topics": ["orders"]})
        assert [(o["id"], o["table"]) for o in orders["data"]["orders"]] == [(oid, "Patio 3")]
        assert (await request(ws, {"clientmsg": "order", "table": "T3"}))["code"] == "not_found"
        # A table nothing depends on is removed; its table screen's token is revoked.
        token = await app.issue_token("table-screen", table="T5")
        removed = await request(ws, _site("remove_waypoint", waypoint="T5"))
        assert removed["waypoint"]["removed"] is True and len(removed["revoked"]) == 1
        screen = await connect(app.url)
        assert (await login(screen, token=token))["code"] == "unauthorized"
        listed = await request(ws, {"clientmsg": "data", "topics": ["waypoints"]})
        names = [w["name"] for w in listed["data"]["waypoints"]]
        assert "T5" not in names and "T3" not in names and "Patio 3" in names
        # A home is needed by nothing here: but a robot parked there keeps it.
        await request(
            ws,
            {
                "clientmsg": "create",
                "type": "robot",
                "name": "r1",
                "url": "ws://127.0.0.1:9",
                "home": "home1",
            },
        )
        parked = await request(ws, _site("remove_waypoint", waypoint="home1"))
        assert parked["code"] == "conflict" and parked["details"]["homes"] == ["r1"]
        await ws.close()


async def test_settings_apply_at_once_and_survive_a_restart(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws = await _owner(app)
        before = await request(ws, _site("settings"))
        assert before["settings"]["table_timeout"] == 180.0
        assert before["settings"]["target_wait"] == 600.0  # the default until the owner sets it
        await request(ws, {"clientmsg": "data", "topics": ["settings"]})
        changed = await request(
            ws,
            _site(
                "set_settings",
                table_timeout=60,
                trays=2,
                languages=["zh", "en"],
                language="zh",
                target_wait=480,
                call_escalate=60,
                charge_below=0.3,
            ),
        )
        assert changed["settings"] == {
            "table_timeout": 60.0,
            "trays": 2,
            "auto_depart": False,
            "languages": ["zh", "en"],
            "language": "zh",
            "cameras": True,
            "name": "",
            "public_url": None,
            "target_wait": 480.0,
            "call_escalate": 60.0,
            "bussing_wait": 120.0,
            "bussing_max_delay": 90.0,
            "charge_below": 0.3,
            "charge_until": 0.9,
            "cruise_pause": 20.0,
            "cruise_resume": 30.0,
        }
        assert app.core is not None and app.core.config.table_timeout == 60.0
        # A robot would charge below 50 % and stop at 40 %: refused, nothing changed.
        crossed = await request(ws, _site("set_settings", charge_below=0.5, charge_until=0.4))
        assert crossed["code"] == "invalid_field"
        crossed = await request(ws, _site("set_settings", charge_until=0.25))
        assert crossed["code"] == "invalid_field"  # below the charge_below already set
        assert app.core.config.charge_until == 0.9
        bad = await request(ws, _site("set_settings", languages=["en"], language="ms"))
        assert bad["code"] == "invalid_field"
        low = await request(ws, _site("set_settings", table_timeout=1))
        assert low["code"] == "invalid_field"
        await ws.close()
    _, waypoints = load_demo()
    app = App(
        tmp_path / "s.db", port=0, clock=FakeClock(), waypoints=waypoints, security=SecurityConfig()
    )
    await app.start()
    try:
        assert app.core is not None
        assert (app.core.config.table_timeout, app.core.config.capacity) == (60.0, 2)
        assert app.core.settings()["language"] == "zh"
        assert app.core.settings()["target_wait"] == 480.0
        assert app.core.config.call_escalate == 60.0 and app.core.config.charge_below == 0.3
    finally:
        await app.close()


async def test_audit_search_and_who_may_ask(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws = await _owner(app)
        await request(ws, _site("set_settings", trays=3))
        await request(ws, _site("remove_waypoint", waypoint="nowhere"))
        found = await request(ws, _site("audit", verb="site"))
        rows = found["audit"]
        assert [(a["data"].get("action"), a["outcome"]) for a in rows][:2] == [
            ("remove_waypoint", "not_found"),
            ("set_settings", "ok"),
        ]
        refused = await request(ws, _site("audit", verb="site", outcome="not_found"))
        assert [a["data"]["action"] for a in refused["audit"]] == ["remove_waypoint"]
        older = await request(ws, _site("audit", before=rows[0]["id"], limit=1))
        assert [a["id"] for a in older["audit"]] == [rows[1]["id"]]
        token = await app.issue_token("staff")
        staff = await connect(app.url)
        await login(staff, token=token)
        for action, fields in (
            ("settings", {}),
            ("audit", {}),
            ("remove_waypoint", {"waypoint": "T1"}),
        ):
            reply = await request(staff, _site(action, **fields))
            assert reply["code"] == "forbidden", (action, reply)
        await staff.close()
        await ws.close()


async def test_a_new_address_replies_offline_until_the_robot_answers(tmp_path: Path) -> None:
    """The reply to an address change is the robot after the edit: its old link is closed,
    so it is Offline (it said Ready while the link was already gone, Offline following on the
    topic), and it comes back to what it was doing once the new address answers."""
    from tests.conftest import Client, restaurant

    async with restaurant(tmp_path, robots=1) as r:
        token = await r.app.issue_token("integration", scopes=["site", "read", "control"])
        owner = Client(
            await connect(r.app.url, additional_headers={"Authorization": f"Bearer {token}"})
        )
        r.clients.append(owner)
        await owner.subscribe("robots")
        ready = await owner.status("r1", "Ready")
        url = ready["url"]
        moved = await owner.ok("site", action="edit_robot", robot="r1", url="ws://127.0.0.1:9")
        assert moved["robot"]["status"] == "Offline", moved
        assert owner.robot("r1")["status"] == "Offline"  # pushed before the reply
        await owner.until(lambda: owner.robot("r1").get("link_error"), what="the new link fails")
        assert owner.robot("r1")["status"] == "Offline"
        back = await owner.ok("site", action="edit_robot", robot="r1", url=url)
        assert back["robot"]["status"] == "Offline" and back["robot"]["url"] == url
        await owner.status("r1", "Ready")
