"""The chain's broker enforces the topic layout (issue 34), with messages actually flowing.

A real Mosquitto runs the repo's ``deploy/chain/acl`` behind TLS and a password file. What a
client may *not* do is proved without sleeping: Mosquitto keeps the order of one publisher's
messages to one subscriber, and a QoS 1 publish returns only after the broker has routed (or
dropped) it, so "the marker sent after the forbidden message arrived first" means the
forbidden one was never delivered, not that it is late.

Two things the broker does *not* say out loud, so the tests look at what arrives instead:
a denied publish is acknowledged all the same under MQTT 3.1.1 (PUBACK, then dropped; MQTT 5
gets PUBACK "Not authorized" but aiomqtt does not raise on it), and a subscription the ACL
does not allow is granted in the SUBACK (Mosquitto 2.0 checks ``read`` per message).
"""

from __future__ import annotations

import asyncio
import json
import socket
import ssl
import struct
from collections.abc import Iterator
from pathlib import Path
from urllib.parse import unquote, urlsplit

import aiomqtt
import pytest

from tests.chain.broker import ChainBroker, need_mosquitto

WAIT = 10.0  # wall seconds for anything the broker should do at once

#: Passwords with the characters a URL must quote (":", "@", "/", " ").
USERS = {"hq": "hq:s3cret@chain", "bistro": "bistro/pass word", "cafe": "caf@-pw"}


@pytest.fixture
def broker(tmp_path: Path) -> Iterator[ChainBroker]:
    need_mosquitto()
    with ChainBroker(tmp_path / "broker", USERS) as b:
        yield b


def client(
    broker: ChainBroker,
    user: str,
    *,
    password: str | None = None,
    identifier: str | None = None,
    clean_session: bool | None = None,
) -> aiomqtt.Client:
    """A client of ``user`` connected the way a site would: from its ``mqtts://`` URL
    (so the URL's quoting is tested too), trusting only the chain's CA."""
    url = urlsplit(broker.url(user))
    assert url.scheme == "mqtts" and url.hostname and url.port == broker.port
    return aiomqtt.Client(
        url.hostname,
        url.port,
        username=unquote(url.username or ""),
        password=unquote(url.password or "") if password is None else password,
        identifier=identifier,
        clean_session=clean_session,
        protocol=aiomqtt.ProtocolVersion.V311,
        tls_context=broker.client_context(),
        timeout=WAIT,
    )


async def next_message(c: aiomqtt.Client) -> tuple[str, object]:
    """The next message ``c`` receives: its topic and decoded JSON payload."""
    async with asyncio.timeout(WAIT):
        msg = await anext(c.messages)
    assert isinstance(msg.payload, bytes)
    return str(msg.topic), json.loads(msg.payload)


async def publish(c: aiomqtt.Client, topic: str, body: object, *, retain: bool = False) -> None:
    """QoS 1, as every chain topic is: returns once the broker has acknowledged it."""
    await c.publish(topic, json.dumps(body), qos=1, retain=retain)


async def test_hq_receives_what_a_site_publishes(broker: ChainBroker) -> None:
    async with client(broker, "hq") as hq, client(broker, "bistro") as bistro:
        await hq.subscribe("chain/+/events", qos=1)
        await hq.subscribe("chain/+/alive", qos=1)
        batch = [{"seq": 1, "kind": "order"}, {"seq": 2, "kind": "served"}]
        await publish(bistro, "chain/bistro/events", batch)
        await publish(bistro, "chain/bistro/alive", {"head": 2, "at": 1700000000.0})
        async with asyncio.timeout(WAIT):
            msg = await anext(hq.messages)
        assert (str(msg.topic), msg.qos, msg.retain) == ("chain/bistro/events", 1, False)
        assert json.loads(msg.payload) == batch
        assert await next_message(hq) == ("chain/bistro/alive", {"head": 2, "at": 1700000000.0})


async def test_a_site_cannot_publish_under_another_sites_prefix(broker: ChainBroker) -> None:
    async with client(broker, "hq") as hq, client(broker, "bistro") as bistro:
        await hq.subscribe("chain/+/events", qos=1)
        await hq.subscribe("chain/+/alive", qos=1)
        # Acknowledged (MQTT 3.1.1 has no way to say "denied") and dropped.
        await publish(bistro, "chain/cafe/events", [{"seq": 1, "forged": True}])
        await publish(bistro, "chain/cafe/alive", {"head": 99, "at": 0})
        await publish(bistro, "chain/bistro/events", [{"seq": 1, "marker": True}])
        assert await next_message(hq) == ("chain/bistro/events", [{"seq": 1, "marker": True}])
    assert "Denied PUBLISH" in broker.log_tail(200)
    assert "'chain/cafe/events'" in broker.log_tail(200)


async def test_a_site_reads_only_its_own_resend(broker: ChainBroker) -> None:
    async with client(broker, "hq") as hq, client(broker, "cafe") as cafe:
        # Both granted in the SUBACK all the same; the ACL filters each message on delivery.
        await cafe.subscribe("chain/bistro/resend", qos=1)
        await cafe.subscribe("chain/+/resend", qos=1)
        await cafe.subscribe("chain/cafe/resend", qos=1)
        await publish(hq, "chain/bistro/resend", {"from": 5})
        await publish(hq, "chain/cafe/resend", {"from": 9})
        assert await next_message(cafe) == ("chain/cafe/resend", {"from": 9})


async def test_confirmed_is_retained_and_only_hq_writes_it(broker: ChainBroker) -> None:
    async with client(broker, "hq") as hq:
        await publish(hq, "chain/bistro/confirmed", {"seq": 7}, retain=True)
        await publish(hq, "chain/cafe/confirmed", {"seq": 3}, retain=True)
        async with client(broker, "bistro") as bistro:
            await bistro.subscribe("chain/bistro/confirmed", qos=1)
            async with asyncio.timeout(WAIT):
                msg = await anext(bistro.messages)
            assert msg.retain and json.loads(msg.payload) == {"seq": 7}
            # The site forging its own acknowledgement: acknowledged, dropped, not retained.
            # hq has no read on confirmed, so the observer is bistro itself and hq's next
            # confirmed (sent after the forged one was acknowledged) is the marker.
            await publish(bistro, "chain/bistro/confirmed", {"seq": 999}, retain=True)
            await publish(hq, "chain/bistro/confirmed", {"seq": 8}, retain=True)
            assert await next_message(bistro) == ("chain/bistro/confirmed", {"seq": 8})
        async with client(broker, "bistro") as later:
            await later.subscribe("chain/bistro/confirmed", qos=1)
            assert await next_message(later) == ("chain/bistro/confirmed", {"seq": 8})
        # Retained messages come in the order of the subscriptions: bistro's would be first.
        async with client(broker, "cafe") as cafe:
            await cafe.subscribe("chain/bistro/confirmed", qos=1)
            await cafe.subscribe("chain/cafe/confirmed", qos=1)
            assert await next_message(cafe) == ("chain/cafe/confirmed", {"seq": 3})


async def test_wrong_or_missing_credentials_are_refused(broker: ChainBroker) -> None:
    for user, password in (("bistro", "not its password"), ("bistro", USERS["cafe"])):
        with pytest.raises(aiomqtt.MqttCodeError) as refused:
            async with client(broker, user, password=password):
                pass
        assert "Not authorized" in str(refused.value.rc)
    for username, secret in (("nobody", "x"), (None, None)):  # an unknown user, anonymous
        with pytest.raises(aiomqtt.MqttCodeError):
            async with aiomqtt.Client(
                "127.0.0.1",
                broker.port,
                username=username,
                password=secret,
                tls_context=broker.client_context(),
            ):
                pass
    # The broker's certificate is ours, not one the system trusts: verification is on.
    with pytest.raises(aiomqtt.MqttError, match="CERTIFICATE_VERIFY_FAILED"):
        async with aiomqtt.Client(
            "127.0.0.1",
            broker.port,
            username="hq",
            password=USERS["hq"],
            tls_context=ssl.create_default_context(),
        ):
            pass


def connect_packet(user: str, password: str) -> bytes:
    """An MQTT 3.1.1 CONNECT with username and password (clean session, keepalive 60)."""

    def field(s: str) -> bytes:
        return struct.pack("!H", len(s.encode())) + s.encode()

    body = field("MQTT") + bytes([4, 0xC2]) + struct.pack("!H", 60)
    body += field("plain-probe") + field(user) + field(password)
    assert len(body) < 128  # a one-byte remaining length
    return bytes([0x10, len(body)]) + body


async def test_plain_tcp_is_refused(broker: ChainBroker) -> None:
    # hq's right password, in clear: the broker closes the connection without a CONNACK ...
    with socket.create_connection(("127.0.0.1", broker.port), timeout=WAIT) as s:
        s.sendall(connect_packet("hq", USERS["hq"]))
        try:
            answer = s.recv(4)
        except ConnectionResetError:
            answer = b""
    assert answer == b""
    # ... while the same bytes over TLS are accepted (CONNACK, return code 0).
    raw = socket.create_connection(("127.0.0.1", broker.port), timeout=WAIT)
    with broker.client_context().wrap_socket(raw, server_hostname="127.0.0.1") as s:
        s.sendall(connect_packet("hq", USERS["hq"]))
        assert s.recv(4) == bytes([0x20, 2, 0, 0])
    # aiomqtt does not notice a close before CONNACK and gives up at its timeout: keep it short.
    with pytest.raises(aiomqtt.MqttError):
        async with aiomqtt.Client(
            "127.0.0.1", broker.port, username="hq", password=USERS["hq"], timeout=1
        ):
            pass


async def test_a_restart_keeps_the_port_and_clients_reconnect(broker: ChainBroker) -> None:
    port = broker.port
    broker.restart(kill=True)
    assert broker.port == port
    async with client(broker, "hq") as hq, client(broker, "bistro") as bistro:
        await hq.subscribe("chain/+/events", qos=1)
        await publish(bistro, "chain/bistro/events", [{"seq": 1}])
        assert await next_message(hq) == ("chain/bistro/events", [{"seq": 1}])
    broker.restart()
    assert broker.port == port
    async with client(broker, "bistro"):
        pass


async def test_broker_persistence_is_only_a_cache(broker: ChainBroker) -> None:
    """What the broker keeps for hq survives a clean restart, but a crash goes back to the
    last save: queued events are lost and the retained ``confirmed`` goes back to an older
    seq. Hence the site's outbox is the guarantee, and a site must never let ``confirmed``
    move its acknowledged seq backwards."""

    def hq_session() -> aiomqtt.Client:
        return client(broker, "hq", identifier="hq", clean_session=False)

    async with hq_session() as hq:
        await hq.subscribe("chain/+/events", qos=1)
    async with client(broker, "hq") as hq_writer, client(broker, "bistro") as bistro:
        await publish(bistro, "chain/bistro/events", [{"seq": 1}])
        await publish(hq_writer, "chain/bistro/confirmed", {"seq": 1}, retain=True)
    broker.restart()  # SIGTERM: the database is saved
    async with client(broker, "hq") as hq_writer, client(broker, "bistro") as bistro:
        await publish(bistro, "chain/bistro/events", [{"seq": 2}])
        await publish(hq_writer, "chain/bistro/confirmed", {"seq": 2}, retain=True)
    broker.restart(kill=True)  # a crash before the next autosave (60 s)
    async with client(broker, "bistro") as bistro:
        await bistro.subscribe("chain/bistro/confirmed", qos=1)
        assert await next_message(bistro) == ("chain/bistro/confirmed", {"seq": 1})
        async with hq_session() as hq:
            assert await next_message(hq) == ("chain/bistro/events", [{"seq": 1}])
            await publish(bistro, "chain/bistro/events", [{"seq": 3}])
            assert await next_message(hq) == ("chain/bistro/events", [{"seq": 3}])
