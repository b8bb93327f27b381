"""The field types of the ``/ws`` protocol: limits, names, coordinates, request ids, topics.

Part of :mod:`serveur.protocol` (which re-exports what clients of the contract need): the
pydantic annotated types every client and server message is built from, each with the
validator that says in one clear error what is wrong, and the protocol's size limits. Kept
apart so the message models read as the contract they are.
"""

from __future__ import annotations

import math
import re
from typing import Annotated, Final, TypeAlias
from urllib.parse import urlsplit

from pydantic import (
    AfterValidator,
    Field,
    PlainValidator,
    StringConstraints,
    TypeAdapter,
    WithJsonSchema,
)
from pydantic_core import PydanticCustomError

__all__ = [
    "MAX_ANGULAR",
    "MAX_COORD",
    "MAX_DEPTH",
    "MAX_FRAME_BYTES",
    "MAX_LINEAR",
    "MAX_NAME",
    "MAX_ORDERS_PER_TASK",
    "MAX_TOPICS",
    "REQUEST_ID_ADAPTER",
    "ROBOT_TOPICS",
    "STATE_TOPICS",
    "VERBS",
    "AngularSpeed",
    "Coord",
    "LinearSpeed",
    "Name",
    "OrderId",
    "RequestId",
    "Topic",
    "WsUrl",
    "Yaw",
    "dedupe",
    "split_topic",
    "unique_orders",
]

#: Largest client frame the server accepts (the websocket layer enforces it too).
MAX_FRAME_BYTES: Final = 64 * 1024
#: Deepest JSON nesting accepted; real messages nest at most 2 levels.
MAX_DEPTH: Final = 20
#: Longest name (robot, table, waypoint, dish, idempotency key, request id).
MAX_NAME: Final = 64
#: Most orders one confirmed cart may carry.
MAX_ORDERS_PER_TASK: Final = 50
#: Most topics one ``data`` request may name.
MAX_TOPICS: Final = 64
#: Topics whose updates carry one upserted record (``map`` carries the map snapshot).
STATE_TOPICS: Final = (
    "robots",
    "orders",
    "tasks",
    "waypoints",
    "map",
    "events",
    "audit",
    "alerts",
    "menu",
    "blocks",
    "settings",
    "forecast",
    "calls",
    "zones",
    "leases",
    "tickets",
    "till",
)
#: Per-robot topic prefixes: ``pose:<robot>``, ``scan:<robot>`` and ``cloud:<robot>`` (the
#: particle cloud of its localisation).
ROBOT_TOPICS: Final = ("pose", "scan", "cloud")
#: Every ``clientmsg`` verb, in the order the documentation lists them.
VERBS: Final = (
    "login",
    "logout",
    "ping",
    "data",
    "create",
    "control",
    "ready",
    "next",
    "stop",
    "continue",
    "cancel",
    "go",
    "skip",
    "order",
    "dish",
    "ack",
    "clear",
    "account",
    "site",
    "stats",
    "release",
    "camera",
    "call",
    "charge",
    "work",
    "cruise",
    "till",
    "chain",
)

#: Limits of the work area: far beyond any restaurant, close enough to catch unit mistakes.
MAX_COORD: Final = 10_000.0
MAX_LINEAR: Final = 2.0  # m/s, teleop |vx|, |vy|
MAX_ANGULAR: Final = 4.0  # rad/s, teleop |wz|

_CONTROL_CHARS = re.compile(r"[\x00-\x1f\x7f]")


def _no_control_chars(value: str) -> str:
    # Names end up on screens, in logs and in topic names: control characters are never meant.
    if _CONTROL_CHARS.search(value):
        raise PydanticCustomError("name_chars", "must not contain control characters")
    return value


def _normalise_yaw(value: float) -> float:
    """Map any finite angle to (-pi, pi], so equal headings compare equal downstream."""
    out = math.remainder(value, math.tau)
    return math.pi if out <= -math.pi else out


def _check_ws_url(value: str) -> str:
    # A robot is reached over rosbridge, a websocket: anything else is a configuration mistake
    # best caught when the robot is created rather than at the first connection attempt.
    try:
        parts = urlsplit(value)
        _ = parts.port  # raises ValueError for a non-numeric or out-of-range port
    except ValueError as exc:
        raise PydanticCustomError(
            "ws_url", "not a valid URL: {reason}", {"reason": str(exc)}
        ) from None
    if parts.scheme not in ("ws", "wss"):
        raise PydanticCustomError("ws_url", "must start with ws:// or wss://")
    if not parts.hostname or any(c.isspace() for c in value):
        raise PydanticCustomError("ws_url", "must name a host and contain no spaces")
    return value


Name: TypeAlias = Annotated[
    str,
    StringConstraints(strip_whitespace=True, min_length=1, max_length=MAX_NAME),
    AfterValidator(_no_control_chars),
    Field(json_schema_extra={"pattern": r"^[^\x00-\x1f\x7f]+$"}),
]
Coord: TypeAlias = Annotated[
    float,
    Field(ge=-MAX_COORD, le=MAX_COORD, allow_inf_nan=False, description="metres, map frame"),
]
Yaw: TypeAlias = Annotated[
    float,
    Field(allow_inf_nan=False, description="radians; any finite value, normalised to (-pi, pi]"),
    AfterValidator(_normalise_yaw),
]
LinearSpeed: TypeAlias = Annotated[
    float, Field(ge=-MAX_LINEAR, le=MAX_LINEAR, allow_inf_nan=False, description="m/s")
]
AngularSpeed: TypeAlias = Annotated[
    float, Field(ge=-MAX_ANGULAR, le=MAX_ANGULAR, allow_inf_nan=False, description="rad/s")
]
WsUrl: TypeAlias = Annotated[
    str,
    StringConstraints(strip_whitespace=True, max_length=256),
    AfterValidator(_check_ws_url),
    Field(json_schema_extra={"pattern": r"^wss?://\S+$"}),
]
OrderId: TypeAlias = Annotated[int, Field(ge=1, le=2**53)]

_ID_INT_BOUND: Final = 10**63


def _is_utf8(value: str) -> bool:
    """False for text with a lone surrogate (JSON can write one as ``"\\ud800"``): it cannot
    be echoed in a UTF-8 frame, so it is neither a readable id nor a robot name."""
    try:
        value.encode("utf-8")
    except UnicodeEncodeError:
        return False
    return True


def _check_request_id(value: object) -> str | int:
    # One validator instead of a str|int union so that a bad id gets one clear error, not one
    # per union branch. Ints are bounded so their decimal form, like a str id, is <= 64 chars;
    # bool is refused although Python counts it as an int.
    if type(value) is str and len(value) <= MAX_NAME and _is_utf8(value):
        return value
    if type(value) is int and -_ID_INT_BOUND < value < 10 * _ID_INT_BOUND:
        return value
    raise PydanticCustomError(
        "request_id", "must be a string of at most 64 characters or an integer of at most 64 digits"
    )


#: The request ``id`` a client may attach; echoed verbatim in the reply.
RequestId: TypeAlias = Annotated[
    str | int,
    PlainValidator(_check_request_id),
    WithJsonSchema(
        {
            "anyOf": [
                {"type": "string", "maxLength": MAX_NAME},
                {
                    "type": "integer",
                    "exclusiveMinimum": -_ID_INT_BOUND,
                    "exclusiveMaximum": 10 * _ID_INT_BOUND,
                },
            ]
        }
    ),
]
REQUEST_ID_ADAPTER: TypeAdapter[str | int] = TypeAdapter(RequestId)


def split_topic(topic: str) -> tuple[str, str | None]:
    """``"pose:r1"`` -> ``("pose", "r1")``; ``"robots"`` -> ``("robots", None)``.

    Assumes a topic that already passed validation (a :class:`DataMsg` or :class:`UpdateMsg`).
    """
    kind, sep, robot = topic.partition(":")
    return (kind, robot) if sep else (kind, None)


def _check_topic(value: str) -> str:
    kind, robot = split_topic(value)
    if robot is None and kind in STATE_TOPICS:
        return value
    if (
        robot is not None
        and kind in ROBOT_TOPICS
        and 0 < len(robot) <= MAX_NAME
        and robot == robot.strip()
        and not _CONTROL_CHARS.search(robot)
        and _is_utf8(robot)
    ):
        return value
    raise PydanticCustomError(
        "topic",
        "unknown topic {topic}: expected one of {known}, or pose:<robot>, scan:<robot>,"
        " cloud:<robot>",
        {"topic": repr(value[:80]), "known": ", ".join(STATE_TOPICS)},
    )


_TOPIC_PATTERN = (
    r"^(?:" + "|".join(STATE_TOPICS) + r"|(?:" + "|".join(ROBOT_TOPICS) + r"):[^\x00-\x1f\x7f]+)$"
)
Topic: TypeAlias = Annotated[
    str,
    AfterValidator(_check_topic),
    Field(json_schema_extra={"pattern": _TOPIC_PATTERN}, max_length=MAX_NAME + 5),
]


def dedupe(values: list[str]) -> list[str]:
    # Subscribing twice to a topic means subscribing once; keep the client's order.
    return list(dict.fromkeys(values))


def unique_orders(values: list[int]) -> list[int]:
    # The same dish twice in one cart is a client bug (a double tap), not a bigger trip.
    if len(set(values)) != len(values):
        dupes = sorted({v for v in values if values.count(v) > 1})
        raise PydanticCustomError(
            "duplicate_orders", "order ids must be unique; repeated: {dupes}", {"dupes": dupes}
        )
    return values
