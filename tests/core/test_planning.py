"""Path planning never runs on the server's event loop, and no plan is made twice.

Planning holds the GIL for hundreds of milliseconds; in worker threads it starved the loop
(requests at 87-128 ms, robot links dropped at ``--time-scale 10``: bench/bench_stall.py has
the figures). So it runs in a child process, a burst of new waypoints is planned together, and
an identical request already being planned is waited for.
"""

from __future__ import annotations

import asyncio
import logging

import pytest

from serveur.maps.distances import MapData, PlanRequest, plan_async
from serveur.maps.navigation import load_demo
from tests.conftest import Restaurant
from tests.test_e2e import staff


async def test_identical_requests_in_flight_are_planned_once() -> None:
    grid, wps = load_demo()
    m = MapData.from_occupancy(grid)
    spots = [(n, wps[n].x, wps[n].y) for n in ("T1", "T7", "home1")]
    # A radius no other test uses: nothing cached, both calls start before either ends.
    req = PlanRequest(spots=spots, robot_radius=0.2123, map=m)
    a, b = await asyncio.gather(plan_async(req, in_child=True), plan_async(req, in_child=True))
    assert a is b


async def test_a_burst_of_waypoints_is_planned_in_a_child_in_at_most_two_plans(
    one_robot: Restaurant, caplog: pytest.LogCaptureFixture
) -> None:
    c = await staff(one_robot)
    places = one_robot.app.core.places  # type: ignore[union-attr]
    caplog.set_level(logging.INFO, logger="serveur.core.places")
    _, wps = load_demo()
    for i in range(10):
        t = wps[f"T{i + 1}"]
        await c.ok("create", type="waypoint", name=f"B{i}", x=t.x + 0.31, y=t.y, yaw=0.0)
    while places.planning:
        await asyncio.gather(*list(places.planning))
    plans = [r.getMessage() for r in caplog.records if "path distances" in r.getMessage()]
    assert 1 <= len(plans) <= 2, plans
    assert all("child process" in p for p in plans), plans
    # Every pair with a new waypoint was planned (reachable or not), none left to straight lines.
    n = len(places.waypoints)
    assert len(places.distances) == n * (n - 1) // 2
