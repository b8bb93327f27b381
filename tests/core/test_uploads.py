"""Files a connection sends in parts (serveur.core.uploads, pure): in order, within limits, and
never more held for one connection than a plan's worth."""

from __future__ import annotations

import base64

import pytest

from serveur import protocol as P
from serveur.core.uploads import MAX_HELD, Uploads
from serveur.errors import Conflict, InvalidField, NotFound


def up(kind: str, size: int, name: str = "f") -> P.SiteUpload:
    return P.SiteUpload(clientmsg="site", action="upload", kind=kind, name=name, size=size)


def part(upload: int, offset: int, data: bytes) -> P.SiteUploadPart:
    b64 = base64.b64encode(data).decode()
    return P.SiteUploadPart(
        clientmsg="site", action="upload_part", upload=upload, offset=offset, data=b64
    )


def test_parts_in_order_make_a_complete_upload() -> None:
    table = Uploads()
    info = table.start(up("map_yaml", 6))
    table.add_part(part(info["id"], 0, b"abc"))  # type: ignore[arg-type]
    with pytest.raises(Conflict):
        table.add_part(part(info["id"], 0, b"abc"))  # type: ignore[arg-type]  # resent
    with pytest.raises(Conflict):
        table.take(info["id"], "map_yaml")  # type: ignore[arg-type]  # incomplete
    table.add_part(part(info["id"], 3, b"def"))  # type: ignore[arg-type]
    with pytest.raises(InvalidField):
        table.add_part(part(info["id"], 6, b"g"))  # type: ignore[arg-type]  # beyond its size
    assert bytes(table.take(info["id"], "map_yaml").data) == b"abcdef"  # type: ignore[arg-type]


def test_a_connection_never_holds_more_than_a_plans_worth() -> None:
    table = Uploads()
    first = table.start(up("backup", 256 * 2**20))
    second = table.start(up("plan", 25 * 2**20))
    assert first["id"] not in table and second["id"] in table  # the first made room
    assert table.held() <= MAX_HELD
    with pytest.raises(NotFound):
        table.add_part(part(first["id"], 0, b"x"))  # type: ignore[arg-type]
    with pytest.raises(InvalidField):
        table.start(up("map_yaml", 10**6))  # over a YAML's limit


def test_ids_count_per_connection_and_are_never_reused() -> None:
    """A second tablet's ids start at 1 too (the documented examples are what any owner sees);
    on one connection an id dropped for room is never given to a newer file, so a part or a
    set_map naming the old one is refused instead of landing in the new one."""
    one, other = Uploads(), Uploads()
    ids = [one.start(up("map_yaml", 4))["id"] for _ in range(6)]
    assert ids == [1, 2, 3, 4, 5, 6]
    assert other.start(up("map_yaml", 4))["id"] == 1
    assert 1 not in one and 2 not in one  # dropped for room (4 at most)
    one.done(6)
    assert one.start(up("map_yaml", 4))["id"] == 7
    with pytest.raises(NotFound):
        one.take(1, "map_yaml")
