"""One exception root for everything serveur raises on purpose.

Every error a client can see carries a stable machine ``code`` (clients switch on it, so it
never changes once released) and a human message. I/O modules map foreign exceptions
(websockets, sqlite, OS errors) to these at their boundary with ``raise ... from exc`` so that
callers only ever handle ``ServeurError``.
"""

from __future__ import annotations

import math
from typing import Any

__all__ = [
    "BackupError",
    "BadJson",
    "Conflict",
    "Forbidden",
    "InvalidField",
    "LinkError",
    "MapError",
    "NavigationError",
    "NotAllowedInStatus",
    "NotFound",
    "RateLimited",
    "RosbridgeError",
    "ServeurError",
    "Stale",
    "StoreError",
    "TlsError",
    "Unauthorized",
    "UnknownMessage",
    "Unreachable",
    "round_up",
]


class ServeurError(Exception):
    """Root of every serveur error. ``code`` is stable and machine-readable."""

    code: str = "internal_error"
    #: The ``id`` of the client request this error answers, when it could be read.
    request_id: str | int | None = None

    def __init__(self, message: str, **details: Any) -> None:
        super().__init__(message)
        self.message = message
        self.details: dict[str, Any] = details

    def to_dict(self) -> dict[str, Any]:
        """The error as the fields of a protocol error reply."""
        out: dict[str, Any] = {"code": self.code, "message": self.message}
        if self.details:
            out["details"] = self.details
        return out


class BadJson(ServeurError):
    """The frame is not a JSON object."""

    code = "bad_json"


class UnknownMessage(ServeurError):
    """The ``clientmsg`` (or rosbridge ``op``) is missing or not one we know."""

    code = "unknown_message"


class InvalidField(ServeurError):
    """A field is missing, of the wrong type or out of range."""

    code = "invalid_field"


class NotFound(ServeurError):
    """A named robot, waypoint, order or task does not exist."""

    code = "not_found"


class NotAllowedInStatus(ServeurError):
    """The instruction is not in the allowed-actions table for the robot's status."""

    code = "not_allowed_in_status"


class Conflict(ServeurError):
    """The instruction contradicts the current state (order already assigned, key reused...)."""

    code = "conflict"


class StoreError(ServeurError):
    """The database failed (I/O error, corruption, lost connection)."""

    code = "store_error"


class MapError(ServeurError):
    """A map file is missing or malformed."""

    code = "map_error"


class BackupError(ServeurError):
    """A backup cannot be used or made: ``details.reason`` says why (``not_a_backup``,
    ``newer``, ``damaged``, ``not_found``, ``busy``: a restore under way, ``disk``: the copy
    could not be written, ``off``: the server keeps no backups)."""

    code = "backup_error"


class NavigationError(ServeurError):
    """A path cannot be planned."""

    code = "navigation_error"


class Unreachable(NavigationError):
    """The goal is occupied, outside the map or not connected to the start."""

    code = "unreachable"


class Stale(ServeurError):
    """The command names a trip or stop the robot has moved on from since the client saw it.

    A screen on stalled Wi-Fi shows the robot at T5 while it is at T14: its "Food collected"
    must not release the robot at T14. ``details`` carries the robot's current trip, stop and
    status, so the client can redraw and ask again. Nothing was changed.
    """

    code = "stale"


class RosbridgeError(ServeurError):
    """A rosbridge frame is malformed or names an unknown op/topic/service."""

    code = "rosbridge_error"


class LinkError(ServeurError):
    """The link to a robot is down or the robot did not answer in time."""

    code = "link_error"


class Unauthorized(ServeurError):
    """Not logged in, or the credentials are wrong, expired or revoked."""

    code = "unauthorized"


class Forbidden(ServeurError):
    """Logged in, but this role or scope may not do that."""

    code = "forbidden"


class RateLimited(ServeurError):
    """Too many requests (or failed logins); ``details.retry_after`` says when to try again.

    ``retry_after`` is the real ``wait`` rounded *up* to ``step`` seconds: a client told to wait
    0.0 s (a wait of 4 ms rounded to the nearest hundredth) retried at once and was refused
    again, so the figure given is never below the wait and never 0.
    """

    code = "rate_limited"

    def __init__(self, message: str, *, wait: float, step: float = 0.01, **details: Any) -> None:
        super().__init__(message, retry_after=round_up(wait, step), **details)


def round_up(value: float, step: float) -> float:
    """``value`` rounded up to a multiple of ``step`` (at least one step), as a short decimal."""
    digits = max(0, -math.floor(math.log10(step)))
    k = max(1, math.ceil(value / step))
    out = round(k * step, digits)
    while out < value:  # k * step rounded to ``digits`` can land a hair below ``value``
        k += 1
        out = round(k * step, digits)
    return out


class TlsError(ServeurError):
    """A certificate, key or CA file cannot be used (missing, unreadable, not PEM, mismatched).

    Raised while starting up, never in a client's reply: a server or simulator that was asked
    for TLS must refuse to start rather than quietly serve in the clear. Since no client ever
    sees it, it adds no protocol error code (it keeps the root's ``internal_error``).
    """
