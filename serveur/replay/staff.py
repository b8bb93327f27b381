"""The replayed staff: the kitchen's pass, the carts each policy's staff confirm, rescues.

Split from :mod:`serveur.replay.service` because this is the part the comparison is about — what
people at the pass do under each policy — and it reads best on its own. :class:`Staff` acts
only through a :class:`~serveur.replay.client.Console` (the robots and trips the server's
updates show, and protocol instructions); the service tells it when a robot leaves or comes
back (:meth:`Staff.robot_left`, :meth:`Staff.robot_home`), when the pass is worth another
look (:meth:`Staff.look_again`), when a robot waits at the pass for its trays
(:meth:`Staff.robot_loading`) and when a dish came back from a cancelled trip or a table that
timed out (:meth:`Staff.on_order`).

The server runs as a site does: a trip given to a robot waits at the pass (``Loading``) until
staff have loaded its trays and pressed Go; staff take
:func:`serveur.replay.model.loading_time` for it (a fixed part and a part per plate, seeded).
A dish returned from a table nobody collected at comes back on its robot: once that robot is
at the pass again, staff send it again (``dish`` ``ready``: pending, then a new cart). The
kitchen puts each dish on the pass at its ready time (``create order``, pending); with
``kitchen_ahead`` it enters it that many seconds earlier (``ordered``) and marks it ready at
its time, so that the server knows food is coming.

* the ``baseline`` staff fill each cart first-in first-out up to the tray's tables
  (:func:`serveur.scheduler.fifo_cart`, the design report);
* the ``serveur`` staff follow :func:`serveur.scheduler.suggest_carts`: each table on the
  trip that collects it soonest (a free robot now, or one due back from its trip), with a
  hold for a table's next dish seen on the kitchen display.

With calls on, :class:`Floor` is the staff on the floor: they answer the guests' waiter and
bill calls the console shows (:func:`serveur.replay.model.answer_delay`) and empty bussing
robots at the dish return (:func:`serveur.replay.model.unload_time`). The pass counts only
delivery trips as waiting for a robot, and never puts a dish on a bussing trip.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import math
from collections.abc import Callable, Coroutine, Sequence
from functools import partial
from typing import Any

from serveur.replay.client import WAIT, Console, ReplayError
from serveur.replay.model import ReplayOptions, answer_delay, loading_time, unload_time
from serveur.replay.orders import LogOrder
from serveur.scheduler import Dish, TripEstimate, fifo_cart, suggest_carts

__all__ = ["MAX_CART", "Floor", "Staff"]

MAX_CART = 50  # dishes in one ``create task`` (protocol limit)


class Staff:
    """The kitchen and the staff at the pass, for one policy, over one order log.

    ``line_of`` (server order id -> log line) is filled as the kitchen creates dishes; the
    guests key their dwell by it and the service its records. :attr:`recoveries` counts the
    robots staff had to take in manual control, :attr:`loaded` each trip's loading time
    (task id -> s, Go pressed), :attr:`resent` the returned dishes sent again. ``spawn`` runs
    a player's job (loading a robot, sending dishes again) beside the pass's loop.
    """

    def __init__(
        self,
        console: Console,
        log: Sequence[LogOrder],
        opts: ReplayOptions,
        policy: str,
        finished: asyncio.Event,
        spawn: Callable[[Coroutine[Any, Any, None]], None],
    ) -> None:
        self.console = console
        self.log = log
        self.opts = opts
        self.policy = policy
        self.finished = finished
        self.spawn = spawn
        self.line_of: dict[int, int] = {}  # server order id -> log line (dwell key)
        self.ready_of: dict[int, float] = {}  # server order id -> log ready_at (service s)
        self.first_ready: dict[int, float] = {}  # server order id -> its first ready stamp
        self.task_of: dict[int, int] = {}  # server order id -> the trip it last rode
        self.returned: dict[str, list[int]] = {}  # robot -> dishes it brings back to the pass
        self.coming_back: set[int] = set()  # returned dishes not yet sent again
        self.loading: set[int] = set()  # trips being loaded
        self.loaded: dict[int, float] = {}
        self.resent = 0
        self.pending: dict[int, Dish] = {}  # server order id -> dish, not yet carted
        self.created = 0  # dishes of the log the kitchen has put on the pass
        self.announced = 0  # ... has entered as ordered (opts.kitchen_ahead)
        self.ordered: dict[int, int] = {}  # log line -> order id, entered but not ready
        self.carted: set[int] = set()
        self.eta: dict[str, float] = {}  # busy robot -> when staff expect it back (service s)
        self.retries: dict[str, int] = {}
        self.recoveries = 0
        self.cleared = 0  # blocked tables staff cleared (a robot gave up on one)
        self.joined = 0  # dishes put on a trip still at the pass
        self.wake = asyncio.Event()

    # what the service tells the staff ----------------------------------------------------

    def look_again(self) -> None:
        """A robot freed or taken: the staff look at the pass again."""
        self.wake.set()

    def robot_left(self, name: str, robot: dict[str, Any]) -> None:
        """When staff expect a robot that just left to be back, from its trip's stops.

        What a waiter sees on the console (the trip's tables and dishes) and a rule of
        thumb per leg and per stop (:class:`serveur.scheduler.TripEstimate`); the serveur
        staff use it to decide whether a table should wait for that robot.
        """
        c = self.console
        task = c.tasks.get(robot.get("current_task") or -1)
        home = robot.get("home")
        if task is None or not home:
            return
        stops = [(s["table"], len(s["orders"])) for s in task["stops"]]
        dishes = sum(n for _, n in stops)
        loading = 0.0
        if robot.get("status") == "Loading":  # staff's rule of thumb: the model's mean
            loading = self.opts.load_fixed + self.opts.load_per_dish * dishes
        self.eta[name] = c.now() + loading + TripEstimate().trip(home, stops, c.distance)

    def robot_home(self, name: str) -> None:
        """The robot is back at the pass: nobody expects it anymore, and the dishes it
        brought back from a table that timed out are sent again."""
        self.eta.pop(name, None)
        self._unload(name)

    def _unload(self, name: str) -> None:
        back = self.returned.pop(name, [])
        if back:
            self.spawn(self._send_again(back))

    def robot_loading(self, name: str, robot: dict[str, Any]) -> None:
        """A trip waits at the pass on ``name``: staff load its trays, then press Go."""
        self._unload(name)  # at the pass: what it brought back is taken off first
        task = robot.get("current_task")
        if task is not None and task not in self.loading:
            self.loading.add(task)
            self.spawn(self._load(name, task))

    def on_order(self, order: dict[str, Any]) -> None:
        """A dish back to ``pending`` (its trip cancelled, or sent again after it was
        returned) goes on a new cart; a returned dish rides back to the pass on its robot."""
        oid = order["id"]
        if order.get("task_id") is not None:
            self.task_of[oid] = order["task_id"]
        status = order["status"]
        if status == "pending" and oid in self.carted and oid in self.line_of:
            self.carted.discard(oid)
            self.pending[oid] = Dish(oid, order["table"], self.ready_of[oid])
            self.wake.set()
        elif status == "returned" and oid in self.line_of and oid not in self.coming_back:
            self.coming_back.add(oid)  # once per return, however often the server shows it
            task = self.console.tasks.get(self.task_of.get(oid, -1), {})
            robot = task.get("robot")
            r = self.console.robots.get(robot or "", {})
            at_pass = r.get("status") in ("Awaiting", "Loading")
            if robot is None or (at_pass and r.get("current_task") != task.get("id")):
                self.spawn(self._send_again([oid]))  # its robot is at the pass already
            else:
                self.returned.setdefault(robot, []).append(oid)

    async def _load(self, robot: str, task_id: int) -> None:
        """Load the trip's plates (:func:`loading_time`), then press Go for it. A plate put
        on the trip while it loads (:meth:`_join`) takes its own :func:`loading_time` share."""
        c = self.console
        await c.until(lambda: task_id in c.tasks and c.tasks[task_id]["stops"], f"trip {task_id}")

        def plates() -> int:
            return sum(len(s["orders"]) for s in c.tasks[task_id]["stops"])

        orders = [oid for s in c.tasks[task_id]["stops"] for oid in s["orders"]]
        key = min((self.line_of.get(o, 0) for o in orders), default=0)
        secs, counted = 0.0, 0
        while (n := plates()) > counted:
            more = loading_time(self.opts, key, n)
            if counted:
                more -= loading_time(self.opts, key, counted)
            await c.clock.sleep(more)
            secs, counted = secs + more, n
        try:
            await c.call("go", robot=robot, task=task_id)
        except ReplayError as exc:
            # The trip was taken back meanwhile (the robot's link was lost): nothing to send.
            if exc.code not in ("stale", "not_allowed_in_status"):
                raise
            return
        self.loaded[task_id] = secs

    async def _send_again(self, orders: list[int]) -> None:
        """Returned dishes back on the pass: ready again (pending), for a new cart."""
        for oid in orders:
            await self.console.call("dish", order=oid, action="ready", status="returned")
            self.coming_back.discard(oid)  # the server's updates up to here showed it returned
            self.resent += 1

    # the pass --------------------------------------------------------------------------

    async def run(self) -> None:
        """The pass, in simulated-time order: dishes appear, then staff decide on carts.

        One loop does both so that what is on the pass at a decision is a function of the
        decision's simulated time (every dish of the log ready by then), not of how the
        kitchen's and the staff's requests happened to interleave on the event loop. Staff
        look again at each dish's ready time, whenever a robot changes status, and every
        5 s (a held table's hold running out).
        """
        c = self.console
        ahead = self.opts.kitchen_ahead
        while not self.finished.is_set():
            nxt = self.log[self.created].ready_at if self.created < len(self.log) else math.inf
            ann = math.inf
            if ahead > 0 and self.announced < len(self.log):
                ann = self.log[self.announced].ready_at - ahead
            delay = min(nxt - c.now(), ann - c.now(), 5.0)
            self.wake.clear()
            if delay > 0:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self.wake.wait(), c.clock.wall(delay))
            t = c.now()
            if ann <= t:
                await self._announce_due(t)
            if nxt <= t:
                await self._create_due(t)
                t = max(nxt, self.log[self.created - 1].ready_at)
            if self.policy == "serveur" and self.opts.join:
                await self._join()
            for cart in self.carts(t):
                for oid in cart:
                    del self.pending[oid]
                    self.carted.add(oid)
                for i in range(0, len(cart), MAX_CART):  # the protocol's limit per cart
                    reply = await self._send_cart(cart[i : i + MAX_CART])
                    for task in reply["tasks"]:
                        c.tasks.setdefault(task["id"], task)

    async def _join(self) -> None:
        """Dishes for a table whose trip is still at the pass go on that trip: the robot
        would otherwise be back before a second one may stand at the table."""
        c = self.console
        trip_of: dict[str, int] = {}
        for t in c.tasks.values():
            if t.get("kind", "delivery") != "delivery":
                continue  # a bussing trip carries no dishes out
            robot = c.robots.get(t.get("robot") or "", {})
            if t["status"] == "queued" or (
                t["status"] == "active" and robot.get("status") == "Loading"
            ):
                for stop in t["stops"]:
                    trip_of.setdefault(stop["table"], t["id"])
        joins: dict[int, list[int]] = {}
        for d in self.pending.values():
            if d.table in trip_of:
                joins.setdefault(trip_of[d.table], []).append(d.id)
        for task_id, orders in joins.items():
            try:
                reply = await c.call("create", type="task", task=task_id, orders=orders)
            except ReplayError as exc:
                if exc.code != "stale":  # it left meanwhile: the dishes wait for a cart
                    raise
                continue
            for oid in orders:
                del self.pending[oid]
                self.carted.add(oid)
            for task in reply["tasks"]:
                c.tasks[task["id"]] = task
            self.joined += len(orders)

    async def _send_cart(self, orders: list[int]) -> dict[str, Any]:
        """``create task``; a table the server blocked after a robot gave up on it (in the
        replay, only ever another robot in the way: no chairs move) is cleared by staff, who
        see the way is free, and the cart sent again."""
        c = self.console
        for _ in range(8):
            try:
                return await c.call("create", type="task", orders=orders)
            except ReplayError as exc:
                table = exc.details.get("table")
                if exc.code != "unreachable" or not table:
                    raise
                await c.call("clear", table=table)
                self.cleared += 1
        return await c.call("create", type="task", orders=orders)

    async def _announce_due(self, t: float) -> None:
        """The kitchen: every dish of the log ready by ``t + kitchen_ahead`` is entered as
        ``ordered`` (the server then knows it is coming: a bussing trip waits for it)."""
        ahead = self.opts.kitchen_ahead
        while self.announced < len(self.log) and self.log[self.announced].ready_at - ahead <= t:
            o = self.log[self.announced]
            reply = await self.console.call(
                "create",
                type="order",
                dish=o.dish,
                table=o.table,
                key=f"log-{o.line}",
                status="ordered",
            )
            self.ordered[o.line] = reply["order"]["id"]
            self.announced += 1

    async def _create_due(self, t: float) -> None:
        """The kitchen: every dish of the log ready by ``t`` appears at the pass, in order
        (created ``pending``, or, entered ahead, marked ready)."""
        while self.created < len(self.log) and self.log[self.created].ready_at <= t:
            o = self.log[self.created]
            if o.line in self.ordered:
                oid = self.ordered.pop(o.line)
                reply = await self.console.call("dish", order=oid, action="ready")
            else:
                reply = await self.console.call(
                    "create", type="order", dish=o.dish, table=o.table, key=f"log-{o.line}"
                )
            oid = reply["order"]["id"]
            self.line_of[oid] = o.line
            self.ready_of[oid] = o.ready_at
            self.first_ready[oid] = reply["order"]["ready_at"]
            self.pending[oid] = Dish(oid, o.table, o.ready_at)
            self.created += 1

    def free_robots(self) -> int:
        """Robots Awaiting with no trip, less the delivery trips already queued for them (a
        queued bussing trip goes after the dishes: :func:`serveur.scheduler.may_bus`)."""
        c = self.console
        idle = sum(
            1 for r in c.robots.values() if r["status"] == "Awaiting" and r["current_task"] is None
        )
        return idle - sum(
            1
            for t in c.tasks.values()
            if t["status"] == "queued" and t.get("kind", "delivery") == "delivery"
        )

    def carts(self, now: float) -> list[list[int]]:
        """The carts this policy's staff confirm at ``now`` (order ids, one list per trip)."""
        free = self.free_robots()
        if free < 1 or not self.pending:
            return []
        dishes = list(self.pending.values())
        if self.opts.robots_see_each_other:
            # Robots that block each other cannot both stand at one table: staff send a
            # table's dishes once no robot is on its way to it or at it (tables_taken).
            taken = self.tables_taken()
            dishes = [d for d in dishes if d.table not in taken]
            if not dishes:
                return []
        if self.policy == "baseline":
            carts: list[list[int]] = []
            for _ in range(free):
                cart = fifo_cart(dishes, self.opts.capacity)
                if not cart:
                    break
                carts.append(cart)
                dishes = [d for d in dishes if d.id not in set(cart)]
            return carts
        horizon = now + self.opts.lookahead
        coming = [
            Dish(-1 - i, o.table, o.ready_at)
            for i, o in enumerate(self.log[self.created :])
            if o.ready_at <= horizon
        ]
        return suggest_carts(
            dishes,
            free,
            self.console.distance,
            now=now,
            origin=self._origin(),
            capacity=self.opts.capacity,
            coming=coming,
            hold=self.opts.hold,
            hold_max=self.opts.hold_max,
            busy=self._busy(now),
            rank=self.opts.rank,
        )

    def tables_taken(self) -> set[str]:
        """Tables a robot is on its way to or standing at (a stop of a queued or active
        trip not yet done or skipped; a bussing trip's once a robot took it: one still
        queued may wait long, and would hold the table's dishes back)."""
        out: set[str] = set()
        for t in self.console.tasks.values():
            if t.get("status") not in ("queued", "active"):
                continue
            if t.get("kind", "delivery") != "delivery" and t.get("status") != "active":
                continue
            for stop in t.get("stops", []):
                if stop.get("status") in ("pending", "arrived"):
                    out.add(stop["table"])
        return out

    def _busy(self, now: float) -> list[float]:
        """Seconds until each robot out on a trip is expected back at the pass.

        Only robots on a normal trip count, and only until they are 15 s late: one stuck,
        in manual control or offline may be gone for minutes, and a table left on the pass
        for it would wait while a free robot idles.
        """
        out = []
        for name, r in self.console.robots.items():
            eta = self.eta.get(name)
            if eta is None or r["status"] not in ("Loading", "Delivering", "Delivered", "Transit"):
                continue
            if now - eta <= 15.0:
                out.append(max(1.0, eta - now))
        return out

    def _origin(self) -> str:
        """Where trips start: the free robots' home spots sit at the pass; the first one's."""
        robots = sorted(self.console.robots.items())
        homes = [r["home"] for _, r in robots if r.get("home") and r["status"] == "Awaiting"]
        homes = homes or [r["home"] for _, r in robots if r.get("home")]
        return str(homes[0]) if homes else "pass"

    # rescues ---------------------------------------------------------------------------

    async def rescue(self, robot: str) -> None:
        """Staff walk over to a robot that gave up a move (10 s later) and sort it out.

        With dishes aboard they press Continue, twice at most; a robot that still fails, or
        was only going home, is taken in manual control, backed off whatever it bumped with
        the joystick and put back in automatic mode (it then drives home). Taking manual
        control cancels a trip: its dishes are pending again and go on a new cart.
        """
        with contextlib.suppress(ReplayError):  # the link dropped meanwhile: it resumes itself
            await self._rescue(robot)

    async def _rescue(self, robot: str) -> None:
        c = self.console
        await c.clock.sleep(10.0)
        r = c.robots[robot]
        if r["status"] != "Error":
            return
        tries = self.retries.get(robot, 0)
        if r["current_task"] is not None and tries < 2:
            self.retries[robot] = tries + 1
            await c.call("continue", robot=robot)
            return
        self.retries[robot] = 0
        self.recoveries += 1
        await c.call("control", robot=robot, action="manual")
        for _ in range(5):
            await c.call("control", robot=robot, action="teleop", vx=-0.25, vy=0.0, wz=0.0)
            await c.clock.sleep(0.3)
        await c.call("control", robot=robot, action="teleop", vx=0.0, vy=0.0, wz=0.0)
        await c.call("ready", robot=robot)
        await c.call("control", robot=robot, action="auto")


class Floor:
    """The staff on the floor, with calls on: they answer the guests' waiter and bill calls
    the console shows and empty bussing robots at the dish return. Plates calls are the
    robots' (the restaurant has a dish return): staff leave them be, unless the bussing trip
    sent for one was cancelled before a robot reached the table (its table blocked by a robot
    that could not get there, or the robot taken in manual control): nobody is coming then,
    and staff take the plates by hand (:meth:`trip_cancelled`).

    A call is answered :func:`~serveur.replay.model.answer_delay` after staff saw it, keyed
    by its table, kind and how many such calls the table made before (the same party's call
    is answered as fast under either policy); a bussing robot at the dish return is emptied
    in :func:`~serveur.replay.model.unload_time`, then staff press Done. :attr:`answered`
    (call id -> s staff took) and :attr:`unloaded` (trip -> s) say what they did.
    """

    def __init__(
        self,
        console: Console,
        opts: ReplayOptions,
        spawn: Callable[[Coroutine[Any, Any, None]], None],
    ) -> None:
        self.console = console
        self.opts = opts
        self.spawn = spawn
        self._seen: set[int] = set()
        self._count: dict[tuple[str, str], int] = {}
        self.answered: dict[int, float] = {}
        self.unloaded: dict[int, float] = {}

    def on_call(self, call: dict[str, Any]) -> None:
        """A call as the console shows it (the ``calls`` topic)."""
        trip = self.console.tasks.get(call.get("task_id") or -1, {})
        if call["kind"] != "plates" or trip.get("status") == "cancelled":
            self._take(call)

    def trip_cancelled(self, task_id: int) -> None:
        """A bussing trip was cancelled: an open plates call it was sent for is staff's."""
        for call in list(self.console.calls.values()):
            if call["kind"] == "plates" and call.get("task_id") == task_id:
                self._take(call)

    def _take(self, call: dict[str, Any]) -> None:
        if call["id"] in self._seen:
            return
        if call.get("answered_at") is not None or call.get("cancelled_at") is not None:
            return
        self._seen.add(call["id"])
        key = (call["table"], call["kind"])
        n = self._count[key] = self._count.get(key, 0) + 1
        self.spawn(self._answer(call["id"], f"{key[0]}:{key[1]}:{n}"))

    async def _answer(self, call_id: int, key: str) -> None:
        c = self.console
        delay = answer_delay(self.opts.seed, key)
        await c.clock.sleep(delay)
        try:
            await c.call("call", action="answer", call=call_id)
        except ReplayError as exc:
            if exc.code != "conflict":  # closed meanwhile (the guest's screen cancelled it)
                raise
            return
        self.answered[call_id] = delay

    async def unload(self, robot: str, task_id: int, seq: int, tables: int) -> None:
        """A bussing robot at the dish return (stop ``seq`` of trip ``task_id``), with the
        plates of ``tables`` tables: staff empty it, then press Done."""
        c = self.console
        secs = unload_time(self.opts, task_id, tables)
        await c.clock.sleep(secs)
        for attempt in itertools.count():
            try:
                await c.call("next", robot=robot, task=task_id, stop=seq)
                break
            except ReplayError as exc:
                if exc.code == "stale":  # it moved on (cancelled by staff): nothing to do
                    return
                # Its link dropped meanwhile (a stalled host at a high time scale): it
                # comes back Delivered at the dish return, and staff press again.
                if attempt >= 5:
                    raise
                await c.until(partial(c.status_is, robot, "Delivered"), f"{robot} back", 4 * WAIT)
        self.unloaded[task_id] = secs
