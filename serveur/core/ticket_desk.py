"""Tickets from the till become orders: the printer port's jobs, the order-intake API's
requests, and the owner's set-up (``till`` verb).

A job from the till (:mod:`serveur.till.tap` hands its bytes in) is kept before anything reads
it, decoded into tickets (:mod:`serveur.till.escpos`) and each ticket read with the owner's
pattern (:mod:`serveur.till.pattern`): its dishes become ``ordered`` orders on its table, once
(a reprint finds the first ticket: :mod:`serveur.store.tickets`), a void ticket withdraws
dishes, and a ticket nobody can read stays ``unread`` with the problem in words and a
``ticket_unread`` alert until staff add its dishes by hand or the owner's pattern reads it.
Nothing the till sends is dropped or guessed at.

The till's names for items are the menu's dishes where the owner mapped them or where they are
spelt the same (:mod:`serveur.till.names`); an unknown name is kept as the till printed it.
"""

from __future__ import annotations

import asyncio
import hashlib
import logging
from collections.abc import Awaitable, Callable
from typing import Any, Final, Protocol

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.alerts import TillFacts
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.domain import Order, TicketStatus, TillTicket
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store.base import NewDish, Store
from serveur.till.escpos import ENCODINGS, decode_job
from serveur.till.names import dish_for, fold, parse_menu_csv, suggest
from serveur.till.pattern import (
    DishLine,
    Mark,
    MarkAs,
    PatternError,
    Reading,
    TicketPattern,
    propose,
)
from serveur.till.tap import TapStatus

__all__ = ["Tap", "TicketDesk"]

log = logging.getLogger(__name__)

#: Tickets a preview reads (the newest).
PREVIEW: Final = 50
#: Jobs larger than this (bytes) are decoded on a worker thread.
_DECODE_ON_LOOP: Final = 2048
_NO_PATTERN: Final = "no ticket pattern yet: the owner sets it up in the console (Till)"


class Tap(Protocol):
    """The printer port (:class:`serveur.till.tap.PrinterTap`), as the desk drives it."""

    async def configure(self, port: int, printer: str) -> None: ...

    def status(self) -> TapStatus: ...


class TicketDesk:
    """The till's tickets, its set-up and its item names."""

    def __init__(self, store: Store, clock: Clock, *, places: Places, publisher: Publisher) -> None:
        self._store = store
        self._clock = clock
        self._places = places
        self._publisher = publisher
        self.tap: Tap | None = None
        self.port = 0
        self.printer = ""
        self.encoding = "auto"
        self.pattern: TicketPattern | None = None
        self._names: dict[str, str] = {}
        self._unread: set[int] = set()

    async def start(self) -> None:
        saved = await self._store.tickets.settings()
        self.port = int(saved.get("port", 0))
        self.printer = str(saved.get("printer", ""))
        self.encoding = str(saved.get("encoding", "auto"))
        rules = saved.get("pattern")
        if rules:
            try:
                self.pattern = TicketPattern.from_dict(rules)
            except PatternError as exc:  # a pattern saved by an older version, say
                log.error("the saved ticket pattern is unusable: %s", exc)
        self._names = await self._store.tickets.names()
        self._unread = {t.id for t in await self._store.tickets.unread()}
        if self.tap is not None:
            await self.tap.configure(self.port, self.printer)

    # -- what others read -------------------------------------------------------------------

    def state(self) -> dict[str, Any]:
        tap = self.tap.status() if self.tap is not None else TapStatus()
        return {
            "port": self.port,
            "printer": self.printer,
            "encoding": self.encoding,
            "pattern": self.pattern.as_dict() if self.pattern else None,
            "listening": tap.listening,
            "printer_up": tap.printer_up if self.printer else None,
            "error": tap.error,
        }

    def facts(self) -> TillFacts:
        tap = self.tap.status() if self.tap is not None else TapStatus()
        down = self.printer if self.printer and tap.printer_up is False else None
        return TillFacts(tuple(sorted(self._unread)), down)

    def tap_changed(self) -> None:
        """The printer port opened, closed, or found the kitchen printer up or down."""
        self._publisher.pub("till", self.state())

    async def snapshot(self) -> list[TillTicket]:
        """The ``tickets`` topic's: the unread ones and the latest."""
        latest = await self._store.tickets.recent(limit=PREVIEW)
        unread = await self._store.tickets.unread()
        seen = {t.id for t in latest}
        return sorted([*latest, *(t for t in unread if t.id not in seen)], key=lambda t: t.id)

    # -- a job from the printer port --------------------------------------------------------

    async def take_job(self, source: str, data: bytes) -> list[TillTicket]:
        """Keep a print job, then read each of its tickets; the tickets as they ended."""
        if len(data) > _DECODE_ON_LOOP:
            # A byte loop in Python: 0.4 ms a kilobyte here, 3-4x that on a Pi: off the loop.
            printed = await asyncio.to_thread(decode_job, data, self.encoding)
        else:
            printed = decode_job(data, self.encoding)
        if not printed:  # a status request, an empty job: nothing printed, nothing kept
            return []
        tickets = await self._store.tickets.add_job(
            source, data, [t.text for t in printed], now=self._clock.epoch()
        )
        return [await self._take(t) for t in tickets]

    async def _take(self, ticket: TillTicket) -> TillTicket:
        if self.pattern is None:
            return await self._unreadable(ticket, None, _NO_PATTERN)
        reading = self.pattern.read(ticket.lines)
        return await self._apply(ticket, reading, reading.key())

    async def _unreadable(
        self, ticket: TillTicket, reading: Reading | None, problem: str
    ) -> TillTicket:
        done = await self._store.tickets.mark_unread(
            ticket.id, reading.as_dict() if reading else None, problem, now=self._clock.epoch()
        )
        self._unread.add(done.id)
        log.warning("ticket %d from the till not understood: %s", done.id, problem)
        self._publisher.pub("tickets", done)
        return done

    async def _apply(self, ticket: TillTicket, reading: Reading, key: str) -> TillTicket:
        if reading.problem is not None:
            return await self._unreadable(ticket, reading, reading.problem)
        table = reading.table or ""
        if not self._places.is_table(table):
            return await self._unreadable(ticket, reading, f"{table} is not a table of the map")
        menu = [m.dish for m in await self._store.service.list_menu()]
        dishes = [
            NewDish(
                dish_for(d.name, self._names, menu) or d.name,
                d.quantity,
                ", ".join(d.notes)[:200] or None,
            )
            for d in reading.dishes
        ]
        now = self._clock.epoch()
        tickets = self._store.tickets
        if reading.void:
            done, changed, _ = await tickets.void(
                ticket.id, key, table, reading.as_dict(), dishes, now=now
            )
        else:
            done, changed = await tickets.order(
                ticket.id, key, table, reading.as_dict(), dishes, now=now
            )
        self._unread.discard(done.id)
        self._publisher.pub("tickets", done)
        for order in changed:
            self._publisher.pub("orders", order)
        await self._publisher.flush_events()
        return done

    # -- the order-intake API ---------------------------------------------------------------

    async def take_request(
        self, source: str, token_id: int, req: P.IntakeOrder
    ) -> tuple[bool, TillTicket, list[Order]]:
        """An integration's request: (created, its ticket, its orders). The same key again
        with the same content is the first request's answer, stored once."""
        reading = Reading(
            req.table,
            tuple(_dish_line(i, d) for i, d in enumerate(req.dishes)),
            req.ticket,
            req.void,
        )
        key = "api-" + hashlib.sha256(f"{token_id}\0{req.key}".encode()).hexdigest()[:32]
        first = await self._store.tickets.first(key)
        if first is not None:
            if first.reading != reading.as_dict():
                raise Conflict(f"key {req.key!r} was already used for another request", key=req.key)
            return False, first, await self._store.tickets.orders_of(first.id)
        if not self._places.is_table(req.table):
            raise NotFound(f"no table {req.table}", table=req.table)
        lines = _lines_of(reading)
        (ticket,) = await self._store.tickets.add_job(
            source, "\n".join(lines).encode(), ["\n".join(lines)], now=self._clock.epoch()
        )
        done = await self._apply(ticket, reading, key)
        if done.status is TicketStatus.REPRINT and done.of_ticket is not None:
            # Two retries racing: the first stored wins, this one answers with its orders.
            first_ticket = await self._store.tickets.get(done.of_ticket)
            return False, first_ticket, await self._store.tickets.orders_of(first_ticket.id)
        return True, done, await self._store.tickets.orders_of(done.id)

    # -- the till verb ----------------------------------------------------------------------

    async def handle(self, msg: Any, actor: str | None) -> dict[str, Any]:
        action: Callable[[TicketDesk, Any, str], Awaitable[dict[str, Any]]] = _ACTIONS[type(msg)]
        return await action(self, msg, actor or "someone")

    async def _state(self, msg: P.TillState, actor: str) -> dict[str, Any]:
        return {"till": self.state()}

    async def _tickets(self, msg: P.TillTickets, actor: str) -> dict[str, Any]:
        found = await self._store.tickets.recent(
            status=msg.status, before=msg.before, limit=msg.limit
        )
        return {"tickets": found}

    async def _by_hand(self, msg: P.TillByHand, actor: str) -> dict[str, Any]:
        done = await self._store.tickets.handled(msg.ticket, by=actor, now=self._clock.epoch())
        self._unread.discard(done.id)
        self._publisher.pub("tickets", done)
        return {"ticket": done}

    async def _propose(self, msg: P.TillPropose, actor: str) -> dict[str, Any]:
        ticket = await self._store.tickets.get(msg.ticket)
        marks = [Mark(m.line, MarkAs(m.as_), m.table) for m in msg.marks]
        for m in marks:
            if m.as_ is MarkAs.TABLE and m.table is not None and not self._places.is_table(m.table):
                raise NotFound(f"no table {m.table}", table=m.table)
        try:
            pattern = propose(ticket.lines, marks)
        except PatternError as exc:
            raise InvalidField(str(exc), field="marks") from None
        return {"pattern": pattern.as_dict(), "preview": await self._preview_of(pattern)}

    async def _preview(self, msg: P.TillPreview, actor: str) -> dict[str, Any]:
        pattern = _pattern_of(msg.pattern)
        return {"preview": await self._preview_of(pattern)}

    async def _preview_of(self, pattern: TicketPattern) -> list[dict[str, Any]]:
        tickets = await self._store.tickets.recent(limit=PREVIEW)
        return [
            {"ticket": t.id, "reading": pattern.read(t.lines).as_dict()}
            for t in tickets
            if not t.source.startswith("api ")
        ]

    async def _setup(self, msg: P.TillSetup, actor: str) -> dict[str, Any]:
        values: dict[str, Any] = {}
        if msg.port is not None:
            if msg.port and msg.port < 1024:
                raise InvalidField("the printer port is 0 (off) or 1024 to 65535", field="port")
            values["port"] = msg.port
        if msg.printer is not None:
            values["printer"] = msg.printer
        if msg.encoding is not None:
            if msg.encoding not in ENCODINGS:
                raise InvalidField(f"unknown code page {msg.encoding}", field="encoding")
            values["encoding"] = msg.encoding
        pattern = self.pattern
        if msg.pattern is not None and msg.clear_pattern:
            raise InvalidField("give a pattern or clear it, not both", field="clear_pattern")
        if msg.pattern is not None:
            pattern = _pattern_of(msg.pattern)
            values["pattern"] = pattern.as_dict()
        elif msg.clear_pattern:
            pattern = None
            values["pattern"] = None
        if not values:
            raise InvalidField("setup names nothing to change", field="action")
        await self._store.tickets.put_settings(values, now=self._clock.epoch(), by=actor)
        self.port = int(values.get("port", self.port))
        self.printer = str(values.get("printer", self.printer))
        self.encoding = str(values.get("encoding", self.encoding))
        self.pattern = pattern
        if self.tap is not None and ("port" in values or "printer" in values):
            await self.tap.configure(self.port, self.printer)
        read: list[int] = []
        if "pattern" in values and pattern is not None:
            for t in await self._store.tickets.unread():
                done = await self._take(t)
                if done.status in (TicketStatus.ORDERED, TicketStatus.VOID):
                    read.append(done.id)
        self._publisher.pub("till", self.state())
        return {"till": self.state(), "read": read}

    async def _import_menu(self, msg: P.TillImportMenu, actor: str) -> dict[str, Any]:
        try:
            rows = parse_menu_csv(msg.csv)
        except ValueError as exc:
            raise InvalidField(str(exc), field="csv") from None
        menu = [m.dish for m in await self._store.service.list_menu()]
        on_menu = {fold(d): d for d in menu}
        mapping: dict[str, str | None] = {}
        out: list[dict[str, Any]] = []
        for row in rows:
            dish = on_menu.get(fold(row.dish)) if row.dish else dish_for(row.till, {}, menu)
            if dish is not None:
                mapping[row.till] = dish
                out.append({"till": row.till, "dish": dish, "status": "mapped", "suggestions": []})
                continue
            options = suggest(row.dish or row.till, menu)
            status = "suggested" if options else "unknown"
            out.append({"till": row.till, "dish": None, "status": status, "suggestions": options})
        if mapping:
            self._names = await self._store.tickets.set_names(
                mapping, now=self._clock.epoch(), by=actor
            )
        return {"names": self._names, "rows": out}

    async def _map(self, msg: P.TillMap, actor: str) -> dict[str, Any]:
        menu = {m.dish for m in await self._store.service.list_menu()}
        unknown = sorted(d for d in msg.names.values() if d is not None and d not in menu)
        if unknown:
            raise NotFound(f"not on the menu: {', '.join(unknown)}", dishes=unknown)
        self._names = await self._store.tickets.set_names(
            dict(msg.names), now=self._clock.epoch(), by=actor
        )
        return {"names": self._names}

    async def _unmapped(self, msg: P.TillUnmapped, actor: str) -> dict[str, Any]:
        menu = [m.dish for m in await self._store.service.list_menu()]
        printed: dict[str, str] = {}
        for t in await self._store.tickets.recent(limit=200):
            for d in (t.reading or {}).get("dishes", []):
                name = str(d.get("name", ""))
                if name and dish_for(name, self._names, menu) is None:
                    printed.setdefault(fold(name), name)
        names: list[dict[str, Any]] = [
            {"till": n, "suggestions": suggest(n, menu)} for n in sorted(printed.values())
        ]
        return {"unmapped": names}


def _dish_line(i: int, d: P.IntakeDish) -> DishLine:
    notes = (d.note,) if d.note else ()
    return DishLine(d.quantity, d.dish, notes, i)


def _lines_of(reading: Reading) -> list[str]:
    """An API request as a ticket would print it, for the kitchen screen and the record."""
    lines = [f"Ticket {reading.ticket}"] if reading.ticket else []
    lines.append(f"Table {reading.table}")
    if reading.void:
        lines.append("VOID")
    for d in reading.dishes:
        lines.append(f"{d.quantity} x {d.name}")
        lines.extend(f"  - {n}" for n in d.notes)
    return lines


def _pattern_of(rules: P.TillPattern) -> TicketPattern:
    try:
        return TicketPattern.from_dict(rules.rules())
    except PatternError as exc:
        raise InvalidField(str(exc), field="pattern") from None


_ACTIONS: Final[dict[type, Any]] = {
    P.TillState: TicketDesk._state,
    P.TillTickets: TicketDesk._tickets,
    P.TillByHand: TicketDesk._by_hand,
    P.TillPropose: TicketDesk._propose,
    P.TillPreview: TicketDesk._preview,
    P.TillSetup: TicketDesk._setup,
    P.TillImportMenu: TicketDesk._import_menu,
    P.TillMap: TicketDesk._map,
    P.TillUnmapped: TicketDesk._unmapped,
}
