"""What a lost goal means for the robot and its table depends on why it was lost.

The drivers say why (:class:`~serveur.robots.driver.GoalLoss`). A link that failed under the
goal says nothing of the table: a real ROS 2 stack whose bridge lost its ROS side made the old
core put the robot in Error and block a table that was fine (issue 27). A goal the robot never
took says its navigation is broken, not the table's way. Only a navigation failure blocks the
table. Real core and server, a staff client on a socket, a fake robot (no robot socket).
"""

from __future__ import annotations

from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from serveur.app import RobotSpec
from serveur.maps.navigation import load_demo
from serveur.robots.driver import GoalLoss
from serveur.robots.fake import FakeDriver
from tests.conftest import Client, Restaurant, make_app, test_clock
from tests.test_e2e import activate, new_orders, staff


@pytest.fixture
async def fake_robot(tmp_path: Path) -> AsyncIterator[Restaurant]:
    home = load_demo()[1]["home1"]
    url = f"fake://r1?x={home.x}&y={home.y}&yaw={home.yaw}&speed=0.5"
    clock = test_clock(20.0)
    app = make_app(tmp_path / "serveur.db", clock, [RobotSpec("r1", url, "home1")])
    await app.start()
    r = Restaurant(app, None, clock, tmp_path / "serveur.db", [], [])
    r.token = await app.issue_token("staff", label="tests")
    try:
        yield r
    finally:
        for c in r.clients:
            await c.close()
        await app.close()


def _robot(r: Restaurant) -> FakeDriver:
    assert r.app.core is not None
    link = r.app.core._rt["r1"].link
    assert isinstance(link, FakeDriver)
    return link


async def _delivering(r: Restaurant) -> Client:
    c = await staff(r)
    await c.subscribe("blocks")
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T6"))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    return c


async def test_a_goal_lost_with_the_link_blocks_nothing_and_is_sent_again(
    fake_robot: Restaurant,
) -> None:
    c = await _delivering(fake_robot)
    _robot(fake_robot).lose_goal("the bridge's ROS side stopped", cause=GoalLoss.LINK)
    await c.status("r1", "Delivered")  # driven again: it got there
    assert not c.records.get("blocks")
    assert all(f["data"].get("status") != "Error" for f in c.frames if f.get("topic") == "robots")


async def test_a_goal_the_robot_never_took_is_its_failure_not_the_tables(
    fake_robot: Restaurant,
) -> None:
    c = await staff(fake_robot)
    await c.subscribe("blocks")
    await activate(c, "r1")
    _robot(fake_robot).refuse_next_goal("goal not acknowledged by Nav2 after 3 attempts")
    ids = await new_orders(c, ("Laksa", "T6"))
    await c.ok("create", type="task", orders=ids)
    robot = await c.status("r1", "Error")
    assert robot["last_error"] == "goal lost: goal not acknowledged by Nav2 after 3 attempts"
    await c.ok("ping")
    assert not c.records.get("blocks"), c.records.get("blocks")


async def test_a_navigation_failure_blocks_the_table_in_the_drivers_words(
    fake_robot: Restaurant,
) -> None:
    c = await _delivering(fake_robot)
    _robot(fake_robot).abort_goal("Nav2 navigate_to_pose ABORTED: no valid path (error 204)")
    robot = await c.status("r1", "Error")
    assert robot["last_error"] == "Nav2 navigate_to_pose ABORTED: no valid path (error 204)"
    await c.until(lambda: "T6" in c.records.get("blocks", {}), what="T6 blocked")
    assert c.records["blocks"]["T6"]["reason"] == (
        "r1: Nav2 navigate_to_pose ABORTED: no valid path (error 204)"
    )
