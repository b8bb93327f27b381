"""``robots_see_each_other``: every robot's footprint is an obstacle to the others (issue 21).

With the option on, a robot's ``/scan`` shows the other robots' discs, a robot never drives its
footprint into another's (it stops short and waits, plans around one standing still, and its
goal ABORTs after the patience), and two robots meeting head-on in an aisle one robot wide
deadlock: nothing in the simulator decides who gives way, as nothing does between two
move_base/Nav2 robots. With it off (the default) robots pass through each other, the model
every test and replay before it assumed.

Maps are made for each test in its tmp dir (map_server YAML + PGM, and a waypoints file for
the robots' homes). Time runs scaled; every wait is on a condition with a wall timeout, and a
hook on each robot's physics step records how close the robots ever came.
"""

from __future__ import annotations

import argparse
import json
import math
import re
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from serveur.clock import ScaledClock
from serveur.maps.mapio import OccupancyMap, save_map
from serveur.robot_sim import Simulation, add_sim_arguments, start_simulation
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.floor import ROBOT_CLEARANCE
from serveur.sim.robot import ROBOT_GAP, ROBOT_PATIENCE, SCAN_RAYS
from tests.conftest import poll_until
from tests.sim.test_sim_badinput import Raw, goal_op, open_raw, shut
from tests.sim.test_sim_ros2 import result, send_goal

SCALE = 20.0
WAIT = 10.0  # wall seconds; every wait ends as soon as its condition holds
PATIENCE = 6.0  # sim seconds: short, so the tests stay fast
RES = 0.05
RADIUS = 0.2  # the simulator's robot radius (the planner's)


def write_map(
    tmp: Path, name: str, free: np.ndarray, homes: list[tuple[float, float, float]]
) -> Path:
    """A map_server map (free cells where ``free``, walls elsewhere) and home1..homeN."""
    grid = np.where(free, 0, 100).astype(np.int8)
    yaml_path = tmp / f"{name}.yaml"
    save_map(OccupancyMap(grid, RES, (0.0, 0.0, 0.0)), yaml_path)
    wps = [
        {"name": f"home{i + 1}", "x": x, "y": y, "yaw": yaw} for i, (x, y, yaw) in enumerate(homes)
    ]
    (tmp / f"{name}_waypoints.json").write_text(json.dumps({"waypoints": wps}))
    return yaml_path


def room(tmp: Path, homes: list[tuple[float, float, float]]) -> Path:
    """An empty 6 m x 6 m room walled all round."""
    free = np.zeros((120, 120), dtype=bool)
    free[2:-2, 2:-2] = True
    return write_map(tmp, "room", free, homes)


def aisle(tmp: Path, homes: list[tuple[float, float, float]]) -> Path:
    """A 4.8 m aisle 0.5 m wide (y 0.5..1.0): one robot (0.4 m) fits, two cannot pass."""
    free = np.zeros((30, 100), dtype=bool)
    free[10:20, 2:98] = True
    return write_map(tmp, "aisle", free, homes)


async def start(map_path: Path, n: int, *, solid: bool, **kw: Any) -> Simulation:
    return await start_simulation(
        n,
        port=0,
        clock=ScaledClock(SCALE),
        map_path=map_path,
        seed=3,
        robots_see_each_other=solid,
        blocked_patience=PATIENCE,
        **kw,
    )


def watch_closest(sim: Simulation) -> list[float]:
    """[closest centre-to-centre distance of any two robots after any physics step so far]."""
    closest = [math.inf]
    for r in sim.robots:
        step = r._step

        def stepped(dt: float, r: Any = r, step: Any = step) -> None:
            step(dt)
            for o in sim.robots:
                if o is not r:
                    closest[0] = min(closest[0], math.dist(r.pose[:2], o.pose[:2]))

        r._step = stepped  # type: ignore[method-assign]
    return closest


async def ros1_goal(c: Raw, gid: str, x: float, y: float, yaw: float) -> None:
    await c.send(rb.op_subscribe("/move_base/result"))
    await c.ping()  # the subscription is in place before the goal can end
    await c.send(goal_op(gid, x, y, yaw))


async def ros1_result(c: Raw, gid: str) -> dict[str, Any]:
    msg = await c.topic("/move_base/result", lambda m: m["status"]["goal_id"]["id"] == gid)
    return msg["status"]  # type: ignore[no-any-return]


@pytest.fixture
async def sims() -> AsyncIterator[list[Simulation]]:
    made: list[Simulation] = []
    try:
        yield made
    finally:
        for s in made:
            await shut(s)


# -- (a) the laser sees the other robot ---------------------------------------------------------


@pytest.mark.parametrize("solid", [True, False])
async def test_scan_shows_a_robot_parked_in_front(
    tmp_path: Path, sims: list[Simulation], solid: bool
) -> None:
    # r1 at (1.5, 3) facing +x; r2 parked 1.5 m ahead; the wall ahead is 4.4 m away.
    sim = await start(room(tmp_path, [(1.5, 3.0, 0.0), (3.0, 3.0, math.pi)]), 2, solid=solid)
    sims.append(sim)
    c = await open_raw(sim, 0)
    await c.send(rb.op_subscribe("/scan"))
    scan = await c.topic("/scan")
    ranges = [math.inf if r is None else r for r in scan["ranges"]]
    ahead = round((0.0 - scan["angle_min"]) / scan["angle_increment"])  # bearing 0
    assert len(ranges) == SCAN_RAYS
    if not solid:  # the old model: the laser looks through robots, to the wall
        assert ranges[ahead] == pytest.approx(4.4, abs=0.06)
        return
    assert ranges[ahead] == pytest.approx(1.5 - RADIUS, abs=0.04)
    # The disc spans asin(0.2 / 1.5) = 7.7 degrees either side, closer at the middle.
    inc = math.degrees(scan["angle_increment"])
    for deg in (3, 6):
        ray = ahead + round(deg / inc)
        a = math.radians(deg)
        b = 1.5 * math.cos(a)
        expected = b - math.sqrt(b * b - (1.5**2 - RADIUS**2))
        assert ranges[ray] == pytest.approx(expected, abs=0.04)
        assert ranges[ahead - round(deg / inc)] == pytest.approx(expected, abs=0.04)
    beside = ahead + round(12 / inc)  # past the disc's edge: the wall
    assert ranges[beside] > 4.0


# -- (b) a robot driven at a parked one stops short, then goes around, or gives up -----------


async def test_a_robot_stops_short_of_a_parked_one_and_goes_around(
    tmp_path: Path, sims: list[Simulation]
) -> None:
    sim = await start(room(tmp_path, [(1.0, 3.0, 0.0), (3.0, 3.0, 0.0)]), 2, solid=True)
    sims.append(sim)
    closest = watch_closest(sim)
    r1, r2 = sim.robots
    c = await open_raw(sim, 0)
    await ros1_goal(c, "g", 5.0, 3.0, 0.0)  # the straight line runs through r2
    # It stops short of r2 and waits there (velocity 0), before any detour.
    await poll_until(
        lambda: r1.pose[0] > 2.0 and r1.velocity == (0.0, 0.0, 0.0), WAIT, "r1 stopped"
    )
    # Short of r2's footprint and the clearance a costmap keeps (issue 31), not touching it.
    stop = math.dist(r1.pose[:2], r2.pose[:2])
    assert 2 * RADIUS + ROBOT_CLEARANCE < stop <= 2 * RADIUS + ROBOT_CLEARANCE + ROBOT_GAP + 0.05
    status = await ros1_result(c, "g")
    assert status["status"] == rb.GoalStatus.SUCCEEDED, status
    assert math.dist(r1.pose[:2], (5.0, 3.0)) < 0.15  # around r2, to the goal
    assert r2.pose[:2] == (3.0, 3.0)  # never pushed
    assert closest[0] >= 2 * RADIUS + ROBOT_GAP  # not even on the detour


async def test_teleop_into_a_parked_robot_stops_at_its_footprint(
    tmp_path: Path, sims: list[Simulation]
) -> None:
    sim = await start(room(tmp_path, [(1.0, 3.0, 0.0), (2.5, 3.0, 0.0)]), 2, solid=True)
    sims.append(sim)
    closest = watch_closest(sim)
    r1, r2 = sim.robots
    c = await open_raw(sim, 0)
    # One command lasts CMD_VEL_TIMEOUT wall seconds (10 s of sim time at this scale).
    await c.send(rb.op_publish("/cmd_vel", rb.twist(0.5, 0.0, 0.0)))
    await poll_until(lambda: r1.pose[0] > 1.9 and r1.velocity[0] == 0.0, WAIT, "r1 stopped")
    # The base's safety stop: ROBOT_GAP short of r2's footprint, whatever it is told.
    near = math.dist(r1.pose[:2], r2.pose[:2])
    assert 2 * RADIUS + ROBOT_GAP - 1e-9 <= near < 2 * RADIUS + ROBOT_GAP + 0.05
    assert closest[0] >= 2 * RADIUS + ROBOT_GAP - 1e-9
    assert r2.pose[:2] == (2.5, 3.0)


async def test_a_robot_parked_on_the_goal_makes_it_abort_after_the_patience(
    tmp_path: Path, sims: list[Simulation]
) -> None:
    # A ROS 2 robot this time: Nav2's goal ends with action_result status 6 (ABORTED).
    sim = await start(room(tmp_path, [(1.0, 3.0, 0.0), (3.0, 3.0, 0.0)]), 2, solid=True, ros=2)
    sims.append(sim)
    closest = watch_closest(sim)
    r1, r2 = sim.robots
    c = await open_raw(sim, 0)
    await c.send(send_goal("g", (3.0, 3.0, 0.0)))
    await poll_until(lambda: r1.pose[0] > 2.0 and r1.velocity == (0.0, 0.0, 0.0), WAIT, "stop")
    stopped = sim.clock.now()
    res = await result(c, "g")
    assert sim.clock.now() - stopped >= PATIENCE - 0.5
    assert res["status"] == ros2.ABORTED and res["result"] is True
    assert res["values"]["error_code"] == ros2.FAILED_TO_MAKE_PROGRESS
    assert "blocked by another robot (r2)" in res["values"]["error_msg"]
    assert closest[0] >= 2 * RADIUS + ROBOT_GAP
    reach = 2 * RADIUS + ROBOT_CLEARANCE + ROBOT_GAP + 0.05
    assert math.dist(r1.pose[:2], r2.pose[:2]) <= reach


# -- (c) head-on in a narrow aisle: deadlock with the option, ghosts without -----------------


async def head_on(
    tmp_path: Path, sims: list[Simulation], *, solid: bool, kinematics: str = "omni"
) -> dict[str, Any]:
    """r1 (ROS1, move_base) and r2 (ROS 2, Nav2) swap ends of the aisle."""
    a, b = (0.6, 0.75, 0.0), (4.4, 0.75, math.pi)
    sim = await start(aisle(tmp_path, [a, b]), 2, solid=solid, ros=[1, 2], kinematics=kinematics)
    sims.append(sim)
    closest = watch_closest(sim)
    c1, c2 = await open_raw(sim, 0), await open_raw(sim, 1)
    t0 = sim.clock.now()
    await ros1_goal(c1, "r1-go", b[0], b[1], 0.0)
    await c2.send(send_goal("r2-go", (a[0], a[1], math.pi)))
    s1 = await ros1_result(c1, "r1-go")
    s2 = await result(c2, "r2-go")
    return {"sim": sim, "r1": s1, "r2": s2, "closest": closest[0], "took": sim.clock.now() - t0}


@pytest.mark.parametrize("kinematics", ["omni", "diff"])
async def test_head_on_in_a_narrow_aisle_deadlocks_when_robots_see_each_other(
    tmp_path: Path, sims: list[Simulation], kinematics: str
) -> None:
    out = await head_on(tmp_path, sims, solid=True, kinematics=kinematics)
    r1, r2 = out["sim"].robots
    # Both stopped facing each other, nose to nose, and neither got past the other...
    assert r1.pose[0] < r2.pose[0]
    reach = 2 * RADIUS + ROBOT_CLEARANCE + ROBOT_GAP + 0.05
    assert 2 * RADIUS + ROBOT_GAP <= math.dist(r1.pose[:2], r2.pose[:2]) <= reach
    assert out["closest"] >= 2 * RADIUS + ROBOT_GAP - 1e-9  # never closer, at any step
    # ...then both goals aborted after the patience: move_base ABORTED (4), Nav2 status 6.
    assert out["took"] >= PATIENCE
    assert out["r1"]["status"] == rb.GoalStatus.ABORTED
    # The patience (6 s here), counted in whole physics steps from the stop: 6 or 7 s said.
    assert re.fullmatch(r"blocked by another robot \(r2\) for [67] s", out["r1"]["text"])
    assert out["r2"]["status"] == ros2.ABORTED
    said = out["r2"]["values"]["error_msg"]
    assert re.fullmatch(r"blocked by another robot \(r1\) for [67] s", said)


async def test_head_on_without_the_option_robots_pass_through_each_other(
    tmp_path: Path, sims: list[Simulation]
) -> None:
    out = await head_on(tmp_path, sims, solid=False)
    r1, r2 = out["sim"].robots
    assert out["r1"]["status"] == rb.GoalStatus.SUCCEEDED
    assert out["r2"]["status"] == ros2.SUCCEEDED
    assert r1.pose[0] > r2.pose[0]  # swapped ends
    assert out["closest"] < 2 * RADIUS  # through each other: the old model


# -- the options -------------------------------------------------------------------------------


def test_sim_options() -> None:
    parser = argparse.ArgumentParser()
    add_sim_arguments(parser)
    ns = parser.parse_args([])  # robots see each other unless told otherwise (issue 31)
    assert ns.robots_see_each_other is True and ns.blocked_patience == ROBOT_PATIENCE
    assert parser.parse_args(["--robots-pass-through"]).robots_see_each_other is False
    ns = parser.parse_args(["--robots-see-each-other", "--blocked-patience", "12"])
    assert ns.robots_see_each_other is True and ns.blocked_patience == 12.0
