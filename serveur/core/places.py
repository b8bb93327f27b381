"""The restaurant's geography for the core: waypoints, the map, path distances between waypoints.

The core needs three things from the floor plan: a waypoint by name (a table to drive to, a
robot's home), the map screens draw, and the path distance between two waypoints that trip
planning ranks routes by. They change together — a new waypoint needs its distances planned
on the map, a map adopted from a robot needs every pair planned — and nothing in them touches
a robot's status, so they live here, apart from the core's per-robot state machine.

Path distances are planned off the event loop (:mod:`serveur.maps.distances`), in a child process
unless this process already holds numpy (then a thread is cheaper); until a pair is planned,
:meth:`Places.distance` answers with the straight line.
"""

from __future__ import annotations

import asyncio
import json
import logging
import math
import time
from collections.abc import Iterable, Mapping
from typing import Any

from serveur import protocol as P
from serveur.core.hub import Hub
from serveur.domain import WaypointKind, WaypointRecord
from serveur.errors import NotFound, ServeurError, Unreachable
from serveur.maps.distances import Distances, MapData, PlanRequest, plan_async
from serveur.maps.memory import trim_heap

__all__ = ["Places"]

log = logging.getLogger(__name__)


class Places:
    """Waypoints by name, the served map, and planned path distances between waypoints."""

    def __init__(
        self,
        hub: Hub,
        *,
        robot_radius: float,
        nav_map: Any = None,
        map_path: str | None = None,
        plan_in_child: bool = True,
    ) -> None:
        self._hub = hub
        self._robot_radius = robot_radius
        self.waypoints: dict[str, WaypointRecord] = {}
        # The map: a MapData (or an in-process OccupancyMap, converted), or a file the planner
        # reads.
        self.map: MapData | None = (
            nav_map
            if nav_map is None or isinstance(nav_map, MapData)
            else MapData.from_occupancy(nav_map)
        )
        self._map_path = map_path
        self._map_json: str | None = None
        #: The floor plan drawn under the map (``site align_map``), as the snapshot says it.
        self.backdrop: dict[str, Any] | None = None
        self._plan_in_child = plan_in_child
        self.distances = Distances()
        #: Background planning jobs (a new waypoint, an adopted map); cancelled by :meth:`close`.
        self.planning: set[asyncio.Task[None]] = set()
        # Waypoints (or everything) waiting to be planned by the one background job: a burst
        # of new waypoints becomes one or two plans, not one per waypoint.
        self._pending: set[str] = set()
        self._pending_all = False
        self._job: asyncio.Task[None] | None = None

    async def load(
        self, waypoints: Iterable[WaypointRecord], stored: MapData | None = None
    ) -> None:
        """Take the stored waypoints and plan every pair before any robot is driven.

        ``stored``: the map the owner set in the console (the store's ``site_map``); it wins
        over ``--map`` and a robot's. A bad map file stops the start here, with its MapError.
        """
        if stored is not None:
            self.map, self._map_path = stored, None
        for wp in waypoints:
            self.waypoints[wp.name] = wp
        self.distances.set_spots(_spot(w) for w in self.waypoints.values())
        if self.map is not None:
            self._set_map(self.map)
        if self.map is not None or self._map_path is not None:
            await self._plan(None)

    def close(self) -> None:
        """Cancel background planning (shutdown)."""
        for job in list(self.planning):
            job.cancel()

    def waypoint(self, name: str) -> WaypointRecord:
        """The waypoint called ``name``; NotFound if there is none."""
        wp = self.waypoints.get(name)
        if wp is None:
            raise NotFound(f"no waypoint named {name!r}", waypoint=name)
        return wp

    def is_table(self, name: str) -> bool:
        """Is ``name`` a place of kind table?"""
        wp = self.waypoints.get(name)
        return wp is not None and wp.kind is WaypointKind.TABLE

    def check_spot(self, x: float, y: float, what: str = "a place cannot be there:") -> None:
        """(x, y) must be on free floor of the map (when there is one): a manual goal, or a
        place put by hand (a table at (9999, -50) was stored, dishes were taken for it and a
        robot sent there needed help). :class:`~serveur.errors.Unreachable` (``reason``:
        outside_map, unknown, occupied), its message starting with ``what``."""
        problem = None if self.map is None else self.map.goal_problem(x, y)
        if problem is not None:
            reason, message = problem
            raise Unreachable(f"{what} {message}", x=x, y=y, reason=reason)

    def put(self, wp: WaypointRecord) -> None:
        """A waypoint stored (new or moved): its distances are planned in the background."""
        self.waypoints[wp.name] = wp
        self.distances.set_spots([_spot(wp)])
        if self.map is not None:
            self._plan_later([wp.name])

    def remove(self, name: str) -> None:
        """A waypoint removed (or renamed away from): no longer a destination. Its planned
        distances are left: they are only read for waypoints that exist, and a waypoint
        saved again under this name is planned afresh (its spot changed or not)."""
        self.waypoints.pop(name, None)

    def use_map(self, m: MapData) -> None:
        """The owner gave a new map (console): screens get it now, every pair is planned
        again in the background (straight lines meanwhile)."""
        self._map_path = None
        self._set_map(m)
        self._plan_later(None)

    def outside(self, m: MapData) -> list[str]:
        """The waypoints that are not on free floor of ``m`` (a wall, unknown, off the map):
        kept, but staff must move them before robots can go there."""
        out = []
        for wp in self.waypoints.values():
            col = math.floor((wp.x - m.origin[0]) / m.resolution)
            row = math.floor((wp.y - m.origin[1]) / m.resolution)
            inside = 0 <= col < m.width and 0 <= row < m.height
            if not inside or m.data[row * m.width + col] != 0:
                out.append(wp.name)
        return sorted(out)

    def adopt_map(self, robot: str, msg: Mapping[str, Any]) -> None:
        """A robot's ``/map``, used if the server was started without one."""
        if self.map is not None:
            return
        try:
            self._set_map(MapData.from_grid_msg(msg))
            log.info("adopted the map published by %s", robot)
            self._plan_later(None)
        except ServeurError as exc:
            log.warning("%s: unusable /map: %s", robot, exc)

    def map_snapshot(self) -> Any:
        """The ``map`` topic's snapshot: the map as screens draw it, or None."""
        return json.loads(self._map_json) if self._map_json else None

    def use_backdrop(self, backdrop: dict[str, Any] | None) -> None:
        """The floor plan under the map changed (fitted, or gone with a new map): every screen
        gets the map again with it."""
        self.backdrop = backdrop
        if self.map is not None:
            self._set_map(self.map)

    def _set_map(self, m: MapData) -> None:
        self.map = m
        snap = m.snapshot()
        if self.backdrop is not None:
            snap["backdrop"] = self.backdrop
        self._map_json = P.dump(snap)
        self._hub.publish("map", self._map_json)

    async def _plan(self, sources: list[str] | None) -> None:
        """Plan the distances of every pair (``sources`` None) or of pairs touching ``sources``."""
        req = PlanRequest(
            spots=[_spot(w) for w in self.waypoints.values()],
            robot_radius=self._robot_radius,
            map=self.map,
            map_path=self._map_path if self.map is None else None,
            sources=sources,
        )
        started = time.monotonic()
        result = await plan_async(req, in_child=self._plan_in_child)
        log.info(
            "planned %d path distances in %.1f s (%s)",
            len(result.pairs),
            time.monotonic() - started,
            "from the plan cache"
            if result.cached
            else "child process"
            if self._plan_in_child
            else "worker thread",
        )
        if not self._plan_in_child and not result.cached:
            trim_heap()  # the worker thread's freed distance fields (serveur.maps.memory)
        if self.map is None:
            self._set_map(result.map)
        self.distances.merge(req, result)

    def _plan_later(self, sources: list[str] | None) -> None:
        """Plan in the background; until then the scheduler uses straight lines.

        One job at a time: what is asked while it plans is gathered and planned together
        next, so ten waypoints created at once cost two plans, not ten.
        """
        if sources is None:
            self._pending_all = True
        else:
            self._pending.update(sources)
        if self._job is None or self._job.done():
            job = asyncio.get_running_loop().create_task(self._drain())
            self._job = job
            self.planning.add(job)
            job.add_done_callback(self.planning.discard)

    async def _drain(self) -> None:
        while self._pending_all or self._pending:
            sources = None if self._pending_all else sorted(self._pending)
            self._pending_all, self._pending = False, set()
            try:
                await self._plan(sources)
            except ServeurError as exc:
                log.warning("path distances not planned (straight lines used): %s", exc)

    def distance(self, a: str, b: str) -> float:
        """Path distance between two waypoints; straight line if not planned or no path."""
        if a == b:
            return 0.0
        planned = self.distances.planned(a, b)
        if planned is not None:
            return planned
        wa, wb = self.waypoints.get(a), self.waypoints.get(b)
        if wa is None or wb is None:
            return 1e6
        return math.hypot(wa.x - wb.x, wa.y - wb.y)

    def path(self, a: str, b: str) -> list[tuple[float, float]]:
        """The planned path from waypoint ``a`` to ``b``; the straight line until planned."""
        planned = self.distances.path(a, b)
        if planned is not None:
            return planned
        wa, wb = self.waypoint(a), self.waypoint(b)
        return [(wa.x, wa.y), (wb.x, wb.y)]

    def nearest(self, x: float, y: float) -> str | None:
        """The waypoint closest to ``(x, y)`` (a robot's leg starts near one)."""
        best = min(
            self.waypoints.values(), key=lambda w: math.hypot(w.x - x, w.y - y), default=None
        )
        return None if best is None else best.name

    def origin(self, homes: Iterable[str | None]) -> str:
        """Where trips start: the pass, else a home waypoint, else a robot's home, else any."""
        for kind in (WaypointKind.PASS, WaypointKind.HOME):
            for wp in self.waypoints.values():
                if wp.kind is kind:
                    return wp.name
        for home in homes:
            if home:
                return home
        return next(iter(self.waypoints), "")


def _spot(w: WaypointRecord) -> tuple[str, float, float]:
    return (w.name, w.x, w.y)
