"""The replay measures traffic (issue 21): robots that see each other, zones and leases.

One short service (20 minutes of orders, 3 robots) on the narrow-aisle room
(serveur/data/narrow_restaurant*, made by tools/make_narrow_map.py: the kitchen and homes on one
side, five tables on the other, ONE aisle 0.65 m wide between them, leased with the floor at
its ends as the zone ``aisle``), played twice with robots that see each other in the simulator:

* leases on (the room's ``_zones.json``): no two robots ever came within 5 cm of each other,
  no deadlock, no goal aborted because of another robot, every dish delivered — and robots did
  wait for the aisle (the leases were at work, not idle);
* leases off (``--no-leases``): the same log deadlocks in the aisle and goals abort there
  (the model is real, and the first run's zeros are the leases' doing).

Then the measurements' rules on hand-made poses (:class:`TrafficWatch`), the zones file's
lookup, and the report's outputs.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import pytest

import serveur
from serveur.core.leases import point_in_polygon
from serveur.replay.model import ReplayOptions
from serveur.replay.orders import generate_orders
from serveur.replay.report import write_outputs
from serveur.replay.service import PolicyResult, run_replay
from serveur.replay.traffic import TrafficWatch, load_zones, zone_waits
from serveur.replay.world import load_world, zones_path

DATA = Path(serveur.__file__).parent / "data"
NARROW = DATA / "narrow_restaurant.yaml"
OPTS = ReplayOptions(
    robots=3, map_path=str(NARROW), robots_see_each_other=True, progress=False, seed=0
)


def _log() -> list[Any]:
    _, wps, _ = load_world(str(NARROW))
    tables = sorted((w.name for w in wps.values() if w.kind == "table"), key=lambda n: int(n[1:]))
    return generate_orders(tables, hours=20 / 60, rate=200.0, seed=0)


@pytest.fixture(scope="module")
def runs() -> dict[str, PolicyResult]:
    log = _log()
    on = run_replay(log, OPTS, ["serveur"])["serveur"]
    off = run_replay(log, replace(OPTS, leases=False), ["serveur"])["serveur"]
    return {"on": on, "off": off}


def _aisle() -> list[tuple[float, float]]:
    zone = load_zones(DATA / "narrow_restaurant_zones.json")[0]
    return [(p[0], p[1]) for p in zone["points"]]


def test_the_narrow_room_keeps_its_stopping_places_out_of_the_aisle() -> None:
    grid, wps, _ = load_world(str(NARROW))
    aisle = _aisle()
    for w in wps.values():  # homes, the pass, tables: not in the zone, even with the radius
        assert not point_in_polygon((w.x, w.y), aisle), w.name
        for a in range(0, 360, 30):
            p = (w.x + 0.2 * math.cos(math.radians(a)), w.y + 0.2 * math.sin(math.radians(a)))
            assert not point_in_polygon(p, aisle), w.name
    # The aisle is one robot wide: 0.55-0.65 m of free floor across the wall at x 6.
    col = round((6.0 - grid.origin[0]) / grid.resolution)
    free = [r for r in range(grid.height) if grid.grid[r][col] == 0]
    assert 0.55 <= len(free) * grid.resolution <= 0.66, len(free)
    assert zones_path(OPTS) == DATA / "narrow_restaurant_zones.json"


def test_with_leases_robots_never_meet_and_every_dish_arrives(
    runs: dict[str, PolicyResult],
) -> None:
    r = runs["on"]
    s = r.stats()
    assert [z["name"] for z in r.zones] == ["aisle"]
    assert s["undelivered"] == 0 and s["delivered"] == len(_log())
    assert s["conflicts"] == 0, r.traffic["conflicts"]
    assert s["deadlocks"] == 0, r.traffic["deadlocks"]
    assert s["aborted_by_robot"] == 0 and s["aborted_other"] == 0, r.traffic["aborts"]
    assert s["closest_m"] is not None and s["closest_m"] >= OPTS.conflict_distance
    assert s["nav_errors"] == 0 and s["recoveries"] == 0
    # The leases did something: robots waited for the aisle, where they stood (homes, tables).
    assert s["zone_waits"] >= 3 and s["zone_wait_s"] > 0
    assert sum(s["zone_wait_per_robot"].values()) == pytest.approx(s["zone_wait_s"], abs=0.5)
    aisle = _aisle()
    assert r.wait_places and not any(
        point_in_polygon((w["x"], w["y"]), aisle) for w in r.wait_places
    )
    # The records' waits and the server's lease.waited events tell the same story.
    assert len(r.wait_places) == s["zone_waits"]
    assert sum(w["s"] for w in r.wait_places) == pytest.approx(s["zone_wait_s"], abs=2.0)


def test_without_leases_the_same_log_deadlocks_in_the_aisle(
    runs: dict[str, PolicyResult],
) -> None:
    r = runs["off"]
    s = r.stats()
    assert s["zone_waits"] == 0  # nobody asked for the zone
    assert s["deadlocks"] >= 1 and s["aborted_by_robot"] >= 1, r.traffic
    aisle = _aisle()
    spots = [*r.traffic["deadlocks"], *(a for a in r.traffic["aborts"] if a["by_robot"])]
    assert any(point_in_polygon((k["x"], k["y"]), aisle) for k in spots), spots
    assert all(
        "blocked by another robot" in a["text"] for a in r.traffic["aborts"] if a["by_robot"]
    )


def test_the_report_carries_the_traffic(runs: dict[str, PolicyResult], tmp_path: Path) -> None:
    text = write_outputs({"serveur": runs["off"]}, "log.csv", replace(OPTS, leases=False), tmp_path)
    assert "conflicts (< 0.45 m)" in text and "deadlocks (>= 20 s)" in text
    assert "zones: aisle; leases off" in text
    report = json.loads((tmp_path / "report.json").read_text())
    pol = report["policies"]["serveur"]
    assert pol["summary"]["deadlocks"] == len(pol["traffic"]["deadlocks"]) >= 1
    assert report["options"]["leases"] is False and report["options"]["robots_see_each_other"]
    assert (tmp_path / "serveur-traffic.png").stat().st_size > 1000


# -- the rules, on hand-made poses ----------------------------------------------------------


@dataclass
class _Status:
    name: str


@dataclass
class _Robot:
    name: str
    pose: tuple[float, float, float]
    goal_statuses: list[tuple[str, _Status, str]] = field(default_factory=list)


def test_a_conflict_is_an_episode_and_a_deadlock_a_group_that_stopped() -> None:
    t = [0.0]
    a, b, c = _Robot("r1", (0.0, 0.0, 0.0)), _Robot("r2", (1.0, 0.0, 0.0)), _Robot("r3", (9, 9, 0))
    w = TrafficWatch([a, b, c], lambda: t[0])

    def steps(n: int) -> None:
        for _ in range(n):
            t[0] += 0.05
            w.after_step()

    steps(10)
    b.pose = (0.44, 0.0, 0.0)  # closer than 0.45: one episode ...
    steps(5)
    b.pose = (0.46, 0.0, 0.0)  # ... not over within the 2 cm hysteresis ...
    steps(5)
    b.pose = (0.40, 0.0, 0.0)
    steps(5)
    assert len(w.conflicts) == 1 and w.conflicts[0]["distance"] == 0.4
    b.pose = (0.5, 0.0, 0.0)  # apart, then close again: a second episode
    steps(1)
    b.pose = (0.43, 0.0, 0.0)
    steps(1)
    assert len(w.conflicts) == 2 and w.closest == pytest.approx(0.4)
    # Both with a goal, neither moving, 0.5 m apart: a deadlock once 20 s have passed, once.
    active = _Status("ACTIVE")
    a.goal_statuses = [("g1", active, "")]
    b.goal_statuses = [("g2", active, "")]
    steps(20 * 19)
    assert w.deadlocks == []
    steps(20 * 3)
    assert len(w.deadlocks) == 1 and w.deadlocks[0]["robots"] == ["r1", "r2"]
    steps(20 * 30)
    assert len(w.deadlocks) == 1  # the same episode
    # r2's goal aborted because of r1: counted once though listed for several seconds.
    b.goal_statuses = [("g2", _Status("ABORTED"), "blocked by another robot (r1) for 30 s")]
    c.goal_statuses = [("g3", _Status("ABORTED"), "the robot is stuck against an obstacle")]
    steps(20 * 5)
    res = w.result()
    assert res["aborted_by_robot"] == 1 and res["aborted_other"] == 1
    # A lone robot stuck with a goal is not a deadlock, nor robots far apart.
    assert len(res["deadlocks"]) == 1


def test_zone_waits_come_from_the_servers_events(tmp_path: Path) -> None:
    events = [
        {"kind": "lease.waited", "robot": "r1", "data": {"zones": ["aisle"], "waited_s": 4.5}},
        {"kind": "robot.status", "robot": "r1", "data": {"status": "Transit"}},
        {"kind": "lease.waited", "robot": "r2", "data": {"zones": ["aisle"], "waited_s": 10.0}},
        {"kind": "lease.waited", "robot": "r1", "data": {"zones": ["aisle"], "waited_s": 1.0}},
    ]
    zw = zone_waits(events)
    assert zw["waits"] == 3 and zw["seconds"] == 15.5
    assert zw["per_robot"] == {
        "r1": {"waits": 2, "seconds": 5.5},
        "r2": {"waits": 1, "seconds": 10.0},
    }
    # Zones files: the default beside the map, "" for none, a bad file refused.
    assert zones_path(ReplayOptions()) is None  # the demo room has no zones file
    assert zones_path(replace(OPTS, zones="")) is None
    bad = tmp_path / "z.json"
    bad.write_text('{"zones": [{"name": "a"}]}')
    with pytest.raises(ValueError, match="not a zones file"):
        load_zones(bad)
