"""The console's backups: list them, make one now, download one over plain HTTP, restore one.

The server hands the ``site`` backup actions here and the ``/backups/<name>`` GETs; the files
are the shelf's (:mod:`serveur.core.shelf`), the checks :mod:`serveur.store.restore`'s. A
restore never touches the live database itself: it checks the backup, stages it beside the
database and asks the app to restart on it (``restart``, given by :class:`serveur.app.App`,
which owns the database file and the order things stop and start in: it copies the current
state once nothing changes it any more, so a restore can be undone from the list).

A download link carries a ticket instead of the session token: good for one download, within
a minute, of the one backup it was made for. The browser opens it itself (a file save), so no
token lands in its history or a proxy's log.
"""

from __future__ import annotations

import asyncio
import contextlib
import http
import secrets
import shutil
import time
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, Final
from urllib.parse import parse_qs, urlsplit

from serveur import protocol as P
from serveur.core.backups import BackupEntry, BackupKind
from serveur.core.shelf import BackupShelf
from serveur.core.uploads import Uploads
from serveur.errors import BackupError
from serveur.store.restore import inspect_backup, lost_since

__all__ = ["DOWNLOAD_PATH", "TICKET_TTL", "BackupDesk"]

DOWNLOAD_PATH: Final = "/backups/"
#: How long a download link works (seconds): long enough to tap it, too short to be reused.
TICKET_TTL: Final = 60.0


def entry_info(e: BackupEntry) -> dict[str, Any]:
    return {"name": e.name, "kind": e.kind.value, "made": e.made, "size": e.size, "check": e.check}


class BackupDesk:
    """``staging`` is where a backup waits for ``restart`` (the app's) to restore it."""

    def __init__(
        self,
        shelf: BackupShelf,
        *,
        staging: Path,
        restart: Callable[[Path], Awaitable[None]],
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.shelf = shelf
        self._staging = staging
        self._restart = restart
        self._monotonic = monotonic
        self._tickets: dict[str, tuple[str, float]] = {}
        self._restarting: asyncio.Task[None] | None = None
        self._one_restore = asyncio.Lock()  # one staged file: two tablets take turns

    # -- the protocol's actions --------------------------------------------------------------

    async def backups(self) -> dict[str, Any]:
        return {"backups": [entry_info(e) for e in await self.shelf.entries()]}

    async def backup_now(self) -> dict[str, Any]:
        entry = await self.shelf.make(BackupKind.NOW)
        return {"backup": entry_info(entry), "download": self._ticket(entry.name)}

    async def download(self, msg: P.SiteDownloadBackup) -> dict[str, Any]:
        await asyncio.to_thread(self.shelf.path, msg.name)  # it exists
        return {"download": self._ticket(msg.name)}

    async def restore(
        self, msg: P.SiteRestore, uploads: Uploads
    ) -> tuple[dict[str, Any], Path | None]:
        """The reply, and the staged backup once confirmed (then the caller lets the
        requesting connection have its reply and calls :meth:`restart_after`)."""
        async with self._one_restore:
            return await self._restore(msg, uploads)

    async def _restore(
        self, msg: P.SiteRestore, uploads: Uploads
    ) -> tuple[dict[str, Any], Path | None]:
        if self._restarting is not None:
            raise BackupError("a restore is already under way", reason="busy")
        staged = self._staging
        if msg.name is not None:
            source = await asyncio.to_thread(self.shelf.path, msg.name)
            await asyncio.to_thread(shutil.copyfile, source, staged)
        else:
            assert msg.upload is not None  # one of the two (the message says so)
            up = uploads.take(msg.upload, "backup")
            await asyncio.to_thread(staged.write_bytes, bytes(up.data))
        keep = False  # the staged file waits for the restart only once confirmed
        try:
            summary = await asyncio.to_thread(inspect_backup, staged)
            if summary.check != "ok":
                raise BackupError(
                    f"the backup is damaged: {summary.check.splitlines()[0]}", reason="damaged"
                )
            store = self.shelf.store
            lost = await store.db.transact(lambda tx: lost_since(tx, summary), "read")
            keep = msg.confirm
        finally:
            if not keep:
                await asyncio.to_thread(staged.unlink, missing_ok=True)
        if msg.confirm and msg.upload is not None:
            uploads.done(msg.upload)
        info = {**summary.info(), "lost": lost, "restarting": msg.confirm}
        return {"restore": info}, (staged if msg.confirm else None)

    def restart_after(self, replied: Awaitable[None], staged: Path) -> None:
        """Once ``replied`` (the requesting connection closed after its reply, or 5 s), hand
        the staged backup to the app's restart."""
        restart = self._restart

        async def go() -> None:
            with contextlib.suppress(TimeoutError):
                await asyncio.wait_for(replied, 5.0)
            await restart(staged)

        self._restarting = asyncio.create_task(go(), name="restore-restart")

    @property
    def restarting(self) -> asyncio.Task[None] | None:
        return self._restarting

    # -- downloads -----------------------------------------------------------------------------

    def _ticket(self, name: str) -> str:
        now = self._monotonic()
        self._tickets = {t: v for t, v in self._tickets.items() if v[1] > now}
        ticket = secrets.token_urlsafe(18)
        self._tickets[ticket] = (name, now + TICKET_TTL)
        return f"{DOWNLOAD_PATH}{name}?ticket={ticket}"

    async def fetch(self, target: str) -> tuple[http.HTTPStatus, bytes]:
        """The file for ``/backups/<name>?ticket=…`` whose ticket is good (spent now), or the
        status and words saying why not."""
        parts = urlsplit(target)
        name = parts.path.removeprefix(DOWNLOAD_PATH)
        ticket = (parse_qs(parts.query).get("ticket") or [""])[0]
        held = self._tickets.pop(ticket, None)
        if held is None or held[0] != name or held[1] <= self._monotonic():
            return http.HTTPStatus.FORBIDDEN, b"this download link is spent or expired\n"
        try:
            path = await asyncio.to_thread(self.shelf.path, name)
            return http.HTTPStatus.OK, await asyncio.to_thread(path.read_bytes)
        except (BackupError, OSError):
            return http.HTTPStatus.NOT_FOUND, b"no such backup\n"
