"""Path distances planned outside the server's heap (serveur/maps/distances.py).

The child process and the worker thread must give the scheduler the same table the planner
gives, a bad map must come back as a MapError with its message, a result planned for a spot
that has since moved must not be trusted, and ``serveur run`` must never load numpy.
"""

from __future__ import annotations

import asyncio
import json
import math
from pathlib import Path

import pytest

from serveur.errors import MapError
from serveur.maps.distances import Distances, MapData, PlanRequest, PlanResult, plan_async
from serveur.maps.navigation import DistanceTable, Planner, demo_map_path, load_demo, load_map
from serveur.robots import rosbridge as rb
from tests.conftest import restaurant
from tests.subprocess_server import ServerProcess, staff_client

SPOTS = ["pass", "home1", "T1", "T7", "T13", "T16"]


def _request(**kw: object) -> PlanRequest:
    _, wps = load_demo()
    spots = [(n, wps[n].x, wps[n].y) for n in SPOTS]
    return PlanRequest(spots=spots, robot_radius=0.2, **kw)  # type: ignore[arg-type]


def _expected() -> dict[tuple[str, str], float]:
    m, wps = load_demo()
    table = DistanceTable(Planner(m, robot_radius=0.2), {n: wps[n] for n in SPOTS})
    names = sorted(SPOTS)
    return {(a, b): table.distance(a, b) for i, a in enumerate(names) for b in names[i + 1 :]}


@pytest.mark.parametrize("in_child", [True, False], ids=["child", "thread"])
async def test_planned_distances_equal_the_planner(in_child: bool) -> None:
    result = await plan_async(_request(map_path=str(demo_map_path())), in_child=in_child)
    expected = _expected()
    assert result.pairs.keys() == expected.keys()
    for key, d in expected.items():
        assert result.pairs[key] == pytest.approx(d, abs=1e-9), key
    # path lengths, not straight lines: some spot is round a table or the counter from another
    _, wps = load_demo()
    detour = max(
        d - math.dist((wps[a].x, wps[a].y), (wps[b].x, wps[b].y)) for (a, b), d in expected.items()
    )
    assert detour > 0.5
    assert result.map == MapData.from_occupancy(load_map(demo_map_path()))


async def test_sources_plan_only_their_rows() -> None:
    m = MapData.from_occupancy(load_demo()[0])
    result = await plan_async(_request(map=m, sources=["T7"]), in_child=True, reuse=False)
    assert sorted(result.pairs) == sorted((min(a, "T7"), max(a, "T7")) for a in SPOTS if a != "T7")


async def test_an_identical_request_is_answered_from_memory() -> None:
    m = MapData.from_occupancy(load_demo()[0])
    first = await plan_async(_request(map=m, sources=["T1"]), in_child=False)
    assert await plan_async(_request(map=m, sources=["T1"]), in_child=True) is first
    fresh = await plan_async(_request(map=m, sources=["T1"]), in_child=True, reuse=False)
    assert fresh is not first and fresh.pairs == first.pairs
    other = await plan_async(_request(map=m, sources=["T7"]), in_child=False)
    assert other is not first


async def test_a_bad_map_file_is_a_map_error(tmp_path: Path) -> None:
    bad = tmp_path / "room.yaml"
    bad.write_text(
        "image: missing.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n"
        "occupied_thresh: 0.65\nfree_thresh: 0.196\nnegate: 0\n"
    )
    with pytest.raises(MapError, match=r"missing\.pgm"):
        await plan_async(_request(map_path=str(bad)), in_child=True)


def test_map_from_a_rosbridge_grid_message_is_the_same_map() -> None:
    m = load_demo()[0]
    msg = json.loads(rb.encode(rb.occupancy_grid(m, stamp=1.0, seq=0)))
    assert MapData.from_grid_msg(msg) == MapData.from_occupancy(m)
    assert MapData.from_snapshot(MapData.from_occupancy(m).snapshot()) == MapData.from_occupancy(m)
    msg["data"] = msg["data"][:-1]
    with pytest.raises(MapError):
        MapData.from_grid_msg(msg)
    msg["data"] = [300] * (len(msg["data"]) + 1)
    with pytest.raises(MapError):
        MapData.from_grid_msg(msg)


def test_a_result_for_a_spot_that_moved_is_dropped() -> None:
    table = Distances()
    table.set_spots([("a", 0.0, 0.0), ("b", 3.0, 4.0)])
    req = PlanRequest(spots=[("a", 0.0, 0.0), ("b", 3.0, 4.0)], robot_radius=0.2)
    table.set_spots([("b", 6.0, 8.0)])  # moved while the plan ran
    table.merge(req, PlanResult(MapData(1.0, (0, 0, 0), 1, 1, b"\0"), {("a", "b"): 7.5}))
    assert table.planned("a", "b") is None
    req2 = PlanRequest(spots=[("a", 0.0, 0.0), ("b", 6.0, 8.0)], robot_radius=0.2)
    table.merge(req2, PlanResult(MapData(1.0, (0, 0, 0), 1, 1, b"\0"), {("a", "b"): 12.0}))
    assert table.planned("b", "a") == 12.0
    table.set_spots([("a", 1.0, 0.0)])  # moving forgets the pairs that involve it
    assert table.planned("a", "b") is None


async def test_a_new_waypoint_gets_path_distances(tmp_path: Path) -> None:
    async with restaurant(tmp_path) as r:
        core = r.app.core
        assert core is not None
        c = await r.client()
        served = (await c.ok("data", topics=["map"]))["data"]["map"]
        assert MapData.from_snapshot(served) == MapData.from_occupancy(load_demo()[0])
        # Just inside the pass corner: the straight line to T1 crosses the counter.
        wp = core.places.waypoints["pass"]
        await c.ok("create", type="waypoint", name="P2", x=wp.x, y=wp.y, yaw=0.0, kind="other")
        await asyncio.wait_for(asyncio.gather(*core.places.planning), 30)
        assert core.places.distances.planned("P2", "T1") == pytest.approx(
            core.distance("pass", "T1")
        )
        assert core.distance("P2", "T13") > 0


@pytest.mark.skipif(not Path("/proc/self/maps").exists(), reason="reads /proc/PID/maps")
async def test_serveur_run_plans_in_a_child_and_never_loads_numpy(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("SERVEUR_PLAN_CACHE", "off")  # a cached plan spawns no child
    server = ServerProcess(
        tmp_path / "serveur.db", {}, time_scale=1.0, extra=["--map", str(demo_map_path())]
    )
    await server.start()
    try:
        assert any("path distances" in line and "child process" in line for line in server.output)
        assert server.proc is not None
        libs = await asyncio.to_thread(Path(f"/proc/{server.proc.pid}/maps").read_text)
        assert "_multiarray_umath" not in libs and "/PIL/" not in libs
        c = await staff_client(server)
        served = (await c.ok("data", topics=["map"]))["data"]["map"]
        assert MapData.from_snapshot(served) == MapData.from_occupancy(load_map(demo_map_path()))
        await c.close()
    finally:
        await server.close()
