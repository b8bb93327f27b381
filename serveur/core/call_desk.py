"""Guests' calls: opened from a table screen, a Wi-Fi button or by staff; shown and sounded on
every console (the ``calls`` topic); answered or cancelled by staff, or answered by the robot
sent to take the plates; escalated when nobody answers in time.

The rules are :mod:`serveur.core.calls`' (pure); this is the desk that applies them with the
store, the screens and the dispatcher. A plates call sends a bussing trip at once when the
restaurant has a dish return (a place of kind ``dish_return``): the trip is queued like any
other, and the dispatcher decides when it may leave (:func:`serveur.scheduler.may_bus`).
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from typing import Any

from serveur.clock import Clock
from serveur.core.calls import (
    BUTTON_PREFIX,
    ButtonLimits,
    button_digest,
    due,
    new_button_token,
)
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig
from serveur.domain import Call, CallButton, CallKind, Task, TaskStatus, WaypointKind
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.base import Store

__all__ = ["CALL_PATH", "CallDesk", "Press"]

log = logging.getLogger(__name__)

#: The address a Wi-Fi button requests: ``GET /call/<token>`` (``?kind=bill`` may override
#: the button's own kind).
CALL_PATH = "/call/"


class Press:
    """What a button's HTTP request is answered: a status code and a short plain text (what
    the button's log shows)."""

    __slots__ = ("retry_after", "status", "text")

    def __init__(self, status: int, text: str, retry_after: int = 0) -> None:
        self.status, self.text, self.retry_after = status, text, retry_after


class CallDesk:
    """Open calls, the buttons, and what answering one does."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: CoreConfig,
        *,
        places: Places,
        publisher: Publisher,
        kick: Callable[[], None],
    ) -> None:
        self._store = store
        self._clock = clock
        self._config = config
        self._places = places
        self._publisher = publisher
        self._kick = kick
        self._limits = ButtonLimits()
        #: The open calls by id (loaded at start, kept as they change): the topic's snapshot
        #: and what the watch escalates, without a query a second.
        self.open: dict[int, Call] = {}

    async def start(self) -> None:
        self.open = {c.id: c for c in await self._store.calls.open_calls()}

    async def reload(self) -> None:
        """Read the open calls again (a table renamed or removed moved or cancelled some in
        the store): the screens are told each one that changed."""
        before = self.open
        self.open = {c.id: c for c in await self._store.calls.open_calls()}
        for call_id, old in before.items():
            now = self.open.get(call_id)
            if now is None:
                self._publisher.pub("calls", await self._store.calls.get(call_id))
            elif now != old:
                self._publisher.pub("calls", now)

    def snapshot(self) -> list[Call]:
        return sorted(self.open.values(), key=lambda c: c.id)

    def _table(self, name: str) -> None:
        wp = self._places.waypoint(name)  # NotFound for a table that does not exist
        if wp.kind is not WaypointKind.TABLE:
            raise InvalidField(
                f"{name} is not a table (it is a {wp.kind.value})", field="table", table=name
            )

    def _changed(self, call: Call) -> Call:
        if call.answered_at is None and call.cancelled_at is None:
            self.open[call.id] = call
        else:
            self.open.pop(call.id, None)
        self._publisher.pub("calls", call)
        return call

    # -- calls ------------------------------------------------------------------------------

    async def call(self, table: str, kind: CallKind, source: str) -> dict[str, Any]:
        """Open a call (or merge it into the open one); a plates call sends a bussing trip."""
        self._table(table)
        now = self._clock.epoch()
        call, merged = await self._store.calls.open_call(table, kind, source, now=now)
        if not merged:
            log.info("call %d: %s at %s (%s)", call.id, kind.value, table, source)
        if kind is CallKind.PLATES and not await self._robot_coming(call):
            # A new plates call, or one whose trip was cancelled (its table blocked, its robot
            # taken by staff): pressed again, a robot is sent again.
            call = await self._send_bussing(call)
        return {"call": self._changed(call), "merged": merged}

    async def _robot_coming(self, call: Call) -> bool:
        if call.task_id is None:
            return False
        task = await self._store.tasks.get_task(call.task_id)
        return task.status in (TaskStatus.QUEUED, TaskStatus.ACTIVE)

    async def _send_bussing(self, call: Call) -> Call:
        dish_return = self.dish_return()
        if dish_return is None:
            return call  # staff take the plates: the call waits for them like a waiter call
        task = await self._store.rounds.create_bussing(
            [call.table], dish_return, now=self._clock.epoch()
        )
        self._publisher.pub_task(task)
        self._kick()
        return await self._store.calls.set_task(call.id, task.id)

    def dish_return(self) -> str | None:
        """The restaurant's dish return (the first by name if it has several), or None."""
        found = sorted(
            n for n, wp in self._places.waypoints.items() if wp.kind is WaypointKind.DISH_RETURN
        )
        return found[0] if found else None

    async def bussing(self, tables: list[str], key: str | None) -> Task:
        """Staff send a robot for these tables' used dishes (``create bussing``)."""
        for t in tables:
            self._table(t)
        dish_return = self.dish_return()
        if dish_return is None:
            raise Conflict(
                "the restaurant has no dish return: add a place of kind dish_return first",
                reason="no_dish_return",
            )
        task = await self._store.rounds.create_bussing(
            tables, dish_return, key=key, now=self._clock.epoch()
        )
        self._publisher.pub_task(task)
        self._kick()
        return task

    async def answer(self, call_id: int, by: str | None) -> dict[str, Any]:
        call = await self._store.calls.close(call_id, "answered", by, now=self._clock.epoch())
        return {"call": self._changed(call)}

    async def cancel(self, call_id: int, by: str | None) -> dict[str, Any]:
        call = await self._store.calls.close(call_id, "cancelled", by, now=self._clock.epoch())
        if call.task_id is not None:
            task = await self._store.tasks.get_task(call.task_id)
            if task.robot is None and task.status.value == "queued":
                # Not under way: nobody needs it any more. A robot already on its way goes
                # on (staff may cancel its trip on the console).
                task = await self._store.tasks.cancel_task(
                    task.id, now=self._clock.epoch(), reason=f"call {call_id} cancelled"
                )
                self._publisher.pub_task(task)
        return {"call": self._changed(call)}

    async def robot_at(self, task_id: int, table: str, robot: str) -> None:
        """A bussing robot reached ``table``: the plates call it was sent for is answered."""
        for call in list(self.open.values()):
            if call.task_id == task_id and call.table == table:
                try:
                    done = await self._store.calls.close(
                        call.id, "answered", f"robot:{robot}", now=self._clock.epoch()
                    )
                except Conflict:
                    continue  # answered by staff meanwhile
                self._changed(done)

    async def escalate_due(self) -> None:
        """Escalate the calls nobody answered within the site's ``call_escalate``."""
        now = self._clock.epoch()
        for call_id in due(self.open.values(), now, self._config.call_escalate):
            call = await self._store.calls.escalate(call_id, now=now)
            if call is not None:
                log.warning("call %d: nobody answered %s at %s", call.id, call.kind, call.table)
                self._changed(call)
            else:  # closed meanwhile by another path: re-read it
                self._changed(await self._store.calls.get(call_id))

    def escalated(self) -> list[Call]:
        return [c for c in self.open.values() if c.escalated_at is not None]

    # -- buttons ----------------------------------------------------------------------------

    async def add_button(self, name: str, table: str, kind: CallKind) -> dict[str, Any]:
        self._table(table)
        token = new_button_token()
        button = await self._store.calls.add_button(
            name, table, kind, button_digest(token), now=self._clock.epoch()
        )
        return {"button": button, "token": token, "path": CALL_PATH + token}

    async def buttons(self) -> dict[str, Any]:
        return {"buttons": await self._store.calls.buttons()}

    async def revoke_button(self, name: str) -> dict[str, Any]:
        button = await self._store.calls.revoke_button(name, now=self._clock.epoch())
        self._limits.forget(name)
        return {"button": button}

    async def press(self, token: str, kind: str | None) -> Press:
        """A button's ``GET /call/<token>``: a call, merged, or refused (nothing changed)."""
        button: CallButton | None = None
        if token.startswith(BUTTON_PREFIX) and len(token) <= 100:
            button = await self._store.calls.button_by_digest(button_digest(token))
        if button is None or button.revoked_at is not None:
            return Press(404, "unknown or revoked button\n")
        wanted = button.kind
        if kind is not None:
            try:
                wanted = CallKind(kind)
            except ValueError:
                return Press(400, f"kind must be one of {', '.join(k.value for k in CallKind)}\n")
        wait = self._limits.allow(button.name, self._clock.now())
        if wait > 0:
            # Whole wall seconds (a demo's clock runs faster), rounded up: "try again in 0 s"
            # would be pressed again at once.
            secs = max(1, math.ceil(self._clock.wall(wait)))
            return Press(429, f"too many presses: try again in {secs} s\n", retry_after=secs)
        try:
            made = await self.call(button.table, wanted, f"button:{button.name}")
        except (NotFound, InvalidField) as exc:  # its table was removed since
            return Press(409, f"{exc}\n")
        await self._store.calls.pressed(button.name, now=self._clock.epoch())
        call: Call = made["call"]
        word = "already called" if made["merged"] else "called"
        return Press(200, f"{word}: {call.kind.value} at {call.table} (call {call.id})\n")
