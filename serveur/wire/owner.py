"""The owner's messages of the ``/ws`` protocol: ``site`` (robots, waypoints, settings, the audit
trail) and ``stats`` (figures and trip history of past services).

Part of :mod:`serveur.protocol` (which puts them in the client-message union and re-exports
them); kept apart because they are the owner's console, not the dinner service's verbs.
Every field is checked here, so a request that reaches the core is well formed: an edit names
at least one field, a setting is within its range, a period is a day or a time.

"""

from __future__ import annotations

from typing import Annotated, Any, Literal, TypeAlias

from pydantic import Field, StrictBool, model_validator
from pydantic_core import PydanticCustomError

from serveur.wire.backups import SiteBackupNow, SiteBackups, SiteDownloadBackup, SiteRestore
from serveur.wire.base import ClientModel
from serveur.wire.calls import SiteAddButton, SiteButtons, SiteRevokeButton
from serveur.wire.fields import Name, OrderId, WsUrl
from serveur.wire.uploads import (
    SiteAlignMap,
    SitePlanMap,
    SiteSetMap,
    SiteUpload,
    SiteUploadPart,
)

__all__ = [
    "LANGUAGES",
    "SETTINGS",
    "SiteAudit",
    "SiteDependents",
    "SiteEditRobot",
    "SiteMessage",
    "SiteProbeRobot",
    "SiteRemoveRobot",
    "SiteRemoveWaypoint",
    "SiteRemoveZone",
    "SiteRenameWaypoint",
    "SiteSetSettings",
    "SiteSettings",
    "StatsFigures",
    "StatsForecast",
    "StatsForecastCancel",
    "StatsLastService",
    "StatsMessage",
    "StatsTrips",
]

#: The languages the pages speak (serveur/web/site/i18n).
LANGUAGES = ("en", "zh", "ms")
Language: TypeAlias = Literal["en", "zh", "ms"]
#: The settings the owner may change, as ``set_settings`` names them.
SETTINGS = (
    "table_timeout",
    "trays",
    "auto_depart",
    "languages",
    "language",
    "cameras",
    "name",
    "public_url",
    "target_wait",
    "call_escalate",
    "bussing_wait",
    "bussing_max_delay",
    "charge_below",
    "charge_until",
    "cruise_pause",
    "cruise_resume",
)
#: The restaurant's address as its tablets reach it: scheme, host and port, nothing after.
PublicUrl = Annotated[str, Field(max_length=200, pattern=r"^https?://[^\s/#?@]+$")]

_Epoch = Annotated[float, Field(ge=0, le=1e11)]
#: A day (``2026-11-24``: the service day starting at 04:00) or a time (``2026-11-24T19:30``).
_When = Annotated[str, Field(pattern=r"^\d{4}-\d{2}-\d{2}(T\d{2}:\d{2}(:\d{2})?)?$")]
_Offset = Annotated[str, Field(pattern=r"^[+-]\d{2}:\d{2}$")]
#: A service day alone (``2026-11-24``: from 04:00 that day).
_Day = Annotated[str, Field(pattern=r"^\d{4}-\d{2}-\d{2}$")]


_Msg = ClientModel


class _SiteMsg(_Msg):
    clientmsg: Literal["site"]


class SiteEditRobot(_SiteMsg):
    """Change a robot's address, home, drive, ROS options or trays; omitted fields are kept.

    A new address, drive or ROS options reconnect the robot, so they are refused while it
    has a trip; home and trays may change at any time (they count from its next trip)."""

    action: Literal["edit_robot"]
    robot: Name
    url: WsUrl | None = None
    home: Name | None = Field(default=None, description="null (given): no home")
    kinematics: Literal["omni", "diff"] | None = None
    link: dict[Name, Annotated[str, Field(max_length=128)]] | None = Field(
        default=None, max_length=16
    )
    trays: Annotated[int, Field(ge=1, le=12)] | None = Field(
        default=None, description="null (given): the site's"
    )
    dock: Name | None = Field(
        default=None, description="its charger, a place of kind dock; null (given): none"
    )

    @model_validator(mode="after")
    def _something(self) -> SiteEditRobot:
        if not self.changes():
            raise PydanticCustomError("nothing_to_edit", "name at least one field to change")
        for key in ("url", "kinematics", "link"):
            if key in self.model_fields_set and getattr(self, key) is None:
                raise PydanticCustomError("not_null", f"{key} cannot be null")
        return self

    def changes(self) -> dict[str, Any]:
        """The fields given, with their new values (``home``/``trays`` may be None)."""
        keys = ("url", "home", "kinematics", "link", "trays", "dock")
        return {k: getattr(self, k) for k in keys if k in self.model_fields_set}


class SiteProbeRobot(_SiteMsg):
    """Is there a robot at ``url``? Connects once (a few seconds at most) and says what it
    found, before the robot is added: reachable or why not, its ROS, its navigator."""

    action: Literal["probe_robot"]
    url: WsUrl


class SiteRemoveRobot(_SiteMsg):
    """Remove a robot with no trip: its link is closed, its screens' tokens revoked."""

    action: Literal["remove_robot"]
    robot: Name


class SiteDependents(_SiteMsg):
    """What depends on a waypoint: robots parked there, open orders, trips, table screens."""

    action: Literal["dependents"]
    waypoint: Name


class SiteRenameWaypoint(_SiteMsg):
    """Rename a waypoint; homes, open orders, its block and its screens follow."""

    action: Literal["rename_waypoint"]
    waypoint: Name
    name: Name


class SiteRemoveWaypoint(_SiteMsg):
    """Remove a waypoint nothing open depends on (``conflict`` names what does)."""

    action: Literal["remove_waypoint"]
    waypoint: Name


class SiteRemoveZone(_SiteMsg):
    """Remove a zone: its leases end, robots waiting for it go."""

    action: Literal["remove_zone"]
    zone: Name


class SiteSettings(_SiteMsg):
    """The site's settings as they apply now."""

    action: Literal["settings"]


class SiteSetSettings(_SiteMsg):
    """Change some of the site's settings; they apply at once and survive a restart."""

    action: Literal["set_settings"]
    table_timeout: Annotated[float, Field(ge=10, le=3600)] | None = Field(
        default=None, description="seconds a robot waits at a table; null (given): for ever"
    )
    trays: Annotated[int, Field(ge=1, le=12)] | None = None
    auto_depart: StrictBool | None = None
    languages: Annotated[list[Language], Field(min_length=1, max_length=3)] | None = Field(
        default=None, description="the languages the pages offer"
    )
    language: Language | None = Field(
        default=None, description="the pages' language where the device has no choice"
    )
    cameras: StrictBool | None = Field(
        default=None, description="staff may watch the robots' cameras (off: guests' privacy)"
    )
    name: Annotated[str, Field(min_length=1, max_length=80)] | None = Field(
        default=None, description="the restaurant's name, on every page"
    )
    public_url: PublicUrl | None = Field(
        default=None,
        description="the server's address as the restaurant's tablets reach it"
        " (http://192.168.1.20:8765): every screen's setup link and QR code uses it",
    )
    target_wait: Annotated[float, Field(ge=60, le=3600)] | None = Field(
        default=None,
        description="seconds within which the owner wants 95 % of dishes at their table:"
        " the forecast recommends the smallest fleet that meets it",
    )
    call_escalate: Annotated[float, Field(ge=15, le=3600)] | None = Field(
        default=None, description="seconds after which a call nobody answered is escalated"
    )
    bussing_wait: Annotated[float, Field(ge=10, le=1800)] | None = Field(
        default=None,
        description="seconds a bussing robot waits at a table for the used dishes before it"
        " goes on by itself",
    )
    bussing_max_delay: Annotated[float, Field(ge=0, le=1800)] | None = Field(
        default=None,
        description="the most a bussing trip may hold back a dish waiting at the pass, in"
        " seconds: a bussing trip that could delay one longer waits",
    )
    charge_below: Annotated[float, Field(ge=0.05, le=0.8)] | None = Field(
        default=None,
        description="a free robot with a dock goes to charge below this battery fraction",
    )
    charge_until: Annotated[float, Field(ge=0.2, le=1.0)] | None = Field(
        default=None, description="a charging robot comes back into service at this fraction"
    )
    cruise_pause: Annotated[float, Field(ge=0, le=600)] | None = Field(
        default=None, description="seconds a cruising robot stops at each place of its round"
    )
    cruise_resume: Annotated[float, Field(ge=5, le=600)] | None = Field(
        default=None,
        description="seconds a cruising robot someone touched waits before it goes on",
    )

    @model_validator(mode="after")
    def _something(self) -> SiteSetSettings:
        if not self.changes():
            raise PydanticCustomError("nothing_to_set", "name at least one setting")
        for key in (
            "trays",
            "auto_depart",
            "languages",
            "language",
            "cameras",
            "name",
            "target_wait",
            "call_escalate",
            "bussing_wait",
            "bussing_max_delay",
            "charge_below",
            "charge_until",
            "cruise_pause",
            "cruise_resume",
        ):
            if key in self.model_fields_set and getattr(self, key) is None:
                raise PydanticCustomError("not_null", f"{key} cannot be null")
        below, until = self.charge_below, self.charge_until
        if below is not None and until is not None and until <= below:
            raise PydanticCustomError("charge_levels", "charge_until must be above charge_below")
        if self.languages is not None and len(set(self.languages)) != len(self.languages):
            raise PydanticCustomError("duplicate", "a language is named twice")
        return self

    def changes(self) -> dict[str, Any]:
        return {k: getattr(self, k) for k in SETTINGS if k in self.model_fields_set}


class SiteAudit(_SiteMsg):
    """Search the audit trail, newest first; ``before`` pages on (the last id seen)."""

    action: Literal["audit"]
    actor: Annotated[str, Field(max_length=255)] | None = Field(
        default=None, description="user:alice or token:7"
    )
    verb: Annotated[str, Field(max_length=32)] | None = None
    outcome: Annotated[str, Field(max_length=32)] | None = Field(
        default=None, description="ok or an error code"
    )
    target: Name | None = None
    since: _Epoch | None = None
    until: _Epoch | None = None
    before: OrderId | None = None
    limit: Annotated[int, Field(ge=1, le=500)] = 100


SiteMessage: TypeAlias = Annotated[
    SiteEditRobot
    | SiteRemoveRobot
    | SiteDependents
    | SiteRenameWaypoint
    | SiteRemoveWaypoint
    | SiteSettings
    | SiteSetSettings
    | SiteAudit
    | SiteRemoveZone
    | SiteUpload
    | SiteUploadPart
    | SiteSetMap
    | SitePlanMap
    | SiteAlignMap
    | SiteProbeRobot
    | SiteBackups
    | SiteBackupNow
    | SiteDownloadBackup
    | SiteRestore
    | SiteAddButton
    | SiteButtons
    | SiteRevokeButton,
    Field(discriminator="action"),
]


class _StatsMsg(_Msg):
    clientmsg: Literal["stats"]
    start: _When | None = Field(default=None, description="from this day or time (local)")
    end: _When | None = Field(default=None, description="to this day (inclusive) or time")
    utc_offset: _Offset | None = Field(
        default=None, description="the restaurant's offset (+08:00); default: the server's"
    )


class StatsFigures(_StatsMsg):
    """The figures of each hour or service day of a range, and of the whole range."""

    action: Literal["figures"]
    by: Literal["hour", "day"] = "day"


class StatsTrips(_StatsMsg):
    """The trips of a range, each with its stops, newest last."""

    action: Literal["trips"]


class StatsLastService(_Msg):
    """The latest service day before ``before`` whose dishes a forecast can replay (a dish was
    ready at the pass that day, not voided): "How many robots do I need?" starts from it, since
    the day before is often one the restaurant was closed."""

    clientmsg: Literal["stats"]
    action: Literal["last_service"]
    before: _Day = Field(description="a service day (the asking device's today)")
    utc_offset: _Offset | None = None


class StatsForecast(_Msg):
    """Replay a recorded service day with other fleet sizes ("how many robots do I need?"):
    each fleet's waits arrive on the ``forecast`` topic as its replay finishes."""

    clientmsg: Literal["stats"]
    action: Literal["forecast"]
    day: _Day = Field(
        description="the service day (from 04:00 local time) whose dishes are replayed"
    )
    robots: Annotated[list[Annotated[int, Field(ge=1, le=12)]], Field(min_length=1, max_length=6)]
    policy: Literal["serveur", "baseline"] = "serveur"
    utc_offset: _Offset | None = None

    @model_validator(mode="after")
    def _distinct(self) -> StatsForecast:
        if len(set(self.robots)) != len(self.robots):
            raise PydanticCustomError("duplicate", "a fleet size is named twice")
        return self


class StatsForecastCancel(_Msg):
    """Stop the forecast under way."""

    clientmsg: Literal["stats"]
    action: Literal["forecast_cancel"]


StatsMessage: TypeAlias = Annotated[
    StatsFigures | StatsTrips | StatsForecast | StatsForecastCancel | StatsLastService,
    Field(discriminator="action"),
]
