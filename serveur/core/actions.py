"""What each staff action does to one robot, once the status machine allowed it.

One function per :class:`~serveur.status.Action`, found through :data:`ACTIONS`: adding an
action is one function and one entry (the allowed-actions table itself stays in
:mod:`serveur.status`). Each runs under the robot's lock, on the robot's
:class:`~serveur.core.robot.RobotController`, with the message that asked for it.
"""

from __future__ import annotations

import contextlib
from collections.abc import Awaitable, Callable
from dataclasses import replace
from typing import Any

from serveur.core.robot import RobotController
from serveur.core.runtime import Destination
from serveur.domain import TaskKind
from serveur.errors import Conflict, LinkError
from serveur.status import Action, Event, RobotStatus

__all__ = ["ACTIONS", "ActionHandler"]

S = RobotStatus

#: ``(controller, message, actor)``: carry the action out.
ActionHandler = Callable[[RobotController, Any, "str | None"], Awaitable[None]]


def _link(ctl: RobotController) -> Any:
    link = ctl.rt.link
    assert link is not None
    return link


async def _auto(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.record.home is None:
        raise Conflict(f"robot {ctl.name} has no home waypoint; set one first")
    await ctl.event(Event.AUTO)
    await ctl.go_home_if_away()


async def _manual(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.record.current_task is not None:
        await ctl.crew.trips.abandon(ctl.name, "manual control taken")
    with contextlib.suppress(LinkError):
        await _link(ctl).cancel_goal()
    ctl.rt.dest = None
    await ctl.event(Event.MANUAL)


async def _teleop(ctl: RobotController, msg: Any, actor: str | None) -> None:
    rt = ctl.rt
    if rt.dest is not None or rt.goal_id is not None:
        # move_base does not listen to /cmd_vel: its goal would keep driving the robot while
        # staff steer, so the goal goes first.
        await _link(ctl).cancel_goal()
        rt.dest = None
        rt.goal_id = None
    await _link(ctl).teleop(msg.vx, msg.vy, msg.wz)


async def _initial_pose(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await _link(ctl).initial_pose(msg.x, msg.y, msg.yaw)


async def _goal(ctl: RobotController, msg: Any, actor: str | None) -> None:
    # Refused at once if the robot could never reach it (off the map, in a wall), rather
    # than sent and reported through ``last_error`` when move_base gives up.
    ctl.crew.places.check_spot(msg.x, msg.y, "goal")
    await ctl.drive(Destination("manual", "", msg.x, msg.y, msg.yaw))


async def _goto(ctl: RobotController, msg: Any, actor: str | None) -> None:
    wp = ctl.crew.places.waypoint(msg.waypoint)
    await ctl.drive(Destination("manual", wp.name, wp.x, wp.y, wp.yaw))


async def _ready(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.rt.state.status is S.MANUAL:
        with contextlib.suppress(LinkError):
            await _link(ctl).cancel_goal()
            await _link(ctl).teleop(0.0, 0.0, 0.0)
    ctl.rt.dest = None
    await ctl.event(Event.RELEASE)


async def _next(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await ctl.serve()


async def _go(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.rt.localisation.lost:
        # It would drive to where it believes the table is: staff set its place first.
        raise Conflict(
            f"{ctl.name} is not sure where it is: set where the robot is on the map first",
            robot=ctl.name,
            reason="lost",
        )
    task = await ctl.crew.trips.current(ctl.name)
    await ctl.event(Event.GO)
    await ctl.drive(ctl.stop_dest(task))


async def _skip(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await ctl.skip("skipped by staff", actor)


async def _stop(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await _link(ctl).cancel_goal()
    ctl.rt.goal_id = None
    await ctl.event(Event.STOP)


async def _continue(ctl: RobotController, msg: Any, actor: str | None) -> None:
    rt = ctl.rt
    if rt.state.resume is None:
        # What to resume is lost when a Stopped/Error robot's link drops (the status column
        # holds one "resume"); the trip tells: dishes aboard -> back to the table.
        has_trip = ctl.record.current_task is not None
        rt.state = replace(rt.state, resume=S.DELIVERING if has_trip else S.TRANSIT)
    await ctl.event(Event.CONTINUE)
    await ctl.resume_move()


async def _cancel(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.record.current_task is not None:
        await ctl.crew.trips.abandon(ctl.name, "cancelled by staff")
    loading = ctl.rt.state.status is S.LOADING
    await ctl.event(Event.CANCEL)
    if not loading:  # a robot still at the pass stays there
        await ctl.drive(ctl.home_dest())


async def _charge(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await ctl.charge()


async def _work(ctl: RobotController, msg: Any, actor: str | None) -> None:
    await ctl.work()


async def _cruise(ctl: RobotController, msg: Any, actor: str | None) -> None:
    if ctl.rt.localisation.lost:
        raise Conflict(
            f"{ctl.name} is not sure where it is: set where the robot is on the map first",
            robot=ctl.name,
            reason="lost",
        )
    crew = ctl.crew
    for place in msg.route:
        crew.places.waypoint(place)  # NotFound names a place that does not exist
    task = await crew.store.rounds.create_cruise(ctl.name, msg.route, now=crew.clock.epoch())
    taken = await crew.trips.take(task.id, ctl.name)
    if taken is None:  # pragma: no cover - the robot's lock is held: nobody else takes it
        raise Conflict(f"robot {ctl.name} was given another trip", robot=ctl.name)
    ctl.rt.trip_kind = TaskKind.CRUISE
    await ctl.event(Event.DISPATCH)
    await ctl.drive(ctl.stop_dest(taken))


#: Action -> what it does (``save_waypoint`` is the core's: it creates a waypoint).
ACTIONS: dict[Action, ActionHandler] = {
    Action.AUTO: _auto,
    Action.MANUAL: _manual,
    Action.TELEOP: _teleop,
    Action.INITIALPOSE: _initial_pose,
    Action.GOAL: _goal,
    Action.GOTO: _goto,
    Action.READY: _ready,
    Action.NEXT: _next,
    Action.GO: _go,
    Action.SKIP: _skip,
    Action.STOP: _stop,
    Action.CONTINUE: _continue,
    Action.CANCEL: _cancel,
    Action.CHARGE: _charge,
    Action.WORK: _work,
    Action.CRUISE: _cruise,
}
