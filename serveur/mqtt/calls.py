"""Call buttons over the site's MQTT broker: a press is a message on ``<prefix>/call``.

What button firmwares publish (ESPHome ``mqtt.publish``, Tasmota ``Publish``, Shelly's MQTT
actions) is a topic and a payload they are told; so a press carries the button's token in the
payload, never in the topic (a topic is seen by every subscriber of ``#`` and kept in the
broker's logs): ``<token>``, ``<token> <kind>`` or ``{"token": "...", "kind": "bill"}``. The
press is then exactly the HTTP one (:meth:`serveur.core.call_desk.CallDesk.press`: the same
token check, merge and rate limit), and its answer is published on ``<prefix>/call/result``
as ``{"status": 200, "text": "called: waiter at T3 (call 7)"}`` for whoever wants to show it.

The connection is kept up by :func:`serveur.mqtt.session.keep_session`, the reconnect loop
every MQTT client here shares (the broker logged once down and once up).
"""

from __future__ import annotations

import asyncio
import json
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from typing import Any
from urllib.parse import unquote, urlsplit

from serveur.core.call_desk import Press
from serveur.mqtt.session import keep_session

__all__ = ["BrokerAddress", "MqttCalls", "parse_press"]

log = logging.getLogger(__name__)

#: The most a press's payload may be (a token is 47 characters): anything longer is not one.
MAX_PAYLOAD = 512


@dataclass(frozen=True, slots=True)
class BrokerAddress:
    """``mqtt://[user[:password]@]host[:port][/prefix]`` as the command line gives it."""

    host: str
    port: int = 1883
    username: str | None = None
    password: str | None = None
    prefix: str = "serveur"

    @classmethod
    def parse(cls, url: str) -> BrokerAddress:
        parts = urlsplit(url)
        if parts.scheme != "mqtt" or not parts.hostname:
            raise ValueError(f"an MQTT broker is mqtt://host[:port][/prefix], not {url!r}")
        prefix = parts.path.strip("/") or "serveur"
        if "#" in url or "+" in prefix or parts.query:
            raise ValueError(f"the topic prefix {prefix!r} may not hold # or +")
        return cls(
            parts.hostname,
            parts.port or 1883,
            unquote(parts.username) if parts.username else None,
            unquote(parts.password) if parts.password else None,
            prefix,
        )


def parse_press(payload: bytes) -> tuple[str, str | None] | None:
    """The (token, kind) a press's payload carries, or None if it is not one."""
    if len(payload) > MAX_PAYLOAD:
        return None
    try:
        text = payload.decode("utf-8").strip()
    except UnicodeDecodeError:
        return None
    if text.startswith("{"):
        try:
            obj: Any = json.loads(text)
        except ValueError:
            return None
        token, kind = obj.get("token"), obj.get("kind")
        if not isinstance(token, str) or not (kind is None or isinstance(kind, str)):
            return None
        return token, kind
    words = text.split()
    if len(words) == 1:
        return words[0], None
    if len(words) == 2:
        return words[0], words[1]
    return None


class MqttCalls:
    """Listens for presses on the broker while the server runs."""

    def __init__(
        self,
        address: BrokerAddress,
        press: Callable[[str, str | None], Awaitable[Press]],
        after: Callable[[], Awaitable[None]],
    ) -> None:
        """``press`` is the call desk's; ``after`` flushes what the press recorded."""
        self.address = address
        self._press = press
        self._after = after
        self._task: asyncio.Task[None] | None = None
        self.connected = asyncio.Event()

    @property
    def topic(self) -> str:
        return f"{self.address.prefix}/call"

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name="mqtt-calls")

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
            self._task = None

    async def _run(self) -> None:
        import aiomqtt  # only where a broker is configured

        a = self.address

        def client() -> aiomqtt.Client:
            return aiomqtt.Client(
                a.host, a.port, username=a.username, password=a.password, timeout=10
            )

        async def setup(client: aiomqtt.Client) -> None:
            await client.subscribe(self.topic, qos=1)

        async def session(client: aiomqtt.Client) -> None:
            async for message in client.messages:
                reply = await self._one(_bytes(message.payload))
                await client.publish(f"{self.topic}/result", reply, qos=0)

        await keep_session(
            f"MQTT call buttons on {a.host}:{a.port} {self.topic}",
            client,
            setup,
            session,
            connected=self.connected,
            log=log,
        )

    async def _one(self, payload: bytes) -> str:
        found = parse_press(payload)
        if found is None:
            press = Press(400, "a press is '<token>', '<token> <kind>' or {\"token\": ...}\n")
        else:
            try:
                press = await self._press(*found)
                await self._after()
            except Exception:  # one bad press must not stop the listener
                log.exception("MQTT: a press failed")
                press = Press(500, "internal error\n")
        if press.status != 200:
            log.info("MQTT call refused: %s", press.text.strip())
        return json.dumps({"status": press.status, "text": press.text.strip()})


def _bytes(payload: object) -> bytes:
    if isinstance(payload, bytes | bytearray):
        return bytes(payload)
    return str(payload if payload is not None else "").encode()
