"""``serveur replay``: an order log played through the real server in virtual time.

Owns :mod:`~serveur.replay.service` (the run: server, simulated fleet, staff and guests),
:mod:`~serveur.replay.vtime` (the virtual-time event loop), :mod:`~serveur.replay.orders`
(order logs, read or generated; parties), :mod:`~serveur.replay.model` (options, guests'
dwell and absences, loading at the pass, statistics; pure), :mod:`~serveur.replay.world`
(map and server settings), :mod:`~serveur.replay.client` (the protocol client and its
console), the players
:mod:`~serveur.replay.staff` and :mod:`~serveur.replay.guests`, :mod:`~serveur.replay.report`
(summary and plots), :mod:`~serveur.replay.recorded` (a recorded service day as a log),
:mod:`~serveur.replay.forecast` (the owner's "how many robots?": a recorded day replayed with
other fleets, in child processes), :mod:`~serveur.replay.traffic` (conflicts, deadlocks and
zone waits measured on the simulator's true poses) and :mod:`~serveur.replay.cli` (the
subcommand). It drives the server
only as a client does, over ``/ws``.

May import: serveur.app, serveur.clock, serveur.robot_sim, serveur.scheduler,
serveur.core.runtime, serveur.core.engine, serveur.security.sessions, serveur.maps,
serveur.sim.kinematics, serveur.stats.periods, serveur.store.factory, serveur.domain.
"""

__all__: list[str] = []
