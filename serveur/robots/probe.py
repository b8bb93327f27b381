"""Is there a robot at this address, and which ROS does it run? Asked once, before it is added.

The owner types a robot's address while setting the restaurant up; this connects to it once
(bounded by a timeout) and says in plain terms what it found: "reachable" with the ROS version
and navigator, or "cannot reach" with why (nothing listening, a wrong address, not rosbridge).

The ROS version comes from what rosbridge's own rosapi answers about the robot's topics: rosapi
2.x (ROS 2) spells message types ``pkg/msg/Type``, rosapi 1.x (ROS1) ``pkg/Type``
(../shared/notes/ros2.md); the navigator from the topics themselves (``move_base/status`` for
move_base, ``navigate_to_pose/_action/status`` for Nav2). A bridge that answers but has no
rosapi still counts as reachable, version unknown.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import ssl as ssl_module
from dataclasses import dataclass
from typing import Any

from websockets.exceptions import InvalidHandshake, InvalidURI, WebSocketException

from serveur.robots import rosbridge as rb
from serveur.robots.reconnect import open_rosbridge

__all__ = ["Probe", "probe"]


@dataclass(frozen=True, slots=True)
class Probe:
    """What was found at an address."""

    reachable: bool
    why: str = ""  # why not, in plain words
    ros: int | None = None  # 1 or 2, None when rosapi did not say
    navigation: str | None = None  # "move_base", "Nav2" or None
    topics: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {
            "reachable": self.reachable,
            "why": self.why,
            "ros": self.ros,
            "navigation": self.navigation,
            "topics": self.topics,
        }


def _judge(topics: list[str], types: list[str]) -> Probe:
    ros = 2 if any("/msg/" in t for t in types) else 1 if types else None
    navigation = None
    if any(t.endswith("navigate_to_pose/_action/status") for t in topics):
        navigation = "Nav2"
    elif any(t.endswith("move_base/status") for t in topics):
        navigation = "move_base"
    return Probe(True, ros=ros, navigation=navigation, topics=len(topics))


async def _call(ws: Any, service: str) -> dict[str, Any] | None:
    """One rosapi call's values (None: refused, or the bridge closed)."""
    await ws.send(rb.encode(rb.op_call_service(service, {}, id=service)))
    async for raw in ws:
        with contextlib.suppress(ValueError, TypeError):
            op = json.loads(raw)
            if isinstance(op, dict) and op.get("id") == service:
                values = op.get("values")
                ok = op.get("result") is not False and isinstance(values, dict)
                return values if ok else None
    return None


async def probe(
    url: str, *, ssl: ssl_module.SSLContext | None = None, within: float = 4.0
) -> Probe:
    """Connect to ``url`` once and ask rosapi for the robot's topics (at most ``within`` s:
    the owner waits on the page for the answer)."""
    timeout = within
    tls = ssl if url[:6].lower() == "wss://" else None
    try:
        async with asyncio.timeout(timeout):
            async with open_rosbridge(url, ssl=tls, open_timeout=timeout) as ws:
                values = await _call(ws, "/rosapi/topics")
                if values is None:
                    return Probe(True, why="rosapi did not answer")
                topics = [str(t) for t in values.get("topics") or []]
                found = _judge(topics, [str(t) for t in values.get("types") or []])
                if found.ros == 2 and found.navigation is None:
                    # Nav2's action topics are hidden from rosapi 2.x's topic list: ask for
                    # the action servers (a service only rosapi 2.x has).
                    servers = await _call(ws, "/rosapi/action_servers") or {}
                    names = [str(a) for a in servers.get("action_servers") or []]
                    if any(n.endswith("navigate_to_pose") for n in names):
                        found = Probe(True, ros=2, navigation="Nav2", topics=found.topics)
                return found
    except TimeoutError:
        return Probe(False, why=f"no answer within {timeout:g} s (switched off? another network?)")
    except ConnectionRefusedError:
        return Probe(False, why="nothing listens there (is rosbridge running? the right port?)")
    except (InvalidURI, InvalidHandshake) as exc:
        return Probe(False, why=f"not a rosbridge server: {exc}")
    except ssl_module.SSLError as exc:
        return Probe(False, why=f"TLS: {exc.reason or exc}")
    except (OSError, WebSocketException) as exc:
        return Probe(False, why=str(exc) or type(exc).__name__)
