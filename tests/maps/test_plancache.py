"""The plan cache on disk: a second start plans nothing, and any change is another plan.

A plan is a pure function of its request (the map's cells or file, the waypoints, the radius),
so it is read back only for the very same request; an edited map file or a moved waypoint
plans afresh. Real files in a temporary folder; the planner runs in a worker thread.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from serveur.maps import distances as D
from serveur.maps import plancache
from serveur.maps.navigation import demo_map_path, load_demo


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    folder = tmp_path / "plans"
    monkeypatch.setenv("SERVEUR_PLAN_CACHE", str(folder))
    return folder


def _request(map_path: Path, moved: float = 0.0) -> D.PlanRequest:
    wps = list(load_demo()[1].values())[:6]
    spots = [(w.name, w.x + (moved if i == 0 else 0.0), w.y) for i, w in enumerate(wps)]
    return D.PlanRequest(spots=spots, robot_radius=0.2, map_path=str(map_path))


def _entries(folder: Path) -> list[Path]:
    return list(folder.glob("*.json"))


async def _plan(req: D.PlanRequest, monkeypatch: pytest.MonkeyPatch) -> tuple[D.PlanResult, int]:
    """Plan ``req`` as a fresh process would (nothing in memory), counting real plans."""
    monkeypatch.setattr(D, "_RECENT", type(D._RECENT)())
    calls = 0
    real = D.plan

    def counting(r: D.PlanRequest) -> D.PlanResult:
        nonlocal calls
        calls += 1
        return real(r)

    monkeypatch.setattr(D, "plan", counting)
    result = await D.plan_async(req, in_child=False)
    monkeypatch.setattr(D, "plan", real)
    return result, calls


async def test_a_second_start_reads_the_plan_and_a_change_plans_again(
    cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    room = tmp_path / "room"
    shutil.copytree(demo_map_path().parent, room)
    yaml = room / demo_map_path().name
    first, planned = await _plan(_request(yaml), monkeypatch)
    assert planned == 1 and not first.cached and len(_entries(cache)) == 1
    again, planned = await _plan(_request(yaml), monkeypatch)
    assert planned == 0 and again.cached
    assert again.pairs == first.pairs and again.paths == first.paths and again.map == first.map
    # A moved waypoint is another request.
    _, planned = await _plan(_request(yaml, moved=0.3), monkeypatch)
    assert planned == 1
    # The same request on an edited map file (one line more in its YAML) plans again.
    yaml.write_text(yaml.read_text() + "\n# edited\n")
    _, planned = await _plan(_request(yaml), monkeypatch)
    assert planned == 1


async def test_a_broken_entry_is_planned_again_and_off_means_off(
    cache: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    req = _request(demo_map_path())
    await _plan(req, monkeypatch)
    [entry] = _entries(cache)
    entry.write_text('{"map": ')  # a disk that filled up mid-write, a hand edit
    result, planned = await _plan(req, monkeypatch)
    assert planned == 1 and not result.cached
    monkeypatch.setenv("SERVEUR_PLAN_CACHE", "off")
    assert plancache.cache_dir() is None
    _, planned = await _plan(req, monkeypatch)
    assert planned == 1


def test_the_folder_follows_systemd_then_xdg(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("SERVEUR_PLAN_CACHE", raising=False)
    monkeypatch.setenv("CACHE_DIRECTORY", "/var/cache/serveur")
    assert plancache.cache_dir() == Path("/var/cache/serveur/plans")
    monkeypatch.delenv("CACHE_DIRECTORY")
    monkeypatch.setenv("XDG_CACHE_HOME", "/x")
    assert plancache.cache_dir() == Path("/x/serveur/plans")
