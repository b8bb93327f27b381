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

from pydantic import Field

from serveur.wire.base import ClientModel

__all__ = ["UPLOAD_LIMITS", "UPLOAD_PART", "SiteSetMap", "SiteUpload", "SiteUploadPart"]

#: The largest part (bytes, before base64): 4/3 of it plus the message fits in 64 KiB.
UPLOAD_PART: Final = 45_000
#: The largest file of each kind (bytes).
UPLOAD_LIMITS: Final = {"map_yaml": 16 * 1024, "map_image": 20 * 1024 * 1024}
UploadKind = Literal["map_yaml", "map_image"]
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
