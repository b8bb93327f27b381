"""The hub's stream fast path: written at once when a client has nothing queued, else queued."""

from __future__ import annotations

import asyncio
import json

from serveur.hub import Hub, Subscriber


class FakeConn:
    """Records frames by path: ``direct`` from the fast path, ``sent`` from the writer task."""

    def __init__(self) -> None:
        self.direct: list[dict[str, object]] = []
        self.sent: list[dict[str, object]] = []
        self.accept = True

    def write_now(self, frame: str) -> bool:
        if self.accept:
            self.direct.append(json.loads(frame))
        return self.accept

    async def send(self, frame: str) -> None:
        self.sent.append(json.loads(frame))

    async def close(self, code: int, reason: str) -> None:
        pass


async def test_stream_frames_skip_the_writer_task_when_nothing_is_queued() -> None:
    conn = FakeConn()
    sub = Subscriber(conn.send, conn.close, write_now=conn.write_now)
    sub.start()
    hub = Hub()
    hub.add(sub)
    hub.subscribe(sub, ["pose:r1", "robots"])
    # Idle client: the pose goes out inside publish, with the next seq.
    hub.publish("pose:r1", '{"x":1}')
    assert [f["seq"] for f in conn.direct] == [1] and conn.sent == []
    # A state update is queued for the writer: a pose published behind it must not overtake
    # it, so it is queued too (latest-only) and both go out in order, seq 2 then 3.
    hub.publish("robots", '{"name":"r1"}')
    hub.publish("pose:r1", '{"x":2}')
    assert len(conn.direct) == 1
    await asyncio.sleep(0.01)
    assert [(f["topic"], f["seq"]) for f in conn.sent] == [("robots", 2), ("pose:r1", 3)]
    # A connection that cannot take a frame now (buffer full) gets it through the writer.
    conn.accept = False
    hub.publish("pose:r1", '{"x":3}')
    await asyncio.sleep(0.01)
    assert conn.sent[-1]["seq"] == 4 and conn.sent[-1]["data"] == {"x": 3}
    await sub.stop()


async def test_updates_during_a_snapshot_go_out_after_its_reply() -> None:
    """An update published while a data request reads its snapshot is newer than the snapshot:
    it must reach the client after the reply, or the stale snapshot would overwrite it."""
    conn = FakeConn()
    sub = Subscriber(conn.send, conn.close, write_now=conn.write_now)
    sub.start()
    hub = Hub()
    hub.add(sub)
    sub.hold()
    hub.subscribe(sub, ["robots", "pose:r1"])
    hub.publish("robots", '{"name":"r1","status":"Delivered"}')
    hub.publish("pose:r1", '{"x":2}')
    sub.reply('{"servermsg":"ok","id":1,"data":{}}')
    sub.release()
    sub.release()  # harmless when not holding
    for _ in range(20):
        await asyncio.sleep(0)
    frames = conn.direct + conn.sent
    assert [f.get("servermsg") for f in frames] == ["ok", "update", "update"]
    assert [f.get("seq") for f in frames[1:]] == [1, 2]
    assert conn.direct == []  # nothing jumped the queue while held
    await sub.stop()
