"""Pure tests of the simulated bases: limits, omni vs differential, path following, odometry."""

from __future__ import annotations

import itertools
import math
import random

import pytest

from serveur.maps.navigation import Planner, load_demo
from serveur.sim.kinematics import Limits, MotionModel, OdometryModel, PathFollower, wrap_angle

DT = 0.05


def _drive(
    model: MotionModel, follower: PathFollower, max_time: float = 120.0
) -> tuple[float, list[tuple[float, float, float]]]:
    """Step until the follower is done and the base at rest; return (time, velocity history)."""
    t = 0.0
    history = []
    while t < max_time:
        cmd = follower.command(model.x, model.y, model.yaw)
        if follower.done and model.speed < 1e-3 and abs(model.wz) < 1e-3:
            return t, history
        model.step(*cmd, DT)
        history.append((model.vx, model.vy, model.wz))
        t += DT
    raise AssertionError(f"did not arrive within {max_time} s: at {model.x, model.y, model.yaw}")


@pytest.mark.parametrize("kind", ["omni", "diff"])
def test_speed_and_acceleration_limits_hold_for_any_command(kind: str) -> None:
    lim = Limits()
    m = MotionModel(kind, lim)  # type: ignore[arg-type]
    rng = random.Random(1)
    prev = (0.0, 0.0, 0.0)
    for i in range(2000):
        if i % 15 == 0:
            cmd = (rng.uniform(-3, 3), rng.uniform(-3, 3), rng.uniform(-6, 6))
        m.step(*cmd, DT)
        assert m.speed <= lim.max_speed + 1e-9
        assert abs(m.wz) <= lim.max_wz + 1e-9
        dv = math.hypot(m.vx - prev[0], m.vy - prev[1])
        assert dv <= lim.max_accel * DT + 1e-9
        assert abs(m.wz - prev[2]) <= lim.max_alpha * DT + 1e-9
        prev = (m.vx, m.vy, m.wz)


def test_diff_drive_cannot_move_sideways_but_omni_can() -> None:
    diff = MotionModel("diff", Limits())
    omni = MotionModel("omni", Limits())
    for _ in range(40):
        diff.step(0.0, 0.5, 0.0, DT)
        omni.step(0.0, 0.5, 0.0, DT)
    assert diff.vy == 0.0 and (diff.x, diff.y) == (0.0, 0.0)
    assert omni.y > 0.3 and abs(omni.x) < 1e-9  # sideways, heading unchanged
    assert omni.yaw == 0.0


def test_heading_decides_the_direction_of_forward_motion() -> None:
    m = MotionModel("diff", Limits(), yaw=math.pi / 2)
    for _ in range(40):
        m.step(0.5, 0.0, 0.0, DT)
    assert m.y > 0.3 and abs(m.x) < 1e-9


def test_bumper_stops_at_an_obstacle() -> None:
    m = MotionModel("omni", Limits())
    free = lambda x, y: x < 1.0  # noqa: E731 - a wall at x = 1
    for _ in range(200):
        m.step(0.7, 0.0, 0.0, DT, free)
    assert 0.9 < m.x < 1.0
    assert m.step(0.7, 0.0, 0.0, DT, free) is False and m.vx == 0.0


PATHS = [
    ([(0.0, 0.0), (2.0, 0.0), (2.0, 3.0)], 1.0, (0.0, 0.0, 0.0)),
    ([(0.0, 0.0), (-1.0, -1.0)], -2.5, (0.0, 0.0, 1.5)),
    ([(0.0, 0.0), (0.05, 0.0)], 3.0, (0.0, 0.0, 0.0)),  # shorter than the tolerance: just turn
    ([(0.0, 0.0), (3.0, 0.2), (5.0, 4.0), (0.0, 4.0)], 0.0, (0.0, 0.0, 3.0)),
]


@pytest.mark.parametrize("kind", ["omni", "diff"])
@pytest.mark.parametrize(("path", "goal_yaw", "start"), PATHS)
def test_path_following_ends_within_tolerance(
    kind: str, path: list[tuple[float, float]], goal_yaw: float, start: tuple[float, float, float]
) -> None:
    lim = Limits()
    m = MotionModel(kind, lim, *start)  # type: ignore[arg-type]
    f = PathFollower(path, goal_yaw, kind, lim)  # type: ignore[arg-type]
    t, history = _drive(m, f)
    gx, gy = path[-1]
    assert math.hypot(m.x - gx, m.y - gy) <= 0.1
    assert abs(wrap_angle(m.yaw - goal_yaw)) <= 0.1
    assert max(math.hypot(vx, vy) for vx, vy, _ in history) <= lim.max_speed + 1e-9
    if kind == "diff":
        assert all(vy == 0.0 for _, vy, _ in history)
    length = sum(math.dist(a, b) for a, b in itertools.pairwise(path))
    assert t < 3 * length / lim.max_speed + 10  # no dawdling or orbiting


@pytest.mark.parametrize("kind", ["omni", "diff"])
def test_following_a_planned_path_on_the_demo_map_stays_clear(kind: str) -> None:
    grid, waypoints = load_demo()
    planner = Planner(grid, robot_radius=0.2)
    home, table = waypoints["home1"], waypoints["T16"]
    path = planner.plan((home.x, home.y), (table.x, table.y))
    lim = Limits()
    m = MotionModel(kind, lim, home.x, home.y, home.yaw)  # type: ignore[arg-type]
    f = PathFollower(path, table.yaw, kind, lim)  # type: ignore[arg-type]
    t = 0.0
    while not (f.done and m.speed < 1e-3 and abs(m.wz) < 1e-3):
        assert grid.is_free(m.x, m.y), f"drove into an obstacle at {m.x:.2f}, {m.y:.2f}"
        m.step(*f.command(m.x, m.y, m.yaw), DT)
        t += DT
        assert t < 120
    assert math.hypot(m.x - table.x, m.y - table.y) <= 0.1
    assert abs(wrap_angle(m.yaw - table.yaw)) <= 0.1


def test_odometry_integrates_with_seeded_noise_and_no_drift_at_rest() -> None:
    def run(seed: int) -> tuple[float, float, float]:
        odom = OdometryModel(random.Random(seed))
        for _ in range(200):  # 10 s at 0.5 m/s along x
            odom.update(0.5, 0.0, 0.0, DT)
        for _ in range(100):
            odom.update(0.0, 0.0, 0.0, DT)
        assert (odom.vx, odom.vy, odom.wz) == (0.0, 0.0, 0.0)
        return odom.x, odom.y, odom.yaw

    a, b, c = run(3), run(3), run(4)
    assert a == b  # reproducible
    assert a != c  # but it is noise
    assert a[0] == pytest.approx(5.0, rel=0.03)  # about right, not exact
    assert a[0] != 5.0
    assert abs(a[1]) < 0.05


def test_odometry_follows_a_turning_base() -> None:
    odom = OdometryModel(random.Random(0), scale_error=0.0, noise=0.0)
    wz = 2 * math.pi / (200 * DT)
    for _ in range(200):  # a full circle of radius 0.5 / wz
        odom.update(0.5, 0.0, wz, DT)
    assert math.hypot(odom.x, odom.y) < 0.01
    assert abs(wrap_angle(odom.yaw)) < 1e-6


def test_the_follower_drives_between_every_pair_of_demo_waypoints_without_clipping() -> None:
    """Every waypoint to every other on the demo map, with the simulator's bumper: no drive may
    end stuck against a table corner (a longer carrot cut corners: docs/performance.md)."""
    grid, wps = load_demo()
    planner = Planner(grid, robot_radius=0.2)
    stuck: list[tuple[str, str]] = []
    for a, wa in wps.items():
        for b, wb in wps.items():
            if a == b:
                continue
            base = MotionModel("omni", Limits(), wa.x, wa.y, wa.yaw)
            follower = PathFollower(
                planner.plan((wa.x, wa.y), (wb.x, wb.y)), wb.yaw, "omni", Limits()
            )
            blocked = 0
            for _ in range(20 * 120):
                cmd = follower.command(base.x, base.y, base.yaw)
                if follower.done:
                    break
                blocked = 0 if base.step(*cmd, 0.05, planner.is_traversable) else blocked + 1
                if blocked >= 40:  # 2 s against an obstacle: the simulator aborts the goal
                    stuck.append((a, b))
                    break
            else:
                stuck.append((a, b))
    assert stuck == []
