"""How a robot moves through its trip: goals sent, arrivals, skips, timeouts, goal outcomes.

A mixin of :class:`~serveur.core.engine.Core` (which keeps the robots' locks and status
changes): the steps here run under the robot's lock, called from an instruction
(:meth:`Core._act <serveur.core.engine.Core>`) or a link report. Split from the engine so that
each module stays about one thing: the engine wires collaborators and carries out
instructions; this module decides where a robot goes next and what a goal's end means.
"""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.places import Places
from serveur.core.runtime import CoreConfig, Destination, Runtime
from serveur.core.service import Service
from serveur.core.trips import Trips
from serveur.domain import Robot, Task
from serveur.errors import Conflict, Forbidden, LinkError, Stale, StoreError, Unreachable
from serveur.robots import rosbridge as rb
from serveur.status import Event, RobotState, RobotStatus

__all__ = ["RobotMoves"]

log = logging.getLogger("serveur.core.engine")

S = RobotStatus


class RobotMoves:
    """Where a robot goes next and what its goal's end means; mixed into the core."""

    _rt: dict[str, Runtime]
    _robots: dict[str, Robot]
    places: Places
    trips: Trips
    config: CoreConfig
    service: Service
    clock: Clock

    async def _event(self, rt: Runtime, ev: Event, *, error: str | None = None) -> Robot:
        raise NotImplementedError  # the core's: apply the status machine, store, publish

    async def _save_state(
        self,
        name: str,
        st: RobotState,
        *,
        event: str = "robot.status",
        error: str | None = None,
        keep_error: bool = False,
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        raise NotImplementedError  # the core's: store the state, publish the robot

    async def flush_events(self) -> None:
        raise NotImplementedError

    async def _check_at_table(self, rt: Runtime, table: str) -> None:
        """A table screen acts only on the robot standing at its own table."""
        here = None
        if rt.state.status is S.DELIVERED and self._robots[rt.name].current_task is not None:
            task = await self.trips.current(rt.name)
            if task.current_stop < len(task.stops):
                here = task.stops[task.current_stop].table
        if here != table:
            raise Forbidden(f"{rt.name} is not at table {table}", robot=rt.name, table=table)

    async def _check_target(self, rt: Runtime, msg: P.TargetMsg) -> None:
        """Refuse (``stale``) a command on a trip or stop the robot has moved on from."""
        given, task, stop = msg.expects()
        current = self._robots[rt.name].current_task
        at: int | None = None
        if current is not None and stop is not None:
            at = (await self.trips.current(rt.name)).current_stop
        if (given and task != current) or (stop is not None and stop != at):
            seen = _trip_words(task, stop)
            now = _trip_words(current, at)
            raise Stale(
                f"{rt.name} has moved on: you saw {seen}, it is on {now} ({rt.state.status.value})",
                robot=rt.name,
                task=current,
                stop=at,
                status=rt.state.status.value,
            )

    def _check_reachable(self, x: float, y: float) -> None:
        """Refuse at once a manual goal the robot could never reach (off the map, in a wall),
        rather than send it and report move_base's failure later through ``last_error``."""
        m = self.places.map
        problem = m.goal_problem(x, y) if m is not None else None
        if problem is not None:
            reason, message = problem
            raise Unreachable(f"goal {message}", x=x, y=y, reason=reason)

    async def _next(self, rt: Runtime) -> None:
        await self._go_on(rt, await self.trips.serve_stop(rt.name))

    async def _skip(self, rt: Runtime, reason: str, actor: str | None) -> None:
        """Leave the current table unserved: dishes returned, on to the next table or home."""
        if self._robots[rt.name].current_task is None:
            raise Conflict(f"robot {rt.name} has no trip: there is no table to skip")
        if rt.state.status is not S.DELIVERED and rt.link is not None:
            with contextlib.suppress(LinkError):
                await rt.link.cancel_goal()
        rt.goal_id = None
        await self._go_on(rt, await self.trips.skip_stop(rt.name, reason, actor))

    async def _go_on(self, rt: Runtime, task: Task) -> None:
        if task.current_stop < len(task.stops):
            await self._event(rt, Event.NEXT_TABLE)
            await self._drive(rt, self._stop_dest(task))
        else:
            await self._event(rt, Event.NEXT_HOME)
            await self._drive(rt, self._home_dest(rt))

    def _stop_dest(self, task: Task) -> Destination:
        wp = self.places.waypoint(task.stops[task.current_stop].table)
        return Destination("table", wp.name, wp.x, wp.y, wp.yaw)

    def _home_dest(self, rt: Runtime) -> Destination:
        home = self._robots[rt.name].home
        if home is None:
            raise Conflict(f"robot {rt.name} has no home waypoint")
        wp = self.places.waypoint(home)
        return Destination("home", wp.name, wp.x, wp.y, wp.yaw)

    def _near(self, rt: Runtime, dest: Destination) -> bool:
        if rt.pose is None:
            return False
        return math.hypot(rt.pose[0] - dest.x, rt.pose[1] - dest.y) <= self.config.arrive_tolerance

    async def _drive(self, rt: Runtime, dest: Destination) -> None:
        """Send the robot to ``dest`` once it holds the zones on the way (at once without
        zones); until then it stays where it is (serveur.core.traffic)."""
        rt.dest = dest
        rt.goal_id = None
        rt.resume_dest = None
        if await self._lease_leg(rt, dest):
            await self._send_goal(rt, dest)

    if TYPE_CHECKING:  # the core's (serveur.core.traffic): declared, not defined, here

        async def _lease_leg(self, rt: Runtime, dest: Destination) -> bool: ...

        def leg_ended(self, rt: Runtime) -> None: ...

        async def _waited(self, rt: Runtime, succeeded: bool, text: str) -> bool: ...

    async def _send_goal(self, rt: Runtime, dest: Destination) -> None:
        assert rt.link is not None
        try:
            rt.goal_id = await rt.link.send_goal(dest.x, dest.y, dest.yaw)
        except LinkError as exc:
            rt.goal_id = None  # re-sent when the link is back (resume)
            log.warning("%s: goal to %s not sent: %s", rt.name, dest.name, exc)

    async def _go_home_if_away(self, rt: Runtime) -> None:
        dest = self._home_dest(rt)
        if rt.state.status is S.AWAITING and not self._near(rt, dest):
            await self._event(rt, Event.GO_HOME)
            await self._drive(rt, dest)

    async def _resume_move(self, rt: Runtime) -> None:
        """Re-send the goal for the current move (after continue, or when the link returns)."""
        status = rt.state.status
        if status is S.DELIVERING:
            task = await self.trips.current(rt.name)
            dest = self._stop_dest(task)
            if self._near(rt, dest):
                await self._arrived(rt)
            else:
                await self._drive(rt, dest)
        elif status is S.TRANSIT:
            dest = self._home_dest(rt)
            if self._near(rt, dest):
                rt.dest = dest
                await self._event(rt, Event.ARRIVED)
            else:
                await self._drive(rt, dest)

    async def _arrived(self, rt: Runtime) -> None:
        if rt.state.status is S.DELIVERING:
            await self.trips.arrive(rt.name)
        await self._event(rt, Event.ARRIVED)

    async def _table_timeout(self, rt: Runtime, task_id: int, since: float) -> None:
        robot = self._robots[rt.name]
        if (
            rt.state.status is not S.DELIVERED
            or robot.current_task != task_id
            or robot.status_since != since
        ):
            return  # food collected (or skipped) meanwhile
        limit = self.config.table_timeout or 0.0
        log.warning("%s: nobody collected the food in %g s, going on", rt.name, limit)
        await self._skip(rt, f"nobody collected the food in {limit:g} s", None)
        await self.flush_events()

    async def _on_goal(self, rt: Runtime, goal_id: str, status: rb.GoalStatus, text: str) -> None:
        if goal_id != rt.goal_id:
            return  # a goal we already replaced or cancelled
        rt.goal_id = None
        try:
            await self._goal_ended(rt, status, text)
        except StoreError:
            if rt.goal_id is None:
                rt.goal_id = goal_id  # not applied: the retry must still recognise the goal
            raise

    async def _goal_ended(self, rt: Runtime, status: rb.GoalStatus, text: str) -> None:
        self.leg_ended(rt)
        dest = rt.dest
        # Back outside a zone, at its waiting point: the leg it waited for is asked again.
        succeeded = status is rb.GoalStatus.SUCCEEDED
        if dest is not None and dest.kind == "wait" and await self._waited(rt, succeeded, text):
            return
        st = rt.state.status
        if status is rb.GoalStatus.SUCCEEDED and dest is not None:
            if rt.pose is not None:
                off = math.hypot(rt.pose[0] - dest.x, rt.pose[1] - dest.y)
                if off > self.config.far_tolerance:
                    reason = f"robot reports arriving {off:.2f} m from {dest.name or 'its goal'}"
                    await self._failed(rt, reason)
                    return
            if st in (S.DELIVERING, S.TRANSIT):
                await self._arrived(rt)
            elif st is S.MANUAL:
                await self._save_state(rt.name, rt.state, error=None, event="robot.goal_reached")
            return
        what = {rb.GoalStatus.LOST: "goal lost"}.get(status, f"move_base {status.name}")
        await self._failed(rt, f"{what}: {text}" if text else what)

    async def _failed(self, rt: Runtime, reason: str) -> None:
        dest = rt.dest
        if rt.state.status is S.DELIVERING and dest is not None and dest.kind == "table":
            # No second robot is sent where this one could not go: the table is blocked
            # until staff clear it (its dishes wait at the pass, with the reason).
            await self.service.block(dest.name, f"{rt.name}: {reason}", rt.name)
        if rt.state.status in (S.DELIVERING, S.TRANSIT):
            await self._event(rt, Event.NAV_FAILED, error=reason)
        else:
            await self._save_state(rt.name, rt.state, error=reason, event="robot.goal_failed")


def _trip_words(task: int | None, stop: int | None) -> str:
    """``trip 12 stop 0`` or ``no trip``: what a ``stale`` message says was seen and is now."""
    if task is None:
        return "no trip"
    return f"trip {task}" + (f" stop {stop}" if stop is not None else "")
