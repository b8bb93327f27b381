"""Planned distances kept on disk between starts, by the content they were planned from.

Every start of the server plans the path between every pair of waypoints before any robot is
driven: ~0.75 s of CPU on the demo map on a PC, about 15 s on a Raspberry Pi 4, every
restart, for a map and waypoints that rarely change. A plan is a pure function of its request
(the map's cells, the waypoints, the robot's radius, the planner), so its result is written
once under the SHA-256 of that request and read back at the next start with the same one.
A changed map file, a moved waypoint or a new planner version is another key; nothing is
ever served stale. Entries are small (a few hundred kB of JSON on the demo map) and few.

Where: ``$SERVEUR_PLAN_CACHE`` (``off`` or empty: no cache), else systemd's
``$CACHE_DIRECTORY`` (``CacheDirectory=serveur`` in deploy/serveur.service), else
``$XDG_CACHE_HOME/serveur/plans`` or ``~/.cache/serveur/plans``. A cache that cannot be read
or written is skipped (logged once at debug level): planning still works without it.
"""

from __future__ import annotations

import hashlib
import logging
import os
import tempfile
from pathlib import Path

__all__ = ["PLANNER_VERSION", "cache_dir", "digest", "load", "store"]

log = logging.getLogger(__name__)

#: Bumped whenever :func:`serveur.maps.distances.plan` would answer the same request
#: differently (the planner, the path simplification, the rounding): old entries then miss.
PLANNER_VERSION = 1
#: Entries kept at most: the oldest (by last use) go first.
MAX_ENTRIES = 32


def cache_dir() -> Path | None:
    """The folder plans are kept in, or None when caching is off."""
    given = os.environ.get("SERVEUR_PLAN_CACHE")
    if given is not None:
        return None if given.strip().lower() in ("", "off", "0", "no") else Path(given)
    systemd = os.environ.get("CACHE_DIRECTORY")
    if systemd:
        return Path(systemd.split(":")[0]) / "plans"
    xdg = os.environ.get("XDG_CACHE_HOME")
    base = Path(xdg) if xdg else Path.home() / ".cache"
    return base / "serveur" / "plans"


def digest(*parts: bytes) -> str:
    """The key of a request made of ``parts`` (its JSON, the map file's bytes ...)."""
    h = hashlib.sha256(f"plan-v{PLANNER_VERSION}".encode())
    for part in parts:
        h.update(len(part).to_bytes(8, "big"))
        h.update(part)
    return h.hexdigest()


def load(key: str) -> str | None:
    """The result stored under ``key`` (its JSON), or None."""
    folder = cache_dir()
    if folder is None:
        return None
    path = folder / f"{key}.json"
    try:
        text = path.read_text()
        os.utime(path)  # last used: what the pruning keeps
    except OSError:
        return None
    return text


def store(key: str, text: str) -> None:
    """Keep ``text`` under ``key`` (atomically: a reader never sees half a file)."""
    folder = cache_dir()
    if folder is None:
        return
    try:
        folder.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=folder, suffix=".tmp")
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, folder / f"{key}.json")
        _prune(folder)
    except OSError as exc:
        log.debug("plan cache %s not written: %s", folder, exc)


def _prune(folder: Path) -> None:
    entries = sorted(folder.glob("*.json"), key=lambda p: p.stat().st_mtime, reverse=True)
    for old in entries[MAX_ENTRIES:]:
        old.unlink(missing_ok=True)
