"""Is there a robot at this address? (serveur.robots.probe, over real sockets): a simulated
ROS1 and ROS 2 robot are found with their ROS and navigator; a closed port, a web server that
is not rosbridge and a silent one are each said in plain words."""

from __future__ import annotations

import asyncio
import contextlib

import pytest

from serveur.maps.navigation import demo_map_path
from serveur.robot_sim import start_simulation
from serveur.robots.probe import probe
from tests.subprocess_server import free_port


@pytest.mark.parametrize(("ros", "navigation"), [(1, "move_base"), (2, "Nav2")])
async def test_a_simulated_robot_is_found_with_its_ros(ros: int, navigation: str) -> None:
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), ros=ros)
    try:
        found = await probe(sim.urls[0])
        assert found.reachable and found.ros == ros and found.navigation == navigation, found
        assert found.topics > 5 and found.why == ""
    finally:
        await sim.close()


async def test_nothing_listening_is_said() -> None:
    found = await probe(f"ws://127.0.0.1:{free_port()}")
    assert not found.reachable and "nothing listens" in found.why


async def test_a_web_server_that_is_not_rosbridge_is_said() -> None:
    async def http(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        await reader.readuntil(b"\r\n\r\n")
        writer.write(b"HTTP/1.1 200 OK\r\nContent-Length: 2\r\n\r\nhi")
        await writer.drain()
        writer.close()

    server = await asyncio.start_server(http, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    try:
        found = await probe(f"ws://127.0.0.1:{port}")
        assert not found.reachable and "not a rosbridge server" in found.why, found
    finally:
        server.close()


async def test_a_silent_address_is_given_up_on_in_time() -> None:
    held: list[asyncio.StreamWriter] = []

    async def silent(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
        held.append(writer)  # accepts, then says nothing (a box that hangs)

    server = await asyncio.start_server(silent, "127.0.0.1", 0)
    port = server.sockets[0].getsockname()[1]
    try:
        found = await asyncio.wait_for(probe(f"ws://127.0.0.1:{port}", within=0.5), 5)
        assert not found.reachable and "no answer within 0.5 s" in found.why
    finally:
        for w in held:
            with contextlib.suppress(Exception):
                w.close()
        server.close()
