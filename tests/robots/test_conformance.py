"""One conformance suite every robot driver passes (issue 27, item 5; Equinor ISAR's model).

The core drives every robot through :class:`~serveur.robots.driver.RobotDriver` and hears it
through a :class:`~serveur.robots.driver.LinkListener`; it must not be able to tell the drivers
apart. So the same assertions run against each: the ROS1 link and the ROS 2 link, each against
a simulated robot of its dialect on a scaled clock, the ROS 2 link once more with a docking
server (``docking=nav2`` against a simulated robot running opennav_docking's), and the fake
driver on a :class:`~serveur.clock.FakeClock` that the test moves (no socket, no wall time).
Every driver is made by :func:`~serveur.robots.factory.make_driver`, as the core makes them.

What is asserted is what the core relies on: the link comes up only with a pose; a goal ends
SUCCEEDED at the goal; a goal the robot never takes is lost once, as not accepted; a blocked
way ends a goal ABORTED with the robot's reason; a cancelled goal is never reported and the
robot stops; a goal replaced by another is never reported as a failure; halt stops the robot
and refuses what follows; a joystick command with none after it is stopped by the dead man's
switch; a dropped link is reported down once and up once (what Home Assistant and the staff
console show as availability); an initial pose puts the robot there; scans come only while
wanted; close() leaves no task of the driver running; a dock ends SUCCEEDED with the robot on
its charger (charging, where the robot is simulated) and undock takes it off before the next
goal; a cancelled dock is never reported and the robot stops.
"""

from __future__ import annotations

import asyncio
import logging
import math
from collections.abc import AsyncIterator, Callable
from pathlib import Path
from typing import Any

import pytest

from serveur.clock import Clock, FakeClock
from serveur.errors import LinkError
from serveur.maps.navigation import demo_map_path, load_demo
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import rosbridge as rb
from serveur.robots.driver import GoalLoss, RobotDriver
from serveur.robots.factory import make_driver
from serveur.robots.fake import FakeDriver
from serveur.robots.names import RosNames
from tests.conftest import test_clock

TIME_SCALE = 10.0
#: Where every robot starts (the demo map's home1), a goal a short drive away, one far off.
HOME = load_demo()[1]["home1"]
NEAR = (4.0, 9.6, math.pi / 2)
FAR = (12.6, 1.6, 0.0)  # T16, across the room
ROBOTS = Path(__file__).resolve().parents[2] / "serveur" / "robots"


class Recorder:
    """A link listener that keeps every report, in order, as (kind, args)."""

    def __init__(self) -> None:
        self.events: list[tuple[str, tuple[Any, ...]]] = []

    def link_up(self, robot: str) -> None:
        self.events.append(("up", ()))

    def link_down(self, robot: str, reason: str) -> None:
        self.events.append(("down", (reason,)))

    def link_failed(self, robot: str, reason: str) -> None:
        self.events.append(("failed", (reason,)))

    def pose(self, robot: str, x: float, y: float, yaw: float, stamp: float) -> None:
        self.events.append(("pose", (x, y, yaw)))

    def battery(self, robot: str, fraction: float) -> None:
        self.events.append(("battery", (fraction,)))

    def localisation(self, robot: str, metres: float, radians: float) -> None:
        self.events.append(("spread", (metres, radians)))

    def cloud(self, robot: str, cloud: Any) -> None:
        self.events.append(("cloud", (cloud,)))

    def goal_done(self, robot: str, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        self.events.append(("done", (goal_id, status, text)))

    def goal_lost(
        self, robot: str, goal_id: str, reason: str, *, cause: GoalLoss = GoalLoss.NAVIGATION
    ) -> None:
        self.events.append(("lost", (goal_id, reason, cause)))

    def scan(self, robot: str, msg: Any) -> None:
        self.events.append(("scan", ()))

    def map(self, robot: str, msg: Any) -> None:
        self.events.append(("map", ()))

    def kinds(self, since: int = 0) -> list[str]:
        streams = ("pose", "battery", "scan", "spread", "cloud")
        return [k for k, _ in self.events[since:] if k not in streams]

    def count(self, kind: str, since: int = 0) -> int:
        return sum(1 for k, _ in self.events[since:] if k == kind)

    def of(self, kind: str) -> list[tuple[Any, ...]]:
        """The arguments of every report of ``kind``, in order."""
        return [a for k, a in self.events if k == kind]

    def ends(self, handle: str) -> list[tuple[str, tuple[Any, ...]]]:
        """What was reported of goal ``handle``'s end (done or lost)."""
        return [(k, a) for k, a in self.events if k in ("done", "lost") and a[0] == handle]


def driver_for(
    url: str, ros: int, listener: Recorder, clock: Clock, docking: str = ""
) -> RobotDriver:
    """The driver ``make_driver`` picks for ``url``, with the tests' link settings."""
    return make_driver(
        "r1",
        url,
        listener,
        clock,
        names=RosNames(ros=ros, docking=docking),
        heartbeat=2.0,
        ack_timeout=3.0,
        ack_retries=2,
        want_map=False,
        ssl=None,
        pose_watched=False,
        moving_pose_ms=0,
        status_ms=0,
        battery_ms=0,
    )


class Rig:
    """One driver under test, its robot, and time: what each kind of robot provides."""

    clock: Clock
    driver: RobotDriver

    def __init__(self) -> None:
        self.rec = Recorder()

    def make(self, url: str, ros: int, docking: str = "") -> RobotDriver:
        return driver_for(url, ros, self.rec, self.clock, docking)

    async def until(self, cond: Callable[[], Any], seconds: float, what: str) -> None:
        """Wait until ``cond()`` holds, for at most ``seconds`` of the robot's clock."""
        raise NotImplementedError

    async def pass_time(self, seconds: float) -> None:
        """Let ``seconds`` of the robot's clock pass (to see that nothing more happens)."""
        raise NotImplementedError

    def where(self) -> tuple[float, float, float]:
        """Where the robot really is."""
        raise NotImplementedError

    def charging(self) -> bool | None:
        """Whether the robot charges now (None: the robot has no battery model)."""
        return None

    def speed(self) -> float:
        """How fast it really moves (m/s plus rad/s: turning on the spot counts)."""
        raise NotImplementedError

    async def cut(self) -> None:
        """The network to the robot goes."""
        raise NotImplementedError

    async def mend(self) -> None:
        """The network comes back."""
        raise NotImplementedError

    def refuse_goals(self, on: bool) -> None:
        """The robot's navigation takes no goal: none is ever acknowledged."""
        raise NotImplementedError

    def block(self, on: bool) -> None:
        """The robot's way is blocked: its navigation gives its goal up."""
        raise NotImplementedError

    async def close(self) -> None:
        await self.driver.close()


class SimRig(Rig):
    """A real driver against a simulated robot speaking its ROS, on a scaled clock."""

    def __init__(self, sim: Simulation, clock: Clock, ros: int, docking: str = "") -> None:
        super().__init__()
        self.sim = sim
        self.clock = clock
        self.driver = self.make(sim.urls[0], ros, docking)

    async def until(self, cond: Callable[[], Any], seconds: float, what: str) -> None:
        # Nothing to wait on for the simulated robot's own state: polled, every 10 ms of the
        # loop's time (virtual in this module), with an allowance on top of the clock's time.
        loop = asyncio.get_running_loop()
        deadline = loop.time() + self.clock.wall(seconds) + 10.0
        while not cond():
            if loop.time() > deadline:
                raise AssertionError(f"timed out waiting for {what}: {self.rec.kinds()}")
            await asyncio.sleep(0.01)

    async def pass_time(self, seconds: float) -> None:
        await self.clock.sleep(seconds)

    def where(self) -> tuple[float, float, float]:
        return self.sim.robots[0].pose

    def charging(self) -> bool | None:
        return self.sim.robots[0].charging

    def speed(self) -> float:
        vx, vy, wz = self.sim.robots[0].velocity
        return math.hypot(vx, vy) + abs(wz)

    def refuse_goals(self, on: bool) -> None:
        self.sim.robots[0].ignore_goals(on)

    def block(self, on: bool) -> None:
        self.sim.robots[0].block_path(on)

    async def cut(self) -> None:
        await self.sim.stop_endpoint(0)

    async def mend(self) -> None:
        await self.sim.start_endpoint(0)

    async def close(self) -> None:
        await super().close()
        await self.sim.close()


class FakeRig(Rig):
    """The fake driver on a clock only the test moves."""

    STEP = 0.05

    def __init__(self) -> None:
        super().__init__()
        self.clock = self.fake_clock = FakeClock()
        x, y, yaw = HOME.x, HOME.y, HOME.yaw
        self.driver = self.make(f"fake://r1?x={x}&y={y}&yaw={yaw}", 1)
        assert isinstance(self.driver, FakeDriver)
        self.fake = self.driver

    async def until(self, cond: Callable[[], Any], seconds: float, what: str) -> None:
        end = self.fake_clock.now() + seconds
        while not cond():
            if self.fake_clock.now() >= end:
                raise AssertionError(f"timed out waiting for {what}: {self.rec.kinds()}")
            await self.fake_clock.advance(self.STEP)

    async def pass_time(self, seconds: float) -> None:
        end = self.fake_clock.now() + seconds
        while self.fake_clock.now() < end:
            await self.fake_clock.advance(self.STEP)

    def where(self) -> tuple[float, float, float]:
        assert self.fake.true_pose is not None
        return self.fake.true_pose

    def speed(self) -> float:
        vx, vy, wz = self.fake.velocity
        return math.hypot(vx, vy) + abs(wz)

    def refuse_goals(self, on: bool) -> None:
        if on:
            self.fake.refuse_next_goal()

    def block(self, on: bool) -> None:
        self.fake.block_path(on)

    async def cut(self) -> None:
        self.fake.drop_link("network unreachable")

    async def mend(self) -> None:
        self.fake.restore_link()


@pytest.fixture(params=["ros1", "ros2", "ros2-docking", "fake"])
async def rig(request: pytest.FixtureRequest) -> AsyncIterator[Rig]:
    """Each driver in turn, started, its robot at home1 (its dock)."""
    made: Rig
    if request.param == "fake":
        made = FakeRig()
    else:
        ros = 1 if request.param == "ros1" else 2
        docking = request.param == "ros2-docking"
        clock = test_clock(TIME_SCALE)
        sim = await start_simulation(
            1,
            port=0,
            map_path=demo_map_path(),
            clock=clock,
            ros=ros,
            amcl="real",
            docking=docking,
        )
        made = SimRig(sim, clock, ros, "nav2" if docking else "")
    try:
        made.driver.start()
        yield made
    finally:
        await made.close()


async def up(rig: Rig) -> None:
    await rig.until(lambda: rig.driver.up, 10.0, "the link up")


async def moving(rig: Rig) -> None:
    await rig.until(lambda: rig.speed() > 0.1, 20.0, "the robot moving")


async def stopped(rig: Rig, seconds: float = 5.0) -> None:
    await rig.until(lambda: rig.speed() < 0.01, seconds, "the robot stopped")


def distance(a: tuple[float, ...], b: tuple[float, ...]) -> float:
    return math.hypot(a[0] - b[0], a[1] - b[1])


async def test_the_link_comes_up_only_with_a_pose(rig: Rig) -> None:
    await up(rig)
    kinds = [k for k, _ in rig.rec.events]
    assert kinds.count("up") == 1
    assert "pose" in kinds[: kinds.index("up")], kinds  # the core knows where it is at once
    assert rig.driver.pose is not None and distance(rig.driver.pose, (HOME.x, HOME.y)) < 0.3
    assert rig.driver.last_failure == "" and rig.driver.goal_id is None
    assert rig.driver.heartbeat_timeout() > 0 and rig.driver.kind


async def test_a_goal_ends_succeeded_at_the_goal(rig: Rig) -> None:
    await up(rig)
    handle = await rig.driver.send_goal(*NEAR)
    assert rig.driver.goal_id == handle
    await rig.until(lambda: rig.rec.ends(handle), 30.0, "the goal's end")
    [(kind, (_, status, text))] = rig.rec.ends(handle)
    assert (kind, status) == ("done", rb.GoalStatus.SUCCEEDED), text
    assert distance(rig.where(), NEAR) < 0.25
    assert rig.driver.pose is not None and distance(rig.driver.pose, NEAR) < 0.3
    assert rig.driver.goal_id is None


async def test_a_cancelled_goal_stops_the_robot_and_is_never_reported(rig: Rig) -> None:
    await up(rig)
    handle = await rig.driver.send_goal(*FAR)
    await moving(rig)
    await rig.driver.cancel_goal()
    assert rig.driver.goal_id is None
    await stopped(rig)
    there = rig.where()
    await rig.pass_time(2.0)
    assert distance(rig.where(), there) < 0.02, "the robot drove on"
    assert rig.rec.ends(handle) == []


async def test_a_new_goal_replaces_the_one_under_way_without_a_failure(rig: Rig) -> None:
    await up(rig)
    first = await rig.driver.send_goal(*FAR)
    await moving(rig)
    second = await rig.driver.send_goal(*NEAR)
    assert second != first and rig.driver.goal_id == second
    await rig.until(lambda: rig.rec.ends(second), 30.0, "the second goal's end")
    [(kind, (_, status, text))] = rig.rec.ends(second)
    assert (kind, status) == ("done", rb.GoalStatus.SUCCEEDED), text
    assert distance(rig.where(), NEAR) < 0.25
    await rig.pass_time(1.0)
    assert rig.rec.ends(first) == [], "the replaced goal was reported"


async def test_a_goal_the_robot_never_takes_is_lost_once(rig: Rig) -> None:
    await up(rig)
    rig.refuse_goals(True)
    handle = await rig.driver.send_goal(*NEAR)
    await rig.until(lambda: rig.rec.ends(handle), 30.0, "the goal lost")
    [(kind, (_, reason, cause))] = rig.rec.ends(handle)
    assert (kind, cause) == ("lost", GoalLoss.NOT_ACCEPTED) and reason, reason
    assert rig.driver.goal_id is None
    assert distance(rig.where(), (HOME.x, HOME.y)) < 0.05, "the robot drove"
    rig.refuse_goals(False)
    await rig.pass_time(1.0)
    assert len(rig.rec.ends(handle)) == 1


async def test_a_blocked_way_ends_the_goal_aborted_with_the_robots_reason(rig: Rig) -> None:
    await up(rig)
    rig.block(True)
    handle = await rig.driver.send_goal(*FAR)
    await rig.until(lambda: rig.rec.ends(handle), 30.0, "the goal's end")
    [(kind, (_, status, text))] = rig.rec.ends(handle)
    assert (kind, status) == ("done", rb.GoalStatus.ABORTED) and text, text
    assert rig.driver.goal_id is None
    rig.block(False)
    again = await rig.driver.send_goal(*NEAR)  # a failed goal leaves the link usable
    await rig.until(lambda: rig.rec.ends(again), 30.0, "the next goal's end")
    assert rig.rec.ends(again)[0][1][1] is rb.GoalStatus.SUCCEEDED


async def test_halt_stops_the_robot_and_refuses_what_follows(rig: Rig) -> None:
    await up(rig)
    handle = await rig.driver.send_goal(*FAR)
    await moving(rig)
    await rig.driver.halt()
    await stopped(rig)
    there = rig.where()
    await rig.pass_time(1.0)
    assert distance(rig.where(), there) < 0.02, "the robot drove on"
    assert not [e for e in rig.rec.ends(handle) if e[1][1] is rb.GoalStatus.SUCCEEDED]
    with pytest.raises(LinkError):
        await rig.driver.send_goal(*NEAR)
    with pytest.raises(LinkError):
        await rig.driver.teleop(0.2, 0.0, 0.0)


async def test_a_joystick_that_goes_quiet_stops_the_robot(
    rig: Rig, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.WARNING, logger="serveur.robots.deadman")
    await up(rig)
    await rig.driver.teleop(0.0, 0.0, 0.5)  # turning on the spot: no wall in the way
    await moving(rig)
    # No second twist: the driver's own switch stops the robot, half a wall second later.
    await rig.until(
        lambda: "no joystick command" in caplog.text, 2.0 * rig.clock.time_scale, "the switch"
    )
    await stopped(rig)
    there = rig.where()
    await rig.pass_time(1.0)
    assert abs(math.remainder(rig.where()[2] - there[2], math.tau)) < 0.02


async def test_initial_pose_puts_the_robot_there(rig: Rig) -> None:
    await up(rig)
    # At once after the link came up: a ROS1 link subscribes to an idle robot's /amcl_pose at
    # one message a second, and rosbridge's throttle drops (not delays) the one pose AMCL
    # publishes after /initialpose when it comes sooner than that after the latched first one
    # — the link must lift the throttle until the new pose has come.
    spot = (HOME.x + 0.5, HOME.y - 0.5, 0.0)
    await rig.driver.initial_pose(*spot)
    await rig.until(
        lambda: rig.driver.pose is not None and distance(rig.driver.pose, spot) < 0.1,
        10.0,
        "the new pose reported",
    )
    assert distance(rig.where(), spot) < 0.1


async def test_scans_come_while_wanted_and_stop_after(rig: Rig) -> None:
    await up(rig)
    await rig.driver.want_scan(True)
    await rig.until(lambda: rig.rec.count("scan") >= 3, 10.0, "scans")
    await rig.driver.want_scan(False)
    await rig.pass_time(0.5)  # one may be on its way
    mark = len(rig.rec.events)
    await rig.pass_time(1.0)
    assert rig.rec.count("scan", mark) == 0
    await rig.driver.want_pose(True)  # accepted by every driver, whatever it does with it
    await rig.driver.want_pose(False)


@pytest.mark.cuts_links
async def test_a_dropped_link_is_down_once_and_up_once(
    rig: Rig, caplog: pytest.LogCaptureFixture
) -> None:
    caplog.set_level(logging.INFO, logger="serveur.robots")
    await up(rig)
    for how in ("network", "drop"):
        mark, logged = len(rig.rec.events), len(caplog.records)
        if how == "network":
            await rig.cut()
            await rig.until(lambda: not rig.driver.up, 10.0, "the link down")
            with pytest.raises(LinkError):
                await rig.driver.send_goal(*NEAR)
            await rig.pass_time(1.0)  # retries fail meanwhile: still one "down"
            await rig.mend()
        else:
            await rig.driver.drop()  # the driver's own fault hook: it reconnects by itself
        back = lambda m=mark: rig.rec.count("up", m) == 1  # noqa: E731
        await rig.until(back, 30.0, f"the link back ({how})")
        await rig.pass_time(1.0)
        assert [k for k in rig.rec.kinds(mark) if k != "failed"] == ["down", "up"], how
        assert rig.driver.up
        lines = [r.getMessage() for r in caplog.records[logged:]]
        assert sum("r1: link down (" in m for m in lines) == 1, lines
        assert sum("r1: link up (" in m for m in lines) == 1, lines


def _driver_tasks() -> list[asyncio.Task[Any]]:
    """Tasks running code of serveur/robots (a driver's), other than this test's own."""
    out = []
    for task in asyncio.all_tasks():
        coro = task.get_coro()
        code = getattr(coro, "cr_code", None)
        if not task.done() and code is not None and ROBOTS in Path(code.co_filename).parents:
            out.append(task)
    return out


async def test_close_ends_cleanly(rig: Rig) -> None:
    await up(rig)
    await rig.driver.send_goal(*FAR)
    await rig.driver.want_scan(True)
    await moving(rig)
    await rig.driver.close()
    assert not rig.driver.up
    assert rig.rec.events[-1] == ("down", ("server shutting down",))
    mark = len(rig.rec.events)
    await rig.until(lambda: not _driver_tasks(), 2.0, "the driver's tasks to end")
    await rig.pass_time(1.0)
    assert rig.rec.events[mark:] == []
    with pytest.raises(LinkError):
        await rig.driver.send_goal(*NEAR)
    await rig.driver.close()  # a second close is harmless


async def test_a_dock_ends_succeeded_on_the_charger_and_undock_takes_it_off(rig: Rig) -> None:
    await up(rig)
    dock = (HOME.x, HOME.y, HOME.yaw)  # the simulated robot's charger: its home
    away = await rig.driver.send_goal(*NEAR)
    await rig.until(lambda: rig.rec.ends(away), 30.0, "the robot away from its dock")
    assert rig.charging() in (False, None)
    handle = await rig.driver.dock(*dock, "home1")
    assert rig.driver.goal_id == handle
    await rig.until(lambda: rig.rec.ends(handle), 60.0, "the dock's end")
    [(kind, (_, status, text))] = rig.rec.ends(handle)
    assert (kind, status) == ("done", rb.GoalStatus.SUCCEEDED), text
    assert rig.driver.goal_id is None
    assert distance(rig.where(), dock) < 0.05, rig.where()  # on the contacts
    await rig.until(lambda: rig.charging() in (True, None), 2.0, "the robot charging")
    # With a docking server the robot is off its dock when undock returns; without one there
    # is nothing to do, and the next goal drives it off.
    await rig.driver.undock()
    assert rig.driver.goal_id is None
    again = await rig.driver.send_goal(*NEAR)  # the next goal goes as any other
    await rig.until(lambda: rig.rec.ends(again), 30.0, "the next goal's end")
    assert rig.rec.ends(again)[0][1][1] is rb.GoalStatus.SUCCEEDED
    assert rig.charging() in (False, None)
    await rig.driver.undock()  # off the dock already: nothing to do, no error


async def test_a_cancelled_dock_stops_the_robot_and_is_never_reported(rig: Rig) -> None:
    await up(rig)
    far = await rig.driver.send_goal(*FAR)
    await rig.until(lambda: rig.rec.ends(far), 60.0, "the robot across the room")
    handle = await rig.driver.dock(HOME.x, HOME.y, HOME.yaw, "home1")
    await moving(rig)
    await rig.driver.cancel_goal()
    assert rig.driver.goal_id is None
    await stopped(rig)
    there = rig.where()
    await rig.pass_time(2.0)
    assert distance(rig.where(), there) < 0.02, "the robot drove on"
    assert distance(there, (HOME.x, HOME.y)) > 1.0
    assert rig.rec.ends(handle) == []
