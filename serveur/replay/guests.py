"""The replayed guests: at each stop they take their dishes and press "Food collected".

Split from :mod:`serveur.replay.service` so that the one thing guests do — wait their seeded dwell
(:func:`serveur.replay.model.stop_dwell`, the same for both policies) and send ``next`` —
is seen apart from the staff, and so that the service's end (every dish collected) is
decided in one place. Guests act only through a :class:`~serveur.replay.client.Console`.
"""

from __future__ import annotations

import asyncio
import itertools
from collections.abc import Mapping
from functools import partial

from serveur.replay.client import WAIT, Console, ReplayError
from serveur.replay.model import stop_dwell

__all__ = ["Guests"]


class Guests:
    """Everyone seated: ``dishes`` dishes to collect, keyed for dwell by ``line_of``.

    ``line_of`` (server order id -> log line) is the kitchen's, read when a robot stops.
    :attr:`delivered` holds the dishes collected so far; ``finished`` is set once all are.
    """

    def __init__(
        self,
        console: Console,
        seed: int,
        line_of: Mapping[int, int],
        dishes: int,
        finished: asyncio.Event,
    ) -> None:
        self.console = console
        self.seed = seed
        self.line_of = line_of
        self.dishes = dishes
        self.finished = finished
        self.delivered: set[int] = set()

    async def collect(self, robot: str, order_ids: list[int]) -> None:
        """Guests at the table take their dishes, then press "Food collected"."""
        c = self.console
        await c.clock.sleep(stop_dwell(self.seed, [self.line_of[i] for i in order_ids]))
        for attempt in itertools.count():
            try:
                await c.call("next", robot=robot)
                break
            except ReplayError:
                # The robot's link dropped meanwhile (a stalled host at a high time scale):
                # it comes back Delivered at the same table, and the guests press again.
                if attempt >= 5:
                    raise
                await c.until(partial(c.status_is, robot, "Delivered"), f"{robot} back", 4 * WAIT)
        self.delivered.update(order_ids)
        if len(self.delivered) == self.dishes:
            self.finished.set()
