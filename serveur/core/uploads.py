"""Files a connection is sending in parts (``site`` ``upload`` / ``upload_part``): pure
bookkeeping, one :class:`Uploads` per connection (serveur.server keeps it in the connection).

Each upload declares its kind, name and size first; parts must come in order (``offset`` is
what was received so far: a part resent after a reconnect is refused, not appended twice);
a connection holds at most :data:`MAX_OPEN` uploads and :data:`MAX_HELD` bytes (the oldest
are dropped for a new one), never more bytes than the sizes it declared, each within its
kind's limit (:data:`serveur.wire.uploads.UPLOAD_LIMITS`). ``take`` hands over a complete
one. Ids count from 1 on each connection and are never reused on it: a part or a ``set_map``
naming an upload that was dropped is refused, never applied to a newer file.
"""

from __future__ import annotations

import base64
import binascii
from dataclasses import dataclass, field
from typing import Final

from serveur import protocol as P
from serveur.errors import Conflict, InvalidField, NotFound

__all__ = ["MAX_HELD", "MAX_OPEN", "Upload", "Uploads"]

MAX_OPEN: Final = 4
#: The most bytes one connection's uploads may declare together: one backup (held in memory
#: until it is staged: a Pi 4 holds one), or a floor plan, or a map's image and YAML.
MAX_HELD: Final = 280 * 1024 * 1024


@dataclass
class Upload:
    id: int
    kind: str
    name: str
    size: int
    data: bytearray = field(default_factory=bytearray)

    def info(self) -> dict[str, object]:
        return {
            "id": self.id,
            "kind": self.kind,
            "name": self.name,
            "size": self.size,
            "received": len(self.data),
            "part": P.UPLOAD_PART,
        }


class Uploads:
    """One connection's uploads, oldest first."""

    __slots__ = ("_files", "_issued")

    def __init__(self) -> None:
        self._files: dict[int, Upload] = {}
        self._issued = 0

    def __contains__(self, upload_id: object) -> bool:
        return upload_id in self._files

    def held(self) -> int:
        """The bytes the open uploads declared."""
        return sum(u.size for u in self._files.values())

    def start(self, msg: P.SiteUpload) -> dict[str, object]:
        limit = P.UPLOAD_LIMITS[msg.kind]
        if msg.size > limit:
            raise InvalidField(
                f"{msg.name} is {msg.size} bytes: a {msg.kind} is at most {limit}",
                field="size",
                reason="too_large",
            )
        # The oldest uploads make room for a new one (a file abandoned halfway is not kept).
        while self._files and (len(self._files) >= MAX_OPEN or self.held() + msg.size > MAX_HELD):
            del self._files[next(iter(self._files))]
        self._issued += 1
        up = Upload(self._issued, msg.kind, msg.name, msg.size)
        self._files[up.id] = up
        return up.info()

    def add_part(self, msg: P.SiteUploadPart) -> dict[str, object]:
        up = self._files.get(msg.upload)
        if up is None:
            raise NotFound(f"no upload {msg.upload} on this connection", upload=msg.upload)
        if msg.offset != len(up.data):
            raise Conflict(
                f"upload {up.id} has {len(up.data)} bytes: send the part at that offset",
                upload=up.id,
                received=len(up.data),
            )
        try:
            part = base64.b64decode(msg.data, validate=True)
        except (binascii.Error, ValueError):
            raise InvalidField("a part's data is base64", field="data") from None
        if len(part) > P.UPLOAD_PART or len(up.data) + len(part) > up.size:
            raise InvalidField(
                f"the part overruns upload {up.id}'s declared size or the part size",
                field="data",
            )
        up.data += part
        return up.info()

    def take(self, upload_id: int, kind: str) -> Upload:
        """The complete upload ``upload_id`` of ``kind`` (it stays until :meth:`done`: a file
        refused can be given again with another one)."""
        up = self._files.get(upload_id)
        if up is None:
            raise NotFound(f"no upload {upload_id} on this connection", upload=upload_id)
        if up.kind != kind:
            raise InvalidField(f"upload {upload_id} is a {up.kind}, not a {kind}", field="upload")
        if len(up.data) != up.size:
            raise Conflict(
                f"upload {upload_id} is not complete ({len(up.data)} of {up.size} bytes)",
                upload=upload_id,
            )
        return up

    def done(self, *done_ids: int) -> None:
        """The uploads were used: forget them."""
        for i in done_ids:
            self._files.pop(i, None)
