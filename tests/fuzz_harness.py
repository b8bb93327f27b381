"""Run fuzz examples (``tests/fuzz_strategies.py``) against one live restaurant, and check them.

:class:`LiveRestaurant` owns an event loop in a background thread, with a real server on a real
SQLite file and simulated robots (``tests/conftest.restaurant``), so that a synchronous caller
— a hypothesis ``@given`` test, ``bench/fuzz.py`` — can run thousands of examples against the
same server: :meth:`LiveRestaurant.run` sends one example's frames and checks every reply,
:meth:`LiveRestaurant.check` checks the database invariants (``tests/invariants.py``) while
holding every robot's lock, so no instruction is half-way.

What is checked, per frame: exactly one reply, in order (a connection's frames are answered
one at a time), ``ok`` or ``error`` shaped as the protocol's server models say, an error ``code``
from the documented list and never ``internal_error``, the request's ``id`` echoed (or none for
an unreadable frame), and no parse error for a frame the strategies know is valid (an error for
one they know is broken). Per example: the connections are still open and still answer a
``data`` request, and no ``serveur``/``websockets``/``asyncio`` logger logged an error.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import random
import re
import threading
from collections import Counter, deque
from collections.abc import AsyncIterator, Coroutine
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, TypeVar, get_args

import websockets
import websockets.asyncio.connection
import websockets.client
from pydantic import TypeAdapter, ValidationError
from websockets.asyncio.client import ClientConnection, connect

from serveur import protocol as P
from serveur.core.runtime import CoreConfig
from serveur.domain import OrderStatus, TaskStatus
from serveur.errors import Conflict
from tests import invariants
from tests.conftest import Restaurant, restaurant
from tests.fuzz_strategies import Live, Obj, Ref, Relog, Send, Step, Wait, encode

__all__ = ["ERROR_CODES", "FuzzFailure", "LiveRestaurant", "Stats", "open_connection"]

T = TypeVar("T")

#: Every documented error code (docs/protocol.md's table; protocol.ErrorCode mirrors it).
ERROR_CODES: frozenset[str] = frozenset(get_args(P.ErrorCode))
#: The codes that mean "your frame is malformed".
PARSE_ERRORS = frozenset({"bad_json", "unknown_message", "invalid_field"})
#: The ok payload field each valid message's reply carries (docs: "ok" table).
PAYLOAD = {
    "login": "session",
    "ping": "time",
    "data": "data",
    "create order": "order",
    "create task": "tasks",
    "create waypoint": "waypoint",
    "create robot": "robot",
    "order": "orders",
    "create dish": "dish",
    "dish": "order",
    "ack": "alert",
    "clear": "table",
    # owners only: the fuzz connections (staff) are refused, but were one let through...
    "account list_users": "users",
    "account add_user": "password",
    "account set_role": "user",
    "account reset_password": "password",
    "account remove_user": "user",
    "account create_token": "token",
    "account list_tokens": "tokens",
    "account revoke_token": "device",
    "site edit_robot": "robot",
    "site remove_robot": "robot",
    "site dependents": "dependents",
    "site rename_waypoint": "renamed",
    "site remove_waypoint": "waypoint",
    "site remove_zone": "zone",
    "create zone": "zone",
    "release": "broken",
    "camera": "camera",
    "site settings": "settings",
    "site set_settings": "settings",
    "site audit": "audit",
    "stats figures": "stats",
    "stats trips": "stats",
    "stats forecast": "forecast",
    "stats forecast_cancel": "forecast",
    "call open": "call",
    "call answer": "call",
    "call cancel": "call",
    "create bussing": "task",
    "site add_button": "token",
    "site buttons": "buttons",
    "site revoke_button": "button",
    "till state": "till",
    "till tickets": "tickets",
    "till by_hand": "ticket",
    "till propose": "pattern",
    "till preview": "preview",
    "till setup": "till",
    "till import_menu": "rows",
    "till map": "names",
    "till unmapped": "unmapped",
    "chain": "chain",
}
#: The owner's verbs: a fuzz connection (staff) sending one well formed is always refused
#: ``forbidden`` (or ``rate_limited``), so no robot or table is ever edited or removed, and no
#: statistics child process or forecast replay runs.
OWNER_VERBS = frozenset({"account", "site", "stats", "chain"})
REPLY_TIMEOUT = 30.0  # wall seconds; generous for a loaded 2-core box
MAX_QUEUED = 6  # trips waiting for a robot kept by housekeeping
MAX_PENDING = 40  # dishes waiting at the pass kept by housekeeping
MAX_TEXT = 60_000  # stay under the 64 KiB frame limit (beyond it the server closes: 1009)
#: The restaurant as shipped: a trip waits at the pass (Loading) for Go, a table times out.
SITE = CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=False)
_WS_RANDOM_USERS = (websockets.asyncio.connection, websockets.client)
_SERVER_MSG: TypeAdapter[Any] = TypeAdapter(P.ServerMessage)
_MISSING = object()


class FuzzFailure(AssertionError):
    """A property of the server broke; the message says which, on which frame."""


async def open_connection(r: Restaurant) -> ClientConnection:
    """The one place the fuzzer opens a websocket to the server (authentication goes here)."""
    return await connect(
        r.app.url, additional_headers=r.auth_headers(), max_size=2**24, open_timeout=REPLY_TIMEOUT
    )


@dataclass
class Stats:
    examples: int = 0
    frames: int = 0
    replies: Counter[str] = field(default_factory=Counter)  # "ok" or the error code
    labels: Counter[str] = field(default_factory=Counter)  # valid labels answered ok
    waits: Counter[str] = field(default_factory=Counter)  # "reached" / "timed out"
    statuses: Counter[str] = field(default_factory=Counter)  # robot statuses seen on updates
    checks: int = 0
    failures: list[str] = field(default_factory=list)
    last_code: str = ""  # the code of the latest reply checked
    relogins: int = 0  # connections logged in again after a fuzzed logout

    def summary(self) -> str:
        lines = [
            f"examples {self.examples}, frames {self.frames}, invariant checks {self.checks},"
            f" failures {len(self.failures)}",
            "replies: " + ", ".join(f"{k} {v}" for k, v in self.replies.most_common()),
            "ok by verb: " + ", ".join(f"{k} {v}" for k, v in sorted(self.labels.items())),
            "robot statuses seen: " + ", ".join(f"{k} {v}" for k, v in self.statuses.most_common()),
            "waits: " + ", ".join(f"{k} {v}" for k, v in sorted(self.waits.items())),
        ]
        return "\n".join(lines)


@dataclass
class Expect:
    """What the reply to one sent frame must look like."""

    label: str
    verb: str
    valid: bool | None
    id: Any  # the exact id the reply must carry (None: none), or _MISSING when unknown
    ids: tuple[Any, ...]  # ids the reply may carry when ``id`` is _MISSING (besides none)
    text: str
    code: str | None = None  # the one reply code allowed ("ok" or an error code), if known


class _Conn:
    """One fuzz connection: frames out, replies into a queue (updates only counted)."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.replies: asyncio.Queue[Any] = asyncio.Queue()
        self.pending: deque[Expect] = deque()
        self.updates = 0
        #: A fuzzed frame turned out to be a valid ``logout`` (a mutation can make one, e.g.
        #: ``next`` with its robot dropped and its tag swapped): log in before the next step.
        self.logged_out = False
        self.reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                if isinstance(frame, bytes):
                    self.replies.put_nowait(("binary frame", frame[:200]))
                    continue
                try:
                    msg = json.loads(frame)
                except ValueError:
                    self.replies.put_nowait(("not JSON", frame[:200]))
                    continue
                if isinstance(msg, dict) and msg.get("servermsg") == "update":
                    self.updates += 1
                else:
                    self.replies.put_nowait(msg)

    @property
    def open(self) -> bool:
        return self.ws.close_code is None and not self.reader.done()

    async def close(self) -> None:
        with contextlib.suppress(Exception):
            await self.ws.close()
        self.reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.reader


class _Observer:
    """Watches ``robots`` for :class:`Wait` steps and counts the statuses robots go through."""

    def __init__(self, ws: ClientConnection, stats: Stats) -> None:
        self.ws = ws
        self.stats = stats
        self.status: dict[str, str] = {}
        self.changed = asyncio.Condition()
        self.reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                msg = json.loads(frame)
                if msg.get("servermsg") == "ok" and "data" in msg:
                    robots = msg["data"].get("robots", [])
                elif msg.get("servermsg") == "update" and msg.get("topic") == "robots":
                    robots = [msg["data"]]
                else:
                    continue
                for rb in robots:
                    if self.status.get(rb["name"]) != rb["status"]:
                        self.stats.statuses[rb["status"]] += 1
                    self.status[rb["name"]] = rb["status"]
                async with self.changed:
                    self.changed.notify_all()

    async def wait(self, robot: str, statuses: frozenset[str], timeout: float) -> bool:
        async def until() -> None:
            async with self.changed:
                await self.changed.wait_for(lambda: self.status.get(robot) in statuses)

        try:
            await asyncio.wait_for(until(), timeout)
        except TimeoutError:
            return False
        return True

    async def close(self) -> None:
        await self.ws.close()
        self.reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.reader


class _ErrorLog(logging.Handler):
    """Collects ERROR records of the server's loggers (a logged exception is a bug)."""

    LOGGERS = ("serveur", "websockets", "asyncio")

    def __init__(self) -> None:
        super().__init__(logging.ERROR)
        self.records: list[str] = []

    def emit(self, record: logging.LogRecord) -> None:
        text = f"{record.name}: {record.getMessage()}"
        if record.exc_info and record.exc_info[1] is not None:
            text += f" [{type(record.exc_info[1]).__name__}: {record.exc_info[1]}]"
        self.records.append(text)

    def install(self) -> None:
        for name in self.LOGGERS:
            logging.getLogger(name).addHandler(self)

    def remove(self) -> None:
        for name in self.LOGGERS:
            logging.getLogger(name).removeHandler(self)


def _has_ref(node: Any) -> bool:
    if isinstance(node, Ref):
        return True
    if isinstance(node, Obj):
        return any(_has_ref(v) for _, v in node.pairs)
    if isinstance(node, (list, tuple)):
        return any(_has_ref(v) for v in node)
    return False


def _request_id(value: Any) -> Any:
    """The id the reply must echo for a readable frame's ``id`` value (docs: "Requests and
    replies": a string of at most 64 characters or an integer of at most 64 digits), or None."""
    if type(value) is str and len(value) <= P.MAX_NAME:
        try:
            value.encode("utf-8")
        except UnicodeEncodeError:
            return None  # not text that can be echoed in a UTF-8 frame
        return value
    if type(value) is int and len(str(abs(value))) <= 63:
        return value
    if type(value) is int and len(str(abs(value))) == 64:
        return _MISSING  # the 64-digit edge: the reply may echo it or not
    return None


def _expected_id(text: str, slot_ids: list[int], body: Any) -> tuple[Any, tuple[Any, ...]]:
    """(exact id or _MISSING, ids allowed when not exact) for the frame ``text``."""

    def dup_hook(pairs: list[tuple[str, Any]]) -> dict[str, Any]:
        if len({k for k, _ in pairs}) != len(pairs):
            raise KeyError("duplicate")
        return dict(pairs)

    # An unreadable frame's id is read "best effort" (docs): any "id" member the text shows.
    loose: tuple[Any, ...] = tuple(slot_ids)
    for m in _ID_MEMBER.finditer(text, 0, 8192):
        with contextlib.suppress(ValueError, RecursionError):
            loose += (json.loads(m.group(1)),)
    try:
        obj = json.loads(text, object_pairs_hook=dup_hook)
    except (ValueError, KeyError, RecursionError):
        return _MISSING, loose
    if not isinstance(obj, dict):
        return None, ()
    if _depth(obj) > P.MAX_DEPTH:
        return _MISSING, loose
    exact = _request_id(obj.get("id"))
    if exact is _MISSING:
        return _MISSING, (obj.get("id"),)
    return exact, ()


_ID_MEMBER = re.compile(r'"id"\s*:\s*(-?\d+|"(?:[^"\\]|\\.)*")')


def _depth(value: Any) -> int:
    best, stack = 0, [(value, 1)]
    while stack:
        item, d = stack.pop()
        if isinstance(item, dict):
            best = max(best, d)
            stack.extend((v, d + 1) for v in item.values())
        elif isinstance(item, list):
            best = max(best, d)
            stack.extend((v, d + 1) for v in item)
    return best


class LiveRestaurant:
    """One live restaurant shared by many examples; every method is called from one thread."""

    def __init__(
        self,
        tmp: Path,
        *,
        robots: int = 2,
        time_scale: float = 30.0,
        conns: int = 2,
        wait_scale: float = 1.0,
        fresh_every: int = 10,
    ) -> None:
        self.tmp = tmp
        self.robots = robots
        self.time_scale = time_scale
        self.n_conns = conns
        self.wait_scale = wait_scale  # multiplies every Wait's timeout (0: never wait)
        # New connections every few examples: subscriptions (pose, scan at 10 and 5 Hz a
        # robot) would otherwise pile up on two connections and slow everything down.
        self.fresh_every = fresh_every
        self.stats = Stats()
        self.live = Live()
        self.errors = _ErrorLog()
        self.loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self.loop.run_forever, name="fuzz-loop", daemon=True)
        self._stack = contextlib.AsyncExitStack()
        self.r: Restaurant | None = None
        self.conns: list[_Conn] = []
        self.observer: _Observer | None = None
        self._saved_random: dict[Any, Any] = {}

    # -- lifecycle ---------------------------------------------------------------------------

    def call(self, coro: Coroutine[Any, Any, T], timeout: float = 300.0) -> T:
        return asyncio.run_coroutine_threadsafe(coro, self.loop).result(timeout)

    def start(self) -> LiveRestaurant:
        self.errors.install()
        # websockets draws ping payloads and reconnect delays from the global ``random``; from
        # this background thread that would move hypothesis's global PRNG state while it
        # generates an example (it warns). Give websockets a PRNG of its own.
        for module in _WS_RANDOM_USERS:
            self._saved_random[module] = module.random
            module.random = random.Random()
        self._thread.start()
        self.call(self._start())
        return self

    async def _start(self) -> None:
        self.r = await self._stack.enter_async_context(
            restaurant(self.tmp, robots=self.robots, time_scale=self.time_scale, config=SITE)
        )
        self.observer = _Observer(await open_connection(self.r), self.stats)
        await self.observer.ws.send(json.dumps({"clientmsg": "data", "topics": ["robots"]}))
        for name in (f"r{i + 1}" for i in range(self.robots)):
            await self.observer.wait(name, frozenset({"Ready"}), REPLY_TIMEOUT)
        self.live.urls = {s.name: s.url for s in self.r.specs}
        await self._reconnect()

    async def _reconnect(self) -> None:
        assert self.r is not None
        for c in self.conns:
            await c.close()
        self.conns = [_Conn(await open_connection(self.r)) for _ in range(self.n_conns)]

    def close(self) -> None:
        try:
            self.call(self._close())
        finally:
            self.loop.call_soon_threadsafe(self.loop.stop)
            self._thread.join(30)
            self.loop.close()
            self.errors.remove()
            for module, saved in self._saved_random.items():
                module.random = saved

    async def _close(self) -> None:
        for c in self.conns:
            await c.close()
        if self.observer is not None:
            await self.observer.close()
        await self._stack.aclose()

    @property
    def db_path(self) -> Path:
        assert self.r is not None
        return Path(self.r.db)

    # -- running examples --------------------------------------------------------------------

    def run(self, steps: list[Step], *, check: bool = True) -> None:
        """Run one example; raise :class:`FuzzFailure` if any property broke."""
        try:
            self.call(self._run(steps), timeout=REPLY_TIMEOUT * (len(steps) + 4))
            if check:
                self.check()
            if self.fresh_every and (self.stats.examples + 1) % self.fresh_every == 0:
                self.call(self._reconnect())
                self.call(self._housekeep())
        except Exception as exc:
            self.stats.failures.append(f"{type(exc).__name__}: {str(exc)[:2000]}")
            self.call(self._reconnect())  # a clean start for the next example
            if isinstance(exc, AssertionError):
                raise
            raise FuzzFailure(f"{type(exc).__name__}: {exc}") from exc
        finally:
            self.stats.examples += 1

    def check(self) -> None:
        """Check the database invariants with every robot's lock held (nothing half-way)."""
        found = self.call(self._check())
        self.stats.checks += 1
        if found:
            raise invariants.InvariantViolation("\n  ".join(["invariants broken:", *found]))

    async def _check(self) -> list[str]:
        async with self._robots_locked():
            return invariants.violations(self.db_path)

    @contextlib.asynccontextmanager
    async def _robots_locked(self) -> AsyncIterator[None]:
        """Every robot's lock, in name order (the server never holds two at once)."""
        assert self.r is not None and self.r.app.core is not None
        runtimes = self.r.app.core._rt
        async with contextlib.AsyncExitStack() as stack:
            for name in sorted(runtimes):
                await stack.enter_async_context(runtimes[name].lock)
            yield

    async def _housekeep(self) -> None:
        """Keep the restaurant in a realistic regime: the kitchen withdraws the oldest carts
        and dishes beyond a backlog (store calls, as a kitchen screen would make them).

        The fuzzer queues trips far faster than two robots deliver them, and no client verb
        cancels a queued trip; without this the backlog grows without bound and every
        dispatch round and ``tasks``/``orders`` snapshot grows with it.
        """
        assert self.r is not None
        store, now = self.r.app.store, self.r.clock.epoch()
        # Under every robot's lock: a robot takes a queued trip under its lock, and
        # ``cancel_task`` also cancels an *active* trip — without the locks a trip taken
        # meanwhile would be cancelled under a Delivering robot (a harness bug, not a server one).
        async with self._robots_locked():
            queued = await store.tasks.list_tasks(status=TaskStatus.QUEUED)
            for task in queued[: max(0, len(queued) - MAX_QUEUED)]:
                await store.tasks.cancel_task(task.id, now=now, reason="fuzz: backlog")
        pending = await store.orders.list_orders(status=OrderStatus.PENDING)
        for order in pending[: max(0, len(pending) - MAX_PENDING)]:
            with contextlib.suppress(Conflict):  # put on a trip meanwhile
                await store.orders.cancel_order(order.id, now=now)

    async def _run(self, steps: list[Step]) -> None:
        assert self.observer is not None
        self.errors.records.clear()
        for step in steps:
            await self._login_logged_out()
            if isinstance(step, Wait):
                timeout = step.timeout * self.wait_scale
                reached = await self.observer.wait(step.robot, step.statuses, timeout)
                self.stats.waits["reached" if reached else "timed out"] += 1
            elif isinstance(step, Relog):
                await self._relog(step)
            else:
                await self._send(step)
        # Every connection still open and answering.
        for i, c in enumerate(self.conns):
            probe = {"clientmsg": "data", "id": "probe", "topics": ["robots"]}
            if c.open:
                await c.ws.send(json.dumps(probe))
                c.pending.append(Expect("probe", "data", True, "probe", (), json.dumps(probe)))
            await self._drain(c, i)
            if not c.open:
                raise FuzzFailure(f"connection {i} was closed by the server ({c.ws.close_code})")
            if not c.replies.empty():
                raise FuzzFailure(
                    f"connection {i}: a reply nobody asked for: {c.replies.get_nowait()}"
                )
        await self._login_logged_out()  # the example ends with every connection logged in
        if self.errors.records:
            raise FuzzFailure("the server logged errors:\n  " + "\n  ".join(self.errors.records))

    async def _send(self, step: Send) -> None:
        if _has_ref(step.body):  # ids created by frames still in flight must be known first
            for i, c in enumerate(self.conns):
                await self._drain(c, i)
        ids: list[int] = []
        text = encode(step.body, self.live, ids)
        valid = step.valid
        if step.cut is not None and step.cut < len(text):
            text, valid = text[: step.cut], False
        text = step.pad + text + step.pad
        if len(text.encode("utf-8", "surrogatepass")) > MAX_TEXT:
            text, valid = text[: MAX_TEXT // 4], False  # cut: no prefix of an object is one
        exact, loose = _expected_id(text, ids, step.body)
        if step.bad_utf8:
            exact, loose = _MISSING, tuple(ids)
        payload: str | bytes = text
        if step.binary:
            payload = text.encode("utf-8") + (b"\xff\xfe\x80" if step.bad_utf8 else b"")
        conn = self.conns[step.conn % len(self.conns)]
        conn.pending.append(Expect(step.label, step.verb, valid, exact, loose, text))
        self.stats.frames += 1
        try:
            await conn.ws.send(payload)
        except websockets.exceptions.ConnectionClosed as exc:
            raise FuzzFailure(f"connection closed by the server before {text[:300]!r}") from exc

    async def _relog(self, step: Relog) -> None:
        """Logout, a refused probe, login again (see :class:`Relog`).

        The fuzzer's wrong-credential logins may have locked this address by then; a login
        refused as ``rate_limited`` (documented: even the right token waits) is answered by
        reconnecting with the token on the handshake, which the lock does not cover.
        """
        assert self.r is not None
        index = step.conn % len(self.conns)
        conn = self.conns[index]
        await self._drain(conn, index)  # ids of earlier creates known before the probe
        ids: list[int] = []
        probe = encode(step.probe, self.live, ids)
        exact, loose = _expected_id(probe, ids, step.probe)
        frames = [
            (
                Expect("logout", "logout", True, "out", (), "logout", code="ok"),
                json.dumps({"clientmsg": "logout", "id": "out"}),
            ),
            (
                Expect(
                    f"{step.label} (logged out)",
                    step.label,
                    True,
                    exact,
                    loose,
                    probe,
                    code="unauthorized",
                ),
                probe,
            ),
            self._login_frame(),
        ]
        if conn.logged_out:  # a fuzzed logout, not yet noticed: in again first
            await self._login_again(index)
        await self._exchange(index, frames)
        await self._logged_in(index)

    def _login_frame(self) -> tuple[Expect, str]:
        """A login with the connections' token, and what its reply must be."""
        assert self.r is not None
        login = json.dumps({"clientmsg": "login", "id": "in", "token": self.r.token})
        return Expect("login", "login", True, "in", (), login), login

    async def _login_logged_out(self) -> None:
        """Log in again every connection a fuzzed ``logout`` logged out."""
        for i, c in enumerate(self.conns):
            if c.logged_out:
                await self._login_again(i)

    async def _login_again(self, index: int) -> None:
        """Log connection ``index`` in again with its token after a fuzzed ``logout``."""
        self.conns[index].logged_out = False
        self.stats.relogins += 1
        await self._exchange(index, [self._login_frame()])
        await self._logged_in(index)

    async def _exchange(self, index: int, frames: list[tuple[Expect, str]]) -> None:
        """Send each frame on connection ``index`` and check its reply before the next."""
        conn = self.conns[index]
        for expect, text in frames:
            conn.pending.append(expect)
            self.stats.frames += 1
            try:
                await conn.ws.send(text)
            except websockets.exceptions.ConnectionClosed as exc:
                raise FuzzFailure(f"connection closed by the server before {text[:300]!r}") from exc
            await self._drain(conn, index)

    async def _logged_in(self, index: int) -> None:
        """After a login with the connection's token: ok, or (the fuzzer's wrong-credential
        logins locked this address) a new connection with the token on the handshake."""
        assert self.r is not None
        if self.stats.last_code == "rate_limited":
            await self.conns[index].close()
            self.conns[index] = _Conn(await open_connection(self.r))
        elif self.stats.last_code != "ok":
            raise FuzzFailure(f"login with the connection's own token: {self.stats.last_code}")

    async def _drain(self, conn: _Conn, index: int) -> None:
        while conn.pending:
            expect = conn.pending.popleft()
            reply = await self._reply(conn)
            if reply is _MISSING:
                closed = "" if conn.open else f" (connection closed: {conn.ws.close_code})"
                raise FuzzFailure(
                    f"no reply within {REPLY_TIMEOUT}s{closed} to {expect.label}:"
                    f" {expect.text[:500]!r}"
                )
            self._check_reply(expect, reply)
            if expect.label != "logout" and reply.get("session", False) is None:
                conn.logged_out = True  # only a logout's ok reply carries "session": null

    @staticmethod
    async def _reply(conn: _Conn) -> Any:
        """The next reply on ``conn``; _MISSING after REPLY_TIMEOUT or once it is closed."""
        if not conn.replies.empty():
            return conn.replies.get_nowait()
        get = asyncio.ensure_future(conn.replies.get())
        await asyncio.wait({get, conn.reader}, timeout=REPLY_TIMEOUT, return_when="FIRST_COMPLETED")
        if get.done():
            return get.result()
        get.cancel()
        return conn.replies.get_nowait() if not conn.replies.empty() else _MISSING

    def _check_reply(self, expect: Expect, reply: Any) -> None:
        def fail(why: str) -> FuzzFailure:
            return FuzzFailure(
                f"{why}\n  frame ({expect.label}, valid={expect.valid}): {expect.text[:600]!r}"
                f"\n  reply: {str(reply)[:600]}"
            )

        if not isinstance(reply, dict):
            raise fail("the reply is not a JSON object")
        try:
            _SERVER_MSG.validate_python(reply)
        except ValidationError as exc:
            raise fail(f"the reply does not match the protocol's server models: {exc}") from None
        kind = reply["servermsg"]
        if kind not in ("ok", "error"):
            raise fail("a reply must be ok or error")
        code = "ok" if kind == "ok" else reply["code"]
        self.stats.replies[code] += 1
        self.stats.last_code = code
        if code != "ok" and code not in ERROR_CODES:
            raise fail(f"undocumented error code {code!r}")
        if code == "internal_error":
            raise fail("internal_error: a server bug")
        got = reply.get("id")
        if expect.id is not _MISSING:
            if got != expect.id or type(got) is not type(expect.id):
                raise fail(f"the reply's id is {got!r}, expected {expect.id!r}")
        elif got is not None and got not in expect.ids:
            raise fail(f"the reply's id {got!r} is none of the frame's ids {expect.ids!r}")
        if expect.code is not None and code != expect.code:
            raise fail(f"expected {expect.code!r}, got {code!r}")
        if expect.valid is True and code in PARSE_ERRORS:
            raise fail(f"a valid frame was refused as malformed ({code})")
        if expect.valid is False and code == "ok":
            raise fail("a malformed frame was accepted")
        owners = expect.verb.split(" ")[0] in OWNER_VERBS and expect.code is None
        if owners and expect.valid is True and code not in ("forbidden", "rate_limited"):
            raise fail(f"staff sent the owner's {expect.verb} and got {code}, not forbidden")
        if code == "ok" and expect.valid is True:
            self.stats.labels[expect.label] += 1
            want = PAYLOAD.get(expect.verb, "robot")
            if expect.verb == "logout":
                if "session" not in reply or reply["session"] is not None:
                    raise fail("an ok reply to logout must carry session: null")
            elif reply.get(want) is None:
                raise fail(f"an ok reply to {expect.verb} lacks its {want!r} payload")
        if code == "ok" and isinstance(reply.get("order"), dict):
            self.live.saw_order(reply["order"]["id"])
