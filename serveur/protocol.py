"""The client/server message contract of the ``/ws`` endpoint, as pydantic models (no I/O).

Staff tablets, robot screens, table screens and scripts all speak this one protocol, so its
rules live here once: the models validate what clients send, serialise what the server sends
and produce the JSON Schema that ``serveur schema`` prints. ``docs/protocol.md`` is the prose
contract; ``tests/test_protocol.py`` parses that document's examples with these models so the two
cannot drift apart.

Design choices, and why:

* Client messages are a discriminated union on ``clientmsg`` (``create`` and ``control`` are
  nested unions on ``type`` / ``action``), so a message is checked against exactly one shape and
  the error names the field that is wrong rather than listing every shape it did not match.
* Validation is strict (no ``"1"`` for ``1``, no ``1`` for ``true``) and unknown fields are
  refused: a typo such as ``"vz"`` must fail loudly instead of silently sending zero velocity.
* :func:`parse_client` only ever raises :class:`~serveur.errors.ServeurError` subclasses and
  always sets ``request_id`` when the frame's ``id`` could be read, so the server's reader loop
  has one ``except`` and every error reply can be correlated by the client.
* Updates are fanned out to many connections: the record is serialised once (:func:`dump`) and
  :func:`update_frame` splices each connection's ``seq`` in by string concatenation.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Callable
from typing import Annotated, Any, Final, Literal, TypeAlias
from urllib.parse import urlsplit

import pydantic_core
from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    PlainValidator,
    StringConstraints,
    TypeAdapter,
    ValidationError,
    WithJsonSchema,
    model_validator,
)
from pydantic_core import PydanticCustomError

from serveur.domain import (
    AuditRecord,
    EventRecord,
    Order,
    Robot,
    Task,
    WaypointKind,
    WaypointRecord,
)
from serveur.errors import BadJson, InvalidField, ServeurError, UnknownMessage
from serveur.status import Action

__all__ = [
    "MAX_DEPTH",
    "MAX_FRAME_BYTES",
    "MAX_NAME",
    "MAX_ORDERS_PER_TASK",
    "MAX_PASSWORD",
    "MAX_TOKEN",
    "MAX_TOPICS",
    "ROBOT_TOPICS",
    "STATE_TOPICS",
    "VERBS",
    "CancelMsg",
    "ClientMessage",
    "ContinueMsg",
    "ControlAuto",
    "ControlGoal",
    "ControlGoto",
    "ControlInitialPose",
    "ControlManual",
    "ControlMessage",
    "ControlTeleop",
    "CreateMessage",
    "CreateOrder",
    "CreateRobot",
    "CreateTask",
    "CreateWaypoint",
    "DataMsg",
    "ErrorCode",
    "ErrorReply",
    "LoginMsg",
    "LogoutMsg",
    "MapSnapshot",
    "NextMsg",
    "OkReply",
    "OrderMsg",
    "PoseData",
    "ReadyMsg",
    "RequestId",
    "ScanData",
    "ServerMessage",
    "Session",
    "Snapshot",
    "StopMsg",
    "UpdateData",
    "UpdateMsg",
    "action_of",
    "dump",
    "error_frame",
    "ok_frame",
    "parse_client",
    "robot_of",
    "schema",
    "split_topic",
    "update_frame",
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
STATE_TOPICS: Final = ("robots", "orders", "tasks", "waypoints", "map", "events", "audit")
#: Per-robot topic prefixes: ``pose:<robot>`` and ``scan:<robot>``.
ROBOT_TOPICS: Final = ("pose", "scan")
#: Every ``clientmsg`` verb, in the order the documentation lists them.
VERBS: Final = (
    "login",
    "logout",
    "data",
    "create",
    "control",
    "ready",
    "next",
    "stop",
    "continue",
    "cancel",
    "order",
)

#: Limits of the work area: far beyond any restaurant, close enough to catch unit mistakes.
MAX_COORD: Final = 10_000.0
MAX_LINEAR: Final = 2.0  # m/s, teleop |vx|, |vy|
MAX_ANGULAR: Final = 4.0  # rad/s, teleop |wz|

_CONTROL_CHARS = re.compile(r"[\x00-\x1f\x7f]")


# --------------------------------------------------------------------------- field types


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
_REQUEST_ID: TypeAdapter[str | int] = TypeAdapter(RequestId)


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
        "unknown topic {topic}: expected one of {known}, or pose:<robot>, scan:<robot>",
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


def _dedupe(values: list[str]) -> list[str]:
    # Subscribing twice to a topic means subscribing once; keep the client's order.
    return list(dict.fromkeys(values))


def _unique_orders(values: list[int]) -> list[int]:
    # The same dish twice in one cart is a client bug (a double tap), not a bigger trip.
    if len(set(values)) != len(values):
        dupes = sorted({v for v in values if values.count(v) > 1})
        raise PydanticCustomError(
            "duplicate_orders", "order ids must be unique; repeated: {dupes}", {"dupes": dupes}
        )
    return values


# --------------------------------------------------------------------------- client messages


class _ClientMsg(BaseModel):
    """Common base: strict types, unknown fields refused, immutable once parsed."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, hide_input_in_errors=True)

    id: RequestId | None = Field(
        default=None, description="Echoed in the reply so the client can match it"
    )


#: Longest password accepted (scrypt hashes any length; this bounds the work).
MAX_PASSWORD: Final = 1024
#: Longest token accepted (ours are 47 characters).
MAX_TOKEN: Final = 256


class LoginMsg(_ClientMsg):
    """Authenticate this connection: ``username`` + ``password`` (a person: the reply carries a
    new session ``token``), or a ``token`` (a saved session, a screen's or a script's)."""

    clientmsg: Literal["login"]
    username: Name | None = None
    # repr=False: a logged message must never show a secret.
    password: Annotated[str, Field(min_length=1, max_length=MAX_PASSWORD)] | None = Field(
        default=None, repr=False
    )
    token: Annotated[str, Field(min_length=1, max_length=MAX_TOKEN)] | None = Field(
        default=None, repr=False
    )

    @model_validator(mode="after")
    def _one_way(self) -> LoginMsg:
        has_pw = self.username is not None or self.password is not None
        if has_pw == (self.token is not None) or (
            has_pw and (self.username is None or self.password is None)
        ):
            raise PydanticCustomError("login", "give username and password, or token")
        return self


class LogoutMsg(_ClientMsg):
    """End this connection's session: a password session's token is revoked for good."""

    clientmsg: Literal["logout"]


class DataMsg(_ClientMsg):
    """Subscribe to topics (reply: a snapshot of each) or, with ``unsubscribe``, leave them."""

    clientmsg: Literal["data"]
    topics: Annotated[
        list[Topic], Field(min_length=1, max_length=MAX_TOPICS), AfterValidator(_dedupe)
    ]
    unsubscribe: bool = False


class CreateWaypoint(_ClientMsg):
    """Name a map pose: explicit ``x, y[, yaw]``, or robot ``robot``'s current pose."""

    clientmsg: Literal["create"]
    type: Literal["waypoint"]
    name: Name
    x: Coord | None = None
    y: Coord | None = None
    yaw: Yaw | None = None
    robot: Name | None = Field(
        default=None, description="Save this robot's current pose (then omit x, y, yaw)"
    )
    kind: WaypointKind = Field(default=WaypointKind.OTHER, strict=False)
    replace: bool = Field(
        default=False, description="Overwrite an existing waypoint of this name (else conflict)"
    )

    @model_validator(mode="before")
    @classmethod
    def _default_yaw(cls, data: Any) -> Any:
        # An explicit pose without yaw (absent or null) faces along +x, like WaypointRecord's
        # default. (A null yaw once reached the record and failed there: internal_error.)
        if isinstance(data, dict) and data.get("robot") is None and data.get("yaw") is None:
            return {**data, "yaw": 0.0}
        return data

    @model_validator(mode="after")
    def _one_source(self) -> CreateWaypoint:
        if self.robot is not None:
            if self.x is not None or self.y is not None or self.yaw is not None:
                raise PydanticCustomError(
                    "waypoint_source",
                    "give either robot (save its current pose) or x, y, yaw — not both",
                )
        elif self.x is None or self.y is None:
            raise PydanticCustomError(
                "waypoint_source", "x and y are required unless robot is given"
            )
        return self


class CreateOrder(_ClientMsg):
    """A dish ready at the pass for a table. ``key`` makes a resend safe (idempotent)."""

    clientmsg: Literal["create"]
    type: Literal["order"]
    dish: Name
    table: Name
    key: Name | None = Field(default=None, description="Client-chosen idempotency key")


class CreateTask(_ClientMsg):
    """The confirmed virtual cart: dispatch these pending orders (split into trips)."""

    clientmsg: Literal["create"]
    type: Literal["task"]
    orders: Annotated[
        list[OrderId],
        Field(min_length=1, max_length=MAX_ORDERS_PER_TASK),
        AfterValidator(_unique_orders),
    ]
    key: Name | None = Field(default=None, description="Client-chosen idempotency key")


class CreateRobot(_ClientMsg):
    """Register a robot reachable over rosbridge at ``url``."""

    clientmsg: Literal["create"]
    type: Literal["robot"]
    name: Name
    url: WsUrl
    home: Name | None = Field(default=None, description="Waypoint the robot parks at")
    kinematics: Literal["omni", "diff"] = Field(
        default="omni", description="omni: vx, vy, wz; diff (differential drive): vx, wz only"
    )


CreateMessage: TypeAlias = Annotated[
    CreateWaypoint | CreateOrder | CreateTask | CreateRobot, Field(discriminator="type")
]


class _RobotMsg(_ClientMsg):
    robot: Name


class ControlAuto(_RobotMsg):
    """Activate the robot for automatic deliveries."""

    clientmsg: Literal["control"]
    action: Literal["auto"]


class ControlManual(_RobotMsg):
    """Take manual control (teleop, calibration, goals, go-to)."""

    clientmsg: Literal["control"]
    action: Literal["manual"]


class ControlTeleop(_RobotMsg):
    """One velocity command; send repeatedly while the joystick is held."""

    clientmsg: Literal["control"]
    action: Literal["teleop"]
    vx: LinearSpeed
    vy: LinearSpeed = Field(default=0.0, description="Sideways; ignored by diff robots")
    wz: AngularSpeed


class ControlInitialPose(_RobotMsg):
    """Calibrate: tell the robot's localisation where it is (RViz "2D Pose Estimate")."""

    clientmsg: Literal["control"]
    action: Literal["initialpose"]
    x: Coord
    y: Coord
    yaw: Yaw


class ControlGoal(_RobotMsg):
    """Send the robot to a map pose (RViz "2D Nav Goal")."""

    clientmsg: Literal["control"]
    action: Literal["goal"]
    x: Coord
    y: Coord
    yaw: Yaw


class ControlGoto(_RobotMsg):
    """Send the robot to a named waypoint (the Go-To list)."""

    clientmsg: Literal["control"]
    action: Literal["goto"]
    waypoint: Name


ControlMessage: TypeAlias = Annotated[
    ControlAuto | ControlManual | ControlTeleop | ControlInitialPose | ControlGoal | ControlGoto,
    Field(discriminator="action"),
]


class ReadyMsg(_RobotMsg):
    """Control finished: hand the robot back (leave manual or automatic mode)."""

    clientmsg: Literal["ready"]


class NextMsg(_RobotMsg):
    """Food collected at this table: go on to the next table, or home after the last."""

    clientmsg: Literal["next"]


class StopMsg(_RobotMsg):
    """Halt the current move (the trip is kept)."""

    clientmsg: Literal["stop"]


class ContinueMsg(_RobotMsg):
    """Resume the move that was stopped or failed."""

    clientmsg: Literal["continue"]


class CancelMsg(_RobotMsg):
    """Give up the trip: undelivered orders go back to pending, the robot goes home."""

    clientmsg: Literal["cancel"]


class OrderMsg(_ClientMsg):
    """List orders: a table's (table screen) or those on a robot's tray (robot screen)."""

    clientmsg: Literal["order"]
    table: Name | None = None
    robot: Name | None = None

    @model_validator(mode="after")
    def _exactly_one(self) -> OrderMsg:
        if (self.table is None) == (self.robot is None):
            raise PydanticCustomError("order_query", "give exactly one of table or robot")
        return self


ClientMessage: TypeAlias = Annotated[
    LoginMsg
    | LogoutMsg
    | DataMsg
    | CreateMessage
    | ControlMessage
    | ReadyMsg
    | NextMsg
    | StopMsg
    | ContinueMsg
    | CancelMsg
    | OrderMsg,
    Field(discriminator="clientmsg"),
]
_CLIENT: TypeAdapter[ClientMessage] = TypeAdapter(ClientMessage)

#: Sub-discriminators of the nested verbs, with their tags (for clear error messages).
_SUBTAGS: Final[dict[str, tuple[str, tuple[str, ...]]]] = {
    "create": ("type", ("waypoint", "order", "task", "robot")),
    "control": ("action", ("auto", "manual", "teleop", "initialpose", "goal", "goto")),
}

_ACTIONS: Final[dict[type[BaseModel], Action]] = {
    ControlAuto: Action.AUTO,
    ControlManual: Action.MANUAL,
    ControlTeleop: Action.TELEOP,
    ControlInitialPose: Action.INITIALPOSE,
    ControlGoal: Action.GOAL,
    ControlGoto: Action.GOTO,
    ReadyMsg: Action.READY,
    NextMsg: Action.NEXT,
    StopMsg: Action.STOP,
    ContinueMsg: Action.CONTINUE,
    CancelMsg: Action.CANCEL,
}


def action_of(msg: ClientMessage) -> Action | None:
    """The robot-status action ``msg`` needs (for ``status.check_allowed``), or None.

    None means the message is not bound to a robot's status: reading (``data``, ``order``),
    creating orders, tasks, robots, or waypoints from explicit poses.
    """
    if isinstance(msg, CreateWaypoint):
        return Action.SAVE_WAYPOINT if msg.robot is not None else None
    return _ACTIONS.get(type(msg))


def robot_of(msg: ClientMessage) -> str | None:
    """The existing robot ``msg`` is about (it must exist), or None.

    ``create robot`` returns None: it names a robot that does not exist yet.
    """
    robot = getattr(msg, "robot", None)
    return robot if isinstance(robot, str) else None


# --------------------------------------------------------------------------- parsing


class _DuplicateKey(Exception):
    def __init__(self, key: str) -> None:
        super().__init__(key)
        self.key = key


def _object_pairs(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
    # Two "clientmsg" (or two "robot") keys make a message mean two things; refuse it.
    out = dict(pairs)
    if len(out) != len(pairs):
        seen: set[str] = set()
        for key, _ in pairs:
            if key in seen:
                raise _DuplicateKey(key)
            seen.add(key)
    return out


_ID_SNIFF = re.compile(r'"id"\s*:\s*(-?\d{1,64}(?![\d.eE])|"(?:[^"\\\x00-\x1f]|\\.){0,64}")')


def _read_id(value: object) -> str | int | None:
    """``value`` as a request id if it is a valid one, else None (never raises)."""
    if value is None:
        return None
    try:
        return _REQUEST_ID.validate_python(value)
    except ValidationError:
        return None


def _sniff_id(text: str) -> str | int | None:
    """Best effort: the ``"id"`` of a frame that is not valid JSON (a truncated object...)."""
    match = _ID_SNIFF.search(text, 0, 4096)
    if match is None:
        return None
    try:
        return _read_id(json.loads(match.group(1)))
    except ValueError:
        return None


def _too_deep(value: object, limit: int) -> bool:
    """True if ``value`` nests containers more than ``limit`` deep (iterative: no recursion)."""
    stack: list[tuple[object, int]] = [(value, 1)]
    while stack:
        item, depth = stack.pop()
        if isinstance(item, dict):
            children: Any = item.values()
        elif isinstance(item, list):
            children = item
        else:
            continue
        if depth > limit:
            return True
        stack.extend((child, depth + 1) for child in children)
    return False


def _path(loc: tuple[int | str, ...]) -> str:
    out = ""
    for part in loc:
        out += f"[{part}]" if isinstance(part, int) else (f".{part}" if out else part)
    return out


_FRIENDLY: Final = {
    "extra_forbidden": "unknown field",
    "missing": "required field missing",
}


def _invalid(obj: dict[str, Any], verb: str, exc: ValidationError) -> InvalidField:
    """Turn pydantic's errors into one InvalidField naming each field path."""
    subtag = _SUBTAGS.get(verb)
    errors: list[dict[str, Any]] = []
    for err in exc.errors(include_url=False, include_input=False, include_context=True):
        loc = tuple(err["loc"])
        kind = err["type"]
        msg = _FRIENDLY.get(kind, err["msg"])
        if loc and loc[0] == verb:  # drop the discriminator tags pydantic puts in the path
            loc = loc[1:]
        if subtag is not None and loc and loc[0] == obj.get(subtag[0]):
            loc = loc[1:]
        if kind in ("union_tag_invalid", "union_tag_not_found") and subtag is not None:
            field, tags = subtag
            loc = (field,)
            msg = f"must be one of {', '.join(tags)}"
        errors.append({"loc": list(loc), "msg": msg, "type": kind})
    what = verb
    if subtag is not None and obj.get(subtag[0]) in subtag[1]:
        what = f"{verb} {obj[subtag[0]]}"[:80]
    shown = "; ".join(
        f"{_path(tuple(e['loc']))}: {e['msg']}" if e["loc"] else e["msg"] for e in errors[:5]
    )
    more = f" (and {len(errors) - 5} more)" if len(errors) > 5 else ""
    return InvalidField(f"invalid {what}: {shown}{more}", errors=errors[:20])


def parse_client(frame: str | bytes) -> ClientMessage:
    """Parse and validate one client frame.

    Raises ``BadJson`` (not JSON, not an object, binary frame not UTF-8), ``UnknownMessage``
    (missing or unknown ``clientmsg``) or ``InvalidField`` (anything else wrong, with
    ``details["errors"]`` listing ``loc``/``msg`` per field). Every raised error carries the
    frame's ``id`` as ``request_id`` whenever it could be read. Nothing else escapes.
    """
    try:
        return _parse(frame)
    except ServeurError:
        raise
    except Exception as exc:  # a bug here must not kill the connection's reader loop
        raise _internal(exc) from exc


def _internal(exc: Exception) -> ServeurError:
    return ServeurError(f"internal error while parsing the message: {type(exc).__name__}")


def _parse(frame: str | bytes) -> ClientMessage:
    if isinstance(frame, (bytes, bytearray, memoryview)):
        raw = bytes(frame)
        if len(raw) > MAX_FRAME_BYTES:
            raise InvalidField(
                f"frame is {len(raw)} bytes; the limit is {MAX_FRAME_BYTES}", size=len(raw)
            )
        try:
            text = raw.decode("utf-8")
        except UnicodeDecodeError as exc:
            raise BadJson(f"binary frame is not UTF-8 text: {exc.reason}") from None
    elif isinstance(frame, str):
        text = frame
        if len(text) > MAX_FRAME_BYTES:
            raise InvalidField(
                f"frame is over {MAX_FRAME_BYTES} bytes; the limit is {MAX_FRAME_BYTES}",
                size=len(text),
            )
    else:
        raise BadJson(f"frame must be text, not {type(frame).__name__}")

    try:
        obj = json.loads(text, object_pairs_hook=_object_pairs)
    except _DuplicateKey as exc:
        err: ServeurError = InvalidField(f"duplicate key {exc.key[:80]!r}", key=exc.key[:80])
        err.request_id = _sniff_id(text)
        raise err from None
    except RecursionError:
        err = InvalidField(f"JSON nested too deep (limit {MAX_DEPTH})")
        err.request_id = _sniff_id(text)
        raise err from None
    except ValueError as exc:  # JSONDecodeError, or an integer with too many digits
        err = BadJson(f"not valid JSON: {str(exc)[:200]}")
        err.request_id = _sniff_id(text)
        raise err from None

    if not isinstance(obj, dict):
        kind = {list: "an array", str: "a string", bool: "a boolean"}.get(type(obj), "a number")
        if obj is None:
            kind = "null"
        raise BadJson(f"a message must be a JSON object, not {kind}")

    request_id = _read_id(obj.get("id"))
    try:
        if _too_deep(obj, MAX_DEPTH):
            raise InvalidField(f"JSON nested too deep (limit {MAX_DEPTH})")
        verb = obj.get("clientmsg")
        if not isinstance(verb, str) or verb not in VERBS:
            got = "missing clientmsg" if verb is None else f"unknown clientmsg {str(verb)[:40]!r}"
            raise UnknownMessage(f"{got}; known: {', '.join(VERBS)}", known=list(VERBS))
        try:
            return _CLIENT.validate_python(obj)
        except ValidationError as exc:
            raise _invalid(obj, verb, exc) from None
    except ServeurError as exc:
        exc.request_id = request_id
        raise
    except Exception as exc:  # a bug in a validator: still answer with the request's id
        err = _internal(exc)
        err.request_id = request_id
        raise err from exc


# --------------------------------------------------------------------------- server messages


class _ServerModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class PoseData(_ServerModel):
    """A robot's map pose, as pushed on ``pose:<robot>``."""

    x: float
    y: float
    yaw: float = Field(description="radians, (-pi, pi]")
    stamp: float = Field(description="Unix time of the measurement, seconds")


class ScanData(_ServerModel):
    """One laser scan in the map frame, as pushed on ``scan:<robot>``.

    Beam ``i`` points at ``yaw + angle_min + i * angle_increment`` from ``(x, y)``; ``None``
    means no hit within ``range_max`` (ROS sends inf or NaN, which JSON cannot carry).
    """

    stamp: float
    x: float
    y: float
    yaw: float
    angle_min: float
    angle_increment: float
    range_max: float
    ranges: list[float | None]


class MapSnapshot(_ServerModel):
    """The occupancy grid: ``data`` is base64 of ``width * height`` int8 cells, row-major.

    Row 0 is the lowest y (ROS OccupancyGrid order); -1 unknown, 0 free .. 100 occupied. The
    cell at column ``i``, row ``j`` covers ``origin + (i, j) * resolution`` (origin yaw is 0 for
    maps made by ROS map_server).
    """

    resolution: float = Field(gt=0, description="metres per cell")
    origin: tuple[float, float, float] = Field(description="map pose of cell (0, 0): x, y, yaw")
    width: int = Field(ge=0)
    height: int = Field(ge=0)
    encoding: Literal["int8-base64"] = "int8-base64"
    data: str


#: What one ``data`` snapshot holds per topic: a list of records for state topics, the map,
#: or the latest pose/scan (null until the robot has reported one).
Snapshot: TypeAlias = (
    list[Robot]
    | list[Order]
    | list[Task]
    | list[WaypointRecord]
    | list[EventRecord]
    | list[AuditRecord]
    | MapSnapshot
    | PoseData
    | ScanData
    | None
)

#: What one ``update`` carries: one upserted record, the map, a pose or a scan.
UpdateData: TypeAlias = (
    Robot
    | Order
    | Task
    | WaypointRecord
    | EventRecord
    | AuditRecord
    | MapSnapshot
    | PoseData
    | ScanData
)

ErrorCode: TypeAlias = Literal[
    "unauthorized",
    "forbidden",
    "rate_limited",
    "bad_json",
    "unknown_message",
    "invalid_field",
    "not_found",
    "not_allowed_in_status",
    "conflict",
    "store_error",
    "map_error",
    "navigation_error",
    "unreachable",
    "rosbridge_error",
    "link_error",
    "internal_error",
]


class OkReply(_ServerModel):
    """The success reply to one request; which payload field is present depends on the verb."""

    servermsg: Literal["ok"]
    id: RequestId | None = None
    data: dict[str, Snapshot] | None = Field(default=None, description="data: topic -> snapshot")
    waypoint: WaypointRecord | None = Field(default=None, description="create waypoint")
    order: Order | None = Field(default=None, description="create order")
    tasks: list[Task] | None = Field(default=None, description="create task: the trips made")
    robot: Robot | None = Field(
        default=None, description="create robot, control, ready, next, stop, continue, cancel"
    )
    orders: list[Order] | None = Field(default=None, description="order")
    session: Session | None = Field(default=None, description="login, logout")


class Session(_ServerModel):
    """Who this connection is. ``token`` only in the reply to a password login."""

    user: str | None = None
    role: Literal["owner", "staff", "robot-screen", "table-screen", "integration"]
    robot: str | None = None
    table: str | None = None
    scopes: list[str]
    expires: float | None = Field(default=None, description="epoch seconds; null: never")
    token: str | None = None


class ErrorReply(_ServerModel):
    """The failure reply to one request (or to a frame that could not be read)."""

    servermsg: Literal["error"]
    id: RequestId | None = None
    code: ErrorCode
    message: str
    details: dict[str, Any] | None = None


class UpdateMsg(_ServerModel):
    """A pushed change on a subscribed topic. ``seq`` is +1 per update on this connection."""

    servermsg: Literal["update"]
    topic: Topic
    seq: int = Field(ge=1)
    data: UpdateData


ServerMessage: TypeAlias = Annotated[
    OkReply | ErrorReply | UpdateMsg, Field(discriminator="servermsg")
]
_SERVER: TypeAdapter[ServerMessage] = TypeAdapter(ServerMessage)
_OK_PAYLOAD: Final = frozenset(OkReply.model_fields) - {"servermsg", "id"}


# --------------------------------------------------------------------------- serialising


def _to_json(obj: object, fallback: Callable[[Any], Any] | None = None) -> str:
    return pydantic_core.to_json(obj, inf_nan_mode="null", fallback=fallback).decode()


def dump(obj: object) -> str:
    """Compact JSON of a model, a list of them or a dict; NaN and ±inf become ``null``.

    Enums become their values, tuples arrays. Non-ASCII text is kept as UTF-8, not escaped.
    """
    return _to_json(obj)


def ok_frame(request_id: str | int | None, **payload: object) -> str:
    """The success reply. ``payload`` keys must be :class:`OkReply` fields (else TypeError),
    so that what the server sends cannot drift from the documented schema."""
    unknown = payload.keys() - _OK_PAYLOAD
    if unknown:
        raise TypeError(f"not an OkReply field: {', '.join(sorted(unknown))}")
    frame: dict[str, object] = {"servermsg": "ok"}
    if request_id is not None:
        frame["id"] = request_id
    frame.update(payload)
    return _to_json(frame)


def error_frame(request_id: str | int | None, exc: ServeurError) -> str:
    """The error reply for ``exc``; ``request_id`` defaults to ``exc.request_id``.

    Never raises: details that are not JSON-able are sent as their ``str``, and text that UTF-8
    cannot carry (a lone surrogate a client sent as ``"\\ud800"``) with ``?`` in its place.
    """
    rid = request_id if request_id is not None else exc.request_id
    frame: dict[str, object] = {"servermsg": "error"}
    if rid is not None:
        frame["id"] = rid
    frame.update(exc.to_dict())
    try:
        return _to_json(frame, fallback=str)
    except ValueError:  # text that UTF-8 cannot carry (a lone surrogate from a \ud800 escape)
        return _to_json(_scrub(frame), fallback=str)


def _scrub(value: Any) -> Any:
    """``value`` with every string made UTF-8-safe (lone surrogates become ``?``)."""
    if isinstance(value, str):
        return value.encode("utf-8", "replace").decode("utf-8")
    if isinstance(value, dict):
        return {_scrub(k): _scrub(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_scrub(v) for v in value]
    return value


_topic_json: dict[str, str] = {}


def update_frame(topic: str, seq: int, data_json: str) -> str:
    """One update frame, from data serialised once per fan-out (``dump``).

    Equal to the compact ``json.dumps`` of ``{"servermsg": "update", "topic": topic, "seq":
    seq, "data": data}``; built by concatenation because it runs once per subscriber.
    """
    if type(seq) is not int:
        raise TypeError(f"seq must be an int, not {type(seq).__name__}")
    quoted = _topic_json.get(topic)
    if quoted is None:
        quoted = json.dumps(topic, ensure_ascii=False)
        if len(_topic_json) < 4096:
            _topic_json[topic] = quoted
    return (
        '{"servermsg":"update","topic":'
        + quoted
        + ',"seq":'
        + str(seq)
        + ',"data":'
        + data_json
        + "}"
    )


def schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of every client and every server message."""
    dialect = "https://json-schema.org/draft/2020-12/schema"
    client = {"$schema": dialect, "title": "ClientMessage", **_CLIENT.json_schema()}
    server = {"$schema": dialect, "title": "ServerMessage", **_SERVER.json_schema()}
    return {"client": client, "server": server}
