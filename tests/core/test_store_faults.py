"""A store that cannot write for a while (disk full, an I/O error) loses no robot report.

The store is made to refuse every write with SQLite's ``query_only`` pragma on the server's own
connection: each write then fails inside SQLite exactly as a full disk's does (an
``OperationalError`` from the statement, the transaction rolled back), deterministically,
without filling the test machine's disk.
"""

from __future__ import annotations

import asyncio
import math

from serveur.maps.navigation import load_demo
from serveur.robots import rosbridge as rb
from tests.conftest import Restaurant, poll_until
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

_, WAYPOINTS = load_demo()


async def writable(r: Restaurant, on: bool) -> None:
    db = r.app.store._db  # type: ignore[attr-defined]
    await db.execute(f"PRAGMA query_only = {0 if on else 1}")


async def test_a_goal_result_the_store_could_not_write_is_applied_when_it_can(
    one_robot: Restaurant,
) -> None:
    r = one_robot
    c = await staff(r)
    await activate(c, "r1")
    [oid] = await new_orders(c, ("Laksa", "T6"))
    await c.ok("create", type="task", orders=[oid])
    await c.status("r1", "Delivering")
    await writable(r, False)
    robot = r.sim.robots[0]
    t6 = WAYPOINTS["T6"]
    await poll_until(
        lambda: (
            robot.goal_statuses
            and robot.goal_statuses[-1][1] is rb.GoalStatus.SUCCEEDED
            and math.hypot(robot.pose[0] - t6.x, robot.pose[1] - t6.y) < 0.5
        ),
        30.0,
        "the robot at T6",
    )
    # The result arrived while the disk was "full": nothing is applied yet, nothing dropped.
    await asyncio.sleep(1.0)  # a few of the worker's retries (0.5 s, 1 s, ... wall)
    assert c.robot("r1")["status"] == "Delivering"
    await writable(r, True)
    await c.status("r1", "Delivered")
    stop = await serve_current_stop(c, "r1")
    assert stop["table"] == "T6"
    await c.until(lambda: c.order(oid).get("status") == "delivered", what="delivered")
    await c.status("r1", "Awaiting")
