"""The robot link asks for /amcl_pose at full rate only while someone watches or it moves,
and for /move_base/status at full rate only while the robot has a goal.

An idle server with ten parked robots spent most of its CPU decoding 10 Hz AMCL poses that
nobody looked at; docs/performance.md has the figures. These tests read the throttle the
simulated rosbridge applies to the server's subscription, so they break if the link stops
slowing the stream down, or stops restoring full rate for a watcher or a moving robot.
"""

from __future__ import annotations

import asyncio
from collections.abc import Callable

from serveur.robots.ros1.link import IDLE_POSE_MS, IDLE_STATUS_MS
from tests.conftest import WAIT, Restaurant
from tests.test_e2e import activate, new_orders, staff


def pose_throttle(r: Restaurant, topic: str = "/amcl_pose") -> float | None:
    """Seconds between ``topic`` messages the simulator grants the server (None: none)."""
    subs = r.sim.robots[0]._subs.get(topic, [])
    return min(s.throttle for s in subs) if subs else None


def status_throttle(r: Restaurant) -> float | None:
    return pose_throttle(r, "/move_base/status")


async def eventually(cond: Callable[[], bool], what: str) -> None:
    for _ in range(int(WAIT / 0.02)):
        if cond():
            return
        await asyncio.sleep(0.02)
    raise AssertionError(f"timed out waiting for {what}")


async def test_pose_is_throttled_while_parked_and_unwatched(one_robot: Restaurant) -> None:
    c = await staff(one_robot)
    await activate(c, "r1")
    idle = IDLE_POSE_MS / 1000
    await eventually(lambda: pose_throttle(one_robot) == idle, "idle pose rate")
    await c.subscribe("pose:r1")
    await eventually(lambda: pose_throttle(one_robot) == 0.0, "full rate for a watcher")
    await c.ok("data", topics=["pose:r1"], unsubscribe=True)
    await eventually(lambda: pose_throttle(one_robot) == idle, "idle rate again")


async def test_pose_is_full_rate_while_the_robot_drives(one_robot: Restaurant) -> None:
    c = await staff(one_robot)
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T6"))
    await c.ok("create", type="task", orders=ids)
    assert status_throttle(one_robot) == IDLE_STATUS_MS / 1000  # parked: heartbeat only
    await c.status("r1", "Delivering")
    await eventually(lambda: pose_throttle(one_robot) == 0.0, "full rate while driving")
    assert status_throttle(one_robot) == 0.0  # set before the goal went out
    await c.status("r1", "Delivered")  # arrived: parked at the table, nobody watching
    await eventually(lambda: pose_throttle(one_robot) == IDLE_POSE_MS / 1000, "idle at table")
    await eventually(lambda: status_throttle(one_robot) == IDLE_STATUS_MS / 1000, "idle status")


class _Quiet:
    """A link listener that ignores everything (the test reads the simulator's side)."""

    def __getattr__(self, name: str) -> Callable[..., None]:
        return lambda *args: None


async def test_replay_throttles_reach_the_robot() -> None:
    """What ``serveur replay`` asks for at high time scales: slow status, 2 Hz moving pose."""
    from serveur.clock import ScaledClock
    from serveur.maps.navigation import demo_map_path
    from serveur.robot_sim import start_simulation
    from serveur.robots.ros1.link import RobotLink

    clock = ScaledClock(10.0)
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), clock=clock)
    link = RobotLink(
        "r1", sim.urls[0], _Quiet(), clock, moving_pose_ms=500, status_ms=1000, battery_ms=30_000
    )
    subs = sim.robots[0]._subs

    def throttle(topic: str) -> float | None:
        return min((s.throttle for s in subs.get(topic, [])), default=None)

    try:
        link.start()
        await eventually(lambda: link.up, "link up")
        assert throttle("/move_base/status") == 1.0
        assert throttle("/battery_state") == 30.0
        assert throttle("/amcl_pose") == IDLE_POSE_MS / 1000
        await link.send_goal(6.1, 7.3, 0.0)
        await eventually(lambda: throttle("/amcl_pose") == 0.5, "2 Hz while moving")
        await link.want_pose(True)  # a watcher always gets every pose
        await eventually(lambda: throttle("/amcl_pose") == 0.0, "full rate for a watcher")
    finally:
        await link.close()
        await sim.close()
