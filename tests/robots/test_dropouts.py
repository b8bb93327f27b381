"""Robots that drop off the network mid-delivery: no order is lost or served twice.

A robot back within ``CoreConfig.handover_after`` resumes its trip
(tests/robots/test_link_faults.py); one away longer has the trip handed to another robot
and, on its return, goes home.
"""

from __future__ import annotations

import asyncio
import os
import random
from pathlib import Path
from typing import Any

import pytest

from serveur.app import App, RobotSpec
from serveur.clock import Clock
from serveur.core.engine import Core, CoreConfig
from serveur.maps.mapio import demo_map_path
from serveur.maps.navigation import load_demo
from serveur.robot_sim import start_simulation
from tests import invariants
from tests.conftest import Client, Restaurant, test_clock
from tests.test_e2e import activate, near, new_orders, serve_current_stop, staff

# Link faults happen to ROS1 and ROS 2 robots alike (and to a mixed fleet): issue 19.


@pytest.fixture
def one_robot(any_robot: Restaurant) -> Restaurant:
    return any_robot


@pytest.fixture
def two_robots(any_two_robots: Restaurant) -> Restaurant:
    return any_two_robots


pytestmark = pytest.mark.cuts_links  # robots drop off the network on purpose

#: Fault schedule seed; set SERVEUR_FAULT_SEED to explore other schedules.
SEED = int(os.environ.get("SERVEUR_FAULT_SEED", "2"))


def core_of(r: Restaurant) -> Core:
    assert r.app.core is not None
    return r.app.core


def statuses_since(c: Client, robot: str, mark: int) -> list[str]:
    """Every status ``robot`` was seen in by ``c`` from frame ``mark`` on."""
    return [
        f["data"]["status"]
        for f in c.frames[mark:]
        if f["servermsg"] == "update" and f["topic"] == "robots" and f["data"]["name"] == robot
    ]


async def test_robot_gone_too_long_hands_its_trip_to_another_robot(
    two_robots: Restaurant,
) -> None:
    r = two_robots
    core_of(r).config.handover_after = 4.0
    c = await staff(r)
    await activate(c, "r1")
    ids = await new_orders(c, ("Laksa", "T16"), ("Pho", "T12"))
    [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
    on_trip = len(c.frames)
    await c.status("r1", "Delivering")
    await activate(c, "r2")
    await r.sim.stop_endpoint(0)
    await c.status("r1", "Offline")
    t0 = r.clock.now()
    # The trip goes back to the queue once the limit has passed, and r2 takes it.
    await c.until(lambda: c.task(task["id"]).get("robot") == "r2", what="r2 takes the trip")
    assert r.clock.now() - t0 >= 3.0  # not before the limit (4 s, less our observation lag)
    assert c.robot("r1")["current_task"] is None
    assert "handed to another robot" in c.robot("r1")["last_error"]
    # The dishes were never free for another cart: the orders stayed on the trip throughout.
    seen = [f["data"]["status"] for f in c.frames[on_trip:] if f.get("topic") == "orders"]
    assert "pending" not in seen and all(c.order(i)["status"] == "assigned" for i in ids)
    # r1 comes back: it goes home, it does not drive on with the trip r2 now has.
    mark = len(c.frames)
    await r.sim.start_endpoint(0)
    await c.status("r1", "Awaiting")
    assert near(c.robot("r1"), "home1")
    assert not {"Delivering", "Delivered"} & set(statuses_since(c, "r1", mark))
    served = [await serve_current_stop(c, "r2") for _ in range(2)]
    assert sorted(o for s in served for o in s["orders"]) == sorted(ids)
    await c.until(lambda: c.task(task["id"]).get("status") == "done", what="trip done")
    await c.status("r2", "Awaiting")
    snap = invariants.read(r.db)
    invariants.check_deliveries(snap)
    invariants.check_robots(snap)
    assert snap.delivered() == set(ids) and set(snap.deliveries.values()) == {1}
    assert c.task(task["id"])["robot"] == "r2"


async def test_dropouts_at_random_moments_lose_and_repeat_nothing(two_robots: Restaurant) -> None:
    """Seeded link cuts (endpoint killed for a short or a long while, or the socket dropped)
    while two robots deliver three carts; every order ends delivered exactly once."""
    r = two_robots
    rng = random.Random(SEED)
    core = core_of(r)
    core.config.handover_after = 5.0
    c = await staff(r)
    await activate(c, "r1")
    await activate(c, "r2")
    tables = ["T1", "T16", "T6", "T11", "T4", "T15", "T9", "T2"]
    ids = await new_orders(c, *[(f"dish{i}", t) for i, t in enumerate(tables)])
    for cart in (ids[:3], ids[3:6], ids[6:]):
        await c.ok("create", type="task", orders=cart)
    delivered = lambda: all(c.order(i).get("status") == "delivered" for i in ids)  # noqa: E731

    async def waiter() -> None:
        """Staff pressing "food collected" whenever a robot waits at a table, and "continue"
        when one reports a failed move (Error is where a failure ends; staff decide)."""

        def needs_staff() -> tuple[str, str, dict[str, Any]] | None:
            for name in ("r1", "r2"):
                status = c.robot(name).get("status")
                if status in ("Delivered", "Error"):
                    verb = "next" if status == "Delivered" else "continue"
                    return name, verb, c.robot(name)
            return None

        while True:
            name, verb, rec = await c.until(needs_staff, what="a robot needing staff")
            reply = await c.call(verb, robot=name)
            if reply["servermsg"] == "error":  # it dropped meanwhile: wait for news of it
                await c.until(lambda n=name, r0=rec: c.robot(n) is not r0)

    cuts: list[str] = []

    async def faults() -> None:
        for _ in range(6):
            await r.clock.sleep(rng.uniform(0.5, 4.0))
            if delivered():
                return
            i = rng.randrange(2)
            name = f"r{i + 1}"
            if rng.random() < 0.3:
                link = core._rt[name].link
                assert link is not None
                await link.drop()
                cuts.append(f"{name} socket")
                continue
            away = rng.choice([0.5, 2.0, 8.0])  # 8 s is past the hand-over limit
            await r.sim.stop_endpoint(i)
            await c.status(name, "Offline")
            await r.clock.sleep(away)
            await r.sim.start_endpoint(i)
            cuts.append(f"{name} {away}s")

    staff_task = asyncio.create_task(waiter())
    try:
        await faults()
        await c.until(delivered, what=f"every order delivered after cuts {cuts}")
    finally:
        staff_task.cancel()
    assert len(cuts) >= 4, cuts
    assert any(cut.endswith(" 8.0s") for cut in cuts), cuts  # the schedule hands a trip over
    await c.status("r1", "Awaiting")
    await c.status("r2", "Awaiting")
    snap = invariants.read(r.db)
    invariants.check_deliveries(snap)
    invariants.check_robots(snap)
    assert snap.delivered() == set(ids)
    assert [snap.deliveries[i] for i in ids] == [1] * len(ids)


async def test_silent_robot_is_offline_within_the_heartbeat(tmp_path: Path) -> None:
    """The socket stays open but the robot stops talking (ROS hung, Wi-Fi half-dead): the
    move_base status heartbeat, with the default settings, makes it Offline after two idle
    status periods (0.5 s each, robot time) plus the 2 s (wall) Wi-Fi stall allowance."""
    clock = test_clock(2.0)  # virtual time here; slow, not loaded, on the wall clock
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), clock=clock)
    nav_map, waypoints = load_demo()
    app = App(
        tmp_path / "serveur.db",
        port=0,
        clock=clock,
        nav_map=nav_map,
        waypoints=waypoints,
        robots=[RobotSpec("r1", sim.urls[0], "home1")],
        config=CoreConfig(auto_depart=True),  # the defaults otherwise: heartbeat 1 s
    )
    await app.start()
    r = Restaurant(app, sim, clock, tmp_path / "serveur.db", [], [])
    r.token = await app.issue_token("staff")
    try:
        c = await staff(r)
        await c.status("r1", "Ready")
        loop_task = sim._loop_task  # the physics and publishing loop: the robot goes silent
        assert loop_task is not None
        loop_task.cancel()
        t0 = clock.now()
        await c.status("r1", "Offline")
        limit = 2 * 0.5 + 2.0 * clock.time_scale  # clock seconds
        # The last status came up to half a second before t0; the watchdog looks 8 times a
        # timeout.
        assert limit - 0.6 <= clock.now() - t0 <= limit * 1.125 + 0.3
        assert "link lost" in c.robot("r1")["last_error"]
        sim._loop_task = None
        await sim.start()  # it talks again: back in the status of its mode
        await c.status("r1", "Ready")
    finally:
        for cl in r.clients:
            await cl.close()
        await app.close()
        await sim.close()


async def test_hand_over_limit_counts_from_the_drop_across_a_restart(tmp_path: Path) -> None:
    """A robot that dropped before a server restart is handed over ``handover_after`` after
    the drop, not ``handover_after`` after the restart."""
    from serveur.core.engine import HANDOVER_GRACE
    from tests.conftest import restaurant

    limit = 30.0
    assert limit - 12.0 > HANDOVER_GRACE  # the grace must not hide the difference

    def make(db: Path | str, clock: Clock, specs: list[RobotSpec], port: int) -> App:
        nav_map, waypoints = load_demo()
        cfg = CoreConfig(heartbeat=2.0, ack_timeout=3.0, handover_after=limit, auto_depart=True)
        return App(
            db,
            port=port,
            clock=clock,
            nav_map=nav_map,
            waypoints=waypoints,
            robots=specs,
            config=cfg,
        )

    async with restaurant(tmp_path, robots=2, time_scale=10.0) as r:
        r.make = make
        core_of(r).config.handover_after = limit
        c = await staff(r)
        await activate(c, "r1")
        await activate(c, "r2")
        ids = await new_orders(c, ("Laksa", "T16"))
        [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
        await c.until(lambda: c.task(task["id"]).get("robot") is not None, what="dispatched")
        robot = c.task(task["id"])["robot"]
        await c.status(robot, "Delivering")
        await r.sim.stop_endpoint(int(robot[1:]) - 1)
        await c.status(robot, "Offline")
        t0 = r.clock.now()
        await r.clock.sleep(12.0)  # part of the limit passes before the restart
        await r.restart_server()
        c = await staff(r)
        other = "r2" if robot == "r1" else "r1"
        await c.until(
            lambda: c.task(task["id"]).get("robot") == other, what="hand-over", timeout=60
        )
        # From the drop: ~30 s (plus observation lag); from the restart it would be >= 42 s.
        assert limit - 2.0 <= r.clock.now() - t0 < limit + 9.0
