"""A service the restaurant really had, as an order log the replay can play again.

"How many robots do I need?" is best answered with the restaurant's own nights: the store
keeps every dish with the time it was first ready at the pass (a dish sent back and sent
again keeps it), its table and its quantity. :func:`recorded_orders` turns one service day of
them into the replay's order log (one line a plate, times from the service's first dish), so
``serveur replay`` can play that night again with another fleet size or policy, and
``serveur orders --from-db`` writes it.

Voided dishes are left out (they never left the pass), as are dishes never ready (still at
the kitchen when the night was recorded).
"""

from __future__ import annotations

from collections.abc import Sequence

from serveur.domain import Order, OrderStatus

__all__ = ["recorded_orders"]


def recorded_orders(
    orders: Sequence[Order], start: float, end: float
) -> list[tuple[float, str, str]]:
    """The log's rows ``(ready_at, table, dish)`` of the dishes first ready in
    ``[start, end)``, times from the first of them; a dish of quantity q is q plates (q rows),
    as the pass sends them."""
    served = [
        o
        for o in orders
        if o.ready_at is not None
        and start <= o.ready_at < end
        and o.status is not OrderStatus.VOIDED
    ]
    if not served:
        return []
    t0 = min(o.ready_at for o in served if o.ready_at is not None)
    log: list[tuple[float, str, str]] = []
    for o in sorted(served, key=lambda o: (o.ready_at or 0.0, o.id)):
        assert o.ready_at is not None
        log += [(round(o.ready_at - t0, 1), o.table, o.dish)] * o.quantity
    return log
