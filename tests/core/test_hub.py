"""The hub's write paths: paced stream frames, direct replies, the writer task for the rest.

Each test runs on a real event loop and counts loop turns with ``asyncio.sleep(0)`` (one turn
each, deterministic), never wall-clock sleeps.
"""

from __future__ import annotations

import asyncio
import json

import pytest

from serveur.core.hub import Hub, Pacer, Subscriber


class FakeConn:
    """Records every frame in order with its path: ``direct`` (``write_now``) or ``task``
    (the writer task's ``send``)."""

    def __init__(self, log: list[tuple[str, str, dict[str, object]]] | None = None) -> None:
        self.log: list[tuple[str, str, dict[str, object]]] = [] if log is None else log
        self.name = f"c{id(self)}"
        self.accept = True

    def write_now(self, frame: str) -> bool:
        if self.accept:
            self.log.append((self.name, "direct", json.loads(frame)))
        return self.accept

    async def send(self, frame: str) -> None:
        self.log.append((self.name, "task", json.loads(frame)))

    async def close(self, code: int, reason: str) -> None:
        pass

    def mine(self) -> list[tuple[str, dict[str, object]]]:
        return [(path, f) for who, path, f in self.log if who == self.name]


async def turns(n: int) -> None:
    """Let the loop run ``n`` turns (each ``sleep(0)`` resumes this task one turn later)."""
    for _ in range(n):
        await asyncio.sleep(0)


def subscriber(conn: FakeConn, hub: Hub, topics: list[str]) -> Subscriber:
    sub = Subscriber(conn.send, conn.close, write_now=conn.write_now, name=conn.name)
    sub.start()
    hub.add(sub)
    hub.subscribe(sub, topics)
    return sub


async def test_stream_frames_are_written_directly_on_the_next_turn() -> None:
    conn = FakeConn()
    hub = Hub()
    sub = subscriber(conn, hub, ["pose:r1", "robots"])
    # Idle client: publish only queues it in the pacer; the next turn writes it directly.
    hub.publish("pose:r1", '{"x":1}')
    assert conn.log == []
    await turns(1)
    assert [(p, f["seq"]) for p, f in conn.mine()] == [("direct", 1)]
    # A state update is queued for the writer: a pose published behind it must not overtake
    # it, so it is queued too (latest-only) and both go out in order, seq 2 then 3.
    hub.publish("robots", '{"name":"r1"}')
    hub.publish("pose:r1", '{"x":2}')
    await turns(5)
    assert [(p, f["topic"], f["seq"]) for p, f in conn.mine()[1:]] == [
        ("task", "robots", 2),
        ("task", "pose:r1", 3),
    ]
    # A connection that cannot take a frame now (buffer full) gets it through the writer.
    conn.accept = False
    hub.publish("pose:r1", '{"x":3}')
    await turns(5)
    path, last = conn.mine()[-1]
    assert (path, last["seq"], last["data"]) == ("task", 4, {"x": 3})
    await sub.stop()


async def test_the_pacer_writes_per_turn_subscribers_a_turn_and_keeps_the_newest() -> None:
    log: list[tuple[str, str, dict[str, object]]] = []
    hub = Hub(per_turn=4)
    conns = [FakeConn(log) for _ in range(10)]
    subs = [subscriber(c, hub, ["pose:r1"]) for c in conns]
    hub.publish("pose:r1", '{"x":1}')
    hub.publish("pose:r1", '{"x":2}')  # before anything went out: replaces x=1 (latest-only)
    written = []
    for _ in range(4):
        await turns(1)
        written.append(len(log))
    assert written == [4, 8, 10, 10]
    assert all(path == "direct" and f["data"] == {"x": 2} and f["seq"] == 1 for _, path, f in log)
    assert [s.dropped_stream_frames for s in subs] == [1] * 10
    assert len(hub.pacer) == 0
    for s in subs:
        await s.stop()


async def test_other_callbacks_run_between_two_chunks_of_a_fan_out() -> None:
    """What the pacing is for: a request that arrives during a fan-out is read and answered
    between two chunks, not after the whole of it."""
    log: list[tuple[str, str, dict[str, object]]] = []
    hub = Hub(per_turn=8)
    conns = [FakeConn(log) for _ in range(40)]
    subs = [subscriber(c, hub, ["pose:r1"]) for c in conns]
    hub.publish("pose:r1", '{"x":1}')
    requester = list(hub.pacer)[-1]  # the last one the fan-out reaches
    assert len(hub.pacer) == 40

    async def request() -> None:
        await turns(1)  # the frame is read on one turn, answered on the next
        requester.reply('{"servermsg":"ok","id":7}')

    await asyncio.create_task(request())
    replied_after = next(i for i, (_, _, f) in enumerate(log) if f.get("servermsg") == "ok")
    assert replied_after <= 2 * 8  # behind at most two chunks, not all 40 frames
    await turns(10)
    assert sum(1 for _, _, f in log if f.get("servermsg") == "update") == 40
    # The requester's own frames: the reply went directly, ahead of its pending pose.
    mine = next(c for c in conns if c.name == requester.name).mine()
    assert [f.get("servermsg") for _, f in mine] == ["ok", "update"]
    for s in subs:
        await s.stop()


async def test_a_reply_waits_behind_queued_state_updates() -> None:
    conn = FakeConn()
    hub = Hub()
    sub = subscriber(conn, hub, ["robots"])
    hub.publish("robots", '{"name":"r1"}')
    sub.reply('{"servermsg":"ok","id":1}')  # must not overtake the queued update
    await turns(5)
    assert [(p, f["servermsg"]) for p, f in conn.mine()] == [("task", "update"), ("task", "ok")]
    sub.reply('{"servermsg":"ok","id":2}')  # nothing queued now: straight to the socket
    assert conn.mine()[-1] == ("direct", {"servermsg": "ok", "id": 2})
    await sub.stop()


async def test_updates_during_a_snapshot_go_out_after_its_reply() -> None:
    """An update published while a data request reads its snapshot is newer than the snapshot:
    it must reach the client after the reply, or the stale snapshot would overwrite it."""
    conn = FakeConn()
    hub = Hub()
    sub = subscriber(conn, hub, [])
    sub.hold()
    hub.subscribe(sub, ["robots", "pose:r1"])
    hub.publish("robots", '{"name":"r1","status":"Delivered"}')
    hub.publish("pose:r1", '{"x":2}')
    await turns(5)
    assert conn.log == []  # nothing jumped the snapshot while held
    sub.reply('{"servermsg":"ok","id":1,"data":{}}')
    sub.release()
    sub.release()  # harmless when not holding
    await turns(10)
    frames = [f for _, f in conn.mine()]
    assert [f.get("servermsg") for f in frames] == ["ok", "update", "update"]
    assert [f.get("seq") for f in frames[1:]] == [1, 2]
    await sub.stop()


def test_a_pacer_needs_a_positive_budget() -> None:
    with pytest.raises(ValueError):
        Pacer(0)
