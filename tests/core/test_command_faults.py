"""A robot that says it arrived but is not where it was sent ends in Error, not Delivered.

(Goals never acknowledged and goals aborted by a blocked aisle: tests/robots/test_link_faults.py.)
"""

from __future__ import annotations

from typing import Any

import pytest

from tests import invariants
from tests.conftest import Restaurant
from tests.test_e2e import activate, near, new_orders, staff


async def test_arrival_reported_far_from_the_goal_is_an_error(
    one_robot: Restaurant, monkeypatch: pytest.MonkeyPatch
) -> None:
    r = one_robot
    robot = r.sim.robots[0]
    c = await staff(r)
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T6"))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    # Its localisation drifts 2 m: move_base reaches the goal, AMCL says it is elsewhere.
    true_amcl = robot._build_amcl

    def drifted(seq: int, stamp: float) -> dict[str, Any]:
        msg = true_amcl(seq, stamp)
        msg["pose"]["pose"]["position"]["x"] += 2.0
        return msg

    monkeypatch.setattr(robot, "_build_amcl", drifted)
    failed = await c.status("r1", "Error")
    assert (
        failed["last_error"].startswith("robot reports arriving")
        and "m from T6" in failed["last_error"]
    )
    assert c.order(ids[0])["status"] == "assigned"  # not delivered on a false arrival
    assert c.task(failed["current_task"])["stops"][0]["status"] == "pending"
    # Staff recalibrate (here: the drift ends) and cancel: the dish goes back to the pass.
    monkeypatch.setattr(robot, "_build_amcl", true_amcl)
    await c.ok("cancel", robot="r1")
    await c.until(lambda: c.order(ids[0]).get("status") == "pending", what="dish pending")
    await c.status("r1", "Awaiting")
    assert near(c.robot("r1"), "home1")
    invariants.check_deliveries(invariants.read(r.db))
