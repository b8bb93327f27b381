"""The centre's rules for one site's stream (pure: numbers and times in, decisions out).

**Exactly once, in order.** The centre keeps, per site, ``stored``: every event up to it is
stored and none after it. A batch is judged against it (:meth:`SiteLedger.judge`):

* entirely at or below ``stored``: a duplicate (QoS 1 delivers at least once; a site that
  restarted before noting the broker's acknowledgement sends again) — nothing changes;
* starting at or below ``stored + 1``: the part after ``stored`` is taken, the rest ignored;
* starting above ``stored + 1``: a gap — a batch the broker lost (Mosquitto keeps a queue on
  disk only as of its last autosave) or one still to come after a resend. Nothing is taken
  (storing past a hole would break "in order"); the site is asked to send again from
  ``stored + 1``.

So the centre's copy is always a prefix of the site's outbox: all of it, once, in order.

**Asking again** is paced (:data:`RESEND_EVERY`): one request, then another only if nothing
was taken for that long — a site catching up sends its batches in order, and asking again at
every out-of-order batch would make it start over each time. A heartbeat whose ``head`` is
past ``stored`` while nothing comes asks the same way (the lost batch was the last one).

**Liveness**, as Home Assistant reports a device's availability: a site is ``up`` when heard
(any message), ``down`` after :attr:`SiteLedger.down_after` seconds of silence; each change
is reported once (:meth:`heard` and :meth:`check` return it), not at every tick. A centre
cut off from the broker hears nobody: it judges nobody then, and counts silence from when
it is back (every site down after a broker restart would be the centre's fault, not theirs).
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

from serveur.chain.wire import Batch
from serveur.domain import EventRecord

__all__ = ["RESEND_EVERY", "Decision", "Liveness", "SiteLedger", "Verdict"]

#: Seconds between two requests to send again while a gap stays open.
RESEND_EVERY = 5.0


class Verdict(enum.Enum):
    TAKE = "take"
    DUPLICATE = "duplicate"
    GAP = "gap"


class Liveness(enum.Enum):
    UP = "up"
    DOWN = "down"


@dataclass(frozen=True, slots=True)
class Decision:
    verdict: Verdict
    #: The events to store (TAKE), numbered from ``first``.
    events: tuple[EventRecord, ...] = ()
    first: int = 0
    #: Ask the site to send again from this number (a gap, paced), else None.
    resend_from: int | None = None


@dataclass(slots=True)
class SiteLedger:
    """One site, as the centre follows it (one per site, like a coordinator per device)."""

    site: str
    stored: int = 0
    down_after: float = 300.0
    head: int = 0  # the highest number the site said it gave (heartbeat or batch)
    heard_at: float | None = None
    progress_at: float | None = None  # when events were last taken
    asked_at: float | None = None
    asked_from: int = 0
    state: Liveness | None = None

    def judge(self, batch: Batch, now: float) -> Decision:
        """What to do with ``batch`` (call :meth:`stored_up_to` once it is stored)."""
        self.head = max(self.head, batch.last)
        if batch.last <= self.stored:
            verdict = Decision(Verdict.DUPLICATE)
        elif batch.first > self.stored + 1:
            verdict = Decision(Verdict.GAP, resend_from=self._ask(now))
        else:
            skip = self.stored + 1 - batch.first
            verdict = Decision(Verdict.TAKE, batch.events[skip:], self.stored + 1)
        return verdict

    def stored_up_to(self, seq: int, now: float) -> None:
        if seq > self.stored:
            self.stored = seq
            self.progress_at = now
            if self.asked_from <= seq:
                self.asked_at = None  # the gap is filled: a new one may be asked at once

    def alive(self, head: int, now: float) -> int | None:
        """A heartbeat said the site gave numbers up to ``head``: where to ask it to send
        again from, if it is ahead and nothing came for a while, else None."""
        self.head = max(self.head, head)
        if self.head <= self.stored:
            return None
        if self.progress_at is not None and now - self.progress_at < RESEND_EVERY:
            return None
        return self._ask(now)

    def _ask(self, now: float) -> int | None:
        start = self.stored + 1
        if (
            self.asked_at is not None
            and now - self.asked_at < RESEND_EVERY
            and self.asked_from == start
        ):
            return None
        self.asked_at, self.asked_from = now, start
        return start

    def heard(self, now: float) -> Liveness | None:
        """The site said something: UP if that is news (it was down or never seen)."""
        self.heard_at = now
        if self.state is not Liveness.UP:
            self.state = Liveness.UP
            return Liveness.UP
        return None

    def check(self, now: float, listening_since: float | None = None) -> Liveness | None:
        """DOWN if the site has been silent past ``down_after`` and was up (once).

        ``listening_since``: when the centre's own link to the broker last came up. Silence
        while the centre itself was cut off says nothing of the site, so it counts from
        then; None: the centre is cut off now, and nobody is judged."""
        if (
            self.state is Liveness.UP
            and self.heard_at is not None
            and listening_since is not None
            and now - max(self.heard_at, listening_since) >= self.down_after
        ):
            self.state = Liveness.DOWN
            return Liveness.DOWN
        return None
