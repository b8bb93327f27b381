"""``serveur sim --spread-phases``: robot i's poses leave i/N of the AMCL period after robot 0's.

Lock-step simulated robots send their poses in bursts no real fleet produces (independent
robots' timers are not phase-locked); the server must cope with both, and the benchmark
reports both (docs/performance.md). Read from the simulator's own rosbridge endpoints, with
the robots' stamps (simulated time, so the test runs time-scaled and exact).
"""

from __future__ import annotations

import asyncio
import json

import pytest
from websockets.asyncio.client import connect

from serveur.robot_sim import TICK, start_simulation
from serveur.robots import rosbridge as rb
from serveur.sim.robot import AMCL_TICKS

PERIOD = AMCL_TICKS * TICK


async def amcl_phases(n: int, spread: bool) -> list[float]:
    """Each robot's AMCL stamp phase (seconds after robot 0's, modulo the period)."""
    sim = await start_simulation(n, port=0, time_scale=5.0, spread=spread)
    try:

        async def first_stamp(url: str) -> float:
            async with connect(url, compression=None, max_size=2**24) as ws:
                await ws.send(json.dumps({"op": "subscribe", "topic": "/amcl_pose"}))
                async for frame in ws:
                    op = json.loads(frame)
                    if op.get("topic") == "/amcl_pose":
                        return rb.from_ros_time(op["msg"]["header"]["stamp"])
            raise AssertionError("no pose")

        stamps = await asyncio.wait_for(asyncio.gather(*(first_stamp(u) for u in sim.urls)), 10.0)
    finally:
        await sim.close()
    phases = [(s - stamps[0]) % PERIOD for s in stamps]
    return [p - PERIOD if p > PERIOD - 1e-3 else p for p in phases]  # ~PERIOD is phase 0


async def test_spread_robots_publish_evenly_over_the_period() -> None:
    phases = await amcl_phases(4, spread=True)
    assert phases == pytest.approx([0.0, PERIOD / 4, PERIOD / 2, 3 * PERIOD / 4], abs=2e-3)


async def test_lock_step_robots_publish_in_two_bursts() -> None:
    phases = await amcl_phases(4, spread=False)
    assert phases == pytest.approx([0.0, PERIOD / 2, 0.0, PERIOD / 2], abs=2e-3)


def test_phases_are_whole_ticks_then_a_fraction() -> None:
    from serveur.clock import ScaledClock
    from serveur.robot_sim import Simulation

    # Placeholders: this is about the phases, not the floor (no robot to share it).
    sim = Simulation(
        [object()] * 10,  # type: ignore[list-item]
        [],
        ScaledClock(1.0),
        spread=True,
        robots_see_each_other=False,
    )
    ticks = [t * TICK + off for t, off in sim.phases()]
    assert ticks == pytest.approx([i * PERIOD / 10 for i in range(10)])
    assert all(0.0 <= off < TICK for _, off in sim.phases())
