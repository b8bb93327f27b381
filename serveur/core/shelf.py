"""The backups folder on the box: a checked copy made nightly or on the owner's request, each
with a small ``.json`` beside it saying when it was made and what its check found.

Every copy is the store's online backup (the server keeps running) read back by
:func:`serveur.store.restore.inspect_backup` before it is listed as good: a backup nobody can
restore is worse than none, because it is trusted. The rules (names, when, how many are kept)
are :mod:`serveur.core.backups`; this is the thin file side.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
from datetime import tzinfo
from pathlib import Path

from serveur.clock import Clock
from serveur.core.backups import BackupEntry, BackupKind, backup_name, kind_of, next_nightly
from serveur.core.backups import to_prune as prune_rule
from serveur.errors import BackupError
from serveur.store.base import Store
from serveur.store.restore import BackupSummary, inspect_backup

__all__ = ["BackupShelf"]

log = logging.getLogger(__name__)


class BackupShelf:
    """One folder of backups of one store. ``tz`` is the restaurant's (None: the box's)."""

    def __init__(
        self, folder: str | Path, store: Store, clock: Clock, tz: tzinfo | None = None
    ) -> None:
        self.folder = Path(folder)
        self.store = store
        self.clock = clock
        self.tz = tz
        self._making = asyncio.Lock()
        self._nightly: asyncio.Task[None] | None = None
        #: The nights backed up (or failed) since start; a waiter on the next one wakes.
        self.nights = 0
        self._night = asyncio.Condition()

    # -- making ---------------------------------------------------------------------------------

    async def make(self, kind: BackupKind) -> BackupEntry:
        """Write and check a new backup (one at a time: two copies at once would only double
        the SD card's work). A full card or a folder it may not write is a BackupError."""
        try:
            return await self._make(kind)
        except OSError as exc:
            raise BackupError(f"the backup could not be written: {exc}", reason="disk") from exc

    async def _make(self, kind: BackupKind) -> BackupEntry:
        async with self._making:
            await asyncio.to_thread(self.folder.mkdir, parents=True, exist_ok=True)
            made = self.clock.epoch()
            name = backup_name(kind, made, self.tz)
            n = 1
            while await asyncio.to_thread((self.folder / name).exists):
                n += 1
                name = backup_name(kind, made, self.tz, n)
            path = self.folder / name
            await self.store.backup(path)
            try:
                summary = await asyncio.to_thread(inspect_backup, path)
            except BackupError as exc:  # a copy we just wrote that does not read back
                summary = BackupSummary(f"damaged: {exc.message}", None)
            size = (await asyncio.to_thread(path.stat)).st_size
            entry = BackupEntry(name, kind, made, size, summary.check)
            await asyncio.to_thread(self._write_note, entry)
            if entry.check != "ok":
                log.error("backup %s is damaged: %s", name, entry.check)
            await self.prune()
            return entry

    def _write_note(self, e: BackupEntry) -> None:
        note = {"kind": e.kind.value, "made": e.made, "size": e.size, "check": e.check}
        tmp = self.folder / f"{e.name}.json.tmp"
        tmp.write_text(json.dumps(note), encoding="utf-8")
        tmp.replace(self.folder / f"{e.name}.json")

    async def prune(self) -> None:
        for name in prune_rule(await self.entries()):
            await asyncio.to_thread(self._delete, name)

    def _delete(self, name: str) -> None:
        for p in (self.folder / name, self.folder / f"{name}.json"):
            p.unlink(missing_ok=True)

    # -- reading --------------------------------------------------------------------------------

    async def entries(self) -> list[BackupEntry]:
        """Every backup in the folder, newest first."""
        return await asyncio.to_thread(self._list)

    def _list(self) -> list[BackupEntry]:
        if not self.folder.is_dir():
            return []
        out = []
        for path in self.folder.glob("serveur-*.db"):
            kind = kind_of(path.name)
            if kind is None:
                continue
            try:
                note = json.loads((self.folder / f"{path.name}.json").read_text("utf-8"))
                made, check = float(note["made"]), str(note["check"])
            except (OSError, ValueError, KeyError, TypeError):
                # No note (copied in by hand, or the box stopped mid-write): listed unchecked.
                made, check = path.stat().st_mtime, "unchecked"
            out.append(BackupEntry(path.name, kind, made, path.stat().st_size, check))
        out.sort(key=lambda e: (e.made, e.name), reverse=True)
        return out

    def path(self, name: str) -> Path:
        """The file of backup ``name``; :class:`BackupError` for any name that is not one of
        the shelf's (no path can be reached through it)."""
        p = self.folder / name
        if kind_of(name) is None or not p.is_file():
            raise BackupError(f"no backup {name!r} on this box", reason="not_found")
        return p

    # -- nightly --------------------------------------------------------------------------------

    def start(self) -> None:
        """Make a backup every night at :data:`~serveur.core.backups.NIGHTLY_AT`."""
        self._nightly = asyncio.create_task(self._night_loop(), name="nightly-backup")

    async def close(self) -> None:
        """Stop the nightly loop, once a copy under way is finished (its thread would go on
        reading the database while a restore replaces it)."""
        async with self._making:
            task, self._nightly = self._nightly, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def _night_loop(self) -> None:
        while True:
            now = self.clock.epoch()
            await self.clock.sleep(next_nightly(now, self.tz) - now)
            try:
                entry = await self.make(BackupKind.NIGHTLY)
                log.info("nightly backup %s (check: %s)", entry.name, entry.check)
            except Exception as exc:  # a full card: said, and tried again the next night
                log.error("nightly backup failed: %s", exc)
            async with self._night:
                self.nights += 1
                self._night.notify_all()

    async def night(self, n: int) -> None:
        """Wait until ``n`` nights have been backed up since start."""
        async with self._night:
            await self._night.wait_for(lambda: self.nights >= n)
