"""Slow and dead clients: nobody waits for them, they cost bounded memory, and a client cut
off for being too far behind (4002) resynchronises from a snapshot.

The hub's rules (serveur/core/hub.py): state updates queue per client up to ``max_pending``, then
the client is closed with 4002; pose and scan keep only the newest frame per topic.
"""

from __future__ import annotations

import asyncio
import contextlib
import dataclasses
import functools
import json
import socket

import pytest
import websockets
from websockets.asyncio.client import connect

from serveur import server as server_module
from serveur.core import hub as hub_module
from serveur.core.hub import CLOSE_TOO_SLOW, Hub, Subscriber
from tests.conftest import Restaurant
from tests.test_e2e import staff


async def test_a_client_that_stops_reading_costs_bounded_memory_and_delays_nobody() -> None:
    """Unit level, no sockets: the stuck client's send never returns."""
    stuck = asyncio.Event()  # never set
    fast_frames: list[str] = []
    closed: list[int] = []

    async def send_stuck(frame: str) -> None:
        await stuck.wait()

    async def send_fast(frame: str) -> None:
        fast_frames.append(frame)

    async def close(code: int, reason: str) -> None:
        closed.append(code)

    hub = Hub()
    slow = Subscriber(send_stuck, close, max_pending=100, name="slow")
    fast = Subscriber(send_fast, close, max_pending=100, name="fast")
    for s in (slow, fast):
        s.start()
        hub.add(s)
        hub.subscribe(s, ["orders", "pose:r1"])
    peak = 0
    for i in range(1000):
        hub.publish("pose:r1", json.dumps({"x": i}))
        hub.publish("orders", json.dumps({"id": i}))
        peak = max(peak, len(slow._state) + len(slow._latest))
        await asyncio.sleep(0)  # let the writers run, as the event loop would between updates
    await asyncio.sleep(0)
    # The fast client got every state update, in order, with consecutive seq numbers.
    orders = [json.loads(f) for f in fast_frames if '"topic":"orders"' in f]
    assert [m["data"]["id"] for m in orders] == list(range(1000))
    seqs = [json.loads(f)["seq"] for f in fast_frames]
    assert seqs == list(range(1, len(seqs) + 1))
    # The stuck one never held more than its bound (plus one newest pose), and was cut off.
    assert peak <= 100 + 1
    assert closed == [CLOSE_TOO_SLOW]
    slow.update("orders", "{}")  # after the cut, nothing more is queued for it
    assert len(slow._state) <= 100
    for s in (slow, fast):
        await s.stop()


async def test_stream_topics_keep_only_the_newest_frame_for_a_slow_reader() -> None:
    gate = asyncio.Event()
    sent: list[str] = []

    async def send(frame: str) -> None:
        await gate.wait()
        sent.append(frame)

    async def close(code: int, reason: str) -> None:
        raise AssertionError("a slow pose reader must not be disconnected")

    sub = Subscriber(send, close, max_pending=10)
    sub.start()
    hub = Hub()
    hub.add(sub)
    hub.subscribe(sub, ["pose:r1"])
    for i in range(500):
        hub.publish("pose:r1", json.dumps({"x": i}))
        await asyncio.sleep(0)
    gate.set()
    for _ in range(5):
        await asyncio.sleep(0)
    xs = [json.loads(f)["data"]["x"] for f in sent]
    assert xs[-1] == 499 and len(xs) <= 3  # the first in flight, then the newest only
    assert sub.dropped_stream_frames >= 490
    await sub.stop()


async def test_too_slow_client_is_closed_4002_and_resyncs_from_a_snapshot(
    one_robot: Restaurant, monkeypatch: pytest.MonkeyPatch
) -> None:
    """End to end: a real socket that stops reading. The bound is lowered so that a few
    hundred updates overflow it; the socket buffers are kept small for the same reason
    (otherwise megabytes of frames would sit in the kernel first)."""
    r = one_robot
    monkeypatch.setattr(
        server_module, "Subscriber", functools.partial(hub_module.Subscriber, max_pending=40)
    )
    # 400 creates as fast as the loop goes: lift this test's per-connection rate limit.
    assert r.app.server is not None
    monkeypatch.setattr(
        r.app.server, "security", dataclasses.replace(r.app.server.security, rate=1e6, burst=1e6)
    )
    fast = await staff(r)
    host, port = r.app.server.host, r.app.server.port  # type: ignore[union-attr]
    sock = socket.socket()
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, 4096)
    sock.connect((host, port))
    slow_ws = await connect(r.app.url, sock=sock, additional_headers=r.auth_headers())
    await slow_ws.send(json.dumps({"clientmsg": "data", "id": 1, "topics": ["orders", "events"]}))
    while (first := json.loads(await slow_ws.recv())).get("id") != 1:
        pass  # an update may come before the snapshot's reply
    assert first["servermsg"] == "ok"
    # The server's side of that connection: small buffers there too.
    core = r.app.core
    assert core is not None
    [sub] = [s for s in core.hub.subscribers if "events" in s.topics]
    server_transport = sub._send.__self__.transport  # type: ignore[attr-defined]
    server_transport.get_extra_info("socket").setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, 4096)
    server_transport.set_write_buffer_limits(high=4096)
    slow_ws.transport.pause_reading()  # the tablet's app freezes
    created: list[int] = []
    close_code: list[int | None] = []
    slow_seqs: list[int] = []

    async def watch_close() -> None:
        """Read what the frozen client has pending, up to the server's close frame."""
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in slow_ws:
                msg = json.loads(frame)
                if msg["servermsg"] == "update":
                    slow_seqs.append(msg["seq"])
        close_code.append(slow_ws.close_code)

    watcher = asyncio.create_task(watch_close())
    # Orders keep coming; the frozen client falls behind while the fast one keeps up.
    for i in range(400):
        reply = await fast.ok("create", type="order", dish=f"d{i}", table="T1")
        created.append(reply["order"]["id"])
    slow_ws.transport.resume_reading()
    await asyncio.wait_for(watcher, 30)
    assert close_code == [CLOSE_TOO_SLOW], close_code
    # Until the cut it missed nothing either: updates are never dropped silently.
    assert slow_seqs == list(range(slow_seqs[0], slow_seqs[0] + len(slow_seqs)))
    # The fast client was never cut off and missed nothing.
    await fast.until(lambda: all(fast.order(i) for i in created), what="every order seen")
    assert fast.seqs == list(range(1, len(fast.seqs) + 1))
    # The cut-off tablet reconnects and resynchronises from a snapshot: it has everything.
    again = await r.client()
    snap = await again.subscribe("orders")
    assert {o["id"] for o in snap["data"]["orders"]} >= set(created)
