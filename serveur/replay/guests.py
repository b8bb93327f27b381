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
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Mapping, Sequence
from functools import partial

from serveur.replay.client import WAIT, Console, ReplayError
from serveur.replay.model import Absence, stop_dwell

__all__ = ["Guests"]


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
        if len(self.delivered) == self.dishes:
            self.finished.set()
