"""The robot link against what real robots and real Wi-Fi do (issue: drive robots as the real
ROS stack behaves).

Each test here failed on the server before the fix it names: goals stamped with the server's
clock, a number out of range killing the link, a silent path noticed only after websockets'
10 s close timeout, a one-second Wi-Fi stall taking a delivering robot Offline, a joystick left
pushed when the tablet went quiet, a manual goal that kept driving under teleop.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect

from serveur.core.runtime import CoreConfig
from serveur.robots import rosbridge as rb
from tests.conftest import Client, Restaurant, restaurant
from tests.conftest import poll_until as until
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

# The defaults otherwise: the heartbeat a site gets.
CONFIG = CoreConfig(ack_timeout=3.0, auto_depart=True)


@contextlib.asynccontextmanager
async def robot_topic(r: Restaurant, topic: str) -> AsyncIterator[list[dict[str, Any]]]:
    """What the robot's rosbridge delivers on ``topic`` (a client's publishes are relayed)."""
    seen: list[dict[str, Any]] = []
    async with connect(r.sim.urls[0]) as ws:
        default = r.sim.robots[0].local(topic)
        await ws.send(rb.encode(rb.op_subscribe(topic, rb.TOPIC_TYPES[default])))

        async def read(ws: ClientConnection) -> None:
            async for frame in ws:
                op = json.loads(frame)
                if op.get("topic") == topic:
                    seen.append(op["msg"])

        reader = asyncio.create_task(read(ws))
        try:
            yield seen
        finally:
            reader.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await reader


@pytest.fixture
async def proxied(tmp_path: Path) -> AsyncIterator[Restaurant]:
    async with restaurant(tmp_path, proxied=True, config=CONFIG) as r:
        yield r


async def deliver(c: Client, table: str) -> list[int]:
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", table))
    await c.ok("create", type="task", orders=ids)
    await c.status("r1", "Delivering")
    return ids


async def test_goals_go_out_with_a_zero_stamp(one_robot: Restaurant) -> None:
    # SimpleActionServer recalls a goal stamped before the last one it accepted, and the
    # server's clock (no RTC on a Pi) can be minutes behind the robot's: actionlib stamps a
    # zero-stamped goal with the robot's own clock instead.
    c = await staff(one_robot)
    async with robot_topic(one_robot, "/move_base/goal") as goals:
        await deliver(c, "T6")
        await until(lambda: goals, 10.0, "the goal on the robot")
    assert goals[0]["goal_id"]["stamp"] == {"secs": 0, "nsecs": 0}
    assert goals[0]["goal"]["target_pose"]["header"]["frame_id"] == "map"


async def test_numbers_out_of_range_from_a_robot_do_not_kill_its_link(
    proxied: Restaurant,
) -> None:
    c = await staff(proxied)
    await c.status("r1", "Ready")
    proxy = proxied.proxies[0]
    huge = "1" + "0" * 400
    frames = [
        '{"op":"publish","topic":"/move_base/status","msg":{"header":{"seq":1,'
        '"stamp":{"secs":0,"nsecs":0},"frame_id":""},"status_list":[{"goal_id":'
        '{"stamp":{"secs":0,"nsecs":0},"id":"g"},"status":1e999,"text":""}]}}',
        '{"op":"publish","topic":"/battery_state","msg":{"percentage":' + huge + "}}",
        '{"op":"publish","topic":"/amcl_pose","msg":{"header":{"seq":1,"stamp":{"secs":'
        + huge
        + ',"nsecs":0},"frame_id":"map"},"pose":{"pose":{"position":{"x":1,"y":1,"z":0},'
        '"orientation":{"x":0,"y":0,"z":0,"w":1}},"covariance":[]}}}',
        '{"op":"publish","topic":"/amcl_pose","msg":{"header":{"seq":1,"stamp":{"secs":0,'
        '"nsecs":0},"frame_id":"map"},"pose":{"pose":{"position":{"x":' + huge + ',"y":1,'
        '"z":0},"orientation":{"x":0,"y":0,"z":0,"w":1}},"covariance":[]}}}',
    ]
    for frame in frames:
        assert await proxy.inject(frame) == 1
    # The link read on: a delivery goes out on the same connection and the robot drives it.
    await deliver(c, "T6")
    link = proxied.app.core._rt["r1"].link  # type: ignore[union-attr]
    assert link is not None and link.connects == 1 and proxy.connections == 1
    await c.until(lambda: c.robot("r1").get("current_stop") is not None or True)
    await c.status("r1", "Delivered")


@pytest.mark.cuts_links
async def test_a_silent_path_is_offline_within_the_heartbeat(proxied: Restaurant) -> None:
    c = await staff(proxied)
    await c.status("r1", "Ready")
    # docs/robots.md: two idle status periods (0.5 s, robot time) plus the 2 s (wall) Wi-Fi
    # stall allowance; on this module's virtual time a wall second is a clock second.
    scale = proxied.clock.time_scale
    limit = 2 * 0.5 + 2.0 * scale  # clock seconds
    link = proxied.app.core._rt["r1"].link  # type: ignore[union-attr]
    assert getattr(link, "heartbeat_timeout", lambda: limit)() == limit
    t0 = proxied.clock.now()
    proxied.proxies[0].blackhole()
    await c.status("r1", "Offline", timeout=limit + 5.0)
    took = proxied.clock.now() - t0
    # Before: "no move_base status", then ten seconds in websockets' closing handshake.
    assert took <= limit + 0.8 * scale, f"Offline after {took:.1f}s (heartbeat {limit:.1f}s)"
    proxied.proxies[0].resume()
    await c.status("r1", "Ready")


async def test_a_wifi_stall_shorter_than_the_allowance_loses_no_delivery(
    proxied: Restaurant,
) -> None:
    c = await staff(proxied)
    await deliver(c, "T16")
    proxy = proxied.proxies[0]
    for _ in range(2):  # two stalls of 1.2 wall seconds while the robot drives
        proxy.stall()
        await asyncio.sleep(1.2)  # the fault's length, not a wait for a result
        proxy.resume()
        await asyncio.sleep(0.3)
    await c.status("r1", "Delivered")
    statuses = [
        f["data"]["status"]
        for f in c.frames
        if f.get("topic") == "robots" and isinstance(f.get("data"), dict)
    ]
    assert "Offline" not in statuses, statuses
    link = proxied.app.core._rt["r1"].link  # type: ignore[union-attr]
    assert link is not None and link.connects == 1


async def manual(c: Client) -> None:
    await activate(c, "r1")
    await c.ok("ready", robot="r1")
    await c.status("r1", "Ready")
    await c.ok("control", robot="r1", action="manual")
    await c.status("r1", "Manual")


async def test_the_server_stops_a_robot_whose_joystick_went_quiet(any_robot: Restaurant) -> None:
    # ROS1 and ROS 2 drivers share the dead man's switch (serveur.robots.deadman).
    one_robot = any_robot
    c = await staff(one_robot)
    await manual(c)
    async with robot_topic(one_robot, "/cmd_vel") as twists:
        await c.ok("control", robot="r1", action="teleop", vx=-0.3, vy=0.0, wz=0.0)
        sent = asyncio.get_running_loop().time()
        await until(lambda: twists and twists[-1]["linear"]["x"] == 0.0, 3.0, "a zero twist")
        took = asyncio.get_running_loop().time() - sent
    assert twists[0]["linear"]["x"] == -0.3
    assert took <= 0.5 + 0.3, f"stopped {took:.2f}s after the last joystick command"


async def test_teleop_during_a_manual_goal_cancels_the_goal(one_robot: Restaurant) -> None:
    # Real move_base does not listen to /cmd_vel: the goal would keep the robot driving.
    c = await staff(one_robot)
    await manual(c)
    robot = one_robot.sim.robots[0]
    await c.ok("control", robot="r1", action="goto", waypoint="T16")
    await until(
        lambda: any(st is rb.GoalStatus.ACTIVE for _, st, _ in robot.goal_statuses), 10.0, "active"
    )
    await c.ok("control", robot="r1", action="teleop", vx=0.0, vy=0.0, wz=0.3)
    await until(
        lambda: all(st in rb.TERMINAL_STATUSES for _, st, _ in robot.goal_statuses),
        5.0,
        "the goal cancelled",
    )
    (_, status, text) = robot.goal_statuses[-1]
    assert status in (rb.GoalStatus.PREEMPTED, rb.GoalStatus.RECALLED)
    assert "cmd_vel" not in text  # cancelled by the server, not by the simulator's teleop


async def test_a_namespaced_robot_is_driven_under_its_own_names(tmp_path: Path) -> None:
    # Robots on one ROS master are namespaced: /r1/move_base/goal, /r1/amcl_pose, ...
    async with restaurant(tmp_path, namespaced=True) as r:
        assert r.sim.robots[0].namespace == "/r1"
        assert dict(r.specs[0].link) == {"ns": "/r1"}
        c = await staff(r)
        async with robot_topic(r, "/r1/move_base/goal") as goals:
            await deliver(c, "T6")
            await c.status("r1", "Delivered")
        assert goals and goals[0]["goal"]["target_pose"]["header"]["frame_id"] == "map"
        stop = await serve_current_stop(c, "r1")
        assert stop["table"] == "T6"
        await c.status("r1", "Awaiting")
