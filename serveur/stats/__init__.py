"""Statistics and trip history of past services, read from the server's own event log.

Owns :mod:`~serveur.stats.compute` (pure: the event records read back into dishes, trips and
robot timelines, and the figures of any period: dishes delivered, waits, time on the pass,
loading, returned and voided dishes, trips, each robot's busy share and errors, guests'
calls and the time to answer them, bussing trips),
:mod:`~serveur.stats.periods` (pure: hours and service days in local time, dates on the
command line), :mod:`~serveur.stats.load` (the events read from any store, page by page) and
:mod:`~serveur.stats.cli` (``serveur stats``: tables and CSV). There is no second
bookkeeping: every figure comes from the ``events`` table (docs/statistics.md).

May import: serveur.domain, serveur.store, serveur.protocol.
"""

__all__: list[str] = []
