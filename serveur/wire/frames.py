"""The server's side of the ``/ws`` protocol: reply, error and update models, and the framing.

Part of :mod:`serveur.protocol` (which re-exports all of it). The models document and
validate (in tests, and in ``serveur schema``) what the server sends; the hot path does not
build them: :func:`ok_frame`, :func:`error_frame` and :func:`update_frame` write the JSON
directly, ``update_frame`` by concatenation because it runs once per subscriber of a fan-out.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from typing import Annotated, Any, Final, Literal, TypeAlias

import pydantic_core
from pydantic import BaseModel, ConfigDict, Field, TypeAdapter

from serveur.domain import (
    Alert,
    AuditRecord,
    Call,
    CallButton,
    EventRecord,
    MenuItem,
    Order,
    Robot,
    TableBlock,
    Task,
    TillTicket,
    WaypointRecord,
    ZoneLease,
    ZoneRecord,
)
from serveur.errors import ServeurError
from serveur.wire.backups import BackupInfo, RestoreInfo
from serveur.wire.chain import ChainInfo
from serveur.wire.fields import RequestId, Topic
from serveur.wire.uploads import AlignInfo, BackdropInfo

__all__ = [
    "SERVER_ADAPTER",
    "CameraState",
    "CloudData",
    "Dependents",
    "ErrorCode",
    "ErrorReply",
    "FleetForecast",
    "ForecastInfo",
    "MapSnapshot",
    "OkReply",
    "PoseData",
    "ScanData",
    "ServerMessage",
    "Session",
    "Settings",
    "Snapshot",
    "TillInfo",
    "TokenInfo",
    "UpdateData",
    "UpdateMsg",
    "UserInfo",
    "dump",
    "error_frame",
    "ok_frame",
    "update_frame",
]


class _ServerModel(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class Settings(_ServerModel):
    """The site's settings as they apply now (the ``settings`` topic, ``site settings``)."""

    table_timeout: float | None = Field(
        description="seconds a robot waits at a table before it goes on; null: for ever"
    )
    trays: int = Field(description="tables one trip may serve, for robots without their own")
    auto_depart: bool = Field(description="trips leave the pass at once, without Go")
    languages: list[Literal["en", "zh", "ms"]] = Field(description="the languages offered")
    language: Literal["en", "zh", "ms"] = Field(description="for a device without a choice")
    cameras: bool = Field(
        default=True, description="staff may watch the robots' cameras (off: guests' privacy)"
    )
    name: str = Field(default="", description="the restaurant's name (empty: not set yet)")
    public_url: str | None = Field(
        default=None,
        description="the server's address for the restaurant's tablets; null: not set (links"
        " then use the address the owner's browser used)",
    )
    target_wait: float = Field(
        default=600.0,
        description="seconds within which the owner wants 95 % of dishes at their table (the"
        " forecast's target)",
    )
    call_escalate: float = Field(
        default=120.0, description="seconds after which a call nobody answered is escalated"
    )
    bussing_wait: float = Field(
        default=120.0, description="seconds a bussing robot waits at a table for used dishes"
    )
    bussing_max_delay: float = Field(
        default=90.0, description="the most a bussing trip may hold back a waiting dish (s)"
    )
    charge_below: float = Field(
        default=0.25, description="a free robot with a dock goes to charge below this fraction"
    )
    charge_until: float = Field(
        default=0.90, description="a charging robot comes back into service at this fraction"
    )
    cruise_pause: float = Field(default=20.0, description="seconds at each place of a cruise")
    cruise_resume: float = Field(
        default=30.0, description="seconds a touched cruising robot waits before going on"
    )


class Dependents(_ServerModel):
    """What depends on a waypoint now (``site dependents``; a ``conflict``'s details)."""

    homes: list[str] = Field(description="robots whose home it is")
    orders: list[int] = Field(description="open dishes for the table")
    trips: list[int] = Field(description="queued or active trips stopping there")
    tokens: list[int] = Field(description="table-screen tokens bound to it")
    blocked: bool = Field(description="the table is blocked (unreachable)")
    docks: list[str] = Field(default_factory=list, description="robots whose charger it is")
    buttons: list[str] = Field(
        default_factory=list, description="live call buttons of the table (revoked with it)"
    )


class FleetForecast(_ServerModel):
    """One fleet size in a forecast: the replayed day's waits (s) with that many robots."""

    robots: int
    state: Literal["waiting", "running", "done", "failed", "cancelled"]
    delivered: int | None = None
    undelivered: int | None = None
    wait_mean: float | None = None
    wait_p95: float | None = None
    wait_max: float | None = None
    trips: int | None = None


class TillInfo(_ServerModel):
    """The till's set-up and how its printer port is (``till`` topic, ``till state``/``setup``)."""

    port: int = Field(description="the printer port serveur listens on; 0: off")
    printer: str = Field(
        description='"host:port" of the kitchen printer jobs are forwarded to; "": none (serveur'
        " is a second printer)"
    )
    encoding: str = Field(description="the printer's code page before any command")
    pattern: dict[str, Any] | None = Field(description="the ticket pattern; null: none yet")
    listening: bool = Field(description="the printer port is open")
    printer_up: bool | None = Field(
        description="the kitchen printer answered the last try; null: not tried, or none"
    )
    error: str | None = Field(description="why the printer port could not open")


class ForecastInfo(_ServerModel):
    """A forecast ("how many robots?"): a recorded day replayed with each fleet size."""

    id: int
    day: str
    policy: Literal["serveur", "baseline"]
    dishes: int = Field(description="plates that were ready at the pass that day")
    state: Literal["running", "done", "failed", "cancelled"]
    error: str | None = None
    fleets: list[FleetForecast]


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


class CloudData(_ServerModel):
    """The robot's localisation particles (AMCL's particle cloud), as pushed on
    ``cloud:<robot>`` while someone shows it: where the robot may be. A tight cloud is a
    robot sure of its place; one spread over the room, a robot that is lost."""

    stamp: float = Field(description="Unix time of the filter update, seconds (0: unknown)")
    count: int = Field(ge=0, description="particles in the robot's filter")
    particles: list[tuple[float, float, float]] = Field(
        description="at most 300 of them, the most likely first: x, y (m), yaw (rad)"
    )


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
    backdrop: BackdropInfo | None = Field(
        default=None, description="the floor plan drawn under the map (site align_map)"
    )


#: What one ``data`` snapshot holds per topic: a list of records for state topics, the map,
#: or the latest pose/scan (null until the robot has reported one).
Snapshot: TypeAlias = (
    list[Robot]
    | list[Order]
    | list[Task]
    | list[WaypointRecord]
    | list[EventRecord]
    | list[AuditRecord]
    | list[Alert]
    | list[MenuItem]
    | list[TableBlock]
    | list[ZoneRecord]
    | list[ZoneLease]
    | list[Call]
    | list[TillTicket]
    | Settings
    | ForecastInfo
    | TillInfo
    | MapSnapshot
    | PoseData
    | ScanData
    | CloudData
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
    | Alert
    | MenuItem
    | TableBlock
    | ZoneRecord
    | ZoneLease
    | Call
    | TillTicket
    | Settings
    | ForecastInfo
    | TillInfo
    | MapSnapshot
    | PoseData
    | ScanData
    | CloudData
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
    "stale",
    "rosbridge_error",
    "link_error",
    "backup_error",
    "internal_error",
]


class OkReply(_ServerModel):
    """The success reply to one request; which payload field is present depends on the verb."""

    servermsg: Literal["ok"]
    id: RequestId | None = None
    data: dict[str, Snapshot] | None = Field(default=None, description="data: topic -> snapshot")
    waypoint: WaypointRecord | None = Field(default=None, description="create waypoint")
    order: Order | None = Field(default=None, description="create order, dish")
    tasks: list[Task] | None = Field(default=None, description="create task: the trips made")
    robot: Robot | None = Field(
        default=None,
        description="create robot, control, ready, next, stop, continue, cancel, go, skip",
    )
    orders: list[Order] | None = Field(default=None, description="order")
    session: Session | None = Field(default=None, description="login, logout")
    time: float | None = Field(default=None, description="ping: the server's clock (epoch s)")
    alert: Alert | None = Field(default=None, description="ack: the alert, acknowledged")
    dish: MenuItem | None = Field(default=None, description="create dish: the menu entry")
    table: str | None = Field(default=None, description="clear: the table cleared")
    cleared: bool | None = Field(default=None, description="clear: false if it was not blocked")
    users: list[UserInfo] | None = Field(default=None, description="account list_users")
    user: UserInfo | None = Field(
        default=None, description="account add_user, set_role, reset_password, remove_user"
    )
    password: str | None = Field(
        default=None, description="account add_user, reset_password: shown once"
    )
    tokens: list[TokenInfo] | None = Field(default=None, description="account list_tokens")
    device: TokenInfo | None = Field(
        default=None, description="account create_token, revoke_token: the token's record"
    )
    token: str | None = Field(
        default=None, description="account create_token, site add_button: shown once"
    )
    link: str | None = Field(
        default=None, description="account create_token: the screen's setup path, token included"
    )
    qr: str | None = Field(default=None, description="account create_token: SVG of the QR code")
    revoked: list[int] | None = Field(
        default=None, description="site remove_robot, remove_waypoint: screen tokens revoked"
    )
    renamed: str | None = Field(default=None, description="site rename_waypoint: the old name")
    dependents: Dependents | None = Field(
        default=None, description="site dependents, rename_waypoint: what depends on it"
    )
    settings: Settings | None = Field(default=None, description="site settings, set_settings")
    audit: list[AuditRecord] | None = Field(
        default=None, description="site audit: the records found, newest first"
    )
    zone: ZoneRecord | None = Field(
        default=None, description="create zone; site remove_zone (removed: true)"
    )
    broken: list[str] | None = Field(
        default=None, description="release: the robots whose lease on the zone was broken"
    )
    leases: list[ZoneLease] | None = Field(default=None, description="release: the zone now")
    forecast: ForecastInfo | None = Field(
        default=None, description="stats forecast, forecast_cancel: the forecast"
    )
    last_service: str | None = Field(
        default=None,
        description="stats last_service: the latest service day a forecast can replay (null:"
        " none yet)",
    )
    camera: CameraState | None = Field(default=None, description="camera: watching or not")
    call: Call | None = Field(default=None, description="call open, answer, cancel: the call")
    merged: bool | None = Field(
        default=None, description="call open: true if it joined the table's open call"
    )
    task: Task | None = Field(default=None, description="create bussing: the trip queued")
    button: CallButton | None = Field(
        default=None, description="site add_button, revoke_button: the button"
    )
    buttons: list[CallButton] | None = Field(default=None, description="site buttons")
    till: TillInfo | None = Field(default=None, description="till state, setup")
    tickets: list[TillTicket] | None = Field(default=None, description="till tickets")
    ticket: TillTicket | None = Field(default=None, description="till by_hand: the ticket")
    pattern: dict[str, Any] | None = Field(
        default=None, description="till propose: the pattern the marks mean"
    )
    preview: list[dict[str, Any]] | None = Field(
        default=None, description="till propose, preview: what the pattern reads on each ticket"
    )
    read: list[int] | None = Field(
        default=None, description="till setup: the waiting tickets a new pattern made orders of"
    )
    names: dict[str, str] | None = Field(
        default=None, description="till import_menu, map: the till's names -> menu dishes"
    )
    rows: list[dict[str, Any]] | None = Field(
        default=None, description="till import_menu: each row of the file, mapped or not"
    )
    unmapped: list[dict[str, Any]] | None = Field(
        default=None, description="till unmapped: names printed on no menu, with suggestions"
    )
    path: str | None = Field(
        default=None,
        description="site add_button: the address the button requests (GET, token included)",
    )
    upload: UploadInfo | None = Field(default=None, description="site upload, upload_part")
    map: MapInfo | None = Field(
        default=None, description="site set_map, plan_map: the map now (or previewed)"
    )
    plan: PlanResult | None = Field(default=None, description="site plan_map: the result")
    alignment: AlignInfo | None = Field(
        default=None, description="site align_map: the floor plan fitted onto the map"
    )
    probe: ProbeInfo | None = Field(default=None, description="site probe_robot: what was found")
    outside: list[str] | None = Field(
        default=None, description="site set_map: the places no longer on free floor"
    )
    backups: list[BackupInfo] | None = Field(
        default=None, description="site backups: the box's backups, newest first"
    )
    backup: BackupInfo | None = Field(default=None, description="site backup_now: the new one")
    download: str | None = Field(
        default=None, description="site backup_now, download_backup: the backup's link"
    )
    restore: RestoreInfo | None = Field(
        default=None, description="site restore: what the backup holds, what it would lose"
    )
    stats: dict[str, Any] | None = Field(
        default=None,
        description="stats: figures ({periods, total}) or the trip history ({trips, more})",
    )
    chain: ChainInfo | None = Field(
        default=None, description="chain: the site's place in a chain and its outbox"
    )


class UploadInfo(_ServerModel):
    """An upload in progress (``site upload``, ``upload_part``): send its next part at
    ``received``, at most ``part`` bytes."""

    id: int
    kind: Literal["map_yaml", "map_image", "plan", "backup"]
    name: str
    size: int
    received: int
    part: int


class PlanResult(_ServerModel):
    """A floor plan made a map (``site plan_map``): its cells (as the ``map`` topic carries
    them) and the scale, per axis, from the owner's two measures."""

    map: MapSnapshot
    scale_x: float = Field(description="metres a plan pixel spans across")
    scale_y: float = Field(description="metres a plan pixel spans along")
    disagreement: float = Field(description="|x - y| / mean: 0 for an undistorted plan")
    stretched: bool = Field(description="the two scales disagree by more than 3 %")


class ProbeInfo(_ServerModel):
    """What ``site probe_robot`` found at an address."""

    reachable: bool
    why: str = Field(description="why it could not be reached (or what was odd), in plain words")
    ros: Literal[1, 2] | None = Field(
        description="the ROS it runs, as its rosapi said; null: unknown"
    )
    navigation: Literal["move_base", "Nav2"] | None
    topics: int = Field(description="topics the robot publishes or subscribes")


class MapInfo(_ServerModel):
    """The restaurant's map as ``site set_map`` made it (the cells come on the ``map`` topic)."""

    width: int
    height: int
    resolution: float
    origin: tuple[float, float, float]
    source: str


class CameraState(_ServerModel):
    """What a ``camera`` request left: the pictures come (``watching``), stopped, the robot
    has no camera (``none``), or the owner switched the cameras off (``off``)."""

    robot: str
    state: Literal["watching", "stopped", "none", "off"]


class UserInfo(_ServerModel):
    """A person who logs in (never their password)."""

    name: str
    role: Literal["owner", "staff"]
    created_at: float
    changed_at: float = Field(description="when the password last changed")


class TokenInfo(_ServerModel):
    """A device token as stored: never the token itself, only what it is for."""

    id: int
    role: Literal["owner", "staff", "robot-screen", "table-screen", "integration"]
    robot: str | None = None
    table: str | None = None
    scopes: list[str]
    label: str
    created_at: float
    expires_at: float | None = None
    revoked_at: float | None = None
    last_used_at: float | None = None


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
SERVER_ADAPTER: TypeAdapter[ServerMessage] = TypeAdapter(ServerMessage)
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
