"""The simulator against what a real ROS1 stack does (rosbridge 0.11, actionlib, move_base, amcl),
where an idealised robot would differ: shared/notes/rosbridge.md lists these facts, checked on a
real stack; the rules' sources are in serveur.sim.robot's and serveur.sim.bridge's docstrings.

Every test talks to a simulated robot over a real websocket. Nothing sleeps to wait: a wait
reads frames until a condition holds, with a wall-clock timeout. Time runs on a ScaledClock
(``SCALE`` times real time), or on a FakeClock where a goal must stay PENDING until the test
lets time move.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import math
from collections.abc import AsyncIterator, Callable
from typing import Any

import cbor2
import pytest

from serveur.clock import FakeClock, ScaledClock
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import rosbridge as rb
from serveur.sim.robot import TICK
from tests.sim.test_sim_badinput import FAR, T1, Raw, open_raw, shut, statuses

SCALE = 20.0
WAIT = 10.0  # wall seconds; every wait returns as soon as its condition holds
SAS_TEXT = "This goal was canceled because another goal was received by the simple action server"
Status = rb.GoalStatus


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start_simulation(1, port=0, clock=ScaledClock(SCALE), seed=5)
    try:
        yield s
    finally:
        await shut(s)


@pytest.fixture
async def fake() -> AsyncIterator[tuple[Simulation, FakeClock]]:
    """A robot whose time moves only when the test advances its FakeClock."""
    clock = FakeClock()
    s = await start_simulation(1, port=0, clock=clock, seed=5)
    try:
        # Plans are then made at once (a first plan to a spot runs in a thread meanwhile).
        assert await s.warm_plans([FAR[:2], T1[:2]]) == 2
        yield s, clock
    finally:
        await shut(s)


def goal(gid: str, at: tuple[float, float, float], goal_stamp: float) -> dict[str, Any]:
    """A /move_base/goal publish whose goal_id.stamp is ``goal_stamp`` (0.0: the zero stamp)."""
    msg = rb.move_base_action_goal(gid, *at, stamp=goal_stamp or 1.0, goal_stamp=goal_stamp)
    return rb.op_publish("/move_base/goal", msg)


def cancel(gid: str = "", stamp: float = 0.0) -> dict[str, Any]:
    return rb.op_publish("/move_base/cancel", rb.goal_id(gid, stamp))


async def result_of(c: Raw, gid: str) -> dict[str, Any]:
    """The GoalStatus of ``gid``'s /move_base/result (the client subscribed to it)."""
    msg = await c.topic("/move_base/result", lambda m: m["status"]["goal_id"]["id"] == gid)
    return msg["status"]  # type: ignore[no-any-return]


async def status_where(c: Raw, pred: Callable[[dict[str, int]], bool]) -> dict[str, Any]:
    """The next /move_base/status whose {goal id: status} satisfies ``pred``."""
    return await c.topic("/move_base/status", lambda m: pred(statuses(m)))


def entry(msg: dict[str, Any], gid: str) -> dict[str, Any]:
    """``gid``'s GoalStatus in a GoalStatusArray."""
    return next(s for s in msg["status_list"] if s["goal_id"]["id"] == gid)


async def actionlib_client(sim: Simulation) -> Raw:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/status"))
    await c.send(rb.op_subscribe("/move_base/result"))
    await c.ping()  # subscribed (a FakeClock robot publishes no status before time moves)
    return c


def status_of(sim: Simulation, gid: str) -> Status | None:
    """What robot 0's move_base says of ``gid`` now (None: not in its status list)."""
    return next((st for g, st, _ in sim.robots[0].goal_statuses if g == gid), None)


async def run_until(clock: FakeClock, cond: Callable[[], bool], sim_limit: float = 120.0) -> None:
    """Advance the FakeClock a few ticks at a time until ``cond()`` holds."""

    async def run() -> None:
        moved = 0.0
        while not cond():
            assert moved < sim_limit, "condition not met within the simulated time limit"
            await clock.advance(4 * TICK)
            moved += 4 * TICK

    await asyncio.wait_for(run(), WAIT)


# -- 1. SimpleActionServer's stamp rule, preemption texts ----------------------------------------


async def test_goal_stamped_before_the_accepted_one_is_recalled_and_the_active_goal_runs(
    sim: Simulation,
) -> None:
    robot = sim.robots[0]
    c = await actionlib_client(sim)
    t0 = robot.epoch()
    await c.send(goal("a", FAR, t0))
    await status_where(c, lambda s: s.get("a") == Status.ACTIVE)
    await c.send(goal("late", T1, t0 - 10.0))  # delayed on the way: older than "a"
    late = await result_of(c, "late")
    assert late["status"] == Status.RECALLED and late["text"] == SAS_TEXT
    st = await status_where(c, lambda s: "late" in s)
    assert statuses(st)["a"] == Status.ACTIVE  # untouched
    x0, y0, _ = robot.pose
    st = await status_where(c, lambda s: math.hypot(robot.pose[0] - x0, robot.pose[1] - y0) > 0.3)
    assert statuses(st)["a"] == Status.ACTIVE  # and still driving
    # A goal stamped like the accepted one is not older: it is taken and preempts "a".
    await c.send(goal("same", T1, t0))
    a = await result_of(c, "a")
    assert a["status"] == Status.PREEMPTED and a["text"] == SAS_TEXT
    await status_where(c, lambda s: s.get("same") == Status.ACTIVE)


async def test_zero_stamped_goal_gets_the_robots_clock_and_is_always_newest(
    fake: tuple[Simulation, FakeClock],
) -> None:
    sim, clock = fake
    robot = sim.robots[0]
    c = await actionlib_client(sim)
    future = robot.epoch() + 5.0  # a client clock ahead of the robot's
    await c.send(goal("ahead", FAR, future))
    await run_until(clock, lambda: status_of(sim, "ahead") == Status.ACTIVE)
    # A zero stamp is now on the robot's clock: older than "ahead", so recalled.
    now = robot.epoch()
    await c.send(goal("zero1", T1, 0.0))
    z1 = await result_of(c, "zero1")
    assert z1["status"] == Status.RECALLED and z1["text"] == SAS_TEXT
    assert rb.from_ros_time(z1["goal_id"]["stamp"]) == pytest.approx(now, abs=1e-6)
    assert now < future
    assert status_of(sim, "ahead") == Status.ACTIVE
    # Once the robot's clock passed "ahead", zero-stamped goals are the newest again.
    await run_until(clock, lambda: robot.epoch() > future)
    await c.send(goal("zero2", T1, 0.0))
    ahead = await result_of(c, "ahead")
    assert ahead["status"] == Status.PREEMPTED and ahead["text"] == SAS_TEXT
    await run_until(clock, lambda: status_of(sim, "zero2") == Status.ACTIVE)
    await c.send(goal("zero3", FAR, 0.0))  # zero after zero: newest, preempts
    z2 = await result_of(c, "zero2")
    assert z2["status"] == Status.PREEMPTED and z2["text"] == SAS_TEXT
    assert rb.from_ros_time(z2["goal_id"]["stamp"]) > future


async def test_simple_goal_is_stamped_by_the_robot_whatever_its_header(sim: Simulation) -> None:
    c = await actionlib_client(sim)
    robot = sim.robots[0]
    await c.send(goal("a", FAR, robot.epoch()))
    await status_where(c, lambda s: s.get("a") == Status.ACTIVE)
    # RViz's 2D Nav Goal: move_base wraps it in a goal with no id and a zero goal stamp, so an
    # old header stamp does not make it older than "a".
    before = robot.epoch()
    await c.send(rb.op_publish("/move_base_simple/goal", rb.pose_stamped(*T1, stamp=1.0)))
    a = await result_of(c, "a")
    assert a["status"] == Status.PREEMPTED and a["text"] == SAS_TEXT
    st = await status_where(c, lambda s: any(g.startswith("/move_base-") for g in s))
    gid = next(g for g in statuses(st) if g.startswith("/move_base-"))
    assert before <= rb.from_ros_time(entry(st, gid)["goal_id"]["stamp"]) <= robot.epoch()


# -- 2. a robot clock offset from the server's ---------------------------------------------------


async def test_robot_clock_offset_stamps_everything_and_recalls_server_stamped_goals() -> None:
    clock = ScaledClock(SCALE)
    sim = await start_simulation(1, port=0, clock=clock, seed=5, clock_offset=300.0)
    try:
        robot = sim.robots[0]
        assert robot.clock_offset == 300.0
        c = await actionlib_client(sim)
        await c.send(rb.op_subscribe("/map"))
        grid = await c.topic("/map")  # latched: stamped when the simulation started
        assert clock.epoch() + 290.0 < rb.from_ros_time(grid["header"]["stamp"])
        await c.send(rb.op_subscribe("/odom"))
        before = clock.epoch() + 300.0
        reply = await c.ping()
        assert before <= rb.from_ros_time(reply["values"]["time"]) <= clock.epoch() + 300.0
        for topic in ("/odom", "/move_base/status"):
            msg = await c.topic(topic)
            stamp = rb.from_ros_time(msg["header"]["stamp"])
            assert before - 0.5 <= stamp <= clock.epoch() + 300.0, topic  # 0.5: a tick's stamp
        before = clock.epoch() + 300.0
        await c.send(goal("zero", FAR, 0.0))  # roslibpy-style: accepted, stamped +300 s
        st = await status_where(c, lambda s: s.get("zero") == Status.ACTIVE)
        stamp = rb.from_ros_time(entry(st, "zero")["goal_id"]["stamp"])
        assert before <= stamp <= clock.epoch() + 300.0
        # A server stamping with its own (un-offset) clock is 300 s in the robot's past.
        await c.send(goal("server", T1, clock.epoch()))
        srv = await result_of(c, "server")
        assert srv["status"] == Status.RECALLED and srv["text"] == SAS_TEXT
        assert statuses(await c.topic("/move_base/status"))["zero"] == Status.ACTIVE
        await c.send(goal("zero2", T1, 0.0))  # a zero-stamped goal is accepted
        assert (await result_of(c, "zero"))["status"] == Status.PREEMPTED
        await status_where(c, lambda s: s.get("zero2") == Status.ACTIVE)
    finally:
        await shut(sim)


def test_cli_takes_clock_offset_and_amcl() -> None:
    import argparse

    from serveur.robot_sim import add_sim_arguments

    p = argparse.ArgumentParser()
    add_sim_arguments(p)
    ns = p.parse_args([])
    assert ns.clock_offset == 0.0 and ns.amcl == "continuous"
    ns = p.parse_args(["--clock-offset", "-12.5", "--amcl", "real"])
    assert ns.clock_offset == -12.5 and ns.amcl == "real"
    with pytest.raises(SystemExit):
        p.parse_args(["--amcl", "perfect"])


# -- 3. move_base ignores /cmd_vel -----------------------------------------------------------------


async def test_cmd_vel_does_not_touch_an_active_goal(sim: Simulation) -> None:
    c = await actionlib_client(sim)
    await c.send(rb.op_subscribe("/odom"))
    robot = sim.robots[0]
    await c.send(goal("g", T1, robot.epoch()))
    await status_where(c, lambda s: s.get("g") == Status.ACTIVE)
    for _ in range(5):  # a joystick held while the robot drives its goal
        await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.7)))
        await c.topic("/odom")
    st = await status_where(c, lambda s: True)
    assert statuses(st)["g"] == Status.ACTIVE
    assert entry(st, "g")["text"] == "This goal has been accepted by the simple action server"
    done = await result_of(c, "g")  # the controller kept driving to the goal
    assert done["status"] == Status.SUCCEEDED
    x, y, yaw = robot.pose
    assert math.hypot(x - T1[0], y - T1[1]) <= 0.1
    assert abs(math.remainder(yaw - T1[2], math.tau)) <= 0.1


async def test_cmd_vel_does_not_touch_a_pending_goal(fake: tuple[Simulation, FakeClock]) -> None:
    sim, clock = fake
    robot = sim.robots[0]
    c = await actionlib_client(sim)
    await c.send(goal("p", T1, robot.epoch()))
    await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.0)))
    await c.ping()  # both handled; no time passed, so the goal has not started
    assert robot.goal_statuses == [("p", Status.PENDING, "")]
    await run_until(clock, lambda: status_of(sim, "p") == Status.SUCCEEDED)
    assert math.hypot(robot.pose[0] - T1[0], robot.pose[1] - T1[1]) <= 0.1


async def test_cmd_vel_drives_a_robot_without_goal(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/odom"))
    robot = sim.robots[0]
    y0 = robot.pose[1]
    await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.4, 0.0, 0.0)))  # home faces a wall
    await c.topic("/odom", lambda m: abs(m["twist"]["twist"]["linear"]["x"]) > 0.05)
    await c.topic("/odom", lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)  # stale: stops
    assert robot.pose[1] < y0 - 0.02


# -- cancel (actionlib ActionServer.internal_cancel_callback, move_base's executeCb) -------------


async def test_cancel_all_preempts_the_active_goal_and_recalls_a_pending_one(
    fake: tuple[Simulation, FakeClock],
) -> None:
    sim, clock = fake
    robot = sim.robots[0]
    c = await actionlib_client(sim)
    await c.send(goal("a", FAR, robot.epoch()))
    await run_until(clock, lambda: status_of(sim, "a") == Status.ACTIVE)
    await status_where(c, lambda s: s.get("a") == Status.ACTIVE)
    await c.send(cancel())  # {stamp: 0, id: ""}: everything
    st = await status_where(c, lambda s: s.get("a") != Status.ACTIVE)
    assert statuses(st)["a"] == Status.PREEMPTING  # until move_base's next control cycle
    await run_until(clock, lambda: status_of(sim, "a") == Status.PREEMPTED)
    a = await result_of(c, "a")
    assert a["status"] == Status.PREEMPTED and a["text"] == ""  # move_base's setPreempted()
    # A goal not started yet (no time has passed) is RECALLED.
    await c.send(goal("b", T1, robot.epoch()))
    await c.send(rb.op_publish("/move_base/cancel", {}))  # roslibpy's cancel-all
    b = await result_of(c, "b")
    assert b["status"] == Status.RECALLED
    await run_until(clock, lambda: robot.velocity == (0.0, 0.0, 0.0))


async def test_cancel_by_stamp_and_goals_stamped_before_the_last_cancel(
    sim: Simulation,
) -> None:
    robot = sim.robots[0]
    c = await actionlib_client(sim)
    t0 = robot.epoch()
    await c.send(goal("a", FAR, t0))
    await status_where(c, lambda s: s.get("a") == Status.ACTIVE)
    await c.send(cancel(stamp=t0 + 1.0))  # every goal stamped at or before t0 + 1
    assert (await result_of(c, "a"))["status"] == Status.PREEMPTED
    # The action server remembers that stamp: a goal stamped at or before it is canceled.
    await c.send(goal("b", T1, t0 + 0.5))
    b = await result_of(c, "b")
    assert b["status"] == Status.RECALLED
    assert b["text"] == (
        "This goal handle was canceled by the action server because its timestamp is before "
        "the timestamp of the last cancel request"
    )
    await c.send(goal("c", T1, 0.0))  # zero stamps are exempt
    await status_where(c, lambda s: s.get("c") == Status.ACTIVE)


# -- 4. status ops only after set_level ---------------------------------------------------------


async def ops_until_ping(c: Raw, rid: str) -> list[dict[str, Any]]:
    """Every op received up to the reply to a get_time call sent now (replies keep order)."""
    await c.send(rb.op_call_service("/rosapi/get_time", id=rid))
    seen: list[dict[str, Any]] = []

    def keep(m: dict[str, Any]) -> bool:
        seen.append(m)
        return m["op"] == "service_response" and m.get("id") == rid

    await c.wait_for(keep)
    return seen


async def test_status_ops_only_after_set_level_and_at_that_level(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send('{"op": "frobnicate", "id": "x1"}')  # an error
    await c.send(rb.op_unsubscribe("/odom", id="x2"))  # a warning: not subscribed
    assert [m["op"] for m in await ops_until_ping(c, "p1")] == ["service_response"]
    await c.send(rb.op_set_level("error"))
    await c.send('{"op": "frobnicate", "id": "x3"}')
    await c.send(rb.op_unsubscribe("/odom", id="x4"))
    seen = await ops_until_ping(c, "p2")
    assert [(m["op"], m.get("level"), m.get("id")) for m in seen] == [
        ("status", "error", "x3"),
        ("service_response", None, "p2"),
    ]
    await c.send(rb.op_set_level("warning"))
    await c.send('{"op": "frobnicate", "id": "x5"}')
    await c.send(rb.op_unsubscribe("/odom", id="x6"))
    seen = await ops_until_ping(c, "p3")
    assert [(m["op"], m.get("level"), m.get("id")) for m in seen] == [
        ("status", "error", "x5"),
        ("status", "warning", "x6"),
        ("service_response", None, "p3"),
    ]
    await c.send(rb.op_set_level("none"))
    await c.send('{"op": "frobnicate", "id": "x7"}')
    assert [m["op"] for m in await ops_until_ping(c, "p4")] == ["service_response"]
    # A failed service call still gets its failed service_response, with no status.
    await c.send(rb.op_call_service("/no/such", id="s1"))
    resp = await c.wait_for(lambda m: m["op"] in ("service_response", "status"))
    assert resp["op"] == "service_response" and resp["id"] == "s1" and resp["result"] is False


# -- 5. AMCL like the amcl node -----------------------------------------------------------------


@pytest.fixture
async def real_amcl() -> AsyncIterator[Simulation]:
    s = await start_simulation(1, port=0, clock=ScaledClock(SCALE), seed=5, amcl="real")
    try:
        yield s
    finally:
        await shut(s)


def _xy_yaw(msg: dict[str, Any]) -> tuple[float, float, float]:
    return rb.pose_from_msg(msg["pose"]["pose"])


async def _no_pose_during(c: Raw, seconds: int) -> None:
    """``seconds`` s of simulated time (counted by 1 Hz /battery_state) bring no /amcl_pose."""
    for _ in range(seconds):
        op = await c.wait_for(lambda m: m.get("topic") in ("/amcl_pose", "/battery_state"))
        assert op["topic"] == "/battery_state", "a parked robot published a pose"


async def test_real_amcl_is_latched_and_silent_while_parked(real_amcl: Simulation) -> None:
    robot = real_amcl.robots[0]
    assert robot.amcl == "real"
    first = await open_raw(real_amcl)
    await first.send(rb.op_subscribe("/amcl_pose"))
    await first.send(rb.op_subscribe("/battery_state"))
    pose = await first.topic("/amcl_pose")  # the start pose
    assert math.dist(_xy_yaw(pose)[:2], robot.home[:2]) < 0.1
    await _no_pose_during(first, 3)
    # Latched: a new subscriber gets that same message at once, before anything sent later.
    late = await open_raw(real_amcl)
    await late.send(rb.op_subscribe("/amcl_pose"))
    seen = await ops_until_ping(late, "p")
    assert [m["op"] for m in seen] == ["publish", "service_response"]
    assert seen[0]["topic"] == "/amcl_pose" and seen[0]["msg"] == pose


async def test_real_amcl_publishes_after_02_m_or_30_degrees_and_after_initialpose(
    real_amcl: Simulation,
) -> None:
    robot = real_amcl.robots[0]
    c = await actionlib_client(real_amcl)
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.send(rb.op_subscribe("/battery_state"))
    poses = [await c.topic("/amcl_pose")]
    await c.send(goal("g", T1, robot.epoch()))
    while True:
        op = await c.wait_for(lambda m: m.get("topic") in ("/amcl_pose", "/move_base/result"))
        if op["topic"] == "/move_base/result":
            assert op["msg"]["status"]["status"] == Status.SUCCEEDED
            break
        poses.append(op["msg"])
    assert len(poses) >= 4
    noise = 0.05  # AMCL's estimate is noisy by ~1 cm, 0.3 degrees
    for a, b in itertools.pairwise(poses):
        (xa, ya, ta), (xb, yb, tb) = _xy_yaw(a), _xy_yaw(b)
        moved = math.hypot(xb - xa, yb - ya)
        turned = abs(math.remainder(tb - ta, math.tau))
        assert moved > 0.2 - noise or turned > math.radians(30) - noise, (moved, turned)
        assert b["header"]["seq"] == a["header"]["seq"] + 1  # nothing published in between
    await c.topic("/battery_state")  # (the robot may settle over the last tick)
    await _no_pose_during(c, 2)  # parked at the table
    # /initialpose (RViz's 2D Pose Estimate) makes amcl publish the pose it was given, even a
    # few centimetres away.
    x, y, yaw = robot.pose
    await c.send(
        rb.op_publish(
            "/initialpose", rb.pose_with_covariance_stamped(x + 0.05, y, yaw, stamp=robot.epoch())
        )
    )
    moved = await c.topic("/amcl_pose")
    assert _xy_yaw(moved)[0] == pytest.approx(x + 0.05, abs=0.05)
    await _no_pose_during(c, 2)


async def test_continuous_amcl_is_the_default(sim: Simulation) -> None:
    assert sim.robots[0].amcl == "continuous"
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/amcl_pose"))
    seqs = [(await c.topic("/amcl_pose"))["header"]["seq"] for _ in range(5)]  # parked, 10 Hz
    assert seqs == list(range(seqs[0], seqs[0] + 5))


# -- 6. rosbridge 0.11's cbor and fragment quirks -----------------------------------------------


async def test_cbor_sends_nothing_for_types_with_fixed_size_arrays(sim: Simulation) -> None:
    binary, plain = await open_raw(sim), await open_raw(sim)
    for topic in ("/amcl_pose", "/odom", "/scan"):
        await binary.send(rb.op_subscribe(topic, compression="cbor"))
    await plain.send(rb.op_subscribe("/odom"))
    scans = 0
    while scans < 5:  # a second of simulated time: 20 /odom and 10 /amcl_pose published
        frame = await asyncio.wait_for(binary.ws.recv(), WAIT)
        assert isinstance(frame, bytes)
        op = cbor2.loads(frame)
        assert op["topic"] == "/scan", "a covariance message was CBOR-encoded"
        scans += 1
    await plain.topic("/odom")  # published all along, in JSON
    # The same client in JSON gets them again.
    await binary.send(rb.op_subscribe("/odom", compression="none"))

    async def next_odom() -> dict[str, Any]:
        while True:
            frame = await binary.ws.recv()
            if isinstance(frame, str) and json.loads(frame).get("topic") == "/odom":
                return json.loads(frame)  # type: ignore[no-any-return]

    odom = await asyncio.wait_for(next_odom(), WAIT)
    assert len(odom["msg"]["pose"]["covariance"]) == 36


async def _fragments(c: Raw) -> list[dict[str, Any]]:
    """The fragment ops of the next fragmented message (they come one after the other)."""
    first = await c.wait_for(lambda m: m["op"] == "fragment" and m["num"] == 0)
    parts = [first]
    while len(parts) < int(first["total"]):  # ((len - 1) / size) + 1: floor is the count
        nxt = await c.wait_for(lambda m: True)
        assert nxt["op"] == "fragment" and nxt["id"] == first["id"], nxt
        parts.append(nxt)
    return parts


async def test_fragment_size_cuts_frames_with_a_float_total(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/battery_state", fragment_size=100))
    parts = await _fragments(c)
    text = "".join(p["data"] for p in parts)
    assert [p["num"] for p in parts] == list(range(len(parts)))
    assert all(len(p["data"]) <= 100 for p in parts) and len(parts) >= 3
    total = parts[0]["total"]
    assert isinstance(total, float) and total == (len(text) - 1) / 100 + 1  # Python 3 division
    assert parts[0]["id"] == 0  # a publish has no id: fragmentation.py's seed, always 0
    op = json.loads(text)
    assert op["op"] == "publish" and op["topic"] == "/battery_state"
    # fragment_size holds for the client's every frame, and a reply's fragments carry its id.
    await c.send(rb.op_call_service("/rosapi/topics", id="t1"))
    parts = await _fragments(c)
    while parts[0]["id"] != "t1":  # battery messages go on meanwhile
        parts = await _fragments(c)
    reply = json.loads("".join(p["data"] for p in parts))
    assert reply["op"] == "service_response" and reply["id"] == "t1"
    assert set(reply["values"]["topics"]) == set(rb.TOPIC_TYPES)
    # Short frames go whole.
    await c.send(rb.op_unsubscribe("/battery_state"))
    await c.send(
        {"op": "call_service", "service": "/rosapi/get_time", "id": 7, "fragment_size": 500}
    )
    resp = await c.wait_for(lambda m: m["op"] == "service_response")
    assert resp["id"] == 7


def test_fragment_ops_total_is_fractional_on_python3() -> None:
    parts = rb.fragment_ops("x" * 250, 100, "m")
    assert [p["num"] for p in parts] == [0, 1, 2]
    assert [len(p["data"]) for p in parts] == [100, 100, 50]
    assert all(p["total"] == pytest.approx(3.49) and p["id"] == "m" for p in parts)
    assert rb.fragment_ops("y" * 201, 100, 0)[0]["total"] == 3.0


async def test_a_namespaced_robot_has_every_topic_under_its_namespace() -> None:
    # Robots on one ROS master: a node pushed into /r1 resolves every relative name under it.
    s = await start_simulation(1, port=0, clock=ScaledClock(SCALE), seed=5, namespaced=True)
    try:
        c = await open_raw(s, level="error")
        await c.send(rb.op_subscribe("/move_base/status", "actionlib_msgs/GoalStatusArray"))
        err = await c.wait_for(lambda m: m.get("op") == "status" and m.get("level") == "error")
        assert "/move_base/status" in err["msg"]
        await c.send(rb.op_subscribe("/r1/move_base/status", "actionlib_msgs/GoalStatusArray"))
        got = await c.wait_for(lambda m: m.get("op") == "publish")
        assert got["topic"] == "/r1/move_base/status"
        await c.send(rb.op_subscribe("/r1/map", "nav_msgs/OccupancyGrid"))
        m = await c.wait_for(lambda m: m.get("op") == "publish" and "map" in m["topic"])
        assert m["topic"] == "/r1/map"  # latched, under the namespace too
        await c.send({"op": "call_service", "service": "/rosapi/topics", "id": "t", "args": {}})
        topics = await c.wait_for(lambda m: m.get("op") == "service_response")
        assert "/r1/amcl_pose" in topics["values"]["topics"]
        assert "/amcl_pose" not in topics["values"]["topics"]
    finally:
        await shut(s)


async def test_a_joystick_at_5_hz_wall_drives_at_full_speed_whatever_the_time_scale(
    sim: Simulation,
) -> None:
    # The base's velocity watchdog is 0.5 s of wall time: at SCALE x a person's 5 Hz commands
    # are SCALE/5 s of robot time apart, and a robot-time watchdog stopped it between them.
    c = await open_raw(sim)
    robot = sim.robots[0]
    clock = sim.clock
    y0, t0 = robot.pose[1], clock.now()
    for _ in range(5):
        await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.3, 0.0, 0.0)))  # home faces a wall
        await asyncio.sleep(0.2)  # the joystick's period (wall), not a wait for a result
    travelled, elapsed = y0 - robot.pose[1], clock.now() - t0
    assert travelled > 0.6 * 0.3 * elapsed, (travelled, elapsed)
