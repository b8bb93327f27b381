"""Call buttons over the restaurant's MQTT broker (issue 32): a real Mosquitto on a loopback
port, a real server, the button's press published the way its firmware would."""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import shutil
import subprocess
from collections.abc import AsyncIterator, Iterator
from pathlib import Path

import pytest

from serveur.mqtt.calls import BrokerAddress, parse_press
from tests.conftest import Client, restaurant
from tests.core.test_service_day import owner_of, site
from tests.subprocess_server import free_port

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"


def test_what_a_press_may_carry() -> None:
    assert parse_press(b"srb_abc") == ("srb_abc", None)
    assert parse_press(b" srb_abc bill\n") == ("srb_abc", "bill")
    assert parse_press(b'{"token": "srb_abc", "kind": "waiter"}') == ("srb_abc", "waiter")
    for bad in (b"", b"a b c", b'{"token": 7}', b"{not json", b"\xff\xfe", b"x" * 600):
        assert parse_press(bad) is None, bad


def test_the_broker_address() -> None:
    a = BrokerAddress.parse("mqtt://ana:s%40cret@192.168.1.5:1884/bistro")
    assert (a.host, a.port, a.username, a.password, a.prefix) == (
        "192.168.1.5",
        1884,
        "ana",
        "s@cret",
        "bistro",
    )
    assert BrokerAddress.parse("mqtt://box").prefix == "serveur"
    for bad in ("http://box", "mqtt://", "mqtt://box/a/#"):
        with pytest.raises(ValueError):
            BrokerAddress.parse(bad)


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[int]:
    if not os.path.exists(MOSQUITTO):
        if os.environ.get("CI"):
            pytest.fail("the MQTT tests must run in CI: apt-get install mosquitto")
        pytest.skip("mosquitto not installed: apt-get install mosquitto")
    port = free_port()
    conf = tmp_path / "mosquitto.conf"
    conf.write_text(f"listener {port} 127.0.0.1\nallow_anonymous true\npersistence false\n")
    proc = subprocess.Popen(
        [MOSQUITTO, "-c", str(conf)], stdout=subprocess.DEVNULL, stderr=subprocess.PIPE
    )
    try:
        yield port
    finally:
        proc.terminate()
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()


@contextlib.asynccontextmanager
async def listener(port: int, topic: str) -> AsyncIterator[asyncio.Queue[dict[str, object]]]:
    """A subscriber to the presses' results (what a button's own display would show)."""
    import aiomqtt

    results: asyncio.Queue[dict[str, object]] = asyncio.Queue()
    async with aiomqtt.Client("127.0.0.1", port) as client:
        await client.subscribe(topic, qos=1)

        async def read() -> None:
            async for msg in client.messages:
                results.put_nowait(json.loads(bytes(msg.payload)))  # type: ignore[arg-type]

        reader = asyncio.create_task(read())
        try:
            yield results
        finally:
            reader.cancel()
            await asyncio.gather(reader, return_exceptions=True)


async def publish(port: int, topic: str, payload: str) -> None:
    import aiomqtt

    async with aiomqtt.Client("127.0.0.1", port) as client:
        await client.publish(topic, payload, qos=1)


async def test_a_button_publishing_its_token_calls(tmp_path: Path, broker: int) -> None:
    mqtt = f"mqtt://127.0.0.1:{broker}/bistro"
    async with restaurant(tmp_path, robots=1, config=site(), mqtt=mqtt) as r:
        assert r.app.mqtt_calls is not None
        await asyncio.wait_for(r.app.mqtt_calls.connected.wait(), 20)
        c: Client = await r.client()
        await c.subscribe("calls")
        owner = await owner_of(r)
        token = (await owner.ok("site", action="add_button", name="b7", table="T7"))["token"]
        async with listener(broker, "bistro/call/result") as results:
            await publish(broker, "bistro/call", token)
            first = await asyncio.wait_for(results.get(), 20)
            assert first["status"] == 200 and str(first["text"]).startswith("called: waiter at T7")
            await c.until(lambda: any(x["table"] == "T7" for x in c.records["calls"].values()))
            [call] = c.records["calls"].values()
            assert call["source"] == "button:b7"
            await publish(broker, "bistro/call", json.dumps({"token": token, "kind": "bill"}))
            assert (await asyncio.wait_for(results.get(), 20))["status"] == 200
            await publish(broker, "bistro/call", "not a token at all")
            assert (await asyncio.wait_for(results.get(), 20))["status"] == 400
            await publish(broker, "bistro/call", "srb_unknown")
            assert (await asyncio.wait_for(results.get(), 20))["status"] == 404
            await owner.ok("site", action="revoke_button", name="b7")
            await publish(broker, "bistro/call", token)
            assert (await asyncio.wait_for(results.get(), 20))["status"] == 404
        assert sorted(x["kind"] for x in c.records["calls"].values()) == ["bill", "waiter"]
