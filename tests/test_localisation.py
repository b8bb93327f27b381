"""A robot that no longer knows where it is (issue 28), through a real server and simulator,
ROS1 and ROS 2: it is marked lost, raises an alert and gets no trip until staff set where it
is; its particle cloud streams only while someone shows it; a robot without ``/amcl_pose``
takes its pose from tf.

Virtual time (tests/conftest.py ``VIRTUAL_TIME``): "no trip for ten seconds" costs the CPU
those seconds take, not the seconds.
"""

from __future__ import annotations

import math
from collections.abc import AsyncIterator
from pathlib import Path

import pytest

from serveur.core.runtime import CoreConfig
from serveur.maps.navigation import load_demo
from serveur.sim.sensors import CLOUD_PARTICLES, CLOUD_TOPICS
from tests.conftest import Client, Restaurant, poll_until, restaurant, subscribers

HOME = load_demo()[1]["home1"]


@pytest.fixture(params=[1, 2], ids=["ros1", "ros2"])
async def site(request: pytest.FixtureRequest, tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, robots=1, ros=request.param) as r:
        yield r


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "orders", "tasks", "alerts")
    await c.status("r1", "Ready")
    return c


def lost_alert(c: Client) -> dict | None:
    for a in c.records.get("alerts", {}).values():
        if a["kind"] == "robot_lost" and a["subject"] == "r1" and a.get("cleared_at") is None:
            return a
    return None


async def test_a_lost_robot_gets_no_trip_until_staff_set_where_it_is(site: Restaurant) -> None:
    r, c = site, await staff(site)
    await c.ok("control", robot="r1", action="auto")
    await c.status("r1", "Awaiting")
    assert c.robot("r1")["lost"] is False

    r.sim.robots[0].lose_localisation()
    await c.until(lambda: c.robot("r1").get("lost") is True, what="r1 marked lost")
    alert = await c.until(lambda: lost_alert(c), what="the robot_lost alert")
    assert alert["severity"] == "critical" and "set where the robot is" in alert["message"]

    oid = (await c.ok("create", type="order", dish="Laksa", table="T3"))["order"]["id"]
    [task] = (await c.ok("create", type="task", orders=[oid]))["tasks"]
    await r.clock.sleep(10.0)  # a dispatcher round comes at every change; none gives it r1
    assert c.task(task["id"]).get("robot") is None and c.task(task["id"])["status"] == "queued"
    assert c.robot("r1")["status"] == "Awaiting"

    # Staff set where the robot is, from the map: manual control, the pose, back to work.
    await c.ok("ready", robot="r1")
    await c.ok("control", robot="r1", action="manual")
    x, y, yaw = r.sim.robots[0].pose
    await c.ok("control", robot="r1", action="initialpose", x=x, y=y, yaw=yaw)
    await c.until(lambda: c.robot("r1").get("lost") is False, what="r1 sure again")
    await c.until(lambda: lost_alert(c) is None, what="the alert cleared")
    await c.ok("ready", robot="r1")
    await c.ok("control", robot="r1", action="auto")
    await c.until(lambda: c.task(task["id"]).get("robot") == "r1", what="the trip given to r1")


async def test_go_is_refused_to_a_robot_that_is_lost_at_the_pass(tmp_path: Path) -> None:
    config = CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=False)
    async with restaurant(tmp_path, config=config) as r:
        c = await staff(r)
        await c.ok("control", robot="r1", action="auto")
        oid = (await c.ok("create", type="order", dish="Laksa", table="T3"))["order"]["id"]
        await c.ok("create", type="task", orders=[oid])
        await c.status("r1", "Loading")
        r.sim.robots[0].lose_localisation()
        await c.until(lambda: c.robot("r1").get("lost") is True, what="r1 marked lost")
        err = await c.error("go", "conflict", robot="r1")
        assert err["details"]["reason"] == "lost" and "set where the robot is" in err["message"]
        assert c.robot("r1")["status"] == "Loading" and r.sim.robots[0].navigator.active is None


async def test_the_particle_cloud_streams_only_while_shown(site: Restaurant) -> None:
    r, c = site, await staff(site)
    sim_robot = r.sim.robots[0]
    topic = CLOUD_TOPICS[sim_robot.ros]
    assert subscribers(r.sim, topic) == 0
    await c.subscribe("cloud:r1")
    await poll_until(lambda: subscribers(r.sim, topic) == 1, 10.0, "the robot's cloud subscribed")
    cloud = await c.until(lambda: c.streams.get("cloud:r1"), what="a particle cloud")
    assert cloud["count"] == CLOUD_PARTICLES and 0 < len(cloud["particles"]) <= 300
    x, y, _ = sim_robot.pose
    px = [p[0] for p in cloud["particles"]]
    py = [p[1] for p in cloud["particles"]]
    assert math.hypot(sum(px) / len(px) - x, sum(py) / len(py) - y) < 0.1  # tight, here

    # Lost: the cloud spreads over metres, and its spread alone marks the robot lost.
    sim_robot.lose_localisation(metres=2.5, radians=0.2)
    spread = await c.until(
        lambda: (s := c.streams["cloud:r1"]["particles"]) and max(abs(p[0] - x) for p in s) > 2.0,
        what="the cloud spread out",
    )
    assert spread and c.robot("r1")["lost"] is True

    await c.ok("data", topics=["cloud:r1"], unsubscribe=True)
    await poll_until(lambda: subscribers(r.sim, topic) == 0, 10.0, "the cloud unsubscribed")


@pytest.mark.parametrize("ros", [1, 2], ids=["ros1", "ros2"])
async def test_a_robot_without_amcl_pose_takes_its_pose_from_tf(tmp_path: Path, ros: int) -> None:
    async with restaurant(tmp_path, link={"tf": "base_footprint"}, ros=ros) as r:
        c = await staff(r)
        assert subscribers(r.sim, "/amcl_pose") == 0 and subscribers(r.sim, "/tf") == 1
        rb = c.robot("r1")
        assert math.hypot(rb["x"] - HOME.x, rb["y"] - HOME.y) < 0.1
        await c.ok("control", robot="r1", action="manual")
        await c.ok("control", robot="r1", action="goto", waypoint="T3")
        t3 = load_demo()[1]["T3"]
        sim_robot = r.sim.robots[0]
        await poll_until(
            lambda: math.hypot(sim_robot.pose[0] - t3.x, sim_robot.pose[1] - t3.y) < 0.3,
            120.0,
            "the robot at T3",
        )
        await c.subscribe("pose:r1")
        pose = await c.until(
            lambda: (
                (p := c.streams.get("pose:r1"))
                and math.hypot(p["x"] - sim_robot.pose[0], p["y"] - sim_robot.pose[1]) < 0.05
            ),
            what="the tf pose where the robot is",
        )
        assert pose
