"""Zones leased to one robot at a time, on a real server driving a real simulator (issue 21).

A room with one aisle one robot wide between its two halves; robots see each other in the
simulator (their footprints are obstacles, they stop short and give up after a patience), so
two robots sent head-on through the aisle deadlock there unless something keeps them apart.
With the aisle drawn as a zone of capacity 1, the server lets one through while the other
waits at its end of the room, then the other: both arrive and they never touch. Without the
zone the same meeting ends with goals aborted in the aisle (the model is real).
"""

from __future__ import annotations

import contextlib
import json
import math
from collections.abc import AsyncIterator
from pathlib import Path
from typing import Any

import numpy as np
from websockets.asyncio.client import connect

from serveur.app import App, RobotSpec
from serveur.clock import ScaledClock
from serveur.core.runtime import CoreConfig, Destination
from serveur.maps.mapio import OccupancyMap, load_waypoints, save_map
from serveur.robot_sim import start_simulation
from tests.conftest import Client, poll_until
from tests.sim.test_sim_badinput import shut
from tests.sim.test_sim_robots_see_each_other import watch_closest

SCALE = 20.0
WAIT = 30.0
RES = 0.05
RADIUS = 0.2
# The aisle: x 3..5 m, y 1.25..1.8 m (0.55 m: one robot of 0.4 m, never two side by side).
AISLE = [[2.9, 1.0], [5.1, 1.0], [5.1, 2.05], [2.9, 2.05]]
# A part of the east half the aisle leads into (around "east", clear of the table R).
HALL = [[5.6, 0.9], [6.9, 0.9], [6.9, 2.0], [5.6, 2.0]]


def narrow_room(tmp: Path) -> Path:
    """Two 3 m x 3 m halves joined by a 2 m aisle 0.55 m wide."""
    free = np.zeros((60, 160), dtype=bool)
    free[2:58, 2:60] = True  # left half, x 0.1..3.0
    free[2:58, 100:158] = True  # right half, x 5.0..7.9
    free[25:36, 60:100] = True  # the aisle, y 1.25..1.8
    yaml_path = tmp / "narrow.yaml"
    save_map(OccupancyMap(np.where(free, 0, 100).astype(np.int8), RES, (0.0, 0.0, 0.0)), yaml_path)
    wps = [
        {"name": "home1", "x": 1.0, "y": 1.5, "yaw": 0.0, "kind": "home"},
        {"name": "home2", "x": 7.0, "y": 1.5, "yaw": math.pi, "kind": "home"},
        {"name": "L", "x": 1.5, "y": 2.4, "yaw": 0.0, "kind": "table"},
        {"name": "R", "x": 6.5, "y": 2.4, "yaw": 0.0, "kind": "table"},
        {"name": "mid", "x": 4.0, "y": 1.52, "yaw": 0.0, "kind": "other"},  # in the aisle
        {"name": "east", "x": 6.2, "y": 1.5, "yaw": 0.0, "kind": "other"},
    ]
    (tmp / "narrow_waypoints.json").write_text(json.dumps({"waypoints": wps}))
    return yaml_path


@contextlib.asynccontextmanager
async def narrow_restaurant(
    tmp: Path,
    *,
    leases: bool,
    scale: float = SCALE,
    heartbeat: float = 2.0,
    ack_timeout: float = 3.0,
) -> AsyncIterator[tuple[App, Any, Client]]:
    """The narrow room on a real server, two simulated robots that see each other at home1 and
    home2, and a staff client. (A slower ``scale`` and a longer ``heartbeat`` suit Chromium.)"""
    yaml_path = narrow_room(tmp)
    clock = ScaledClock(scale)
    sim = await start_simulation(
        2,
        port=0,
        clock=clock,
        map_path=yaml_path,
        seed=5,
        robots_see_each_other=True,
        blocked_patience=8.0,
    )
    specs = [
        RobotSpec(r.name, url, f"home{i + 1}")
        for i, (r, url) in enumerate(zip(sim.robots, sim.urls, strict=True))
    ]
    app = App(
        tmp / "s.db",
        port=0,
        clock=clock,
        map_path=yaml_path,
        waypoints=load_waypoints(tmp / "narrow_waypoints.json"),
        robots=specs,
        config=CoreConfig(
            heartbeat=heartbeat, ack_timeout=ack_timeout, auto_depart=True, leases=leases
        ),
        plan_in_child=False,
    )
    await app.start()
    token = await app.issue_token("staff", label="tests")
    c = Client(await connect(app.url, additional_headers={"Authorization": f"Bearer {token}"}))
    try:
        yield app, sim, c
    finally:
        await c.close()
        await app.close()
        await shut(sim)


async def head_on(app: App, sim: Any, c: Client) -> list[float]:
    """Both robots under manual control, then r1 sent to R and r2 to L at once."""
    await c.subscribe("robots", "leases", "zones")
    for name in ("r1", "r2"):
        await c.until(lambda n=name: c.robot(n).get("status") == "Ready", WAIT, f"{name} up")
        await c.ok("control", robot=name, action="manual")
    closest = watch_closest(sim)
    await c.ok("control", robot="r1", action="goto", waypoint="R")
    await c.ok("control", robot="r2", action="goto", waypoint="L")
    return closest


async def test_with_the_aisle_leased_both_robots_pass_in_turn(tmp_path: Path) -> None:
    async with narrow_restaurant(tmp_path, leases=True) as (app, sim, c):
        owner_token = await app.issue_token("integration", scopes=["site", "read"])
        owner = Client(
            await connect(app.url, additional_headers={"Authorization": f"Bearer {owner_token}"})
        )
        await owner.ok("create", type="zone", name="aisle", points=AISLE, capacity=1)
        await owner.close()
        closest = await head_on(app, sim, c)
        # r2 asked second: it waits for the aisle, at its end of the room, until r1 is through.
        await c.until(lambda: c.robot("r2").get("waiting_for") == ["aisle"], WAIT, "r2 waits")
        assert sim.robots[1].pose[0] > 5.0
        r1, r2 = sim.robots
        await poll_until(lambda: math.dist(r1.pose[:2], (6.5, 2.4)) < 0.2, WAIT, "r1 at R")
        await poll_until(lambda: math.dist(r2.pose[:2], (1.5, 2.4)) < 0.2, WAIT, "r2 at L")
        await c.until(lambda: c.robot("r2").get("waiting_for") is None, WAIT, "r2 done waiting")
        assert closest[0] >= 2 * RADIUS, closest
        assert c.robot("r1").get("last_error") is None and c.robot("r2").get("last_error") is None
        # Once both are through, nobody holds the aisle.
        await c.until(lambda: c.streams.get("leases", {}).get("holders") == [], WAIT, "aisle free")
        assert app.core is not None and app.core.leases.holders("aisle") == []
        # A Move here to a spot that is no waypoint, across the room, crosses the aisle too:
        # its zones are read off the planned path, not the straight line (which meets a wall).
        far = Destination("manual", "", 7.4, 2.5, 0.0)
        assert app.core.leg_zones(app.core._rt["r2"], far) == ["aisle"]


async def test_without_leases_the_same_meeting_deadlocks(tmp_path: Path) -> None:
    async with narrow_restaurant(tmp_path, leases=False) as (app, sim, c):
        closest = await head_on(app, sim, c)
        # Face to face in the aisle: each stops short of the other and, after the patience,
        # its goal is aborted: the server reports the failure on both robots.
        await c.until(
            lambda: c.robot("r1").get("last_error") and c.robot("r2").get("last_error"),
            WAIT,
            "both goals aborted",
        )
        r1, r2 = sim.robots
        assert 2.5 < r1.pose[0] < 5.5 and 2.5 < r2.pose[0] < 5.5  # stuck in or at the aisle
        assert closest[0] >= 2 * RADIUS  # they do not collide: they block each other


async def test_a_robot_standing_in_the_aisle_waits_at_its_waiting_point(tmp_path: Path) -> None:
    """r1 stopped inside the aisle wants to go east, where r2 stands in the hall; r2 wants to
    go west through the aisle. Holding the aisle while it waited, r1 would block r2 for ever
    (each holds what the other needs). With a waiting point for the aisle, r1 leaves it to
    wait at L, holding nothing: r2 comes through, then r1 goes."""
    async with narrow_restaurant(tmp_path, leases=True) as (app, sim, c):
        token = await app.issue_token("integration", scopes=["site", "read"])
        owner = Client(
            await connect(app.url, additional_headers={"Authorization": f"Bearer {token}"})
        )
        await owner.ok("create", type="zone", name="aisle", points=AISLE, wait_at="L")
        await owner.ok("create", type="zone", name="hall", points=HALL)
        await owner.close()
        await c.subscribe("robots", "leases", "zones")
        for name in ("r1", "r2"):
            await c.until(lambda n=name: c.robot(n).get("status") == "Ready", WAIT, f"{name} up")
            await c.ok("control", robot=name, action="manual")
        r1, r2 = sim.robots
        closest = watch_closest(sim)
        assert app.core is not None
        await c.ok("control", robot="r1", action="goto", waypoint="mid")
        await poll_until(lambda: math.dist(r1.pose[:2], (4.0, 1.52)) < 0.2, WAIT, "r1 in the aisle")
        await c.ok("control", robot="r2", action="goto", waypoint="east")
        await poll_until(lambda: math.dist(r2.pose[:2], (6.2, 1.5)) < 0.2, WAIT, "r2 in the hall")
        assert app.core.leases.holders("aisle") == ["r1"]
        assert app.core.leases.holders("hall") == ["r2"]
        # r1 cannot have the hall: it leaves the aisle for L instead of holding it.
        await c.ok("control", robot="r1", action="goto", waypoint="R")
        await poll_until(lambda: math.dist(r1.pose[:2], (1.5, 2.4)) < 0.25, WAIT, "r1 waits at L")
        await poll_until(lambda: app.core.leases.holders("aisle") == [], WAIT, "aisle free")
        # r2 goes west through the aisle; then r1 gets both zones and reaches R.
        await c.ok("control", robot="r2", action="goto", waypoint="home1")
        await poll_until(lambda: math.dist(r2.pose[:2], (1.0, 1.5)) < 0.2, WAIT, "r2 home")
        await poll_until(lambda: math.dist(r1.pose[:2], (6.5, 2.4)) < 0.2, WAIT, "r1 at R")
        assert app.core.leases.cycles() == []
        assert closest[0] >= 2 * RADIUS
        assert c.robot("r1").get("last_error") is None, c.robot("r1")
