"""Refusals a client can rely on (docs/protocol.md): every ``invalid_field`` carries
``details.errors`` as a list of ``{loc, msg, type}``, and a manual goal the robot could never
reach is refused at once with ``unreachable`` instead of failing later through ``last_error``.
"""

from __future__ import annotations

import json
from typing import Any

from websockets.asyncio.client import connect

from tests.conftest import Restaurant
from tests.test_e2e import activate, staff


async def raw_reply(r: Restaurant, frame: str) -> dict[str, Any]:
    async with connect(r.app.url, additional_headers=r.auth_headers()) as ws:
        await ws.send(frame)
        while True:
            msg = json.loads(await ws.recv())
            if msg.get("servermsg") in ("ok", "error"):
                return msg


def assert_errors_list(reply: dict[str, Any], type_: str) -> None:
    assert reply["code"] == "invalid_field", reply
    errors = reply["details"]["errors"]
    assert isinstance(errors, list) and errors, reply
    for e in errors:
        assert set(e) == {"loc", "msg", "type"}, e
        assert isinstance(e["loc"], list) and isinstance(e["msg"], str)
    assert errors[0]["type"] == type_, errors


async def test_every_invalid_field_has_a_list_of_errors(one_robot: Restaurant) -> None:
    dup = await raw_reply(one_robot, '{"clientmsg":"stop","id":7,"robot":"r1","robot":"r2"}')
    assert dup["id"] == 7
    assert_errors_list(dup, "duplicate_key")
    assert dup["details"]["errors"][0]["loc"] == ["robot"]
    deep = await raw_reply(
        one_robot, '{"clientmsg":"stop","id":8,"robot":"r1","x":' + "[" * 25 + "]" * 25 + "}"
    )
    assert deep["id"] == 8
    assert_errors_list(deep, "too_deep")
    typed = await raw_reply(one_robot, '{"clientmsg":"stop","id":9,"robot":5}')
    assert_errors_list(typed, typed["details"]["errors"][0]["type"])


async def test_a_manual_goal_off_the_map_or_in_a_wall_is_unreachable_at_once(
    one_robot: Restaurant,
) -> None:
    c = await staff(one_robot)
    await activate(c, "r1")
    await c.ok("ready", robot="r1")
    await c.ok("control", robot="r1", action="manual")
    await c.status("r1", "Manual")
    robot = one_robot.sim.robots[0]
    before = list(robot.goal_statuses)
    err = await c.error(
        "control", "unreachable", robot="r1", action="goal", x=-500.0, y=-500.0, yaw=0.0
    )
    assert err["details"]["reason"] == "outside_map"
    assert (err["details"]["x"], err["details"]["y"]) == (-500.0, -500.0)
    # (-0.5, -0.5): the map's border wall at the origin corner.
    err = await c.error(
        "control", "unreachable", robot="r1", action="goal", x=-0.6, y=-0.6, yaw=0.0
    )
    assert err["details"]["reason"] in ("occupied", "unknown")
    assert robot.goal_statuses == before  # nothing was sent to the robot
    assert c.robot("r1")["status"] == "Manual" and c.robot("r1")["last_error"] is None
