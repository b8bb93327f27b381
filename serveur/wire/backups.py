"""The owner's backups over ``/ws`` (``site`` ``backups``, ``backup_now``, ``download_backup``,
``restore``) and the records the replies carry.

A backup's bytes never travel on the websocket: a download is a plain HTTP GET of the link the
reply gives (a ticket in it, good once and for a minute, so the link can be opened by the
browser itself without the session token in the address bar or the history); a backup from
elsewhere is sent as an ``upload`` of kind ``backup``.
"""

from __future__ import annotations

from typing import Annotated, Literal

from pydantic import BaseModel, ConfigDict, Field, model_validator

from serveur.wire.base import ClientModel

__all__ = [
    "BackupInfo",
    "RestoreInfo",
    "SiteBackupNow",
    "SiteBackups",
    "SiteDownloadBackup",
    "SiteRestore",
]

#: A backup's file name as the box lists it (serveur.core.backups.backup_name).
BackupName = Annotated[
    str, Field(max_length=80, pattern=r"^serveur-[a-z_]+-\d{8}-\d{6}(-\d+)?\.db$")
]


class SiteBackups(ClientModel):
    """The backups on the box, newest first, each with its check result."""

    clientmsg: Literal["site"]
    action: Literal["backups"]


class SiteBackupNow(ClientModel):
    """Make a checked backup now; the reply has it and a link to download it."""

    clientmsg: Literal["site"]
    action: Literal["backup_now"]


class SiteDownloadBackup(ClientModel):
    """A link to download one of the box's backups (a ticket good once, for a minute)."""

    clientmsg: Literal["site"]
    action: Literal["download_backup"]
    name: BackupName


class SiteRestore(ClientModel):
    """Put the restaurant back as a backup holds it: one of the box's (``name``) or a file the
    owner sent (``upload`` of kind ``backup``). Without ``confirm`` nothing changes: the reply
    says what the backup holds and what would be lost. With it, the current state is backed
    up first, the server restarts on the backup, and every screen reconnects."""

    clientmsg: Literal["site"]
    action: Literal["restore"]
    name: BackupName | None = None
    upload: Annotated[int, Field(ge=1)] | None = None
    confirm: bool = False

    @model_validator(mode="after")
    def _one_source(self) -> SiteRestore:
        if (self.name is None) == (self.upload is None):
            raise ValueError("give a backup's name or an upload, not both")
        return self


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class BackupInfo(_Record):
    """A backup on the box."""

    name: str
    kind: Literal["nightly", "now", "before_restore"]
    made: float = Field(description="when it was made (epoch s)")
    size: int = Field(description="bytes")
    check: str = Field(description='"ok", "unchecked" or what the integrity check found')


class RestoreInfo(_Record):
    """What a backup holds and what restoring it would lose."""

    check: str
    last_activity: float | None = Field(description="its newest event (epoch s)")
    orders: int
    trips: int
    places: int
    robots: int
    people: int
    lost: dict[str, int] = Field(description="orders and trips made since, lost by a restore")
    restarting: bool = Field(description="true once confirmed: the server restarts on it")
