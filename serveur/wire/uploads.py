"""Files an owner gives the server from the console, sent in parts (``site`` ``upload``,
``upload_part``), and what is done with them (``set_map``).

A client message is at most 64 KiB (serveur.server.MAX_FRAME, so one connection cannot make the
server hold megabytes it never asked for): a file goes in parts of at most
:data:`UPLOAD_PART` bytes, base64 in ``upload_part``, each answered, in order. An upload lives
with its connection (gone when it closes), is owner-only like every ``site`` action, and is at
most :data:`UPLOAD_LIMITS` bytes for its kind, declared when it starts.
"""

from __future__ import annotations

from typing import Annotated, Final, Literal

from pydantic import BaseModel, ConfigDict, Field

from serveur.wire.base import ClientModel

__all__ = [
    "UPLOAD_LIMITS",
    "UPLOAD_PART",
    "AlignInfo",
    "AlignPair",
    "BackdropInfo",
    "PlanMeasure",
    "PlanStroke",
    "SiteAlignMap",
    "SitePlanMap",
    "SiteSetMap",
    "SiteUpload",
    "SiteUploadPart",
]

#: The largest part (bytes, before base64): 4/3 of it plus the message fits in 64 KiB.
UPLOAD_PART: Final = 45_000
#: The largest file of each kind (bytes).
UPLOAD_LIMITS: Final = {
    "map_yaml": 16 * 1024,
    "map_image": 20 * 1024 * 1024,
    "plan": 25 * 1024 * 1024,  # a floor-plan image (serveur.maps.floorplan.MAX_PLAN_BYTES)
    # A backup from elsewhere, a new box's first restore among them (a year of a busy
    # restaurant is ~135 MB: bench/bench_backup.py); the box's own are restored by name.
    "backup": 256 * 1024 * 1024,
}
UploadKind = Literal["map_yaml", "map_image", "plan", "backup"]
FileName = Annotated[str, Field(min_length=1, max_length=128, pattern=r"^[^/\\\x00-\x1f]+$")]


class SiteUpload(ClientModel):
    """Start sending a file: its kind, name and size. The reply's ``upload`` gives its ``id``
    and the ``part`` size to send it in."""

    clientmsg: Literal["site"]
    action: Literal["upload"]
    kind: UploadKind
    name: FileName
    size: Annotated[int, Field(ge=1, le=max(UPLOAD_LIMITS.values()))]


class SiteUploadPart(ClientModel):
    """The next part of an upload, at ``offset`` (the bytes received so far), base64."""

    clientmsg: Literal["site"]
    action: Literal["upload_part"]
    upload: Annotated[int, Field(ge=1)]
    offset: Annotated[int, Field(ge=0)]
    data: Annotated[str, Field(min_length=1, max_length=(UPLOAD_PART * 4) // 3 + 4)]


class SiteSetMap(ClientModel):
    """Make a robot's map files (uploaded: map_server's YAML and its PGM/PNG image) the
    restaurant's map, replacing ``--map``. Places are kept; those no longer on free floor are
    named in the reply (``outside``)."""

    clientmsg: Literal["site"]
    action: Literal["set_map"]
    yaml: Annotated[int, Field(ge=1)]
    image: Annotated[int, Field(ge=1)]


#: A point on the plan image: (column, row) in pixels from its top-left corner.
PlanPoint = Annotated[
    list[Annotated[float, Field(ge=0, le=100_000)]], Field(min_length=2, max_length=2)
]


class PlanStroke(ClientModel):
    """A line the owner drew on the plan: ``wall`` adds wall, ``erase`` makes floor."""

    kind: Literal["wall", "erase"]
    points: Annotated[list[PlanPoint], Field(min_length=1, max_length=500)]
    width: Annotated[float, Field(ge=1, le=500)]


class PlanMeasure(ClientModel):
    """Two points on the plan and the distance the owner measured between them (m)."""

    a: PlanPoint
    b: PlanPoint
    metres: Annotated[float, Field(gt=0.1, le=500)]


class SitePlanMap(ClientModel):
    """Turn an uploaded floor plan (``upload`` of kind ``plan``) into a map: walls darker
    than ``threshold``, the owner's ``strokes``, the scale from a distance measured ``across``
    the room and one ``along`` it, cells of ``resolution`` m. Without ``apply`` it is a
    preview (the map and the scale, nothing changed); with it, the restaurant's map."""

    clientmsg: Literal["site"]
    action: Literal["plan_map"]
    upload: Annotated[int, Field(ge=1)]
    threshold: Annotated[int, Field(ge=0, le=255)] = 128
    strokes: Annotated[list[PlanStroke], Field(max_length=200)] = []
    across: PlanMeasure
    along: PlanMeasure
    resolution: Annotated[float, Field(ge=0.02, le=0.2)] = 0.05
    apply: bool = False


#: A point on the map (m), as the map frame has it.
MapPoint = Annotated[
    list[Annotated[float, Field(ge=-10_000, le=10_000)]], Field(min_length=2, max_length=2)
]


class AlignPair(ClientModel):
    """One spot marked on both: its pixel on the floor plan, its point on the robot's map."""

    plan: PlanPoint
    map: MapPoint


class SiteAlignMap(ClientModel):
    """Fit the floor plan onto the robot's map from matched spots (scale, rotation,
    translation; serveur.maps.align). Without ``apply`` it is the fit alone; with it the plan
    (``upload`` of kind ``plan``) is drawn under the map on every screen from then on."""

    clientmsg: Literal["site"]
    action: Literal["align_map"]
    points: Annotated[list[AlignPair], Field(min_length=2, max_length=20)]
    upload: Annotated[int, Field(ge=1)] | None = None
    apply: bool = False


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class AlignInfo(_Record):
    """The fit: metres on the map = ``scale`` * R(``rotation``) * (column, -row) + (tx, ty);
    each pair's ``residuals`` (m) and their ``rms``."""

    scale: float = Field(description="metres per plan pixel")
    rotation: float = Field(description="radians")
    tx: float
    ty: float
    residuals: list[float]
    rms: float


class BackdropInfo(_Record):
    """The floor plan drawn under the map (the ``map`` topic's ``backdrop``): its image's
    address and the fit that places its pixels (as :class:`AlignInfo`)."""

    url: str
    scale: float
    rotation: float
    tx: float
    ty: float
