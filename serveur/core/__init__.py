"""The application layer: what each instruction and each robot event does.

Owns the robots' live state and the rules applied to it between the websocket endpoint
(:mod:`serveur.server`, which only parses and replies), the store and the robot drivers:
:mod:`~serveur.core.engine` (the :class:`~serveur.core.engine.Core`: the robots' registry,
lifecycle, the dispatcher's and the alerts' view of the fleet), :mod:`~serveur.core.robot`
(one controller per robot: its state, link, events and moves), :mod:`~serveur.core.events`
(what happens to a robot, typed), :mod:`~serveur.core.actions` and
:mod:`~serveur.core.instructions` (staff actions and client messages, each one table),
:mod:`~serveur.core.crew` (the collaborators a controller is given),
:mod:`~serveur.core.runtime` (tunables, a robot's runtime), :mod:`~serveur.core.link_reports`
(reports queued per robot), :mod:`~serveur.core.trips` (each step of a trip in the store),
:mod:`~serveur.core.creation` (create order/task/waypoint), :mod:`~serveur.core.places`
(waypoints, map, distances), :mod:`~serveur.core.publisher` and :mod:`~serveur.core.hub`
(what screens are shown, fan-out), :mod:`~serveur.core.traffic` and
:mod:`~serveur.core.leases` (zones), :mod:`~serveur.core.site` (the owner's changes),
:mod:`~serveur.core.service` (dishes' steps, the menu, blocked tables, the watch loop) and
:mod:`~serveur.core.alerts` (the alert rules, pure), :mod:`~serveur.core.backups` (when backups
are made and kept, pure), :mod:`~serveur.core.shelf` (the backups folder) and
:mod:`~serveur.core.backup_desk` (the console's backups and restores). docs/architecture.md draws
the whole.

May import: serveur.clock, serveur.domain, serveur.status, serveur.protocol,
serveur.scheduler, serveur.store.base, serveur.store.restore, serveur.maps, serveur.robots,
serveur.till.
"""

__all__: list[str] = []
