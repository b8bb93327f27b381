"""docs/protocol.md, executed: every JSON and HTTP example is replayed against a running server.

``tests/test_protocol.py`` checks the examples statically (they parse, they validate); this
test sends them. One restaurant (a real server on a SQLite file, one simulated robot ``r1``,
``--time-scale`` 10) is started, and the document is read top to bottom:

* Each ```` ```json client ```` block is a request. It is sent as written, on the staff
  connection (``login`` and ``logout`` on a connection of their own, which starts
  unauthenticated), and its reply is read.
* The ```` ```json server ```` block(s) after it, up to the next client block, are what the
  server answers: an ``ok`` or ``error`` block is *the* reply to that request (at most one);
  a client block with no reply block must be answered ``ok``. The request is sent with the
  ``id`` it shows, or none: a reply block shows the request's ``id``, or none if the request
  has none, as the server answers (``test_every_reply_shows_its_requests_id``).
* An ``update`` block is a pushed update: the test waits (up to ``UPDATE_WAIT`` s) until one of
  its watching connections, subscribed to every topic since the restaurant started (the owner's
  to ``audit`` and ``forecast``), has received an update on that topic that matches.

Matching, field by field: the same set of keys in every object, recursively; lists of the same
length, element by element; every value equal — except *volatile* values, which depend on the
run (ids the server assigns, times, ``seq``, the simulator's port and poses, a robot's
odometer, tokens). A volatile value is matched by its JSON type (number, string, boolean,
list, object), and ``null`` versus a value always matters. Volatile are the keys in
``VOLATILE`` below, the integers under the keys of ``ID_KEYS`` (ids of orders and of the
till's tickets and jobs, alone or in lists: a list's length is compared), and the keys a
block's hint adds with ``loose=``.

Hints: an HTML comment ``<!-- doctest: ... -->`` (invisible to a reader) before a block applies
to that block. Its space-separated words:

* ``state=S``: before the request, the test drives ``r1`` into status ``S`` through a helper
  connection (serving, stopping or cancelling trips, creating a one-dish trip to T3 when one is
  needed, pressing Go once it is loaded); ``S`` is a robot status, or ``Away`` (Ready, parked
  away from its home). ``Error`` is reached as in a restaurant: a one-dish trip to T12 with the
  simulated robot's way blocked, so T12 is blocked afterwards (until a ``clear``).
* ``orders=T3,T5``: before the request, create one pending order for each table named.
* ``failed-logins=N``: before the request, N logins with a wrong password on the login
  connection.
* ``as=owner``: send the request on the owner's connection (``create robot``, ``create dish``).
  ``as=table-screen:T3``: on a connection logged in with a table-screen token for T3.
* ``fill=a,b``: the request's ids that only the run knows, filled in before it is sent:
  ``order`` (the newest order; ``order:S``: the newest in status ``S``), ``orders`` (the
  orders the ``orders=`` hint just created, in the order the request lists them; a ``trays``
  choice names them as the request's ``orders`` does), ``task`` and ``stop`` (``r1``'s current
  trip and stop), ``alert`` (the active alert of the documented reply's kind and subject),
  ``device`` (the id of the token the latest ``account`` ``create_token`` made, into ``token``),
  ``upload`` (the id the latest ``site`` ``upload`` answered, into ``upload``, ``yaml`` and
  ``image``),
  ``backup`` (the name of the backup the latest ``site`` ``backup_now`` made, into ``name``),
  ``day`` (the run's service day, at the request's ``utc_offset``: a ``stats`` ``forecast`` needs a
  day with dishes), ``before`` (the day after it: ``stats`` ``last_service`` names the run's),
  ``port`` (a free loopback port, into ``port``: ``till`` ``setup``), ``printer`` (a loopback
  address where nothing listens, into ``printer``: a kitchen printer switched off),
  ``ticket`` (the newest ticket from the till; ``ticket:S``: the newest in status ``S``).
* ``print=a,b``: before the request (or the update), the till prints the named jobs of
  ``PRINT_JOBS`` (``t12``, ``t7``: kitchen tickets of the layout tests/test_till.py reads;
  ``garbled``: noise), in order, to the server's printer port over TCP, as a point of sale does
  (connect, send, close its side), each once the one before it is kept (a new ticket on
  ``tickets``); the port must be open (``till`` ``setup`` with a ``port`` before).
* ``token=ROLE:ROBOT``: replace the request's ``token`` by a fresh token of that role.
* ``loose=a,b``: more volatile keys for this block. ``sample=k``: under key ``k`` the example
  lists some of the records (each must match one record the server sent; the real list may be
  longer).
* ``snapshot``: an ``update`` block compared with the topic's snapshot instead of a pushed update
  (the map is pushed only when it changes, which a server started with its map never sees).
* ``skip=reason``: not replayed. Today the two ``stats`` examples of a new restaurant, whose
  database is empty (the replay's is not by then): ``test_stats_examples_on_an_empty_database``
  sends them to a server of their own.

The restaurant runs as shipped (``CoreConfig.auto_depart`` False): a trip given to ``r1`` waits
at the pass, Loading, until a ``go``.

Error codes: ``test_every_error_code_is_produced`` lists, per code of the doc's error table,
the test that makes the server send it.

The order-intake API (HTTP, not websocket) has ```` ```http ```` blocks: each request block
is sent, in order, to a server of its own (``--intake-port``), its ``Bearer`` token replaced by
a fresh integration token, and the response block after it is compared with the answer (the
status, the headers it shows, and the JSON body as above, with its block's hints:
``test_the_order_intake_examples_are_what_the_server_answers``); the section's curl command
must send the first request (``test_the_curl_example_is_the_first_request``).
"""

from __future__ import annotations

import asyncio
import json
import re
import shlex
import socket
import urllib.error
import urllib.request
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any
from urllib.parse import urlsplit

import pytest
from escpos.printer import Dummy
from websockets.asyncio.client import ClientConnection, connect
from websockets.exceptions import ConnectionClosed

from serveur.core.runtime import CoreConfig
from serveur.security import auth
from serveur.stats.periods import parse_offset
from tests.conftest import Client, Restaurant, intake_app, restaurant

DOC = Path(__file__).resolve().parent.parent / "docs" / "protocol.md"
ROBOT = "r1"

#: Matched by JSON type only: ids the server assigns, times, seq, tokens, what depends on the
#: simulation (poses, battery, the laser) and on the run (the simulator's port, peers).
VOLATILE = frozenset(
    {
        "id",
        "task_id",
        "order_id",
        "current_task",
        "seq",
        "ts",
        "stamp",
        "expires",
        "token",
        "ready_at",
        "dispatched_at",
        "delivered_at",
        "created_at",
        "started_at",
        "finished_at",
        "arrived_at",
        "done_at",
        "updated_at",
        "status_since",
        "ordered_at",
        "returned_at",
        "voided_at",
        "raised_at",
        "acked_at",
        "cleared_at",
        "since",
        "opened_at",
        "escalated_at",
        "answered_at",
        "cancelled_at",
        "received_at",
        "read_at",
        "last_press",
        "retry_after",
        "x",
        "y",
        "yaw",
        "battery",
        "odometer",
        "url",
        "peer",
        "angle_min",
        "angle_increment",
        "range_max",
        "ranges",
    }
)
#: Keys whose integers are ids the run assigns (an order's, a ticket's from the till, its print
#: job's), alone or in a list (its length is compared): each id by type. A string under them
#: (a ticket's printed number, ``"1042"``) and ``null`` are compared as usual.
ID_KEYS = frozenset({"orders", "orders_returned", "ticket", "of_ticket", "job", "read"})
UPDATE_WAIT = 10.0
REPLY_WAIT = 15.0
ALL_TOPICS = [
    "robots",
    "orders",
    "tasks",
    "waypoints",
    "map",
    "events",
    "alerts",
    "menu",
    "blocks",
    "settings",
    "calls",
    "zones",
    "leases",
    "tickets",
    "till",
    f"pose:{ROBOT}",
]
#: The site of the doc's restaurant: as shipped (trips wait at the pass for Go).
SITE = CoreConfig(heartbeat=2.0, ack_timeout=3.0, auto_depart=False)
#: The table ``state=Error`` cannot reach.
BLOCKED_TABLE = "T12"


def kitchen_ticket(number: str, table: str, *lines: str) -> bytes:
    """A kitchen ticket as a point of sale prints it (python-escpos: the layout
    tests/test_till.py reads), cut at its end."""
    p = Dummy()
    p.set(align="center", bold=True, double_height=True)
    p.text("KITCHEN\n")
    p.set(align="left", bold=False, double_height=False, normal_textsize=True)
    p.text(f"Order #{number}\nTable: {table}   Guests: 3\n" + "-" * 32 + "\n")
    for line in lines:
        p.text(line + "\n")
    p.cut()
    return bytes(p.output)


#: The jobs the till prints for the ``print=`` hint.
PRINT_JOBS = {
    "t12": kitchen_ticket("1042", "12", "2 x Nasi Lemak", "   - no chilli", "1 x Teh Tarik"),
    "t7": kitchen_ticket("1043", "7", "1 x Laksa", "2 x Roti Canai Telur"),
    # Noise (a job to the wrong port, a damaged cable): one line of nonsense, no table.
    "garbled": bytes((i * 37 + 11) % 256 for i in range(40)),
}

# --------------------------------------------------------------------------- the document


@dataclass
class Block:
    line: int
    side: str  # "client" or "server"
    msg: dict[str, Any]
    hints: dict[str, str]


@dataclass
class Step:
    """One request and its documented reply, or one documented update."""

    request: Block | None
    reply: Block | None = None
    updates: list[Block] = field(default_factory=list)

    @property
    def line(self) -> int:
        first = self.request or self.reply or self.updates[0]
        return first.line


#: A fenced block's first line, at the start of a line: its language and tag (``json client``).
_FENCE = re.compile(r"^```(\w+)(?:[ \t]+(\S+))?[ \t]*$")
_HINT = re.compile(r"^<!--\s*doctest:(.*?)-->\s*$")
#: The blocks the replay reads (hints may precede only these).
_REPLAYED = frozenset({("json", "client"), ("json", "server"), ("http", "")})


def _hints(text: str) -> dict[str, str]:
    head, sep, reason = text.partition("skip=")
    out = {w.partition("=")[0]: w.partition("=")[2] for w in head.split()}
    if sep:
        out["skip"] = reason.strip()
    return out


@dataclass
class Fenced:
    line: int
    lang: str
    tag: str
    body: str
    hints: dict[str, str]


def read_fenced(text: str) -> list[Fenced]:
    """The document's JSON and HTTP blocks, in order, each with the hints written just before
    it."""
    blocks: list[Fenced] = []
    lines = text.splitlines()
    pending: dict[str, str] = {}
    i = 0
    while i < len(lines):
        hint = _HINT.search(lines[i])
        fence = _FENCE.match(lines[i])
        if hint:
            pending.update(_hints(hint.group(1)))
        elif fence:
            end = lines.index("```", i + 1)
            kind = (fence.group(1), fence.group(2) or "")
            if kind in _REPLAYED:
                body = "\n".join(lines[i + 1 : end])
                blocks.append(Fenced(i + 1, *kind, body, pending))
            else:
                assert not pending, f"line {i + 1}: a doctest hint before a {kind} block"
            pending = {}
            i = end
        i += 1
    assert not pending, f"a doctest hint follows the last block: {pending}"
    return blocks


def read_blocks(text: str) -> list[Block]:
    """The document's JSON blocks (websocket messages), in order, with their hints."""
    return [
        Block(b.line, b.tag, json.loads(b.body), b.hints)
        for b in read_fenced(text)
        if b.lang == "json"
    ]


def read_steps(text: str) -> list[Step]:
    steps: list[Step] = []
    for b in read_blocks(text):
        if b.side == "client":
            steps.append(Step(b))
        elif b.msg["servermsg"] == "update":
            steps.append(Step(None, updates=[b]))
        else:
            assert steps and steps[-1].request is not None, f"line {b.line}: reply to no request"
            assert steps[-1].reply is None, f"line {b.line}: a second reply to one request"
            steps[-1].reply = b
    return steps


# --------------------------------------------------------------------------- matching


def _is_id(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def _kind(v: Any) -> str:
    if v is None:
        return "null"
    if isinstance(v, bool):
        return "boolean"
    if isinstance(v, (int, float)):
        return "number"
    if isinstance(v, str):
        return "string"
    if isinstance(v, list):
        return "list"
    return "object"


#: Not checked at all: a robot's connection error depends on the network the test runs on (the
#: documented robots' addresses are not on loopback): null, or any reason.
UNCHECKED = frozenset({"link_error"})


@dataclass(frozen=True)
class Rules:
    volatile: frozenset[str] = VOLATILE
    sample: frozenset[str] = frozenset()

    @classmethod
    def of(cls, block: Block | Fenced) -> Rules:
        def words(key: str) -> frozenset[str]:
            v = block.hints.get(key, "")
            return frozenset(w for w in v.split(",") if w)

        return cls(VOLATILE | words("loose"), words("sample"))


def mismatches(doc: Any, got: Any, rules: Rules, path: str = "", key: str = "") -> list[str]:
    """Where ``got`` (what the server sent) differs from ``doc`` (the example); [] if nowhere."""
    where = path or "(top)"
    if key in UNCHECKED:
        return []
    if key in rules.volatile or (key in ID_KEYS and _is_id(doc)):
        if _kind(doc) != _kind(got):
            return [f"{where}: documented a {_kind(doc)} ({doc!r}), got {got!r}"]
        return []
    if isinstance(doc, dict):
        if not isinstance(got, dict):
            return [f"{where}: documented an object, got {got!r}"]
        out = []
        if doc.keys() != got.keys():
            missing, extra = sorted(doc.keys() - got.keys()), sorted(got.keys() - doc.keys())
            out.append(f"{where}: keys differ: not sent {missing}, not documented {extra}")
        for k in doc.keys() & got.keys():
            out += mismatches(doc[k], got[k], rules, f"{path}.{k}" if path else k, k)
        return out
    if isinstance(doc, list):
        if not isinstance(got, list):
            return [f"{where}: documented a list, got {got!r}"]
        if key in rules.sample:
            out = []
            for i, item in enumerate(doc):
                if not any(not mismatches(item, g, rules, f"{path}[{i}]", key) for g in got):
                    out.append(f"{where}[{i}]: no record sent matches {item!r}")
            return out
        if len(doc) != len(got):
            return [f"{where}: documented {len(doc)} items, got {len(got)}: {got!r}"]
        out = []
        for i, (d, g) in enumerate(zip(doc, got, strict=True)):
            out += mismatches(d, g, rules, f"{path}[{i}]", key)
        return out
    if _kind(doc) != _kind(got) or doc != got:
        return [f"{where}: documented {doc!r}, got {got!r}"]
    return []


def test_matching_rules() -> None:
    r = Rules()
    assert mismatches({"a": 1, "x": 2.5}, {"a": 1, "x": 9.0}, r) == []
    assert mismatches({"x": 2.5}, {"x": None}, r)  # null versus a value matters
    assert mismatches({"x": None}, {"x": 0.0}, r)
    assert mismatches({"a": 1}, {"a": 1, "b": 2}, r)  # an undocumented key
    assert mismatches({"a": True}, {"a": 1}, r)  # true is not 1
    assert mismatches({"orders": [1, 2]}, {"orders": [7]}, r)
    assert mismatches({"orders": [1, 2]}, {"orders": [7, 8]}, r) == []
    assert mismatches({"read": [1, 3]}, {"read": [4, 6]}, r) == []  # ticket ids
    assert mismatches({"ticket": 1}, {"ticket": 9}, r) == []
    assert mismatches({"ticket": 1}, {"ticket": None}, r)  # an order from the till, or not
    assert mismatches({"ticket": "1042"}, {"ticket": "1043"}, r)  # the number it printed
    sample = Rules(sample=frozenset({"w"}))
    assert mismatches({"w": [{"n": "b"}]}, {"w": [{"n": "a"}, {"n": "b"}]}, sample) == []
    assert mismatches({"w": [{"n": "c"}]}, {"w": [{"n": "a"}, {"n": "b"}]}, sample)
    hints = _hints(" state=Delivered loose=a,b skip=it needs two robots ")
    assert hints == {"state": "Delivered", "loose": "a,b", "skip": "it needs two robots"}


# --------------------------------------------------------------------------- connections


class Raw:
    """One connection that sends documented requests as they are and reads their replies."""

    def __init__(self, ws: ClientConnection) -> None:
        self.ws = ws
        self.updates: list[dict[str, Any]] = []

    async def request(self, msg: dict[str, Any]) -> dict[str, Any]:
        await self.ws.send(json.dumps(msg))

        async def reply() -> dict[str, Any]:
            while True:
                got = json.loads(await self.ws.recv())
                if got["servermsg"] == "update":
                    self.updates.append(got)
                else:
                    return dict(got)

        return await asyncio.wait_for(reply(), REPLY_WAIT)


@dataclass
class World:
    r: Restaurant
    helper: Client  # drives the robot for ``state=``; subscribed to every topic
    owner: Client  # subscribed to audit
    staff: Raw
    login: Raw
    owner_raw: Raw  # sends the owner's requests
    codes: set[str] = field(default_factory=set)  # error codes the replay was answered with
    made: list[int] = field(default_factory=list)  # orders the latest ``orders=`` hint created
    screens: dict[str, Raw] = field(default_factory=dict)  # table screens (``as=``)
    alert: int | None = None  # the alert the latest ``fill=alert`` named
    device: int | None = None  # the token the latest ``account create_token`` made
    upload: int | None = None  # the upload the latest ``site upload`` started
    backup: str | None = None  # the backup the latest ``site backup_now`` made

    def watched(self) -> list[dict[str, Any]]:
        return [
            f for c in (self.helper, self.owner) for f in c.frames if f["servermsg"] == "update"
        ]


@pytest.fixture
async def world(tmp_path: Path) -> AsyncIterator[World]:
    async with restaurant(tmp_path, robots=1, config=SITE, backups=True) as r:
        assert r.app.sessions is not None
        store = r.app.store
        await store.accounts.add_user(
            "alice", "staff", auth.hash_password("correct horse battery", n=2**4), now=0.0
        )
        await store.accounts.add_user(
            "olga", "owner", auth.hash_password("olga's pw", n=2**4), now=0.0
        )
        helper = await r.client()
        await helper.subscribe(*ALL_TOPICS, f"scan:{ROBOT}", f"cloud:{ROBOT}")
        # The doc's restaurant has been open a while: its robot has reported its battery.
        await helper.until(lambda: helper.robot(ROBOT).get("battery") is not None, what="battery")
        owner = Client(await connect(r.app.url, max_size=2**24))
        r.clients.append(owner)
        await owner.ok("login", username="olga", password="olga's pw")
        await owner.subscribe("audit", "forecast")
        staff = Raw(await connect(r.app.url, max_size=2**24, additional_headers=r.auth_headers()))
        login = Raw(await connect(r.app.url))
        owner_raw = Raw(await connect(r.app.url))
        await owner_raw.request({"clientmsg": "login", "username": "olga", "password": "olga's pw"})
        try:
            world = World(r, helper, owner, staff, login, owner_raw)
            yield world
        finally:
            for raw in (staff, login, owner_raw):
                await raw.ws.close()
            for raw in world.screens.values():
                await raw.ws.close()


# --------------------------------------------------------------------------- robot states


async def _trip(w: World, table: str = "T3") -> None:
    """A one-dish trip to ``table`` (the dish is Laksa), queued for the robot."""
    c = w.helper
    order = (await c.ok("create", type="order", dish="Laksa", table=table))["order"]
    await c.ok("create", type="task", orders=[order["id"]])


def _status(w: World) -> str:
    return str(w.helper.robot(ROBOT).get("status"))


def _has_trip(w: World) -> bool:
    return w.helper.robot(ROBOT).get("current_task") is not None


async def to_ready(w: World) -> None:
    """From any status to Ready, with no trip: trips are stopped and cancelled."""
    c = w.helper
    for _ in range(40):
        st = _status(w)
        if st == "Ready":
            return
        verb = {
            "Loading": "cancel",
            "Delivering": "stop",
            "Transit": "stop",
            "Stopped": "cancel",
            "Error": "cancel",
            "Delivered": "next",
            "Awaiting": "ready",
            "Manual": "ready",
            "Charging": "work",
        }.get(st)
        if verb is not None:
            # The robot may move on meanwhile (an Awaiting robot takes a queued trip): a
            # refusal then just means "look again".
            reply = await c.call(verb, robot=ROBOT)
            assert reply["servermsg"] == "ok" or reply["code"] == "not_allowed_in_status", reply
            if verb == "cancel" and reply["servermsg"] == "ok":
                await c.until(
                    lambda: _status(w) not in ("Loading", "Stopped", "Error", "Transit"),
                    what=f"{ROBOT} home after a cancel",
                )
                continue
        await c.until(lambda st=st: _status(w) != st, what=f"{ROBOT} to leave {st}")
    raise AssertionError(f"{ROBOT} did not get Ready (is {_status(w)})")


async def _loaded(w: World) -> None:
    """Staff have loaded the trays: Go, and the robot leaves (Delivering)."""
    await w.helper.ok("go", robot=ROBOT)
    await w.helper.status(ROBOT, "Delivering")


async def to_state(w: World, target: str) -> None:
    """Drive the robot into ``target`` (a status, or Away: Ready, parked away from home)."""
    c = w.helper
    on_trip = ("Delivering", "Delivered", "Stopped")
    if target == _status(w) and target not in on_trip:
        return
    if target in on_trip and _has_trip(w):
        st = _status(w)
        if st == "Loading":
            await _loaded(w)
            st = "Delivering"
        if target == "Delivered" and st == "Delivering":
            await c.status(ROBOT, "Delivered")
            return
        if target == st or (target == "Stopped" and st == "Delivering"):
            if target == "Stopped":
                await c.ok("stop", robot=ROBOT)
                await c.status(ROBOT, "Stopped")
            return
    await to_ready(w)
    if target == "Ready":
        return
    if target in ("Manual", "Away"):
        await c.ok("control", robot=ROBOT, action="manual")
        await c.status(ROBOT, "Manual")
        if target == "Away":
            frames = len(c.frames)
            await c.ok("control", robot=ROBOT, action="goto", waypoint="T2")
            await c.until(
                lambda: any(
                    f.get("topic") == "events" and f["data"]["kind"] == "robot.goal_reached"
                    for f in c.frames[frames:]
                ),
                what=f"{ROBOT} to reach T2",
            )
            await c.ok("ready", robot=ROBOT)
            await c.status(ROBOT, "Ready")
        return
    sim = w.r.sim.robots[0]
    if target == "Error":
        sim.block_path(True)
        await _trip(w, BLOCKED_TABLE)
    elif target in (*on_trip, "Loading"):
        await _trip(w)
    await c.ok("control", robot=ROBOT, action="auto")
    if target == "Awaiting":
        await c.status(ROBOT, "Awaiting")
        return
    await c.status(ROBOT, "Loading")
    if target == "Loading":
        return
    await _loaded(w)
    if target == "Error":
        await c.status(ROBOT, "Error")
        sim.block_path(False)
        await c.until(lambda: BLOCKED_TABLE in c.records.get("blocks", {}), what="blocked")
    elif target == "Delivered":
        await c.status(ROBOT, "Delivered")
    elif target == "Stopped":
        await c.ok("stop", robot=ROBOT)
        await c.status(ROBOT, "Stopped")


# --------------------------------------------------------------------------- the replay


def _fail(step: Step, what: str, problems: list[str]) -> None:
    pytest.fail(
        f"docs/protocol.md line {step.line}: {what}:\n  " + "\n  ".join(problems), pytrace=False
    )


async def _prepare(w: World, b: Block) -> None:
    h = b.hints
    if "orders" in h:
        w.made = []
        for table in h["orders"].split(","):
            made = await w.helper.ok("create", type="order", dish="Satay", table=table)
            w.made.append(made["order"]["id"])
    if "failed-logins" in h:
        for _ in range(int(h["failed-logins"])):
            got = await w.login.request(
                {"clientmsg": "login", "username": "alice", "password": "wrong guess"}
            )
            assert got.get("code") == "unauthorized", got
            w.codes.add("unauthorized")
    if "state" in h:
        await to_state(w, h["state"])
    if "print" in h:
        for name in h["print"].split(","):
            await _print(w, name)


async def _print(w: World, name: str) -> None:
    """The till prints job ``name`` to the printer port; back once its ticket is kept."""
    assert w.r.app.tap is not None and w.r.app.tap.bound_port, "print= with the port closed"
    kept = w.helper.records.setdefault("tickets", {})
    before = len(kept)
    reader, writer = await asyncio.open_connection("127.0.0.1", w.r.app.tap.bound_port)
    writer.write(PRINT_JOBS[name])
    await writer.drain()
    writer.write_eof()
    await asyncio.wait_for(reader.read(), REPLY_WAIT)  # the port closes once it has the job
    writer.close()
    await w.helper.until(lambda: len(kept) > before, what=f"the ticket {name} kept")


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def _table_screen(w: World, table: str) -> Raw:
    """A connection logged in as table ``table``'s screen (opened once)."""
    if table not in w.screens:
        token = await w.r.app.issue_token("table-screen", table=table)
        raw = Raw(await connect(w.r.app.url, max_size=2**24))
        got = await raw.request({"clientmsg": "login", "token": token})
        assert got["servermsg"] == "ok", got
        w.screens[table] = raw
    return w.screens[table]


async def _fill(w: World, msg: dict[str, Any], fill: str, reply: Block | None) -> None:
    """Put into ``msg`` the ids only the run knows (the ``fill=`` hint)."""
    c = w.helper
    for word in fill.split(","):
        name, _, status = word.partition(":")
        if name == "order":

            def newest(status: str = status) -> int | None:
                ids = [
                    o["id"]
                    for o in c.records.get("orders", {}).values()
                    if not status or o["status"] == status
                ]
                return max(ids, default=None)

            await c.until(lambda: newest() is not None, what=f"an order {status}")
            msg["order"] = newest()
        elif name == "orders":
            made = dict(zip(msg["orders"], w.made, strict=False))
            msg["orders"] = list(w.made)
            if "trays" in msg:  # the trays chosen name dishes of the cart: the ones just made
                msg["trays"] = [{**t, "order": made[t["order"]]} for t in msg["trays"]]
        elif name in ("task", "stop"):
            task = c.robot(ROBOT)["current_task"]
            msg["task"] = task
            if name == "stop":
                assert task is not None, "no trip to name a stop of"
                t = c.task(task)
                msg["stop"] = t["stops"][t["current_stop"]]["seq"]
        elif name == "alert" and (reply is None or "alert" not in reply.msg):
            assert w.alert is not None, "fill=alert: no alert yet, and no reply to find one"
            msg["alert"] = w.alert
        elif name == "alert":
            want = reply.msg["alert"]

            def active(want: dict[str, Any] = want) -> int | None:
                ids = [
                    a["id"]
                    for a in c.records.get("alerts", {}).values()
                    if a["kind"] == want["kind"]
                    and a["subject"] == want["subject"]
                    and a["cleared_at"] is None
                ]
                return max(ids, default=None)

            await c.until(lambda: active() is not None, what=f"alert {want['kind']}")
            msg["alert"] = w.alert = active()
        elif name == "device":
            assert w.device is not None, "fill=device before any create_token"
            msg["token"] = w.device
        elif name == "upload":
            assert w.upload is not None, "fill=upload before any site upload"
            for key in ("upload", "yaml", "image"):
                if key in msg:
                    msg[key] = w.upload
        elif name == "backup":
            assert w.backup is not None, "fill=backup before any site backup_now"
            msg["name"] = w.backup
        elif name == "port":
            msg["port"] = _free_port()
        elif name == "printer":
            msg["printer"] = f"127.0.0.1:{_free_port()}"  # nothing listens there
        elif name == "ticket":

            def newest_ticket(status: str = status) -> int | None:
                kept = c.records.get("tickets", {}).values()
                ids = [t["id"] for t in kept if not status or t["status"] == status]
                return max(ids, default=None)

            await c.until(lambda: newest_ticket() is not None, what=f"a ticket {status}")
            msg["ticket"] = newest_ticket()
        elif name == "day":
            # The run's own service day (it starts at 04:00), at the request's utc_offset.
            tz = parse_offset(msg.get("utc_offset") or "+00:00")
            local = datetime.fromtimestamp(w.r.clock.epoch(), tz) - timedelta(hours=4)
            msg["day"] = local.date().isoformat()
        elif name == "before":
            # The day after the run's service day: its last service is the run's own.
            tz = parse_offset(msg.get("utc_offset") or "+00:00")
            local = datetime.fromtimestamp(w.r.clock.epoch(), tz) - timedelta(hours=4)
            msg["before"] = (local.date() + timedelta(days=1)).isoformat()
        else:
            raise AssertionError(f"fill: unknown {name!r}")


async def _send(w: World, step: Step) -> None:
    req = step.request
    assert req is not None
    msg = dict(req.msg)
    reply = step.reply
    if "token" in req.hints:
        role, _, robot = req.hints["token"].partition(":")
        msg["token"] = await w.r.app.issue_token(role, robot=robot or None)
    if "fill" in req.hints:
        await _fill(w, msg, req.hints["fill"], reply)
    who = req.hints.get("as", "")
    if who.startswith("table-screen:"):
        got = await (await _table_screen(w, who.partition(":")[2])).request(msg)
    elif who == "owner":
        got = await w.owner_raw.request(msg)
    elif msg["clientmsg"] in ("login", "logout"):
        got = await w.login.request(msg)
    else:
        got = await w.staff.request(msg)
    if got["servermsg"] == "error":
        w.codes.add(got["code"])
    if msg["clientmsg"] == "account" and msg.get("action") == "create_token" and "device" in got:
        w.device = got["device"]["id"]
    if msg["clientmsg"] == "site" and msg.get("action") == "upload" and "upload" in got:
        w.upload = got["upload"]["id"]
    if msg["clientmsg"] == "site" and msg.get("action") == "backup_now" and "backup" in got:
        w.backup = got["backup"]["name"]
    if reply is None:
        if got["servermsg"] != "ok":
            _fail(step, "documented without a reply, so it must succeed", [json.dumps(got)])
        return
    problems = mismatches(reply.msg, got, Rules.of(reply))
    if problems:
        _fail(step, f"the reply to {json.dumps(req.msg)} differs", problems)


async def _update(w: World, step: Step) -> None:
    (b,) = step.updates
    rules = Rules.of(b)
    topic = b.msg["topic"]
    if "snapshot" in b.hints:
        snap = (await w.helper.ok("data", topics=[topic]))["data"][topic]
        got = {"servermsg": "update", "topic": topic, "seq": 1, "data": snap}
        problems = mismatches(b.msg, got, rules)
        if problems:
            _fail(step, f"the {topic} snapshot differs from the update example", problems)
        return

    def found() -> bool:
        return any(not mismatches(b.msg, f, rules) for f in w.watched())

    try:
        await w.helper.until(found, UPDATE_WAIT, f"an update like line {b.line}")
    except AssertionError:
        same = [f for f in w.watched() if f["topic"] == topic]
        if not same:
            _fail(step, f"no update on {topic} arrived", [])
        best = min((mismatches(b.msg, f, rules) for f in same), key=len)
        _fail(step, f"no {topic} update matches the example; the closest", best)


async def test_every_example_in_the_doc_is_what_the_server_does(world: World) -> None:
    steps = read_steps(DOC.read_text(encoding="utf-8"))
    assert len(steps) >= 30
    for step in steps:
        first = step.request or step.updates[0]
        if "skip" in first.hints:
            continue
        await _prepare(world, first)
        if step.request is not None:
            await _send(world, step)
        else:
            await _update(world, step)
    assert world.codes == REPLAYED_CODES
    _check_events(world)


def test_every_reply_shows_its_requests_id() -> None:
    """A documented reply carries the ``id`` of its request, and none when the request has none:
    a client copying an example gets the reply shown, since the server echoes the ``id`` it was
    sent and invents none. (Three ``create`` examples once showed reply ids their requests did
    not carry; the replay added the id to the request and so never saw it.)"""
    steps = read_steps(DOC.read_text(encoding="utf-8"))
    wrong = [
        (s.reply.line, s.request.msg.get("id"), s.reply.msg.get("id"))
        for s in steps
        if s.request is not None
        and s.reply is not None
        and s.request.msg.get("id", ...) != s.reply.msg.get("id", ...)
    ]
    assert wrong == [], "(line, request id, reply id)"


def test_skips_are_rare_and_say_why() -> None:
    blocks = read_blocks(DOC.read_text(encoding="utf-8"))
    skipped = [b for b in blocks if "skip" in b.hints]
    assert len(skipped) <= 4
    assert all(len(b.hints["skip"]) > 10 for b in skipped)
    known = {
        "state",
        "orders",
        "failed-logins",
        "as",
        "token",
        "fill",
        "loose",
        "sample",
        "snapshot",
        "print",
    }
    for b in blocks:
        assert set(b.hints) - {"skip"} <= known, (b.line, b.hints)


def test_a_drifted_example_fails() -> None:
    """The comparison is what makes the replay fail: change one field of a documented reply
    and it no longer matches what the server sent. (Checked by hand on the whole replay too:
    ``"resume":"Ready"`` in the ``manual`` reply fails with ``robot.resume: documented 'Ready',
    got None``; ``"task_id":12`` in the events update, with ``data.task_id: documented a number
    (12), got None``; ``goto`` to ``T99``, with the ``not_found`` it got.)"""
    steps = read_steps(DOC.read_text(encoding="utf-8"))
    step = next(s for s in steps if s.reply and s.reply.msg.get("code") == "not_allowed_in_status")
    assert step.reply is not None
    sent = json.loads(json.dumps(step.reply.msg))
    assert mismatches(step.reply.msg, sent, Rules()) == []
    sent["details"]["status"] = "Offline"
    assert mismatches(step.reply.msg, sent, Rules())


# --------------------------------------------------------------------------- order-intake API


@dataclass
class Exchange:
    """A documented HTTP request to the order-intake API and the response after it."""

    line: int
    method: str
    path: str
    headers: dict[str, str]
    body: str
    status: int
    response_headers: dict[str, str]
    response: Any
    rules: Rules


def _http_message(text: str) -> tuple[str, dict[str, str], str]:
    """(first line, headers, body) of an HTTP message as the document writes it."""
    head, _, body = text.partition("\n\n")
    first, *lines = head.splitlines()
    headers = {k.strip(): v.strip() for k, _, v in (h.partition(":") for h in lines)}
    return first, headers, body.strip()


def read_exchanges(text: str) -> list[Exchange]:
    blocks = [b for b in read_fenced(text) if b.lang == "http"]
    assert len(blocks) % 2 == 0, "every HTTP request block is followed by its response"
    out = []
    for req, resp in zip(blocks[::2], blocks[1::2], strict=True):
        first, headers, body = _http_message(req.body)
        method, path, version = first.split()
        status_line, response_headers, response = _http_message(resp.body)
        assert version == "HTTP/1.1" and status_line.startswith("HTTP/1.1 "), (req.line, resp.line)
        status = int(status_line.split()[1])
        out.append(
            Exchange(
                req.line,
                method,
                path,
                headers,
                body,
                status,
                response_headers,
                json.loads(response),
                Rules.of(resp),
            )
        )
    return out


def _post(url: str, ex: Exchange, token: str) -> tuple[int, dict[str, str], Any]:
    headers = {k: v for k, v in ex.headers.items() if k != "Host"}
    if headers.get("Authorization", "").startswith("Bearer srv_"):
        headers["Authorization"] = f"Bearer {token}"
    req = urllib.request.Request(url, data=ex.body.encode(), headers=headers, method=ex.method)
    try:
        with urllib.request.urlopen(req, timeout=REPLY_WAIT) as resp:
            return resp.status, dict(resp.headers), json.loads(resp.read())
    except urllib.error.HTTPError as exc:
        return exc.code, dict(exc.headers), json.loads(exc.read())


async def test_the_order_intake_examples_are_what_the_server_answers(tmp_path: Path) -> None:
    """The ``http`` examples of docs/protocol.md's "Order-intake API", sent in order to a
    server with the API on (``--intake-port``), under a fresh integration token labelled as
    the examples show, with the ``orders`` scope."""
    from serveur.clock import FakeClock

    exchanges = read_exchanges(DOC.read_text(encoding="utf-8"))
    assert {ex.status for ex in exchanges} >= {201, 200, 409}
    async with intake_app(tmp_path, FakeClock()) as app:
        assert app.intake is not None
        token = await app.issue_token("integration", label="pos bridge", scopes=["orders"])
        for ex in exchanges:
            url = f"http://127.0.0.1:{app.intake.port}{ex.path}"
            status, headers, body = await asyncio.to_thread(_post, url, ex, token)
            problems = mismatches(ex.response, body, ex.rules)
            if status != ex.status:
                problems.insert(0, f"status: documented {ex.status}, got {status}")
            for name, value in ex.response_headers.items():
                if headers.get(name) != value:
                    problems.append(f"{name}: documented {value!r}, got {headers.get(name)!r}")
            if problems:
                pytest.fail(
                    f"docs/protocol.md line {ex.line}: the answer to {ex.method} {ex.path}"
                    " differs:\n  " + "\n  ".join(problems),
                    pytrace=False,
                )


async def test_the_order_intake_api_answers_a_database_failure_as_the_servers(
    tmp_path: Path,
) -> None:
    """A database that refuses every write (a full disk): the request is not the client's
    fault, and ``store_error`` says "resend it", so the status is a server's (5xx)."""
    from serveur.clock import FakeClock

    first = read_exchanges(DOC.read_text(encoding="utf-8"))[0]
    async with intake_app(tmp_path, FakeClock()) as app:
        assert app.intake is not None
        token = await app.issue_token("integration", label="pos bridge", scopes=["orders"])
        db = app.store._db  # type: ignore[attr-defined]
        await db.execute("PRAGMA query_only = 1")
        url = f"http://127.0.0.1:{app.intake.port}{first.path}"
        status, _, body = await asyncio.to_thread(_post, url, first, token)
        await db.execute("PRAGMA query_only = 0")
        assert body["code"] == "store_error", body
        assert status >= 500, (status, body)


def test_the_curl_example_is_the_first_request() -> None:
    """The curl command of the order-intake API sends the first documented request."""
    text = DOC.read_text(encoding="utf-8")
    (command,) = re.findall(r"^```sh\n(curl .*?)^```", text, re.M | re.S)
    words = shlex.split(command.replace("\\\n", " "))
    url = words[words.index("-X") + 2]
    headers = dict(
        (k.strip(), v.strip())
        for k, _, v in (words[i + 1].partition(":") for i, w in enumerate(words) if w == "-H")
    )
    first = read_exchanges(text)[0]
    assert (words[words.index("-X") + 1], urlsplit(url).path) == (first.method, first.path)
    assert urlsplit(url).netloc == first.headers["Host"]
    assert headers == {k: v for k, v in first.headers.items() if k != "Host"}
    assert json.loads(words[words.index("-d") + 1]) == json.loads(first.body)


# --------------------------------------------------------------------------- stats on a new site


def _stats_steps() -> list[Step]:
    """The ``stats`` examples the replay skips: they show a new restaurant's figures."""
    steps = read_steps(DOC.read_text(encoding="utf-8"))
    return [
        s
        for s in steps
        if s.request is not None
        and s.request.msg["clientmsg"] == "stats"
        and "skip" in s.request.hints
    ]


async def _replay_stats(db: str) -> None:
    """Send the skipped ``stats`` examples as written, as the owner, to a real server on a new
    (empty) database ``db``, and compare the replies as the replay does."""
    from serveur.app import App
    from serveur.clock import FakeClock
    from serveur.maps.navigation import load_demo
    from serveur.security.sessions import SecurityConfig

    steps = _stats_steps()
    requests = [s.request for s in steps]
    assert [b.msg["action"] for b in requests if b is not None] == ["figures", "trips"]
    _, waypoints = load_demo()
    app = App(db, port=0, clock=FakeClock(), waypoints=waypoints, security=SecurityConfig())
    await app.start()
    try:
        async with connect(app.url) as ws:
            raw = Raw(ws)
            pw = app.first_owner_password
            got = await raw.request({"clientmsg": "login", "username": "owner", "password": pw})
            assert got["servermsg"] == "ok", got
            for step in steps:
                assert step.request is not None and step.reply is not None
                got = await raw.request(step.request.msg)
                problems = mismatches(step.reply.msg, got, Rules.of(step.reply))
                if problems:
                    _fail(step, f"the reply to {json.dumps(step.request.msg)} differs", problems)
    finally:
        await app.close()


async def test_stats_examples_on_an_empty_database() -> None:
    """The replay's database holds a service by the time it reaches ``stats``, so its two
    examples (a new restaurant: nothing recorded) are replayed here, on a server whose
    database is in memory: its statistics are computed in a worker thread, by the same code
    ``serveur stats --json`` runs."""
    await _replay_stats(":memory:")


@pytest.mark.wall_clock  # the stats verb runs `serveur stats` in a child process
async def test_stats_examples_on_an_empty_database_file(tmp_path: Path) -> None:
    """The same on a SQLite file: the figures come from ``serveur stats --json`` in a child
    process (docs/protocol.md, ``stats``). (It failed with ``internal_error`` while the child
    was ``python -m serveur``, which has no ``__main__``: fixed in 3b004d2.)"""
    await _replay_stats(str(tmp_path / "new.db"))


# --------------------------------------------------------------------------- events


def _event_rows() -> dict[str, set[str]]:
    """The doc's event-kinds table: kind -> the names in backquotes of its ``data`` column."""
    text = DOC.read_text(encoding="utf-8")
    start = text.index("<!-- table:event-kinds -->")
    rows: dict[str, set[str]] = {}
    for line in text[start:].splitlines()[3:]:
        if not line.startswith("|"):
            break
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        rows[cells[0].strip("`")] = set(re.findall(r"`([a-z_]+)`", cells[3]))
    return rows


#: Event kinds the store can write that no request or robot report leads to (no verb deletes a
#: waypoint): not in the doc's table.
UNREACHED_KINDS = frozenset({"waypoint.deleted"})
_KINDS = (
    "robot|waypoint|order|task|stop|table|alert|menu|settings|zone|lease|call|button|cruise|till"
)
_KIND = re.compile(rf'"((?:{_KINDS})\.[a-z_]+)"')


def test_the_event_table_lists_every_kind_the_server_records() -> None:
    from serveur.store.service import _EVENT

    root = Path(__file__).resolve().parent.parent / "serveur"
    kinds = set()
    for path in root.rglob("*.py"):
        kinds |= set(_KIND.findall(path.read_text(encoding="utf-8")))
    # A dish's steps are named from the action (f"order.{...}"): not literals in the code.
    kinds |= {f"order.{name}" for name in _EVENT.values()}
    # A call closed is named from how (f"call.{how}", serveur.store.calls).
    kinds |= {"call.answered", "call.cancelled"}
    assert kinds >= UNREACHED_KINDS
    assert set(_event_rows()) == kinds - UNREACHED_KINDS


def _check_events(w: World) -> None:
    """Every event the replay saw is in the doc's table, with no field the table does not name."""
    rows = _event_rows()
    seen: set[str] = set()
    for f in w.watched():
        if f["topic"] != "events":
            continue
        ev = f["data"]
        assert ev["kind"] in rows, ev
        assert set(ev["data"]) <= rows[ev["kind"]], (ev, rows[ev["kind"]])
        seen.add(ev["kind"])
    assert len(seen) >= 10, seen


# --------------------------------------------------------------------------- error codes

#: Error codes the doc's examples make the server send (the replay checks it sent them all).
REPLAYED_CODES = frozenset(
    {
        "unauthorized",
        "forbidden",
        "rate_limited",
        "not_allowed_in_status",
        "conflict",
        "unreachable",
        "stale",
        "invalid_field",
        "not_found",
        "unknown_message",
        "backup_error",
    }
)
#: Where each error code of the doc's table is produced on the wire.
PRODUCED_BY = {
    **{c: "test_every_example_in_the_doc_is_what_the_server_does" for c in REPLAYED_CODES},
    "bad_json": "test_refusals_the_examples_do_not_show",
    "store_error": "test_refusals_the_examples_do_not_show",
    "link_error": "test_refusals_the_examples_do_not_show",
    "internal_error": "test_refusals_the_examples_do_not_show (a bug, injected)",
    # Never sent by this version (docs/protocol.md says so); their reply shape is checked by
    # raising them where the core answers a request.
    "map_error": "test_refusals_the_examples_do_not_show (injected)",
    "navigation_error": "test_refusals_the_examples_do_not_show (injected)",
    "rosbridge_error": "test_refusals_the_examples_do_not_show (injected)",
}


def _error_table() -> list[str]:
    text = DOC.read_text(encoding="utf-8")
    start = text.index("<!-- table:errors -->")
    out = []
    for line in text[start:].splitlines()[3:]:
        if not line.startswith("|"):
            break
        out.append(line.split("|")[1].strip().strip("`"))
    return out


def test_every_error_code_is_produced() -> None:
    assert sorted(PRODUCED_BY) == sorted(_error_table())


async def _raw(r: Restaurant, frame: str | bytes, headers: bool = True) -> dict[str, Any]:
    extra = r.auth_headers() if headers else {}
    async with connect(r.app.url, additional_headers=extra) as ws:
        await ws.send(frame)
        return dict(json.loads(await ws.recv()))


async def test_refusals_the_examples_do_not_show(
    one_robot: Restaurant, monkeypatch: pytest.MonkeyPatch
) -> None:
    from serveur import errors as E

    r = one_robot
    c = await r.client()
    await c.subscribe("robots")
    await c.status(ROBOT, "Ready")
    bad = await _raw(r, '{"clientmsg":"stop","id":5,"robot":')
    assert (bad["code"], bad["id"]) == ("bad_json", 5), bad
    await c.error("create", "forbidden", type="robot", name="r3", url="ws://10.0.0.23:9090")
    # A frame over 64 KiB is not answered: the connection is closed with 1009.
    async with connect(r.app.url, additional_headers=r.auth_headers()) as ws:
        await ws.send(json.dumps({"clientmsg": "order", "table": "T3" * 40_000}))
        with pytest.raises(ConnectionClosed) as closed:
            await ws.recv()
        assert closed.value.rcvd is not None and closed.value.rcvd.code == 1009
    # The database refuses every write (as a full disk does).
    db = r.app.store._db  # type: ignore[attr-defined]
    await db.execute("PRAGMA query_only = 1")
    await c.error("create", "store_error", type="order", dish="Laksa", table="T3")
    await db.execute("PRAGMA query_only = 0")
    await c.ok("create", type="order", dish="Laksa", table="T3")
    core = r.app.core
    assert core is not None
    for exc in (
        RuntimeError("a bug"),
        E.MapError("map file unreadable"),
        E.NavigationError("planner died"),
        E.RosbridgeError("bad frame"),
    ):

        async def fail(msg: Any, exc: Exception = exc, **_: Any) -> dict[str, Any]:
            raise exc

        with monkeypatch.context() as m:
            m.setattr(core, "handle", fail)
            code = getattr(exc, "code", "internal_error")
            err = await c.error("ready", code, robot=ROBOT)
            assert set(err) <= {"servermsg", "id", "code", "message", "details"}, err
    # Shutting down: robots are stopped first, and every instruction is refused.
    await core.halt_robots()
    await c.error("control", "link_error", robot=ROBOT, action="manual")
