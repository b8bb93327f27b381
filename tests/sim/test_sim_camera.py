"""The simulated camera and the rosbridge camera source, together (issue 28): a JPEG
CompressedImage rendered from the robot's pose, in both ROS dialects, sent as CBOR to the one
connection the relay opens whatever the number of viewers; fast viewers get every frame, a
stalled one only the newest."""

from __future__ import annotations

import asyncio
import base64
import io
import json
from collections.abc import AsyncIterator

import cbor2
import pytest
from PIL import Image

from serveur.clock import ScaledClock
from serveur.core.camera import CameraRelay, CameraViewer
from serveur.maps.navigation import demo_map_path
from serveur.robot_sim import Simulation, start_simulation
from serveur.robots.camera import RosbridgeCamera, frame_of
from serveur.sim.camera import CAMERA_SIZE
from serveur.sim.sensors import CAMERA_TOPIC
from tests.conftest import poll_until, subscribers

WAIT = 10.0


@pytest.fixture(params=[1, 2], ids=["ros1", "ros2"])
async def sim(request: pytest.FixtureRequest) -> AsyncIterator[Simulation]:
    s = await start_simulation(
        1, port=0, map_path=demo_map_path(), clock=ScaledClock(1.0), ros=request.param
    )
    try:
        yield s
    finally:
        await s.close()


async def taken(viewer: CameraViewer, n: int) -> list[int]:
    return [(await asyncio.wait_for(viewer.next(), WAIT)).seq for _ in range(n)]


async def test_five_viewers_one_subscription_and_a_stalled_one_gets_the_newest(
    sim: Simulation,
) -> None:
    source = RosbridgeCamera(sim.urls[0], CAMERA_TOPIC, ros=sim.robots[0].ros)
    loop = asyncio.get_running_loop()
    cam = CameraRelay("r1", source, loop.time)
    fast = [cam.watch(f"tablet {i}") for i in range(4)]
    stalled = cam.watch("sleeping tablet")
    got = await asyncio.gather(*(taken(v, 10) for v in fast))
    # Every fast viewer saw the same ten frames in a row, at the camera's rate (10 fps).
    assert all(g == got[0] for g in got) and got[0] == list(range(got[0][0], got[0][0] + 10))
    assert source.connects == 1 and subscribers(sim, CAMERA_TOPIC) == 1
    # The stalled tablet wakes: the newest frame, not the first it missed.
    frame = await stalled.next()
    assert frame.seq >= got[0][-1] and stalled.skipped >= 9
    with Image.open(io.BytesIO(frame.jpeg)) as img:
        assert img.format == "JPEG" and img.size == CAMERA_SIZE
    assert 3_000 < len(frame.jpeg) < 100_000
    assert abs(frame.captured - sim.clock.epoch()) < 2.0  # the robot's stamp
    for v in [*fast, stalled]:
        await cam.leave(v)
    assert not cam.streaming
    # The bridge drops the closed client's subscription (the simulator's own state: polled).
    await poll_until(lambda: subscribers(sim, CAMERA_TOPIC) == 0, WAIT, "the camera unsubscribed")
    assert cam.counts.not_jpeg == cam.counts.too_large == 0


def test_frames_are_read_from_cbor_and_from_json() -> None:
    jpeg = b"\xff\xd8" + bytes(range(256)) + b"\xff\xd9"
    msg = {"header": {"stamp": {"sec": 12, "nanosec": 500_000_000}}, "format": "jpeg"}
    op = {"op": "publish", "topic": "/cam", "msg": {**msg, "data": jpeg}}
    assert frame_of(cbor2.dumps(op), "/cam") == (jpeg, 12.5)
    text = json.dumps({**op, "msg": {**msg, "data": base64.b64encode(jpeg).decode()}})
    assert frame_of(text, "/cam") == (jpeg, 12.5)
    assert frame_of(text, "/other") is None
    for bad in ("not json", b"\xff\x00", '{"op":"publish","topic":"/cam","msg":{"data":"%%"}}'):
        assert frame_of(bad, "/cam") is None
