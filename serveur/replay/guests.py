"""The replayed guests: at each stop they take their dishes and press "Food collected".

Split from :mod:`serveur.replay.service` so that what guests do — wait their seeded dwell
(:func:`serveur.replay.model.stop_dwell`, the same for both policies) and send ``next`` —
is seen apart from the staff, and so that the service's end (every dish collected) is
decided in one place. Guests act only through a :class:`~serveur.replay.client.Console`.

Some parties are away when their food comes (:func:`serveur.replay.model.absences`, the same
parties for both policies): the robot waits at the table, and the guests press "Food
collected" a dwell after they are back — unless the server's table timeout sent the robot on
first (their ``next`` names the stop they saw, so the server refuses it as ``stale``); then
their dishes went back to the pass, and staff send them again (:mod:`serveur.replay.staff`).

With calls on, each party, once its last dish is collected, calls as
:func:`serveur.replay.orders.guest_calls` drew it (:class:`Callers`: ``call`` ``open``, as its
table screen would), and puts its plates on the bussing robot that comes for them
(:meth:`Guests.put_plates`): Done a :func:`~serveur.replay.model.plates_dwell` later, or, for
the parties that forget (:func:`~serveur.replay.model.forgets_done`), never: the robot goes on
after the server's ``bussing_wait``.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Callable, Coroutine, Mapping, Sequence
from functools import partial
from typing import Any

from serveur.replay.client import WAIT, Console, ReplayError
from serveur.replay.model import Absence, forgets_done, plates_dwell, stop_dwell
from serveur.replay.orders import PartyCalls

__all__ = ["Callers", "Guests"]


class Guests:
    """Everyone seated: ``dishes`` dishes to collect, keyed for dwell by ``line_of``.

    ``line_of`` (server order id -> log line) is the kitchen's, read when a robot stops.
    :attr:`delivered` holds the dishes collected so far; ``finished`` is set once all are.
    :attr:`missed` lists the stops (task, seq) whose robot left before the guests were back.
    """

    def __init__(
        self,
        console: Console,
        seed: int,
        line_of: Mapping[int, int],
        dishes: int,
        finished: asyncio.Event,
        away: Sequence[Absence] = (),
        served: Callable[[list[int]], None] | None = None,
        forget_done: float = 0.0,
    ) -> None:
        self.console = console
        self.seed = seed
        self.line_of = line_of
        self.dishes = dishes
        self.finished = finished
        self.away: dict[str, list[Absence]] = {}
        for a in away:
            self.away.setdefault(a.table, []).append(a)
        self.delivered: set[int] = set()
        self.missed: list[tuple[int, int]] = []
        self.served = served
        self.forget_done = forget_done
        self.plates_done = 0  # bussing stops where the guests pressed Done
        self.plates_left = 0  # ... where they left their plates without pressing it

    def back_at(self, table: str, t: float) -> float:
        """When the guests of ``table`` are at it again, seen at ``t`` (``t``: they are)."""
        for a in self.away.get(table, ()):
            if a.start <= t < a.end:
                return a.end
        return t

    async def collect(
        self, robot: str, task: int, seq: int, table: str, order_ids: list[int]
    ) -> None:
        """Guests at the table (once back, if away) take their dishes, then press "Food
        collected" for the stop they see: stop ``seq`` of trip ``task``."""
        c = self.console
        away = self.back_at(table, c.now()) - c.now()
        await c.clock.sleep(away + stop_dwell(self.seed, [self.line_of[i] for i in order_ids]))
        for attempt in itertools.count():
            try:
                await c.call("next", robot=robot, task=task, stop=seq)
                break
            except ReplayError as exc:
                if exc.code == "stale":  # the robot left (the table timed out): food returned
                    self.missed.append((task, seq))
                    return
                # The robot's link dropped meanwhile (a stalled host at a high time scale):
                # it comes back Delivered at the same table, and the guests press again.
                if attempt >= 5:
                    raise
                await c.until(partial(c.status_is, robot, "Delivered"), f"{robot} back", 4 * WAIT)
        self.delivered.update(order_ids)
        if self.served is not None:
            self.served(order_ids)
        if len(self.delivered) == self.dishes:
            self.finished.set()

    async def put_plates(self, robot: str, task: int, seq: int, party: PartyCalls | None) -> None:
        """A bussing robot at a party's table (stop ``seq`` of trip ``task``): the guests put
        their plates on it and press Done, or leave it to the server's bussing wait."""
        c = self.console
        line, plates = (party.line, party.plates) if party is not None else (0, 2)
        if forgets_done(self.seed, line, self.forget_done):
            self.plates_left += 1
            return
        await c.clock.sleep(plates_dwell(self.seed, line, plates))
        try:
            await c.call("next", robot=robot, task=task, stop=seq)
        except ReplayError as exc:
            if exc.code != "stale":  # the bussing wait ran out first: it left with them
                raise
        self.plates_done += 1


class Callers:
    """The parties' calls (:func:`serveur.replay.orders.guest_calls`), made through the
    console: a party starts calling once its last dish is collected (:meth:`served`).

    :attr:`made` lists every call made (id, table, kind, service s, merged); :attr:`key_of`
    keys each call by its party and kind (staff's answer times are seeded by it);
    :meth:`party_of` names the party a bussing robot comes to. :meth:`done` once every
    party has made all its calls.
    """

    def __init__(
        self,
        console: Console,
        parties: Sequence[PartyCalls],
        line_of: Mapping[int, int],
        spawn: Callable[[Coroutine[Any, Any, None]], None],
    ) -> None:
        self.console = console
        self.line_of = line_of
        self.spawn = spawn
        self._party_of_line = {line: p for p in parties for line in p.lines}
        self._left = {p.line: set(p.lines) for p in parties}  # party -> lines not collected
        self._calling = len(parties)  # parties that have calls still to make
        self.made: list[dict[str, Any]] = []
        self.key_of: dict[int, str] = {}
        self._plates: dict[int, PartyCalls] = {}  # plates call id -> its party

    def served(self, order_ids: list[int]) -> None:
        """Dishes collected: a party whose last dish this was starts its calls."""
        for oid in order_ids:
            line = self.line_of.get(oid)
            party = None if line is None else self._party_of_line.get(line)
            if line is None or party is None:
                continue
            left = self._left[party.line]
            if left:  # else collected again (a dish sent twice): it has called already
                left.discard(line)
                if not left:
                    self.spawn(self._call(party))

    async def _call(self, party: PartyCalls) -> None:
        c = self.console
        start = c.now()
        try:
            for after, kind in party.calls:
                await c.clock.sleep(max(0.0, start + after - c.now()))
                reply = await c.call("call", action="open", table=party.table, kind=kind)
                call = reply["call"]
                self.key_of.setdefault(call["id"], f"{party.line}:{kind}")
                if kind == "plates":
                    self._plates[call["id"]] = party
                self.made.append(
                    {
                        "call": call["id"],
                        "table": party.table,
                        "kind": kind,
                        "t": round(c.now(), 1),
                        "merged": reply["merged"],
                        "party": party.line,
                    }
                )
        finally:
            self._calling -= 1
            c.changed.set()

    def done(self) -> bool:
        """Has every party made all its calls?"""
        return self._calling == 0

    def party_of(self, task: int, table: str) -> PartyCalls | None:
        """The party whose plates call sent bussing trip ``task`` to ``table``."""
        for call in self.console.calls.values():
            if call.get("task_id") == task and call["table"] == table:
                return self._plates.get(call["id"])
        return None
