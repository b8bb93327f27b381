"""The simulator's rosbridge endpoint seen by a raw websocket client: bad input, flow control,
compression, services, actionlib edge cases and fault hooks.

Everything here talks to real sockets. Nothing sleeps to wait: each wait reads frames until a
condition holds, with a wall-clock timeout.
"""

from __future__ import annotations

import asyncio
import itertools
import json
import math
import signal
import socket
import struct
import sys
import time
from collections.abc import AsyncIterator, Callable
from typing import Any

import cbor2
import pytest
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from serveur.clock import FakeClock, ScaledClock
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots import rosbridge as rb

SCALE = 20.0
WAIT = 10.0  # wall seconds; every wait returns as soon as its condition holds
T1 = (2.4, 9.7, -math.pi / 2)  # a table near home1
FAR = (12.6, 1.6, 0.0)  # T16, across the room


class Raw:
    """A raw rosbridge client that keeps every frame it receives, in order."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.frames: list[str | bytes] = []
        self._read = 0  # index of the next frame wait_for looks at

    async def send(self, op: dict[str, Any] | str | bytes) -> None:
        await self.ws.send(op if isinstance(op, str | bytes) else json.dumps(op))

    async def _next(self) -> str | bytes:
        if self._read == len(self.frames):
            self.frames.append(await self.ws.recv())
        frame = self.frames[self._read]
        self._read += 1
        return frame

    async def wait_for(
        self, pred: Callable[[dict[str, Any]], bool], limit: float = WAIT
    ) -> dict[str, Any]:
        """The next JSON op (after those already looked at) for which ``pred`` holds."""

        async def scan() -> dict[str, Any]:
            while True:
                frame = await self._next()
                assert isinstance(frame, str), "binary frame to a client that did not ask for cbor"
                msg = json.loads(frame)
                if pred(msg):
                    return msg

        return await asyncio.wait_for(scan(), limit)

    async def topic(
        self, name: str, pred: Callable[[dict[str, Any]], bool] = lambda m: True
    ) -> dict[str, Any]:
        """The msg of the next publish on ``name`` satisfying ``pred``."""
        op = await self.wait_for(
            lambda m: m.get("topic") == name and m["op"] == "publish" and pred(m["msg"])
        )
        return op["msg"]  # type: ignore[no-any-return]

    async def ping(self, rid: str = "ping") -> dict[str, Any]:
        """A get_time round trip: proves the connection still answers."""
        await self.send(rb.op_call_service("/rosapi/get_time", id=rid))
        reply = await self.wait_for(lambda m: m["op"] == "service_response" and m.get("id") == rid)
        assert reply["result"] is True and set(reply["values"]["time"]) == {"secs", "nsecs"}
        return reply


_OPEN: list[ClientConnection] = []


async def shut(sim: Simulation) -> None:
    """Drop the test's clients first (some stopped reading on purpose), then the simulation."""
    while _OPEN:
        _OPEN.pop().transport.abort()
    await sim.close()


@pytest.fixture
async def sim() -> AsyncIterator[Simulation]:
    s = await start_simulation(2, port=0, time_scale=SCALE, seed=7)
    try:
        yield s
    finally:
        await shut(s)


async def open_raw(sim: Simulation, i: int = 0, *, level: str | None = None, **kw: Any) -> Raw:
    """A raw client of robot ``i``; with ``level`` it first asks for status ops (set_level):
    like rosbridge 0.11, the simulator sends none to a client that did not."""
    ws = await connect(sim.urls[i], max_size=None, **kw)
    _OPEN.append(ws)
    raw = Raw(ws)
    if level is not None:
        await raw.send(rb.op_set_level(level))
    return raw


def statuses(msg: dict[str, Any]) -> dict[str, int]:
    return {s["goal_id"]["id"]: s["status"] for s in msg["status_list"]}


def goal_op(gid: str, x: float, y: float, yaw: float, **kw: Any) -> dict[str, Any]:
    return rb.op_publish(
        "/move_base/goal", rb.move_base_action_goal(gid, x, y, yaw, stamp=time.time(), **kw)
    )


# -- every bad input gets an error status with its id, and nothing breaks --------------------

DEEP = "[" * 50_000 + "]" * 50_000
BAD_INPUTS: list[tuple[str, str | bytes, str | int | None]] = [
    ("not json", "{not json", None),
    ("json array", "[1, 2]", None),
    ("deep nesting", DEEP, None),
    ("binary garbage", b"\xff\x00\x13", None),
    ("no op", '{"id": "x1", "topic": "/cmd_vel"}', "x1"),
    ("op not a string", '{"op": 5, "id": "x2"}', "x2"),
    ("unknown op", '{"op": "frobnicate", "id": "x3"}', "x3"),
    ("integer id", '{"op": "frobnicate", "id": 42}', 42),
    ("publish without topic", '{"op": "publish", "id": "x4", "msg": {}}', "x4"),
    ("publish without msg", '{"op": "publish", "id": "x5", "topic": "/cmd_vel"}', "x5"),
    (
        "cmd_vel of strings",
        json.dumps(rb.op_publish("/cmd_vel", {"linear": {"x": "fast"}}) | {"id": "x6"}),
        "x6",
    ),
    ("msg not an object", '{"op": "publish", "id": "x7", "topic": "/cmd_vel", "msg": "go"}', "x7"),
    ("publish unknown topic", '{"op": "publish", "id": "x8", "topic": "/foo", "msg": {}}', "x8"),
    (
        "publish robot output",
        '{"op": "publish", "id": "x9", "topic": "/amcl_pose", "msg": {}}',
        "x9",
    ),
    ("subscribe unknown topic", '{"op": "subscribe", "id": "x10", "topic": "/nope"}', "x10"),
    (
        "subscribe wrong type",
        '{"op": "subscribe", "id": "x11", "topic": "/odom", "type": "std_msgs/String"}',
        "x11",
    ),
    (
        "bad throttle",
        '{"op": "subscribe", "id": "x12", "topic": "/odom", "throttle_rate": "fast"}',
        "x12",
    ),
    (
        "bad compression",
        '{"op": "subscribe", "id": "x13", "topic": "/odom", "compression": "zip"}',
        "x13",
    ),
    (
        "advertise unknown",
        '{"op": "advertise", "id": "x14", "topic": "/foo", "type": "std_msgs/String"}',
        "x14",
    ),
    ("call without service", '{"op": "call_service", "id": "x15"}', "x15"),
    (
        "goal of wrong shape",
        json.dumps(rb.op_publish("/move_base/goal", {"goal": "T1"}) | {"id": "x16"}),
        "x16",
    ),
    (
        "initialpose of wrong shape",
        json.dumps(
            rb.op_publish("/initialpose", {"pose": {"pose": {"position": {"x": [1]}}}})
            | {"id": "x17"}
        ),
        "x17",
    ),
    (
        "cancel with numeric id",
        json.dumps(rb.op_publish("/move_base/cancel", {"id": 5}) | {"id": "x18"}),
        "x18",
    ),
    ("bad fragment", '{"op": "fragment", "id": "x19", "data": 1, "num": 0, "total": 1}', "x19"),
    (
        "null cmd_vel",
        json.dumps(rb.op_publish("/cmd_vel", {"linear": {"x": None}}) | {"id": "x20"}),
        "x20",
    ),
    ("subscribe without topic", '{"op": "subscribe", "id": "x21"}', "x21"),
]


@pytest.mark.parametrize(
    ("frame", "rid"), [c[1:] for c in BAD_INPUTS], ids=[c[0] for c in BAD_INPUTS]
)
async def test_bad_input_answers_status_and_keeps_everything_running(
    sim: Simulation, frame: str | bytes, rid: str | int | None
) -> None:
    c = await open_raw(sim, level="error")
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.topic("/amcl_pose")
    pose_before = sim.robots[0].pose
    await c.send(frame)
    status = await c.wait_for(lambda m: m["op"] == "status")
    assert status["level"] == "error" and isinstance(status["msg"], str) and status["msg"]
    if rid is None:
        assert "id" not in status
    else:
        assert status["id"] == rid
    await c.ping()  # same connection still answers
    seen = await c.topic("/amcl_pose")  # and the robot still publishes
    assert seen["header"]["frame_id"] == "map"
    assert sim.robots[0].pose == pose_before  # nothing moved it
    await c.ws.close()


async def test_unknown_service_gets_a_failed_response_and_a_status(sim: Simulation) -> None:
    c = await open_raw(sim, level="error")
    await c.send(rb.op_call_service("/no/such", id="s1"))
    resp = await c.wait_for(lambda m: m["op"] == "service_response")
    assert resp["id"] == "s1" and resp["result"] is False and "does not exist" in resp["values"]
    status = await c.wait_for(lambda m: m["op"] == "status")
    assert status["id"] == "s1" and status["level"] == "error"


async def test_oversize_frame_closes_1009_but_others_carry_on(sim: Simulation) -> None:
    big, other = await open_raw(sim), await open_raw(sim)
    await other.send(rb.op_subscribe("/amcl_pose"))
    await big.send("x" * (1 << 20 + 1))
    with pytest.raises(ConnectionClosed) as info:
        await asyncio.wait_for(big.ws.recv(), WAIT)
    assert info.value.rcvd is not None and info.value.rcvd.code == 1009
    await other.topic("/amcl_pose")
    await other.ping()


async def test_huge_but_legal_frame_is_answered(sim: Simulation) -> None:
    c = await open_raw(sim, level="error")
    await c.send(
        json.dumps({"op": "publish", "id": "big", "topic": "/nope", "msg": {"pad": "y" * 900_000}})
    )
    status = await c.wait_for(lambda m: m["op"] == "status")
    assert status["id"] == "big"


# -- compression ------------------------------------------------------------------------------


def _typed(tag: cbor2.CBORTag, fmt: str) -> list[Any]:
    size = struct.calcsize(fmt)
    return list(struct.unpack(f"<{len(tag.value) // size}{fmt}", tag.value))


async def test_cbor_only_for_clients_that_ask(sim: Simulation) -> None:
    binary, plain = await open_raw(sim), await open_raw(sim)
    # Not /odom or /amcl_pose: rosbridge 0.11 sends nothing for those in cbor
    # (test_sim_realstack.py).
    for topic in ("/scan", "/map", "/battery_state"):
        await binary.send(rb.op_subscribe(topic, compression="cbor"))
        await plain.send(rb.op_subscribe(topic, compression="none"))
    got: dict[str, dict[str, Any]] = {}

    async def collect() -> None:
        while len(got) < 3:
            frame = await binary.ws.recv()
            assert isinstance(frame, bytes), "a cbor subscriber gets binary frames"
            op = cbor2.loads(frame)
            assert op["op"] == "publish"
            got[op["topic"]] = op["msg"]

    await asyncio.wait_for(collect(), WAIT)
    scan, grid = got["/scan"], got["/map"]
    assert scan["ranges"].tag == 85  # float32 typed array
    ranges = _typed(scan["ranges"], "f")
    assert len(ranges) == 360 and all(scan["range_min"] <= r or math.isinf(r) for r in ranges)
    assert grid["data"].tag == 72  # int8 typed array
    cells = _typed(grid["data"], "b")
    assert len(cells) == grid["info"]["width"] * grid["info"]["height"]
    assert set(cells) <= {-1, 0, 100}
    assert 0.0 <= got["/battery_state"]["percentage"] <= 1.0
    # The plain client gets the same topics as text (Raw.wait_for asserts every frame is str).
    for topic in ("/map", "/scan", "/battery_state", "/scan"):
        await plain.topic(topic)


# -- subscriptions: throttle_rate, queue_length, ids -------------------------------------------


def _stamp(msg: dict[str, Any]) -> float:
    return rb.from_ros_time(msg["header"]["stamp"])


async def test_throttle_rate_is_in_sim_time(sim: Simulation) -> None:
    throttled, full = await open_raw(sim), await open_raw(sim)
    await throttled.send(rb.op_subscribe("/odom", throttle_rate=500))
    await full.send(rb.op_subscribe("/odom"))
    t = [_stamp(await throttled.topic("/odom")) for _ in range(5)]
    gaps = [b - a for a, b in itertools.pairwise(t)]
    assert all(0.45 <= g <= 1.0 for g in gaps), gaps  # 2 Hz of sim time out of 20 Hz
    f = [_stamp(await full.topic("/odom")) for _ in range(10)]
    assert max(b - a for a, b in itertools.pairwise(f)) < 0.2


async def test_queue_length_with_throttle_sends_one_per_period(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/odom", throttle_rate=1000, queue_length=2))
    t = [_stamp(await c.topic("/odom")) for _ in range(4)]
    gaps = [b - a for a, b in itertools.pairwise(t)]
    assert all(0.85 <= g <= 2.0 for g in gaps), gaps  # one a second (sim), not 20
    client = next(iter(sim._endpoints[0].clients))
    assert client.subs["/odom"].queue.maxlen == 2


async def test_two_subscription_ids_share_one_stream(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/odom", id="a"))
    await c.send(rb.op_subscribe("/odom", id="b"))
    await c.send(rb.op_subscribe("/amcl_pose"))
    seqs = [(await c.topic("/odom"))["header"]["seq"] for _ in range(6)]
    assert len(set(seqs)) == len(seqs)  # one stream, not one per id
    await c.send(rb.op_unsubscribe("/odom", id="a"))
    await c.ping("p1")
    await c.topic("/odom")  # "b" still subscribed
    await c.send(rb.op_unsubscribe("/odom", id="b"))
    await c.ping("p2")
    for _ in range(5):  # half a second of sim time without /odom
        op = await c.wait_for(lambda m: m.get("topic") in ("/amcl_pose", "/odom"))
        assert op["topic"] == "/amcl_pose"


async def test_a_client_that_never_reads_is_bounded_and_stalls_nobody(sim: Simulation) -> None:
    port = int(sim.urls[0].rsplit(":", 1)[1])
    sock = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect(("127.0.0.1", port))
    sock.setblocking(False)
    slow_ws = await connect(sim.urls[0], sock=sock, max_size=None, max_queue=1)
    _OPEN.append(slow_ws)
    for topic in ("/map", "/odom", "/amcl_pose"):
        await slow_ws.send(json.dumps(rb.op_subscribe(topic)))
    await slow_ws.send(json.dumps(rb.op_subscribe("/scan", queue_length=2)))
    fast = await open_raw(sim)
    await fast.send(rb.op_subscribe("/amcl_pose"))
    await fast.topic("/amcl_pose")
    # Ten seconds of sim time while the slow client reads nothing.
    t0 = time.monotonic()
    stamps = [_stamp(await fast.topic("/amcl_pose")) for _ in range(100)]
    wall = time.monotonic() - t0
    assert stamps[-1] - stamps[0] == pytest.approx(9.9, abs=0.3)
    assert wall < 10.0 / SCALE * 3  # the fast client kept pace (nominal 0.5 s)
    slow = next(
        c for c in sim._endpoints[0].clients if c.ws.remote_address[1] == sock.getsockname()[1]
    )
    assert slow.subs["/scan"].queue.maxlen == 2
    assert all(len(s.queue) <= (s.queue.maxlen or 0) for s in slow.subs.values())
    assert slow.ws.transport.get_write_buffer_size() < 512 * 1024
    # Once it reads again, it gets fresh messages, having lost old ones rather than queued them.
    seqs: list[int] = []

    async def drain() -> None:
        while True:
            op = json.loads(await slow_ws.recv())
            if op.get("topic") == "/odom":
                seqs.append(op["msg"]["header"]["seq"])
                if _stamp(op["msg"]) > stamps[-1]:
                    return

    await asyncio.wait_for(drain(), WAIT)
    assert any(b - a > 1 for a, b in itertools.pairwise(seqs)), "old messages were dropped"
    assert len(seqs) < 200 * 0.5  # far fewer than the 200 published during the stall


# -- services and fragments -------------------------------------------------------------------


async def test_rosapi_topics_and_get_time(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_call_service("/rosapi/topics", id=1))
    resp = await c.wait_for(lambda m: m["op"] == "service_response")
    assert resp["id"] == 1 and resp["result"] is True
    topics = dict(zip(resp["values"]["topics"], resp["values"]["types"], strict=True))
    assert topics == rb.TOPIC_TYPES
    reply = await c.ping()
    assert rb.from_ros_time(reply["values"]["time"]) == pytest.approx(sim.clock.epoch(), abs=2.0)


async def test_fragmented_call_is_reassembled(sim: Simulation) -> None:
    c = await open_raw(sim)
    text = json.dumps(rb.op_call_service("/rosapi/get_time", id="frag"))
    parts = [text[:10], text[10:25], text[25:]]
    for num in (2, 0, 1):  # out of order on purpose
        await c.send({"op": "fragment", "id": "f1", "data": parts[num], "num": num, "total": 3})
    resp = await c.wait_for(lambda m: m["op"] == "service_response")
    assert resp["id"] == "frag" and resp["result"] is True


async def test_client_advertised_service_even_called_by_itself(sim: Simulation) -> None:
    provider, caller = await open_raw(sim), await open_raw(sim)
    await provider.send({"op": "advertise_service", "service": "/echo", "type": "std_srvs/Trigger"})
    await provider.ping()

    async def serve_one() -> None:
        call = await provider.wait_for(
            lambda m: m["op"] == "call_service" and m["service"] == "/echo"
        )
        await provider.send(
            {
                "op": "service_response",
                "service": "/echo",
                "id": call["id"],
                "values": {"message": call["args"]},
                "result": True,
            }
        )

    server = asyncio.ensure_future(serve_one())
    await caller.send(rb.op_call_service("/echo", {"a": 1}, id="e1"))
    resp = await caller.wait_for(lambda m: m["op"] == "service_response")
    assert resp == {
        "op": "service_response",
        "service": "/echo",
        "values": {"message": {"a": 1}},
        "result": True,
        "id": "e1",
    }
    await server
    # The provider calls its own service: the call runs beside its read loop, so no deadlock.
    await provider.send(rb.op_call_service("/echo", {"b": 2}, id="self"))
    call = await provider.wait_for(lambda m: m["op"] == "call_service")
    await provider.send(
        {
            "op": "service_response",
            "service": "/echo",
            "id": call["id"],
            "values": {"ok": 1},
            "result": True,
        }
    )
    resp = await provider.wait_for(
        lambda m: m["op"] == "service_response" and m.get("id") == "self"
    )
    assert resp["values"] == {"ok": 1}


# -- actionlib ----------------------------------------------------------------------------------


async def test_goal_lifecycle_pending_active_succeeded(sim: Simulation) -> None:
    c = await open_raw(sim)
    for topic in ("/move_base/status", "/move_base/result", "/move_base/feedback"):
        await c.send(rb.op_subscribe(topic))
    await c.topic("/move_base/status")  # published even when idle
    await c.send(goal_op("g1", *T1))
    seen: list[int] = []
    result = None
    while result is None:
        op = await c.wait_for(lambda m: m["op"] == "publish")
        if op["topic"] == "/move_base/status":
            st = statuses(op["msg"]).get("g1")
            if st is not None and (not seen or seen[-1] != st):
                seen.append(st)
        elif op["topic"] == "/move_base/result":
            result = op["msg"]
        elif op["topic"] == "/move_base/feedback":
            assert op["msg"]["status"]["goal_id"]["id"] == "g1"
    assert seen[:2] == [0, 1]  # PENDING, then ACTIVE
    assert result["status"]["status"] == 3 and result["status"]["goal_id"]["id"] == "g1"
    x, y, yaw = sim.robots[0].pose
    assert (
        math.hypot(x - T1[0], y - T1[1]) <= 0.1
        and abs(math.remainder(yaw - T1[2], math.tau)) <= 0.1
    )
    done = await c.topic("/move_base/status", lambda m: statuses(m).get("g1") == 3)
    assert statuses(done)["g1"] == 3  # terminal goals stay listed for a while


async def test_newer_goal_preempts_and_cancel_by_id_and_all(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/status"))
    await c.send(goal_op("a", *FAR))
    await c.topic("/move_base/status", lambda m: statuses(m).get("a") == 1)
    await c.send(goal_op("b", *T1))
    st = statuses(await c.topic("/move_base/status", lambda m: statuses(m).get("b") == 1))
    assert st["a"] == 2  # PREEMPTED by the newer goal, still listed; the newest is ACTIVE
    await c.send(rb.op_publish("/move_base/cancel", {"id": "b"}))
    await c.topic("/move_base/status", lambda m: statuses(m).get("b") == 2)
    await c.send(goal_op("c", *FAR))
    await c.topic("/move_base/status", lambda m: statuses(m).get("c") == 1)
    await c.send(rb.op_publish("/move_base/cancel", {}))  # roslibpy's cancel-all
    await c.topic("/move_base/status", lambda m: statuses(m).get("c") == 2)
    # move_base's setPreempted() gives no text.
    assert sim.robots[0].goal_statuses[-1] == ("c", rb.GoalStatus.PREEMPTED, "")


@pytest.mark.parametrize(
    ("case", "goal"),
    [
        ("nan", goal_op("r", math.nan, 1.0, 0.0)),  # json.dumps writes NaN; Python reads it back
        (
            "null",
            goal_op("r", 1.0, 1.0, 0.0)
            | {
                "msg": {
                    "goal_id": {"id": "r"},
                    "goal": {
                        "target_pose": {
                            "header": {"frame_id": "map"},
                            "pose": {"position": {"x": None}, "orientation": {"w": 1.0}},
                        }
                    },
                }
            },
        ),
        (
            "quaternion",
            goal_op("r", 3.0, 8.0, 0.0)
            | {
                "msg": {
                    "goal_id": {"id": "r"},
                    "goal": {
                        "target_pose": {
                            "header": {"frame_id": "map"},
                            "pose": {
                                "position": {"x": 3.0, "y": 8.0},
                                "orientation": {"z": 0.5, "w": 0.5},
                            },
                        }
                    },
                }
            },
        ),
        (
            "zero quaternion",
            goal_op("r", 3.0, 8.0, 0.0)
            | {
                "msg": {
                    "goal_id": {"id": "r"},
                    "goal": {
                        "target_pose": {
                            "header": {"frame_id": "map"},
                            "pose": {"position": {"x": 3.0, "y": 8.0}},
                        }
                    },
                }
            },
        ),
        (
            "frame",
            goal_op("r", 3.0, 8.0, 0.0)
            | {
                "msg": {
                    "goal_id": {"id": "r"},
                    "goal": {
                        "target_pose": {
                            "header": {"frame_id": "base_link"},
                            "pose": {"position": {"x": 3.0}, "orientation": {"w": 1.0}},
                        }
                    },
                }
            },
        ),
    ],
)
async def test_malformed_goals_are_rejected(
    sim: Simulation, case: str, goal: dict[str, Any]
) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/result"))
    await c.send(rb.op_subscribe("/move_base/status"))
    await c.topic("/move_base/status")
    await c.send(goal)
    result = await c.topic("/move_base/result")
    assert result["status"]["status"] == rb.GoalStatus.REJECTED, case
    assert result["status"]["goal_id"]["id"] == "r" and result["status"]["text"]
    await c.topic("/move_base/status", lambda m: statuses(m).get("r") == 5)


async def test_unreachable_goal_aborts(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/result"))
    await c.send(goal_op("u", 100.0, 100.0, 0.0))
    result = await c.topic("/move_base/result")
    assert (
        result["status"]["status"] == rb.GoalStatus.ABORTED
        and "outside" in result["status"]["text"]
    )


async def test_simple_goal_gets_an_id_and_drives(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/result"))
    await c.send(rb.op_publish("/move_base_simple/goal", rb.pose_stamped(*T1, stamp=time.time())))
    result = await c.topic("/move_base/result")
    assert result["status"]["status"] == 3 and result["status"]["goal_id"]["id"]


async def test_teleop_drives_an_idle_robot_and_stale_command_stops(sim: Simulation) -> None:
    # With a goal, /cmd_vel changes nothing: test_sim_realstack.py.
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/odom"))
    await c.send(rb.op_publish("/cmd_vel", rb.twist(-0.3, 0.0, 0.0)))
    moving = await c.topic("/odom", lambda m: abs(m["twist"]["twist"]["linear"]["x"]) > 0.05)
    # No new command: within 0.5 s of wall time (the watchdog a joystick's 5-10 Hz needs at
    # any time scale) the command is stale and the base brakes to rest.
    rest = await c.topic("/odom", lambda m: m["twist"]["twist"]["linear"]["x"] == 0.0)
    scale = sim.clock.time_scale
    assert 0.4 * scale <= _stamp(rest) - _stamp(moving) <= (0.5 + 1.5) * scale
    assert sim.robots[0].velocity == (0.0, 0.0, 0.0)


# -- fault hooks, endpoints, battery, reproducibility --------------------------------------------


async def test_block_path_aborts_goals_until_cleared(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/result"))
    robot = sim.robots[0]
    robot.block_path(True)
    start = robot.pose
    await c.send(goal_op("b1", *T1))
    result = await c.topic("/move_base/result")
    assert (
        result["status"]["status"] == rb.GoalStatus.ABORTED
        and "blocked" in result["status"]["text"]
    )
    assert math.dist(robot.pose[:2], start[:2]) < 0.05
    robot.block_path(False)
    await c.send(goal_op("b2", *T1))
    result = await c.topic("/move_base/result")
    assert result["status"]["status"] == rb.GoalStatus.SUCCEEDED


async def test_ignore_goals_never_acknowledges(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/move_base/status"))
    robot = sim.robots[0]
    robot.ignore_goals(True)
    await c.send(goal_op("i1", *T1))
    await c.ping()
    for _ in range(10):  # two seconds of sim time of status without the goal
        assert "i1" not in statuses(await c.topic("/move_base/status"))
    robot.ignore_goals(False)
    await c.send(goal_op("i2", *T1))
    await c.topic("/move_base/status", lambda m: "i2" in statuses(m))


async def test_endpoint_stop_and_restart_keep_the_robot(sim: Simulation) -> None:
    c = await open_raw(sim, 1)
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.topic("/amcl_pose")
    url = sim.urls[1]
    robot = sim.robots[1]
    robot.teleport(6.0, 8.0, 0.0)
    await sim.stop_endpoint(1)
    with pytest.raises(ConnectionClosed):
        await asyncio.wait_for(c.wait_for(lambda m: False), WAIT)
    with pytest.raises(OSError):
        await connect(url)
    other = await open_raw(sim, 0)  # the other robot is unaffected
    await other.ping()
    await sim.start_endpoint(1)
    assert sim.urls[1] == url
    again = await open_raw(sim, 1)
    await again.send(rb.op_subscribe("/amcl_pose"))
    msg = await again.topic("/amcl_pose")
    x, y, _ = rb.pose_from_msg(msg["pose"]["pose"])
    assert math.hypot(x - 6.0, y - 8.0) < 0.1


async def test_battery_charges_at_home_and_drains_away(sim: Simulation) -> None:
    c = await open_raw(sim)
    await c.send(rb.op_subscribe("/battery_state"))
    robot = sim.robots[0]
    robot.battery = 0.5
    first = await c.topic("/battery_state")
    later = await c.topic(
        "/battery_state", lambda m: m["header"]["seq"] >= first["header"]["seq"] + 2
    )
    assert first["power_supply_status"] == rb.BatteryStatus.CHARGING
    assert 0.5 <= first["percentage"] < later["percentage"] < 0.51
    robot.teleport(6.0, 8.0, 0.0)
    away = await c.topic(
        "/battery_state", lambda m: m["power_supply_status"] == rb.BatteryStatus.DISCHARGING
    )
    after = await c.topic("/battery_state", lambda m: m["header"]["seq"] > away["header"]["seq"])
    assert after["percentage"] < away["percentage"]


async def test_runs_are_reproducible_from_the_seed() -> None:
    async def run(seed: int) -> list[tuple[float, float]]:
        clock = FakeClock()
        sim = await start_simulation(1, port=0, seed=seed, clock=clock)
        try:
            c = await open_raw(sim)
            await c.send(rb.op_subscribe("/amcl_pose"))
            await c.ping()
            await clock.advance(1.0)
            poses = []
            for _ in range(8):
                p = (await c.topic("/amcl_pose"))["pose"]["pose"]["position"]
                poses.append((p["x"], p["y"]))
            return poses
        finally:
            await shut(sim)

    a, b, other = await run(3), await run(3), await run(4)
    assert a == b
    assert a != other


async def test_time_scale_runs_sim_time_faster() -> None:
    clock = ScaledClock(20.0)
    sim = await start_simulation(1, port=0, clock=clock)
    try:
        c = await open_raw(sim)
        await c.send(rb.op_subscribe("/battery_state"))  # 1 Hz of sim time
        t0 = time.monotonic()
        s = [_stamp(await c.topic("/battery_state")) for _ in range(4)]
        assert s[-1] - s[0] == pytest.approx(3.0, abs=0.1)
        assert time.monotonic() - t0 < 3.0 / 20.0 * 4
    finally:
        await shut(sim)


async def test_cli_runner_prints_urls_and_stops_cleanly_on_sigint() -> None:
    code = (
        "import argparse, asyncio\n"
        "from serveur.robot_sim import add_sim_arguments, run_sim_from_args\n"
        "p = argparse.ArgumentParser()\n"
        "add_sim_arguments(p)\n"
        "raise SystemExit(asyncio.run(run_sim_from_args(p.parse_args())))\n"
    )
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-c",
        code,
        "--robots",
        "2",
        "--port",
        "0",
        "--kinematics",
        "diff",
        "--time-scale",
        "5",
        "--names",
        "ada,bob",
        stdout=asyncio.subprocess.PIPE,
    )
    try:
        assert proc.stdout is not None
        urls = [
            (await asyncio.wait_for(proc.stdout.readline(), 30)).decode().strip() for _ in range(2)
        ]
        assert all(u.startswith("ws://127.0.0.1:") for u in urls) and urls[0] != urls[1]
        async with connect(urls[1]) as ws:
            c = Raw(ws)
            await c.ping()
        proc.send_signal(signal.SIGINT)
        assert await asyncio.wait_for(proc.wait(), 30) == 0
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()


async def test_per_client_bookkeeping_is_capped(sim: Simulation) -> None:
    c = await open_raw(sim, level="error")
    for i in range(64):
        await c.send(rb.op_subscribe("/odom", id=f"s{i}"))
    await c.send(rb.op_subscribe("/odom", id="one-too-many"))
    status = await c.wait_for(lambda m: m["op"] == "status")
    assert status["id"] == "one-too-many"
    # Calls to a provider that never answers pile up to the cap, then are refused at once.
    await c.send({"op": "advertise_service", "service": "/hang", "type": "std_srvs/Trigger"})
    for i in range(64):
        await c.send(rb.op_call_service("/hang", id=f"c{i}"))
    await c.send(rb.op_call_service("/hang", id="c-too-many"))
    resp = await c.wait_for(lambda m: m["op"] == "service_response")
    assert resp["id"] == "c-too-many" and resp["result"] is False  # a client's call never hangs
    status = await c.wait_for(lambda m: m["op"] == "status")
    assert status["id"] == "c-too-many" and "in progress" in status["msg"]
    await c.send(rb.op_subscribe("/amcl_pose"))
    await c.topic("/amcl_pose")
