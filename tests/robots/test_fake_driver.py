"""The fake robot driver's own behaviour (what tests script with it), on a FakeClock, and a whole
trip through the real server with a ``fake://`` robot and no socket to any robot.

What it shares with the real drivers is in tests/robots/test_conformance.py.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import pytest

from serveur.app import RobotSpec
from serveur.clock import FakeClock, ScaledClock
from serveur.errors import LinkError
from serveur.maps.navigation import load_demo
from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss, RobotDriver
from serveur.robots.fake import BLOCKED_ABORT_AFTER, SPEED, FakeDriver
from serveur.robots.ros1.link import RobotLink
from serveur.robots.ros2.link import Nav2Link
from tests.conftest import Restaurant, make_app
from tests.robots.test_conformance import Recorder, driver_for
from tests.test_e2e import activate, new_orders, serve_current_stop, staff


class Fake:
    """A fake robot at the origin facing +x, its recorder and its clock."""

    def __init__(self, **options: Any) -> None:
        self.clock = FakeClock()
        self.rec = Recorder()
        self.robot = FakeDriver("f1", "fake://f1", self.rec, self.clock, **options)

    async def run(self, seconds: float, step: float = 0.05) -> None:
        end = self.clock.now() + seconds
        while self.clock.now() < end - 1e-9:
            await self.clock.advance(step)

    async def run_until(self, cond: Any, limit: float = 30.0) -> float:
        """Advance until ``cond()``; the clock time it took."""
        t0 = self.clock.now()
        while not cond():
            assert self.clock.now() - t0 < limit, f"not within {limit} s: {self.rec.kinds()}"
            await self.clock.advance(0.05)
        return self.clock.now() - t0

    async def started(self) -> Fake:
        self.robot.start()
        await self.run_until(lambda: self.robot.up)
        return self


@pytest.fixture
async def fake() -> Any:
    f = await Fake().started()
    yield f
    await f.robot.close()


def test_the_fake_is_a_robot_driver() -> None:
    driver: RobotDriver = FakeDriver("f1", "fake://f1", Recorder(), FakeClock())  # mypy checks
    assert driver.kind == "fake" and not driver.up and driver.pose is None


async def test_it_drives_at_its_speed_in_clock_time(fake: Fake) -> None:
    handle = await fake.robot.send_goal(2.0, 0.0, 0.0)
    took = await fake.run_until(lambda: fake.rec.ends(handle))
    assert 2.0 / SPEED <= took <= 2.0 / SPEED + 0.1
    assert fake.rec.ends(handle) == [("done", (handle, rb.GoalStatus.SUCCEEDED, "Goal reached."))]
    assert fake.robot.true_pose == fake.robot.pose == (2.0, 0.0, 0.0)
    poses = [a for k, a in fake.rec.events if k == "pose"]
    assert len(poses) >= 2.0 / SPEED / 0.05  # reported every tick on the way
    assert fake.robot.velocity == (0.0, 0.0, 0.0)


async def test_without_a_pose_the_link_waits_for_one() -> None:
    f = Fake(pose=None)
    f.robot.start()
    await f.run(2.0)
    assert not f.robot.up and f.rec.events == []
    f.robot.localise(1.0, 2.0, 0.5)
    await f.run_until(lambda: f.robot.up)
    assert [k for k, _ in f.rec.events] == ["pose", "spread", "battery", "up"]
    assert f.robot.pose == (1.0, 2.0, 0.5)
    await f.robot.close()


async def test_a_refused_goal_is_lost_after_the_ack_timeout(fake: Fake) -> None:
    fake.robot.refuse_next_goal("never acknowledged")
    handle = await fake.robot.send_goal(2.0, 0.0, 0.0)
    took = await fake.run_until(lambda: fake.rec.ends(handle))
    assert 2.0 <= took <= 2.1  # the default ack_timeout
    [(kind, (_, reason, cause))] = fake.rec.ends(handle)
    assert (kind, reason, cause) == ("lost", "never acknowledged", GoalLoss.NOT_ACCEPTED)
    assert fake.robot.true_pose == (0.0, 0.0, 0.0) and fake.robot.goal_id is None
    again = await fake.robot.send_goal(1.0, 0.0, 0.0)  # only the next goal was refused
    await fake.run_until(lambda: fake.rec.ends(again))
    assert fake.rec.ends(again)[0][1][1] is rb.GoalStatus.SUCCEEDED


async def test_an_aborted_goal_is_done_aborted_with_its_text(fake: Fake) -> None:
    handle = await fake.robot.send_goal(5.0, 0.0, 0.0)
    await fake.run(1.0)
    fake.robot.abort_goal("no valid plan")
    assert fake.rec.ends(handle) == [("done", (handle, rb.GoalStatus.ABORTED, "no valid plan"))]
    there = fake.robot.true_pose
    await fake.run(1.0)
    assert fake.robot.true_pose == there and fake.robot.velocity == (0.0, 0.0, 0.0)


async def test_a_goal_lost_for_a_cause_stops_the_robot(fake: Fake) -> None:
    handle = await fake.robot.send_goal(5.0, 0.0, 0.0)
    await fake.run(1.0)
    fake.robot.lose_goal("bridge gone", GoalLoss.LINK)
    assert fake.rec.ends(handle) == [("lost", (handle, "bridge gone", GoalLoss.LINK))]
    there = fake.robot.true_pose
    await fake.run(1.0)
    assert fake.robot.true_pose == there and fake.robot.goal_id is None


async def test_a_blocked_way_aborts_the_goal(fake: Fake) -> None:
    fake.robot.block_path(True)
    handle = await fake.robot.send_goal(2.0, 0.0, 0.0)
    took = await fake.run_until(lambda: fake.rec.ends(handle))
    assert BLOCKED_ABORT_AFTER <= took <= BLOCKED_ABORT_AFTER + 0.15
    [(kind, (_, status, text))] = fake.rec.ends(handle)
    assert (kind, status) == ("done", rb.GoalStatus.ABORTED) and "blocked" in text
    assert fake.robot.true_pose == (0.0, 0.0, 0.0)
    fake.robot.block_path(False)
    again = await fake.robot.send_goal(2.0, 0.0, 0.0)
    await fake.run_until(lambda: fake.rec.ends(again))
    assert fake.rec.ends(again)[0][1][1] is rb.GoalStatus.SUCCEEDED


async def test_a_goal_ending_while_the_link_is_down_is_not_heard(fake: Fake) -> None:
    handle = await fake.robot.send_goal(1.0, 0.0, 0.0)
    fake.robot.drop_link("wifi gone")
    assert fake.rec.kinds() == ["up", "down", "failed"]
    assert fake.rec.events[-2:] == [("down", ("wifi gone",)), ("failed", ("fake: wifi gone",))]
    assert fake.robot.last_failure == "fake: wifi gone"
    with pytest.raises(LinkError):
        await fake.robot.cancel_goal()
    mark = len(fake.rec.events)
    await fake.run(5.0)
    assert fake.robot.true_pose == (1.0, 0.0, 0.0)  # it drove on, unheard
    assert fake.rec.events[mark:] == [] and fake.rec.ends(handle) == []
    fake.robot.restore_link()
    await fake.run_until(lambda: fake.robot.up)
    assert fake.rec.kinds(mark) == ["up"] and fake.robot.pose == (1.0, 0.0, 0.0)
    assert fake.robot.last_failure == ""


async def test_a_robot_unreachable_at_start_says_why_once() -> None:
    f = Fake(reachable=False)
    f.robot.start()
    await f.run(3.0)
    assert f.rec.events == [("failed", ("fake: network unreachable",))]
    f.robot.restore_link()
    await f.run_until(lambda: f.robot.up)
    await f.robot.close()


async def test_initial_pose_moves_the_robot_and_is_reported(fake: Fake) -> None:
    await fake.robot.initial_pose(3.0, 4.0, 7.0)
    assert fake.robot.true_pose == fake.robot.pose == (3.0, 4.0, math.remainder(7.0, math.tau))
    assert [k for k, _ in fake.rec.events[-2:]] == ["pose", "spread"]
    assert fake.robot.received[-1] == ("initial_pose", 3.0, 4.0, 7.0)


async def test_scans_stream_only_while_wanted(fake: Fake) -> None:
    await fake.robot.want_scan(True)
    await fake.run(1.0)
    assert 4 <= fake.rec.count("scan") <= 6  # 5 Hz
    await fake.robot.want_scan(False)
    await fake.run(0.3)
    mark = len(fake.rec.events)
    await fake.run(1.0)
    assert fake.rec.count("scan", mark) == 0
    await fake.robot.want_pose(True)
    assert fake.robot.pose_watched


async def test_teleop_is_ignored_while_a_goal_runs_and_steers_in_the_robot_frame(
    fake: Fake,
) -> None:
    handle = await fake.robot.send_goal(0.0, 2.0, math.pi / 2)
    await fake.robot.teleop(-1.0, 0.0, 0.0)
    await fake.run_until(lambda: fake.rec.ends(handle))
    assert fake.robot.true_pose == (0.0, 2.0, math.pi / 2)
    await fake.robot.teleop(0.5, 0.0, 0.0)  # forward, i.e. +y now
    await fake.run(0.2)
    await fake.robot.teleop(0.0, 0.0, 0.0)
    await fake.run(0.2)
    assert fake.robot.true_pose is not None
    x, y, _ = fake.robot.true_pose
    assert abs(x) < 1e-9 and 2.05 <= y <= 2.1 + 1e-9  # 0.5 m/s for (about) 0.2 s


def _driver(url: str, ros: int = 1) -> RobotDriver:
    return driver_for(url, ros, Recorder(), FakeClock())


def test_the_factory_makes_a_fake_from_its_url() -> None:
    robot = _driver("fake://r1?x=4&y=10.8&yaw=1.5&speed=0.8&battery=0.4")
    assert isinstance(robot, FakeDriver)
    assert robot.true_pose == (4.0, 10.8, 1.5) and robot.heartbeat_timeout() == 2.0
    assert isinstance(_driver("FAKE://r1"), FakeDriver)
    # Robots on a network get what they always got.
    assert isinstance(_driver("ws://127.0.0.1:9090"), RobotLink)
    assert isinstance(_driver("ws://127.0.0.1:9090", ros=2), Nav2Link)
    for bad in ("fake://r1?z=1", "fake://r1?x=nan", "fake://r1?speed=0", "fake://r1?y="):
        with pytest.raises(ValueError):
            _driver(bad)


async def test_a_whole_trip_through_the_server_with_a_fake_robot(tmp_path: Path) -> None:
    """The real core and server, a staff client on a socket, and a robot with none."""
    home = load_demo()[1]["home1"]
    url = f"fake://r1?x={home.x}&y={home.y}&yaw={home.yaw}&speed=1.0"
    clock = ScaledClock(20.0)
    app = make_app(tmp_path / "serveur.db", clock, [RobotSpec("r1", url, "home1")])
    await app.start()
    r = Restaurant(app, None, clock, tmp_path / "serveur.db", [], [])
    r.token = await app.issue_token("staff", label="tests")
    try:
        assert app.core is not None and isinstance(app.core._rt["r1"].link, FakeDriver)
        c = await staff(r)
        await activate(c, "r1")
        ids = await new_orders(c, ("Laksa", "T1"), ("Satay", "T6"))
        [task] = (await c.ok("create", type="task", orders=ids))["tasks"]
        await serve_current_stop(c, "r1")
        await serve_current_stop(c, "r1")
        await c.status("r1", "Awaiting")
        assert all(c.order(o)["status"] == "delivered" for o in ids)
        assert c.task(task["id"])["status"] == "done"
        assert math.hypot(c.robot("r1")["x"] - home.x, c.robot("r1")["y"] - home.y) < 0.3
    finally:
        for cl in r.clients:
            await cl.close()
        await app.close()
