"""The application layer: what each instruction and each robot report does.

Owns the robots' live state and the rules applied to it between the websocket endpoint
(:mod:`serveur.server`, which only parses and replies), the store and the robot links:
:mod:`~serveur.core.engine` (the :class:`~serveur.core.engine.Core`: per-robot locks, the
status machine applied, the dispatcher wired), :mod:`~serveur.core.runtime` (tunables, a
robot's runtime), :mod:`~serveur.core.link_reports` (reports queued per robot),
:mod:`~serveur.core.trips` (each step of a trip in the store), :mod:`~serveur.core.creation`
(create order/task/waypoint), :mod:`~serveur.core.places` (waypoints, map, distances),
:mod:`~serveur.core.publisher` (what screens are shown), :mod:`~serveur.core.hub`
(subscriptions and fan-out to every client), :mod:`~serveur.core.moves` (where a robot goes
next, what a goal's end means), :mod:`~serveur.core.service` (dishes' steps, the menu, blocked
tables, the watch loop) and :mod:`~serveur.core.alerts` (the alert rules, pure).

May import: serveur.clock, serveur.domain, serveur.status, serveur.protocol,
serveur.scheduler, serveur.store.base, serveur.maps, serveur.robots.
"""

__all__: list[str] = []
