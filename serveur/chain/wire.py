"""What sites and the centre say to each other over the chain's broker (pure).

Topics, all under ``chain/<site>/`` where ``<site>`` is the site's MQTT user name (the
broker's ACL lets a site write only under its own name: deploy/chain/acl, docs/chain.md):

============================ ============ ===============================================
``chain/<site>/events``       site → hq    :class:`Batch`: events numbered ``first`` ...
``chain/<site>/alive``        site → hq    :class:`Alive`: the site's heartbeat and head
``chain/<site>/resend``       hq → site    :class:`Resend`: send again from ``from``
``chain/<site>/confirmed``    hq → site    :class:`Confirmed` (retained): stored up to ``seq``
============================ ============ ===============================================

Every message is JSON with a version ``v``; the centre reads a site's payload as untrusted
input: :func:`read_batch` and friends raise :class:`~serveur.errors.InvalidField` on anything
that is not exactly a message (and the topic's site must be the payload's).
"""

from __future__ import annotations

import json
import re
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any, Final

from serveur.domain import EventRecord
from serveur.errors import InvalidField

__all__ = [
    "MAX_PAYLOAD",
    "PREFIX",
    "VERSION",
    "Alive",
    "Batch",
    "Confirmed",
    "Resend",
    "batches",
    "check_site",
    "read_alive",
    "read_batch",
    "read_confirmed",
    "read_resend",
    "site_of",
    "topic",
]

PREFIX: Final = "chain"
VERSION: Final = 1
#: The largest payload either side accepts (Mosquitto's default message_size_limit is 256 MB;
#: a batch is cut well below this by the shipper).
MAX_PAYLOAD: Final = 1024 * 1024
_SITE = re.compile(r"^[a-z0-9][a-z0-9-]{0,31}$")
_KINDS = ("events", "alive", "resend", "confirmed")


def check_site(name: object) -> str:
    """A site's name: its MQTT user name and topic level (lower-case letters, digits, ``-``,
    at most 32; ``hq`` is the centre's)."""
    if not isinstance(name, str) or not _SITE.match(name) or name == "hq":
        raise InvalidField(
            "a site's name is 1-32 lower-case letters, digits or '-' (not 'hq')", field="site"
        )
    return name


def topic(site: str, kind: str) -> str:
    if kind not in _KINDS:
        raise ValueError(f"no chain topic {kind!r}")
    return f"{PREFIX}/{check_site(site)}/{kind}"


def site_of(name: str) -> tuple[str, str] | None:
    """(site, kind) of a chain topic, or None if it is none."""
    parts = name.split("/")
    if len(parts) != 3 or parts[0] != PREFIX or parts[2] not in _KINDS:
        return None
    try:
        return check_site(parts[1]), parts[2]
    except InvalidField:
        return None


@dataclass(frozen=True, slots=True)
class Batch:
    """Events ``first``, ``first + 1``, ... of one site, in order, without a gap."""

    site: str
    first: int
    events: tuple[EventRecord, ...]

    @property
    def last(self) -> int:
        return self.first + len(self.events) - 1

    def encode(self) -> bytes:
        return _dump(
            {
                "v": VERSION,
                "site": self.site,
                "first": self.first,
                "events": [
                    [e.id, e.ts, e.kind, e.robot, e.task_id, e.order_id, e.data]
                    for e in self.events
                ],
            }
        )


@dataclass(frozen=True, slots=True)
class Alive:
    """The site's heartbeat: its last number given (``head``) and its clock."""

    site: str
    head: int
    at: float

    def encode(self) -> bytes:
        return _dump({"v": VERSION, "site": self.site, "head": self.head, "at": self.at})


@dataclass(frozen=True, slots=True)
class Resend:
    """The centre misses events from ``start`` on."""

    start: int

    def encode(self) -> bytes:
        return _dump({"v": VERSION, "from": self.start})


@dataclass(frozen=True, slots=True)
class Confirmed:
    """The centre stored every event up to ``seq``."""

    seq: int

    def encode(self) -> bytes:
        return _dump({"v": VERSION, "seq": self.seq})


def _dump(obj: dict[str, Any]) -> bytes:
    return json.dumps(obj, ensure_ascii=False, separators=(",", ":")).encode()


def _load(payload: bytes) -> dict[str, Any]:
    if len(payload) > MAX_PAYLOAD:
        raise InvalidField(f"a chain message is at most {MAX_PAYLOAD} bytes", field="payload")
    try:
        obj = json.loads(payload)
    except (ValueError, UnicodeDecodeError) as exc:
        raise InvalidField(f"not JSON: {exc}", field="payload") from exc
    if not isinstance(obj, dict):
        raise InvalidField("a chain message is a JSON object", field="payload")
    if obj.get("v") != VERSION:
        raise InvalidField(f"unknown chain message version {obj.get('v')!r}", field="v")
    return obj


def _int(obj: dict[str, Any], field: str, low: int = 0) -> int:
    v = obj.get(field)
    if isinstance(v, bool) or not isinstance(v, int) or v < low:
        raise InvalidField(f"{field} must be a whole number >= {low}", field=field)
    return v


def _num(v: object, field: str) -> float:
    if isinstance(v, bool) or not isinstance(v, int | float) or v != v:
        raise InvalidField(f"{field} must be a number", field=field)
    return float(v)


def _opt(v: object, kind: type, field: str) -> Any:
    if v is None:
        return None
    if isinstance(v, bool) or not isinstance(v, kind):
        raise InvalidField(f"{field} must be a {kind.__name__} or null", field=field)
    return v


def _site(obj: dict[str, Any], site: str) -> None:
    if obj.get("site") != site:
        raise InvalidField("the message's site is not its topic's", field="site")


def _event(item: object) -> EventRecord:
    if not isinstance(item, list) or len(item) != 7:
        raise InvalidField("an event is [id, ts, kind, robot, task, order, data]", field="events")
    ident, ts, kind, robot, task, order, data = item
    if isinstance(ident, bool) or not isinstance(ident, int) or ident < 1:
        raise InvalidField("an event's id is a whole number >= 1", field="events")
    if not isinstance(kind, str) or not kind or len(kind) > 255:
        raise InvalidField("an event's kind is a text", field="events")
    if not isinstance(data, dict):
        raise InvalidField("an event's data is an object", field="events")
    return EventRecord(
        id=ident,
        ts=_num(ts, "ts"),
        kind=kind,
        robot=_opt(robot, str, "robot"),
        task_id=_opt(task, int, "task_id"),
        order_id=_opt(order, int, "order_id"),
        data=data,
    )


def read_batch(site: str, payload: bytes) -> Batch:
    obj = _load(payload)
    _site(obj, site)
    events = obj.get("events")
    if not isinstance(events, list) or not events:
        raise InvalidField("a batch holds at least one event", field="events")
    return Batch(site, _int(obj, "first", 1), tuple(_event(e) for e in events))


def read_alive(site: str, payload: bytes) -> Alive:
    obj = _load(payload)
    _site(obj, site)
    return Alive(site, _int(obj, "head"), _num(obj.get("at"), "at"))


def read_resend(payload: bytes) -> Resend:
    return Resend(_int(_load(payload), "from", 1))


def read_confirmed(payload: bytes) -> Confirmed:
    return Confirmed(_int(_load(payload), "seq"))


def batches(
    site: str, numbered: Sequence[tuple[int, EventRecord]], max_bytes: int = 256 * 1024
) -> list[Batch]:
    """``numbered`` (consecutive numbers, in order) cut into batches of at most about
    ``max_bytes`` each; a break in the numbers (pruned rows) starts a new batch."""
    out: list[Batch] = []
    run: list[EventRecord] = []
    first = prev = 0
    size = 0
    for seq, event in numbered:
        cost = len(json.dumps(event.data)) + 64
        if run and (seq != prev + 1 or size + cost > max_bytes):
            out.append(Batch(site, first, tuple(run)))
            run, size = [], 0
        if not run:
            first = seq
        run.append(event)
        size += cost
        prev = seq
    if run:
        out.append(Batch(site, first, tuple(run)))
    return out
