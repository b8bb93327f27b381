"""What each client instruction does: one table from message type to handler.

A message arrives parsed (a pydantic model of :mod:`serveur.protocol`, one class per verb and
sub-verb), authorised by the server. :meth:`Instructions.handle` finds its handler in
:data:`_VERBS`; a message about one robot's status (``control``, ``next``, ``stop``, ``go``,
...) is a staff action instead: checked against the robot's status under its lock and carried
out by :data:`serveur.core.actions.ACTIONS`. Adding a verb is one handler and one entry;
permissions stay in :mod:`serveur.security.auth` and the audit in the server.
"""

from __future__ import annotations

from collections.abc import Awaitable, Callable
from typing import Any, get_args

from serveur import protocol as P
from serveur.core.actions import ACTIONS
from serveur.core.call_desk import CallDesk
from serveur.core.creation import Creation
from serveur.core.places import Places
from serveur.core.robot import RobotController
from serveur.core.service import Service
from serveur.core.site import SITE_ACTIONS, Fleet, Site
from serveur.core.ticket_desk import TicketDesk
from serveur.core.traffic import Traffic
from serveur.core.trips import Trips
from serveur.domain import (
    CallKind,
    DishAction,
    MenuItem,
    OrderStatus,
    WaypointKind,
    WaypointRecord,
)
from serveur.errors import Conflict, InvalidField
from serveur.status import Action, check_allowed
from serveur.store.base import Store

__all__ = ["Instructions"]

#: ``(instructions, message, actor)`` -> the reply's payload.
Verb = Callable[["Instructions", Any, "str | None"], Awaitable[dict[str, Any]]]


class Instructions:
    """Carries out the client messages the core handles (the server keeps login, data,
    accounts, statistics and the audit search)."""

    def __init__(
        self,
        store: Store,
        *,
        fleet: Fleet,
        places: Places,
        trips: Trips,
        creation: Creation,
        service: Service,
        traffic: Traffic,
        site: Site,
        calls: CallDesk,
        tickets: TicketDesk,
    ) -> None:
        self.store = store
        self.fleet = fleet
        self.places = places
        self.trips = trips
        self.creation = creation
        self.service = service
        self.traffic = traffic
        self.site = site
        self.calls = calls
        self.tickets = tickets

    async def handle(self, msg: Any, actor: str | None, table: str | None) -> dict[str, Any]:
        """The reply payload for ``msg`` (a ServeurError if refused).

        ``table`` is set for a table screen: its ``next`` may only act on a robot serving that
        table.
        """
        verb = _VERBS.get(type(msg))
        if verb is not None:
            return await verb(self, msg, actor)
        if isinstance(msg, P.CallOpen):  # the one verb that says which screen asked
            source = "table" if table is not None else "staff"
            return await self.calls.call(msg.table, CallKind(msg.kind), source)
        action = P.action_of(msg)
        robot = P.robot_of(msg)
        if robot is None or action is None:
            raise InvalidField(f"{msg.clientmsg!r} is not the core's to carry out")
        return await self._command(self.fleet.controller(robot), action, msg, actor, table)

    async def _command(
        self,
        ctl: RobotController,
        action: Action,
        msg: Any,
        actor: str | None,
        table: str | None,
    ) -> dict[str, Any]:
        """A staff action on one robot, checked against its status under its lock."""
        async with ctl.rt.lock:
            if table is not None:
                await ctl.check_at_table(table)
            if isinstance(msg, P.TargetMsg):
                await ctl.check_target(msg)
            check_allowed(ctl.rt.state.status, action)
            await ACTIONS[action](ctl, msg, actor)
            return {"robot": ctl.view()}

    async def _create_order(self, msg: P.CreateOrder, actor: str | None) -> dict[str, Any]:
        order = await self.creation.order(
            msg.dish,
            msg.table,
            msg.key,
            quantity=msg.quantity,
            note=msg.note,
            status=OrderStatus(msg.status),
            special=msg.special,
        )
        return {"order": order}

    async def _create_dish(self, msg: P.CreateDish, actor: str | None) -> dict[str, Any]:
        item = MenuItem(
            dish=msg.name,
            category=msg.category,
            price_cents=msg.price_cents,
            available=msg.available,
            position=msg.position,
        )
        return {"dish": await self.service.put_dish(item, actor)}

    async def _create_task(self, msg: P.CreateTask, actor: str | None) -> dict[str, Any]:
        if msg.task is None:
            trays = {t.order: t.tray for t in msg.trays} if msg.trays is not None else None
            return {"tasks": await self.creation.tasks(list(msg.orders), msg.key, trays=trays)}
        # Onto a trip at the pass: under its robot's lock, so that Go waits for the dishes.
        robot = (await self.store.tasks.get_task(msg.task)).robot
        if robot is None:
            return {"tasks": [await self.creation.add(msg.task, list(msg.orders), msg.key)]}
        async with self.fleet.controller(robot).rt.lock:
            return {"tasks": [await self.creation.add(msg.task, list(msg.orders), msg.key)]}

    async def _create_waypoint(self, msg: P.CreateWaypoint, actor: str | None) -> dict[str, Any]:
        if msg.robot:
            ctl = self.fleet.controller(msg.robot)
            async with ctl.rt.lock:
                check_allowed(ctl.rt.state.status, Action.SAVE_WAYPOINT)
                if ctl.rt.pose is None:
                    raise Conflict(f"robot {ctl.name} has not reported a pose yet")
                x, y, yaw = ctl.rt.pose
        else:
            assert msg.x is not None and msg.y is not None and msg.yaw is not None
            x, y, yaw = msg.x, msg.y, msg.yaw
            self.places.check_spot(x, y)  # a robot's own pose is where a robot stood
        wp = WaypointRecord(name=msg.name, x=x, y=y, yaw=yaw, kind=WaypointKind(msg.kind))
        before = self.places.waypoints.get(msg.name)
        made = await self.creation.waypoint(wp, replace=msg.replace)
        if (
            before is not None
            and (before.x, before.y) != (x, y)
            and msg.name in self.service.blocks
        ):
            # A table blocked because no robot could reach it, moved: the block was about the
            # old spot. Robots may try the new one at once (its dishes leave the pass again).
            await self.service.clear(msg.name, actor)
        return {"waypoint": made}

    async def _create_robot(self, msg: P.CreateRobot, actor: str | None) -> dict[str, Any]:
        return await self.site.register_robot(msg)

    async def _create_zone(self, msg: P.CreateZone, actor: str | None) -> dict[str, Any]:
        return await self.traffic.create_zone(msg, actor)

    async def _order(self, msg: P.OrderMsg, actor: str | None) -> dict[str, Any]:
        if msg.table:
            self.places.waypoint(msg.table)
            return {"orders": await self.store.orders.cart(msg.table)}
        assert msg.robot is not None
        ctl = self.fleet.controller(msg.robot)
        return {"orders": await self.trips.stop_orders(ctl.name)}

    async def _dish(self, msg: P.DishMsg, actor: str | None) -> dict[str, Any]:
        order = await self.service.dish(
            msg.order,
            DishAction(msg.action),
            seen=None if msg.status is None else OrderStatus(msg.status),
            by=actor,
            quantity=msg.quantity,
            note=msg.note,
            table=msg.table,
        )
        return {"order": order}

    async def _ack(self, msg: P.AckMsg, actor: str | None) -> dict[str, Any]:
        return {"alert": await self.service.ack(msg.alert, actor or "unknown")}

    async def _clear(self, msg: P.ClearMsg, actor: str | None) -> dict[str, Any]:
        return await self.service.clear(msg.table, actor)

    async def _release(self, msg: P.ReleaseMsg, actor: str | None) -> dict[str, Any]:
        return await self.traffic.release(msg, actor)

    async def _site(self, msg: Any, actor: str | None) -> dict[str, Any]:
        return await self.site.site(msg, actor)

    async def _create_bussing(self, msg: P.CreateBussing, actor: str | None) -> dict[str, Any]:
        return {"task": await self.calls.bussing(list(msg.tables), msg.key)}

    async def _call_answer(self, msg: P.CallAnswer, actor: str | None) -> dict[str, Any]:
        return await self.calls.answer(msg.call, actor)

    async def _call_cancel(self, msg: P.CallCancel, actor: str | None) -> dict[str, Any]:
        return await self.calls.cancel(msg.call, actor)

    async def _add_button(self, msg: P.SiteAddButton, actor: str | None) -> dict[str, Any]:
        return await self.calls.add_button(msg.name, msg.table, CallKind(msg.kind))

    async def _buttons(self, msg: P.SiteButtons, actor: str | None) -> dict[str, Any]:
        return await self.calls.buttons()

    async def _revoke_button(self, msg: P.SiteRevokeButton, actor: str | None) -> dict[str, Any]:
        return await self.calls.revoke_button(msg.name)

    async def _till(self, msg: Any, actor: str | None) -> dict[str, Any]:
        return await self.tickets.handle(msg, actor)


#: Client message type -> what it does (the robot actions go through
#: :data:`serveur.core.actions.ACTIONS` once the status machine allowed them).
_VERBS: dict[type, Verb] = {
    P.CreateOrder: Instructions._create_order,
    P.CreateDish: Instructions._create_dish,
    P.CreateTask: Instructions._create_task,
    P.CreateWaypoint: Instructions._create_waypoint,
    P.CreateRobot: Instructions._create_robot,
    P.CreateZone: Instructions._create_zone,
    P.OrderMsg: Instructions._order,
    P.DishMsg: Instructions._dish,
    P.AckMsg: Instructions._ack,
    P.ClearMsg: Instructions._clear,
    P.ReleaseMsg: Instructions._release,
    P.CreateBussing: Instructions._create_bussing,
    P.CallAnswer: Instructions._call_answer,
    P.CallCancel: Instructions._call_cancel,
    P.SiteAddButton: Instructions._add_button,
    P.SiteButtons: Instructions._buttons,
    P.SiteRevokeButton: Instructions._revoke_button,
    **{cls: Instructions._site for cls in SITE_ACTIONS},
    **{cls: Instructions._till for cls in get_args(get_args(P.TillMessage)[0])},
}
