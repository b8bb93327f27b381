"""A robot's trip as the store keeps it: taken, stops reached and served, abandoned, handed back.

Each step of a trip is one store transaction followed by the same chores — refresh the robot's
record (the store frees or binds it in that transaction), publish the trip and the orders it
touched. The core decides *when* a step happens, under the robot's lock and with the robot's
status change; :class:`Trips` does the step. That keeps the core about robots and this module
about trips, including what a crash between two transactions leaves behind
(:meth:`Trips.reconcile`).
"""

from __future__ import annotations

import logging
from collections.abc import Callable, Mapping, MutableMapping

from serveur.clock import Clock
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig
from serveur.domain import Order, Robot, StopPurpose, StopStatus, Task, TaskKind, TaskStatus
from serveur.errors import Conflict
from serveur.scheduler import order_stops
from serveur.status import RobotMode, RobotStatus
from serveur.store.base import Store

__all__ = ["Trips"]

log = logging.getLogger(__name__)

S = RobotStatus
_RESUMABLE = {S.LOADING, S.DELIVERING, S.DELIVERED, S.STOPPED, S.TRANSIT, S.ERROR}


class Trips:
    """The store side of robots' trips; callers hold the robot's lock."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: CoreConfig,
        *,
        robots: MutableMapping[str, Robot],
        places: Places,
        publisher: Publisher,
        origin: Callable[[], str],
    ) -> None:
        """``robots`` is the core's robot records by name, refreshed here after every step
        that binds or frees a robot; ``origin`` names where trips start."""
        self._store = store
        self._clock = clock
        self._config = config
        self._robots = robots
        self._places = places
        self._publisher = publisher
        self._origin = origin

    async def reconcile(
        self, robot: Robot, resume: RobotStatus | None
    ) -> tuple[Robot, RobotStatus | None]:
        """The status to resume after a restart, made consistent with the robot's trip.

        Each step of a trip is its own transaction, and the robot's status another one, so a
        crash (SIGKILL, power cut) can fall between them. The trip in the store is the truth;
        the status to resume is derived from it:

        * a trip whose stops are all done but which is still active (crash after the last
          "food collected"): finish it, the robot goes home;
        * a trip taken but the robot not yet Delivering (crash right after dispatch), or
          Delivered although the current stop is not reached (crash after "food collected"
          at a middle stop): the robot delivers to the current stop;
        * Delivering or Delivered without a trip (crash after a hand-over or a cancel): the
          robot goes home.

        Where the robot really is decides the rest on link-up (the core's ``_resume_move``:
        already at the goal counts as arrived, otherwise the goal is sent again).
        """
        if resume not in _RESUMABLE:
            resume = None
        task_id = robot.current_task
        if task_id is not None:
            task = await self._store.tasks.get_task(task_id)
            if task.status is not TaskStatus.ACTIVE:  # the store frees robots in the same tx
                log.error("%s holds trip %d, which is %s", robot.name, task_id, task.status)
            elif task.current_stop >= len(task.stops):
                log.warning("%s: closing trip %d, served before the restart", robot.name, task_id)
                await self._store.tasks.finish_task(task_id, now=self._clock.epoch())
                robot = await self._store.robots.get_robot(robot.name)
            else:
                reached = task.stops[task.current_stop].status is StopStatus.ARRIVED
                on_trip = (S.LOADING, S.DELIVERING, S.DELIVERED, S.STOPPED, S.ERROR)
                if resume not in on_trip:
                    # Taken, but the status change did not land: loading at the pass (or,
                    # where trips leave at once, under way).
                    left = task.current_stop > 0 or self._config.auto_depart
                    resume = S.DELIVERING if left else S.LOADING
                elif resume is S.DELIVERED and not reached:
                    resume = S.DELIVERING
        if robot.current_task is None and resume is S.LOADING:
            resume = None  # the trip was taken back: automatic again, at the pass
        if robot.current_task is None and resume in (S.DELIVERING, S.DELIVERED):
            resume = S.TRANSIT if robot.mode is RobotMode.AUTO else None
        return robot, resume

    async def current(self, robot: str) -> Task:
        """The robot's trip; Conflict if it has none."""
        task_id = self._robots[robot].current_task
        if task_id is None:
            raise Conflict(f"robot {robot} has no trip")
        return await self._store.tasks.get_task(task_id)

    async def stop_orders(self, robot: str) -> list[Order]:
        """The orders for the robot's current stop (none without a trip or once all served)."""
        task_id = self._robots[robot].current_task
        if task_id is None:
            return []
        task = await self._store.tasks.get_task(task_id)
        if task.current_stop >= len(task.stops):
            return []
        ids = set(task.stops[task.current_stop].orders)
        return [o for o in await self._store.orders.list_orders(task_id=task_id) if o.id in ids]

    async def take(self, task_id: int, robot: str) -> Task | None:
        """Give a queued trip to the robot, stops in route order; None if it was taken."""
        home = self._robots[robot].home or self._origin()
        task = await self._store.tasks.get_task(task_id)
        order = [s.table for s in task.stops]
        if task.kind is TaskKind.CRUISE or self._config.policy == "baseline":
            stop_order = order  # the round as drawn; the cart's order, as the report's robot
        elif task.kind is TaskKind.BUSSING:
            # The tables in the shortest order, the dish return last.
            tables = [s.table for s in task.stops if s.purpose is StopPurpose.COLLECT]
            last = [s.table for s in task.stops if s.purpose is not StopPurpose.COLLECT]
            end = last[0] if last else home
            stop_order = order_stops(home, tables, self._places.distance, end=end) + last
        else:
            stop_order = order_stops(home, order, self._places.distance, end=home)
        try:
            task = await self._store.tasks.start_task(
                task_id, robot, stop_order=stop_order, now=self._clock.epoch()
            )
        except Conflict:
            return None
        self._robots[robot] = await self._store.robots.get_robot(robot)
        self._publisher.pub_task(task)
        await self._publisher.pub_orders([o for s in task.stops for o in s.orders])
        return task

    async def arrive(self, robot: str) -> tuple[Task, bool]:
        """The robot reached the current stop of its trip: the trip, and whether a dish of
        the stop is a special delivery (it then waits for Done, without a timeout)."""
        task = await self.current(robot)
        task = await self._store.tasks.arrive_stop(
            task.id, task.stops[task.current_stop].seq, now=self._clock.epoch()
        )
        self._publisher.pub_task(task)
        ids = set(task.stops[task.current_stop].orders)
        special = False
        if ids:
            aboard = await self._store.orders.list_orders(task_id=task.id)
            special = any(o.special is not None for o in aboard if o.id in ids)
        return task, special

    async def serve_stop(self, robot: str, *, timed_out: bool = False) -> Task:
        """Food collected at the current stop; the trip, finished (``done``) after the last."""
        task = await self.current(robot)
        stop = task.stops[task.current_stop]
        task = await self._store.tasks.complete_stop(
            task.id, stop.seq, now=self._clock.epoch(), timed_out=timed_out
        )
        return await self._left_stop(robot, task, stop.orders)

    async def skip_stop(self, robot: str, reason: str, by: str | None) -> Task:
        """The current stop left unserved, its dishes returned; the trip, finished (``done``)
        after its last stop."""
        task = await self.current(robot)
        stop = task.stops[task.current_stop]
        task = await self._store.tasks.skip_stop(
            task.id, stop.seq, now=self._clock.epoch(), reason=reason, by=by
        )
        return await self._left_stop(robot, task, stop.orders)

    async def _left_stop(self, robot: str, task: Task, orders: list[int]) -> Task:
        """Publish a stop served or skipped; after the trip's last stop, finish the trip."""
        self._publisher.pub_task(task)
        await self._publisher.pub_orders(orders)
        if task.current_stop >= len(task.stops) and task.kind is TaskKind.CRUISE:
            # A round is over: the next begins at the first place (it ends when recalled).
            task = await self._store.rounds.restart(task.id, now=self._clock.epoch())
            self._publisher.pub_task(task)
        elif task.current_stop >= len(task.stops):
            task = await self._store.tasks.finish_task(task.id, now=self._clock.epoch())
            self._robots[robot] = await self._store.robots.get_robot(robot)
            self._publisher.pub_task(task)
        return task

    async def drop_blocked(self, task_id: int, blocks: Mapping[str, object]) -> Task | None:
        """A queued trip without its blocked tables (their dishes back at the pass, pending);
        None if nothing is left of it (cancelled) or it was taken meanwhile."""
        task = await self._store.tasks.get_task(task_id)
        if task.status is not TaskStatus.QUEUED:
            return None
        tables = [s.table for s in task.stops if s.table in blocks]
        if not tables:
            return task
        orders = [o for s in task.stops if s.table in blocks for o in s.orders]
        now = self._clock.epoch()
        task = await self._store.tasks.drop_stops(task_id, tables, now=now)
        if task.status is TaskStatus.QUEUED and not any(
            s.purpose is not StopPurpose.UNLOAD for s in task.stops
        ):
            # A bussing trip whose every table is blocked: nothing to collect, no trip.
            task = await self._store.tasks.cancel_task(task_id, now=now, reason="tables blocked")
        self._publisher.pub_task(task)
        await self._publisher.pub_orders(orders)
        return task if task.status is TaskStatus.QUEUED else None

    async def abandon(self, robot: str, reason: str) -> None:
        """Cancel the robot's trip (staff took over): undelivered orders go back to pending."""
        task_id = self._robots[robot].current_task
        if task_id is None:
            return
        aboard = [o.id for o in await self._store.orders.list_orders(task_id=task_id)]
        task = await self._store.tasks.cancel_task(task_id, now=self._clock.epoch(), reason=reason)
        self._robots[robot] = await self._store.robots.get_robot(robot)
        self._publisher.pub_task(task)
        await self._publisher.pub_orders(aboard)

    async def hand_back(self, robot: str, task_id: int, reason: str) -> None:
        """Take the trip off a robot gone too long and requeue it whole for another robot."""
        now = self._clock.epoch()
        if (await self._store.tasks.get_task(task_id)).kind is TaskKind.CRUISE:
            # Nobody else is sent on a round of snacks: the cruise simply ends.
            await self.abandon(robot, reason)
            return
        try:
            task = await self._store.tasks.requeue_task(task_id, now=now, reason=reason)
        except Conflict:
            # Every stop was served before the link dropped: the trip is over, not handed on.
            task = await self._store.tasks.finish_task(task_id, now=now)
        self._robots[robot] = await self._store.robots.get_robot(robot)
        self._publisher.pub_task(task)
        await self._publisher.pub_orders([o for s in task.stops for o in s.orders])
