"""Robots see each other by default (issue 31), and on the packaged demo room they never meet:
a short busy service (15 minutes at 400 dishes/h, 5 robots, the replay's default options, so
robots that see each other) has no conflict (two centres closer than 0.45 m: footprints within
5 cm), no deadlock and no goal aborted because of another robot, every dish delivered.

Before the simulator's local planner kept a costmap's clearance (serveur.sim.floor
ROBOT_CLEARANCE) and the base its safety stop, the same room had ~100 conflicts an hour with 5
robots: robots brushing footprint to footprint in front of the homes."""

from __future__ import annotations

from serveur.maps.mapio import load_demo
from serveur.replay.model import ReplayOptions
from serveur.replay.orders import generate_orders
from serveur.replay.service import run_replay


def test_a_busy_demo_service_has_no_conflict_and_no_deadlock() -> None:
    opts = ReplayOptions(robots=5, progress=False, seed=11)
    assert opts.robots_see_each_other  # the default, not asked for
    _, waypoints = load_demo()
    tables = sorted(
        (w.name for w in waypoints.values() if w.kind == "table"), key=lambda n: int(n[1:])
    )
    log = generate_orders(tables, hours=0.25, rate=400.0, seed=11)
    r = run_replay(log, opts, ["serveur"])["serveur"]
    s = r.stats()
    assert s["undelivered"] == 0 and s["delivered"] == len(log)
    assert s["conflicts"] == 0, r.traffic["conflicts"]
    assert s["deadlocks"] == 0, r.traffic["deadlocks"]
    assert s["aborted_by_robot"] == 0, r.traffic["aborts"]
    assert s["closest_m"] is not None and s["closest_m"] >= opts.conflict_distance
