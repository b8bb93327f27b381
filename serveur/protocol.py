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
import re
from typing import Annotated, Any, Final, Literal, TypeAlias

from pydantic import (
    AfterValidator,
    BaseModel,
    ConfigDict,
    Field,
    TypeAdapter,
    ValidationError,
    model_validator,
)
from pydantic_core import PydanticCustomError

from serveur.domain import (
    WaypointKind,
)
from serveur.errors import BadJson, InvalidField, ServeurError, UnknownMessage
from serveur.status import Action
from serveur.wire.accounts import (
    AccountAddUser,
    AccountCreateToken,
    AccountListTokens,
    AccountListUsers,
    AccountMessage,
    AccountRemoveUser,
    AccountResetPassword,
    AccountRevokeToken,
    AccountSetRole,
)
from serveur.wire.backups import (
    BackupInfo,
    RestoreInfo,
    SiteBackupNow,
    SiteBackups,
    SiteDownloadBackup,
    SiteRestore,
)
from serveur.wire.base import ClientModel
from serveur.wire.calls import (
    CallAnswer,
    CallCancel,
    CallMessage,
    CallOpen,
    SiteAddButton,
    SiteButtons,
    SiteRevokeButton,
)
from serveur.wire.chain import ChainInfo, ChainMsg, OutboxInfo
from serveur.wire.fields import (
    MAX_ANGULAR,
    MAX_COORD,
    MAX_DEPTH,
    MAX_FRAME_BYTES,
    MAX_LINEAR,
    MAX_NAME,
    MAX_ORDERS_PER_TASK,
    MAX_TOPICS,
    REQUEST_ID_ADAPTER,
    ROBOT_TOPICS,
    STATE_TOPICS,
    VERBS,
    AngularSpeed,
    Coord,
    LinearSpeed,
    Name,
    OrderId,
    RequestId,
    Topic,
    WsUrl,
    Yaw,
    dedupe,
    split_topic,
    unique_orders,
)
from serveur.wire.frames import (
    SERVER_ADAPTER,
    CloudData,
    ErrorCode,
    ErrorReply,
    ForecastInfo,
    MapSnapshot,
    OkReply,
    PoseData,
    ScanData,
    ServerMessage,
    Session,
    Snapshot,
    TokenInfo,
    UpdateData,
    UpdateMsg,
    UserInfo,
    dump,
    error_frame,
    ok_frame,
    update_frame,
)
from serveur.wire.owner import (
    LANGUAGES,
    SiteAudit,
    SiteDependents,
    SiteEditRobot,
    SiteMessage,
    SiteProbeRobot,
    SiteRemoveRobot,
    SiteRemoveWaypoint,
    SiteRemoveZone,
    SiteRenameWaypoint,
    SiteSetSettings,
    SiteSettings,
    StatsFigures,
    StatsForecast,
    StatsForecastCancel,
    StatsLastService,
    StatsMessage,
    StatsTrips,
)
from serveur.wire.till import (
    IntakeDish,
    IntakeOrder,
    TillByHand,
    TillImportMenu,
    TillMap,
    TillMark,
    TillMessage,
    TillPattern,
    TillPreview,
    TillPropose,
    TillSetup,
    TillState,
    TillTickets,
    TillUnmapped,
)
from serveur.wire.uploads import (
    UPLOAD_LIMITS,
    UPLOAD_PART,
    SiteAlignMap,
    SitePlanMap,
    SiteSetMap,
    SiteUpload,
    SiteUploadPart,
)

__all__ = [
    "LANGUAGES",
    "MAX_ANGULAR",
    "MAX_COORD",
    "MAX_DEPTH",
    "MAX_FRAME_BYTES",
    "MAX_LINEAR",
    "MAX_NAME",
    "MAX_ORDERS_PER_TASK",
    "MAX_PASSWORD",
    "MAX_TOKEN",
    "MAX_TOPICS",
    "ROBOT_TOPICS",
    "STATE_TOPICS",
    "UPLOAD_LIMITS",
    "UPLOAD_PART",
    "VERBS",
    "AccountAddUser",
    "AccountCreateToken",
    "AccountListTokens",
    "AccountListUsers",
    "AccountMessage",
    "AccountRemoveUser",
    "AccountResetPassword",
    "AccountRevokeToken",
    "AccountSetRole",
    "AckMsg",
    "BackupInfo",
    "CallAnswer",
    "CallCancel",
    "CallMessage",
    "CallOpen",
    "CameraMsg",
    "CancelMsg",
    "ChainInfo",
    "ChainMsg",
    "ChargeMsg",
    "ClearMsg",
    "ClientMessage",
    "CloudData",
    "ContinueMsg",
    "ControlAuto",
    "ControlGoal",
    "ControlGoto",
    "ControlInitialPose",
    "ControlManual",
    "ControlMessage",
    "ControlTeleop",
    "CreateBussing",
    "CreateDish",
    "CreateMessage",
    "CreateOrder",
    "CreateRobot",
    "CreateTask",
    "CreateWaypoint",
    "CreateZone",
    "CruiseMsg",
    "DataMsg",
    "DishMsg",
    "ErrorCode",
    "ErrorReply",
    "ForecastInfo",
    "GoMsg",
    "IntakeDish",
    "IntakeOrder",
    "LoginMsg",
    "LogoutMsg",
    "MapSnapshot",
    "NextMsg",
    "OkReply",
    "OrderMsg",
    "OutboxInfo",
    "PingMsg",
    "PoseData",
    "ReadyMsg",
    "ReleaseMsg",
    "RequestId",
    "RestoreInfo",
    "ScanData",
    "ServerMessage",
    "Session",
    "SiteAddButton",
    "SiteAlignMap",
    "SiteAudit",
    "SiteBackupNow",
    "SiteBackups",
    "SiteButtons",
    "SiteDependents",
    "SiteDownloadBackup",
    "SiteEditRobot",
    "SiteMessage",
    "SitePlanMap",
    "SiteProbeRobot",
    "SiteRemoveRobot",
    "SiteRemoveWaypoint",
    "SiteRemoveZone",
    "SiteRenameWaypoint",
    "SiteRestore",
    "SiteRevokeButton",
    "SiteSetMap",
    "SiteSetSettings",
    "SiteSettings",
    "SiteUpload",
    "SiteUploadPart",
    "SkipMsg",
    "Snapshot",
    "StatsFigures",
    "StatsForecast",
    "StatsForecastCancel",
    "StatsLastService",
    "StatsMessage",
    "StatsTrips",
    "StopMsg",
    "TargetMsg",
    "TillByHand",
    "TillImportMenu",
    "TillMap",
    "TillMark",
    "TillMessage",
    "TillPattern",
    "TillPreview",
    "TillPropose",
    "TillSetup",
    "TillState",
    "TillTickets",
    "TillUnmapped",
    "TokenInfo",
    "TrayChoice",
    "UpdateData",
    "UpdateMsg",
    "UserInfo",
    "WorkMsg",
    "action_of",
    "dump",
    "error_frame",
    "ok_frame",
    "parse_client",
    "parse_intake",
    "robot_of",
    "schema",
    "split_topic",
    "update_frame",
]

# --------------------------------------------------------------------------- client messages


_ClientMsg = ClientModel  # every client message's base (serveur.wire.base)


#: Longest password accepted (scrypt hashes any length; this bounds the work).
MAX_PASSWORD: Final = 1024
#: Longest token accepted (ours are 47 characters).
MAX_TOKEN: Final = 256


class LoginMsg(_ClientMsg):
    """Authenticate this connection: ``username`` + ``password`` (a person: the reply carries a
    new session ``token``), or a ``token`` (a saved session, a screen's or a script's).

    On a server nobody has set up yet, ``setup`` (the code in the setup link the server printed
    at its first start) with ``username`` + ``password`` creates the restaurant's owner with
    that password and logs in as them; the code is then spent."""

    clientmsg: Literal["login"]
    username: Name | None = None
    # repr=False: a logged message must never show a secret.
    password: Annotated[str, Field(min_length=1, max_length=MAX_PASSWORD)] | None = Field(
        default=None, repr=False
    )
    token: Annotated[str, Field(min_length=1, max_length=MAX_TOKEN)] | None = Field(
        default=None, repr=False
    )
    setup: Annotated[str, Field(min_length=1, max_length=MAX_TOKEN)] | None = Field(
        default=None, repr=False
    )

    @model_validator(mode="after")
    def _one_way(self) -> LoginMsg:
        if self.setup is not None and (self.username is None or self.password is None):
            raise PydanticCustomError("login", "setup needs the new owner's username and password")
        has_pw = self.username is not None or self.password is not None
        if has_pw == (self.token is not None) or (
            has_pw and (self.username is None or self.password is None)
        ):
            raise PydanticCustomError("login", "give username and password, or token")
        return self


class LogoutMsg(_ClientMsg):
    """End this connection's session: a password session's token is revoked for good."""

    clientmsg: Literal["logout"]


class PingMsg(_ClientMsg):
    """Is the link alive? A page's heartbeat: the reply is all it wants (and the server's time).

    A socket on stalled Wi-Fi stays open and silent; a page that sends a ping every couple of
    seconds and hears nothing back knows within a few seconds that what it shows may be stale.
    """

    clientmsg: Literal["ping"]


class DataMsg(_ClientMsg):
    """Subscribe to topics (reply: a snapshot of each) or, with ``unsubscribe``, leave them."""

    clientmsg: Literal["data"]
    topics: Annotated[
        list[Topic], Field(min_length=1, max_length=MAX_TOPICS), AfterValidator(dedupe)
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


Quantity = Annotated[int, Field(ge=1, le=99)]
Note = Annotated[str, Field(max_length=200)]


class CreateOrder(_ClientMsg):
    """A dish for a table: ``ordered`` (the kitchen marks it ready with ``dish``) or, by
    default, ``pending`` (ready at the pass). ``key`` makes a resend safe (idempotent)."""

    clientmsg: Literal["create"]
    type: Literal["order"]
    dish: Name
    table: Name
    quantity: Quantity = 1
    note: Note | None = Field(default=None, description='For the kitchen: "no chilli"')
    special: Annotated[str, Field(min_length=1, max_length=120)] | None = Field(
        default=None,
        description="A special delivery (a birthday): the message the robot shows at the"
        " table while it plays a song; it waits there for Done",
    )
    status: Literal["ordered", "pending"] = Field(
        default="pending", description="ordered: for the kitchen; pending: ready at the pass"
    )
    key: Name | None = Field(default=None, description="Client-chosen idempotency key")


class CreateDish(_ClientMsg):
    """Add a dish to the menu, or change one (the owner's menu)."""

    clientmsg: Literal["create"]
    type: Literal["dish"]
    name: Name  # a name like every other: trimmed, no control characters
    category: Annotated[str, Field(max_length=64)] = ""
    price_cents: Annotated[int, Field(ge=0, le=10_000_000)] | None = None
    available: bool = True
    position: Annotated[int, Field(ge=0, le=10_000)] = 0


class TrayChoice(BaseModel):
    """One dish on the tray staff chose (1 is the top tray)."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True)

    order: OrderId
    tray: Annotated[int, Field(ge=1, le=12)]


class CreateTask(_ClientMsg):
    """The confirmed virtual cart: dispatch these pending orders (split into trips), or put
    them on a trip still being loaded (``task``)."""

    clientmsg: Literal["create"]
    type: Literal["task"]
    orders: Annotated[
        list[OrderId],
        Field(min_length=1, max_length=MAX_ORDERS_PER_TASK),
        AfterValidator(unique_orders),
    ]
    key: Name | None = Field(default=None, description="Client-chosen idempotency key")
    task: OrderId | None = Field(
        default=None,
        description="Put the dishes on this trip, still at the pass, at their tables' stops",
    )
    trays: Annotated[list[TrayChoice], Field(max_length=MAX_ORDERS_PER_TASK)] | None = Field(
        default=None,
        description="The tray staff chose for some of the dishes (the plan places the"
        " others); the cart then leaves as one trip",
    )

    @model_validator(mode="after")
    def _trays_name_cart_dishes(self) -> CreateTask:
        if self.trays is not None:
            named = [t.order for t in self.trays]
            if len(set(named)) != len(named):
                raise PydanticCustomError("duplicate", "a dish is given two trays")
            if not set(named) <= set(self.orders):
                raise PydanticCustomError("tray_order", "a tray is chosen for a dish not in orders")
            if self.task is not None:
                raise PydanticCustomError("tray_join", "trays cannot be chosen when joining a trip")
        return self


class CreateBussing(_ClientMsg):
    """Send a robot for the used dishes of these tables, then to the dish return (a place of
    kind dish_return); it leaves when the scheduler says a waiting dish will not suffer."""

    clientmsg: Literal["create"]
    type: Literal["bussing"]
    tables: Annotated[list[Name], Field(min_length=1, max_length=12)]
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
    link: dict[Name, Annotated[str, Field(max_length=256)]] | None = Field(
        default=None,
        max_length=24,
        description="Which ROS (ros: 1 or 2) and the ROS names that differ from the defaults"
        " (docs/robots.md): ns, move_base, navigate, cmd_vel, pose, initialpose, battery, scan,"
        " map, frame, cloud, tf_topic, tf_static; camera (a CompressedImage topic) or camera_url"
        " (web_video_server); tf (the base frame, for a pose from tf); docking (nav2 or opennav:"
        " its Nav2 has opennav_docking)",
    )
    trays: Annotated[int, Field(ge=1, le=12)] | None = Field(
        default=None, description="Tables one trip may serve (one tray each); null: the site's"
    )


class CreateZone(_ClientMsg):
    """Draw a zone robots take turns through: a polygon of map points (metres) and how many
    robots may be in it at once."""

    clientmsg: Literal["create"]
    type: Literal["zone"]
    name: Name
    points: Annotated[
        list[Annotated[list[Coord], Field(min_length=2, max_length=2)]],
        Field(min_length=3, max_length=32, description="[[x, y], ...] in map metres"),
    ]
    capacity: Annotated[int, Field(ge=1, le=8)] = 1
    wait_at: Name | None = Field(
        default=None,
        description="A waypoint outside the zone where a robot standing in it waits for the"
        " other zones of its next leg",
    )
    replace: bool = Field(default=False, description="Change an existing zone of this name")


CreateMessage: TypeAlias = Annotated[
    CreateWaypoint
    | CreateOrder
    | CreateTask
    | CreateRobot
    | CreateDish
    | CreateZone
    | CreateBussing,
    Field(discriminator="type"),
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


class _TargetMsg(_RobotMsg):
    """A command on a robot's trip, naming the trip and stop the client saw (both optional).

    ``task``: the trip the client's screen shows the robot on (``null``: on none); ``stop``:
    that trip's current stop (seq). When given and the robot has moved on since, the command
    is refused with ``stale`` and changes nothing: a screen behind the server never acts on a
    stop it does not show. Screens send both; a script may leave them out.
    """

    task: OrderId | None = Field(
        default=None, description="The trip the client saw (null: none); checked when present"
    )
    stop: Annotated[int, Field(ge=0, le=1000)] | None = Field(
        default=None, description="The current stop (seq) the client saw; checked when present"
    )

    def expects(self) -> tuple[bool, int | None, int | None]:
        """(whether ``task`` was given, the task, the stop) for the stale check."""
        return "task" in self.model_fields_set, self.task, self.stop


TargetMsg = _TargetMsg  # the commands that name the trip and stop they act on


class NextMsg(_TargetMsg):
    """Food collected at this table: go on to the next table, or home after the last."""

    clientmsg: Literal["next"]


class StopMsg(_TargetMsg):
    """Halt the current move (the trip is kept)."""

    clientmsg: Literal["stop"]


class ContinueMsg(_TargetMsg):
    """Resume the move that was stopped or failed."""

    clientmsg: Literal["continue"]


class CancelMsg(_TargetMsg):
    """Give up the trip: undelivered orders go back to pending, the robot goes home."""

    clientmsg: Literal["cancel"]


class GoMsg(_TargetMsg):
    """Trays loaded at the pass: the robot leaves on its trip (it is Loading)."""

    clientmsg: Literal["go"]


class SkipMsg(_TargetMsg):
    """Leave this table unserved: its dishes are returned to the pass, the robot goes on."""

    clientmsg: Literal["skip"]


class ChargeMsg(_RobotMsg):
    """Send the robot (free, automatic) to its dock to charge."""

    clientmsg: Literal["charge"]


class WorkMsg(_RobotMsg):
    """Take the robot off its dock, back into service."""

    clientmsg: Literal["work"]


class CruiseMsg(_RobotMsg):
    """Send the robot (free, automatic) round these places again and again (snacks, tasting,
    adverts on its screen) until it is called back to deliveries."""

    clientmsg: Literal["cruise"]
    route: Annotated[list[Name], Field(min_length=1, max_length=16)]


class DishMsg(_ClientMsg):
    """One step of a dish: the kitchen starts it or marks it ready (a returned dish: send it
    again), staff void it, or edit its quantity, note or table. ``status``, if given, is the
    status the client saw: a dish that has moved on since is refused with ``stale``."""

    clientmsg: Literal["dish"]
    order: OrderId
    action: Literal["cooking", "ready", "void", "edit"]
    status: (
        Literal["ordered", "cooking", "pending", "assigned", "delivered", "returned", "voided"]
        | None
    ) = None
    quantity: Quantity | None = None
    note: Note | None = Field(default=None, description='edit: the new note ("" clears it)')
    table: Name | None = Field(default=None, description="edit: move the dish to this table")


class AckMsg(_ClientMsg):
    """Staff have seen this alert (it stays until its cause ends)."""

    clientmsg: Literal["ack"]
    alert: OrderId


class ClearMsg(_ClientMsg):
    """A blocked table is reachable again: robots may be sent there."""

    clientmsg: Literal["clear"]
    table: Name


class ReleaseMsg(_ClientMsg):
    """Break a zone's lease (a robot pushed out of the aisle by hand still holds it): from
    ``robot``, or from every holder. Robots waiting for the zone may then go."""

    clientmsg: Literal["release"]
    zone: Name
    robot: Name | None = None


class CameraMsg(_ClientMsg):
    """Watch a robot's camera (``watch: true``) or stop (``false``). While watching, the
    connection also receives the robot's pictures as binary messages (docs/protocol.md,
    "Camera frames"): the newest picture whenever the connection can take one."""

    clientmsg: Literal["camera"]
    robot: Name
    watch: bool


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
    | PingMsg
    | DataMsg
    | CreateMessage
    | ControlMessage
    | ReadyMsg
    | NextMsg
    | StopMsg
    | ContinueMsg
    | CancelMsg
    | GoMsg
    | SkipMsg
    | DishMsg
    | AckMsg
    | ClearMsg
    | ReleaseMsg
    | CameraMsg
    | OrderMsg
    | ChargeMsg
    | WorkMsg
    | CruiseMsg
    | CallMessage
    | AccountMessage
    | SiteMessage
    | StatsMessage
    | TillMessage
    | ChainMsg,
    Field(discriminator="clientmsg"),
]
_CLIENT: TypeAdapter[ClientMessage] = TypeAdapter(ClientMessage)

#: Sub-discriminators of the nested verbs, with their tags (for clear error messages).
_SUBTAGS: Final[dict[str, tuple[str, tuple[str, ...]]]] = {
    "create": ("type", ("waypoint", "order", "task", "robot", "dish", "zone", "bussing")),
    "call": ("action", ("open", "answer", "cancel")),
    "control": ("action", ("auto", "manual", "teleop", "initialpose", "goal", "goto")),
    "account": (
        "action",
        (
            "list_users",
            "add_user",
            "set_role",
            "reset_password",
            "remove_user",
            "create_token",
            "list_tokens",
            "revoke_token",
        ),
    ),
    "site": (
        "action",
        (
            "edit_robot",
            "remove_robot",
            "dependents",
            "rename_waypoint",
            "remove_waypoint",
            "settings",
            "set_settings",
            "audit",
            "remove_zone",
            "upload",
            "upload_part",
            "set_map",
            "plan_map",
            "probe_robot",
            "align_map",
            "backups",
            "backup_now",
            "download_backup",
            "restore",
            "add_button",
            "buttons",
            "revoke_button",
        ),
    ),
    "stats": ("action", ("figures", "trips", "forecast", "forecast_cancel", "last_service")),
    "till": (
        "action",
        (
            "state",
            "tickets",
            "by_hand",
            "propose",
            "preview",
            "setup",
            "import_menu",
            "map",
            "unmapped",
        ),
    ),
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
    GoMsg: Action.GO,
    SkipMsg: Action.SKIP,
    ChargeMsg: Action.CHARGE,
    WorkMsg: Action.WORK,
    CruiseMsg: Action.CRUISE,
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
        return REQUEST_ID_ADAPTER.validate_python(value)
    except ValidationError:
        return None


#: How far into an unreadable frame :func:`_sniff_id` looks for an ``"id"`` member.
_SNIFF_SPAN: Final = 4096


def _sniff_id(text: str) -> str | int | None:
    """Best effort: the ``"id"`` of a frame that is not valid JSON (a truncated object...).

    An ``"id"`` member starting within the first ``_SNIFF_SPAN`` characters is read whole; one
    whose number may go on past the window is not read at all. (The window used to cut the
    text: ``"id":179023`` across the 4096th character was answered with id 17, which a
    client would take for another request's reply. Found by bench/fuzz.py, seed 3.)
    """
    end = min(len(text), _SNIFF_SPAN + 256)
    match = _ID_SNIFF.search(text, 0, end)
    if match is None or match.start() >= _SNIFF_SPAN:
        return None
    if match.end() >= end and end < len(text):
        return None  # the value may go on past the window: not read rather than misread
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


def parse_intake(body: bytes) -> IntakeOrder:
    """The order-intake API's request body (``POST /api/orders``): UTF-8 JSON of an
    :class:`IntakeOrder`; ``BadJson`` or ``InvalidField`` (``details.errors`` as for a frame)."""
    try:
        obj = json.loads(body.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        raise BadJson(f"not valid JSON: {str(exc)[:200]}") from None
    if not isinstance(obj, dict):
        raise BadJson("the request must be a JSON object")
    if _too_deep(obj, MAX_DEPTH):
        raise _too_deep_error()
    try:
        return IntakeOrder.model_validate(obj)
    except ValidationError as exc:
        raise _invalid(obj, "order", exc) from None


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
        key = exc.key[:80]
        err: ServeurError = InvalidField(
            f"duplicate key {key!r}",
            key=key,
            errors=[{"loc": [key], "msg": f"duplicate key {key!r}", "type": "duplicate_key"}],
        )
        err.request_id = _sniff_id(text)
        raise err from None
    except RecursionError:
        err = _too_deep_error()
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
            raise _too_deep_error()
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


def _too_deep_error() -> InvalidField:
    # details.errors as for every invalid_field (docs/protocol.md): a client reads one shape.
    msg = f"JSON nested too deep (limit {MAX_DEPTH})"
    return InvalidField(msg, errors=[{"loc": [], "msg": msg, "type": "too_deep"}])


def schema() -> dict[str, Any]:
    """JSON Schema (draft 2020-12) of every client and every server message."""
    dialect = "https://json-schema.org/draft/2020-12/schema"
    client = {"$schema": dialect, "title": "ClientMessage", **_CLIENT.json_schema()}
    server = {"$schema": dialect, "title": "ServerMessage", **SERVER_ADAPTER.json_schema()}
    return {"client": client, "server": server}
