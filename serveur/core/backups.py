"""The rules of the restaurant's backups, pure: when the nightly one is due, what a backup is
called, which old ones go, and what a restore would lose.

The I/O lives elsewhere: :mod:`serveur.core.shelf` writes, checks and lists the files,
:mod:`serveur.store.restore` reads a backup before it replaces the database, and
:mod:`serveur.core.backup_desk` answers the console. Kept here so they are tested on virtual time,
without files.

Why nightly at 03:30: the service day starts at 04:00 (serveur.stats), so the night's copy holds
the whole of the day just served, and the box is idle then. A box without a clock battery may
start with a wrong time (no network, no NTP); a nightly backup then lands at an odd hour but
still once a day, which is what matters.
"""

from __future__ import annotations

import re
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime, time, timedelta, tzinfo
from enum import StrEnum
from typing import Final

__all__ = [
    "KEEP",
    "NIGHTLY_AT",
    "BackupEntry",
    "BackupKind",
    "backup_name",
    "kind_of",
    "next_nightly",
    "to_prune",
]


class BackupKind(StrEnum):
    """Why a backup was made: each kind keeps its own number of copies."""

    NIGHTLY = "nightly"
    NOW = "now"  # the owner's "Back up now" in the console
    BEFORE_RESTORE = "before_restore"  # the state a restore replaced, to undo it


#: When the nightly backup runs, in the box's local time.
NIGHTLY_AT: Final = time(3, 30)
#: How many of each kind are kept (the oldest go first): a week of nights, and a few others.
KEEP: Final = {BackupKind.NIGHTLY: 7, BackupKind.NOW: 5, BackupKind.BEFORE_RESTORE: 3}

_NAME = re.compile(r"^serveur-(nightly|now|before_restore)-(\d{8}-\d{6})(?:-(\d+))?\.db$")


@dataclass(frozen=True)
class BackupEntry:
    """One backup file as the shelf lists it."""

    name: str
    kind: BackupKind
    made: float  # epoch seconds
    size: int
    check: str  # "ok", or what the integrity check found


def backup_name(kind: BackupKind, made: float, tz: tzinfo | None = None, n: int = 0) -> str:
    """``serveur-nightly-20261128-033000.db`` (``-2`` and on for a second one that second)."""
    stamp = datetime.fromtimestamp(made, tz).strftime("%Y%m%d-%H%M%S")
    return f"serveur-{kind.value}-{stamp}{f'-{n}' if n else ''}.db"


def kind_of(name: str) -> BackupKind | None:
    """The kind of a backup file's name; None for any other name (never served or deleted:
    a name from a client is only ever one of these, so it cannot reach another file)."""
    m = _NAME.match(name)
    return BackupKind(m[1]) if m else None


def next_nightly(now: float, tz: tzinfo | None = None, at: time = NIGHTLY_AT) -> float:
    """The epoch of the next ``at`` (local time in ``tz``; None: the box's) strictly after
    ``now``."""
    # Wall-clock arithmetic on the local date: with tz None a naive local time, whose
    # timestamp() asks the box's zone for that day's offset (a daylight-saving night's 03:30
    # is 03:30, not an hour off as a fixed offset taken today would make it).
    local = datetime.fromtimestamp(now, tz)
    due = local.replace(hour=at.hour, minute=at.minute, second=at.second, microsecond=0)
    if due.timestamp() <= now:
        nxt = local.date() + timedelta(days=1)
        due = datetime.combine(nxt, at, tzinfo=tz)
    return due.timestamp()


def to_prune(entries: Iterable[BackupEntry]) -> list[str]:
    """The names to delete so that each kind keeps its :data:`KEEP` newest."""
    by_kind: dict[BackupKind, list[BackupEntry]] = {}
    for e in entries:
        by_kind.setdefault(e.kind, []).append(e)
    out: list[str] = []
    for kind, found in by_kind.items():
        found.sort(key=lambda e: (e.made, e.name), reverse=True)
        out += [e.name for e in found[KEEP[kind] :]]
    return sorted(out)
