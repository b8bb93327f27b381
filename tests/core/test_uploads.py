"""Files a connection sends in parts (serveur.core.uploads, pure): in order, within limits, and
never more held for one connection than a plan's worth."""

from __future__ import annotations

import base64

import pytest

from serveur import protocol as P
from serveur.core.uploads import MAX_HELD, Upload, add_part, start_upload, take_upload
from serveur.errors import Conflict, InvalidField, NotFound


def up(kind: str, size: int, name: str = "f") -> P.SiteUpload:
    return P.SiteUpload(clientmsg="site", action="upload", kind=kind, name=name, size=size)


def part(upload: int, offset: int, data: bytes) -> P.SiteUploadPart:
    b64 = base64.b64encode(data).decode()
    return P.SiteUploadPart(
        clientmsg="site", action="upload_part", upload=upload, offset=offset, data=b64
    )


def test_parts_in_order_make_a_complete_upload() -> None:
    table: dict[int, Upload] = {}
    info = start_upload(table, up("map_yaml", 6))
    add_part(table, part(info["id"], 0, b"abc"))  # type: ignore[arg-type]
    with pytest.raises(Conflict):
        add_part(table, part(info["id"], 0, b"abc"))  # type: ignore[arg-type]  # resent
    with pytest.raises(Conflict):
        take_upload(table, info["id"], "map_yaml")  # type: ignore[arg-type]  # incomplete
    add_part(table, part(info["id"], 3, b"def"))  # type: ignore[arg-type]
    with pytest.raises(InvalidField):
        add_part(table, part(info["id"], 6, b"g"))  # type: ignore[arg-type]  # beyond its size
    assert bytes(take_upload(table, info["id"], "map_yaml").data) == b"abcdef"  # type: ignore[arg-type]


def test_a_connection_never_holds_more_than_a_plans_worth() -> None:
    table: dict[int, Upload] = {}
    first = start_upload(table, up("map_image", 20 * 2**20))
    second = start_upload(table, up("map_image", 20 * 2**20))
    assert first["id"] not in table and second["id"] in table  # the first made room
    assert sum(u.size for u in table.values()) <= MAX_HELD
    with pytest.raises(NotFound):
        add_part(table, part(first["id"], 0, b"x"))  # type: ignore[arg-type]
    with pytest.raises(InvalidField):
        start_upload(table, up("map_yaml", 10**6))  # over a YAML's limit
