"""The rules of guests' calls (pure; no I/O, no clock of their own).

* **One open call per table and kind.** A second press while one is open is merged into it
  (the store counts presses); the guest is told it is on its way, not asked again.
* **A button's rate limit.** A Wi-Fi button pressed fifty times in a row sends fifty HTTP
  requests: a token bucket per button (:class:`ButtonLimits`) lets a few through (merged
  into the open call) and refuses the rest with a "too many" reply, nothing else changed.
* **Escalation.** A call nobody answered within the site's ``call_escalate`` seconds is
  escalated once (:func:`due`): an alert every console sounds, as hospitality call systems do.
* **Time to answer**, per kind, for the statistics (:func:`answer_times`).

A button's token is random and kept as its SHA-256 digest (:func:`new_button_token`,
:func:`button_digest`), like the API tokens: the database never holds a usable token.
"""

from __future__ import annotations

import hashlib
import secrets
from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Final

from serveur.domain import Call, CallKind

__all__ = [
    "BUTTON_PREFIX",
    "ButtonLimits",
    "answer_times",
    "button_digest",
    "due",
    "new_button_token",
]

#: Button tokens start with this, so one pasted in the wrong place is recognisable.
BUTTON_PREFIX: Final = "srb_"
#: A button may press this many times at once, then once every ``PER`` seconds.
BURST: Final = 3.0
PER: Final = 10.0


def new_button_token() -> str:
    """A new button token: 32 random bytes, URL-safe (it goes in the button's address)."""
    return BUTTON_PREFIX + secrets.token_urlsafe(32)


def button_digest(token: str) -> str:
    """What the store keeps and looks a press up by: SHA-256 of the token, hex."""
    return hashlib.sha256(token.encode()).hexdigest()


@dataclass
class _Bucket:
    tokens: float
    at: float


@dataclass
class ButtonLimits:
    """A token bucket per button: ``burst`` presses at once, then one per ``per`` seconds."""

    burst: float = BURST
    per: float = PER
    _buckets: dict[str, _Bucket] = field(default_factory=dict)

    def allow(self, button: str, now: float) -> float:
        """0 if this press may go ahead (and count it), else seconds until one may."""
        b = self._buckets.get(button)
        if b is None:
            b = self._buckets[button] = _Bucket(self.burst, now)
        b.tokens = min(self.burst, b.tokens + max(0.0, now - b.at) / self.per)
        b.at = now
        if b.tokens >= 1.0:
            b.tokens -= 1.0
            return 0.0
        return (1.0 - b.tokens) * self.per

    def forget(self, button: str) -> None:
        self._buckets.pop(button, None)


def is_open(call: Call) -> bool:
    return call.answered_at is None and call.cancelled_at is None


def due(calls: Iterable[Call], now: float, after: float) -> list[int]:
    """The open calls not escalated yet that have waited ``after`` seconds or more."""
    return [
        c.id for c in calls if is_open(c) and c.escalated_at is None and now - c.opened_at >= after
    ]


def answer_times(calls: Iterable[Call]) -> dict[CallKind, list[float]]:
    """Seconds from opening to answer, per kind, of the answered calls."""
    out: dict[CallKind, list[float]] = {}
    for c in calls:
        if c.answered_at is not None:
            out.setdefault(c.kind, []).append(c.answered_at - c.opened_at)
    return out
