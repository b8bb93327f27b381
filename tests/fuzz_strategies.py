"""Hypothesis strategies for fuzzing the ``/ws`` protocol: valid and mutated client frames.

An example is a list of :class:`Step`: frames to send (:class:`Send`) on one of a few
connections, and short waits for a robot status (:class:`Wait`) so trips get far enough for
``next``, ``stop``, ``continue`` and ``cancel`` to be meaningful.

Frames are generated as small JSON trees (:data:`Node`) rather than Python dicts so that what
``json.dumps`` cannot write can be written: duplicate keys (:class:`Obj` is a list of pairs),
``NaN``/``Infinity`` tokens and 5000-digit numbers (:class:`Raw`), lone surrogates. Values
that only the live server knows — the ids of orders created so far, a robot's rosbridge URL —
are :class:`Ref` placeholders resolved when the frame is sent (:func:`encode`), so a given seed
always produces the same examples (what they hit depends on the server's state).

Adding a verb is one line in :data:`VERB_STRATEGIES` (e.g. ``"login": login_msgs()``).
"""

from __future__ import annotations

import dataclasses
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import date
from typing import Any, TypeAlias, TypeVar

from hypothesis import strategies as st

from serveur import protocol as P
from serveur.domain import OrderStatus
from serveur.status import RobotStatus

__all__ = [
    "ROBOTS",
    "TABLES",
    "VERB_STRATEGIES",
    "IdSlot",
    "Live",
    "Node",
    "Obj",
    "Raw",
    "Ref",
    "Send",
    "Step",
    "Wait",
    "encode",
    "examples",
    "frames",
    "mutated",
    "valid_messages",
]

T = TypeVar("T")

# --------------------------------------------------------------------------- the JSON tree


@dataclass(frozen=True)
class Raw:
    """JSON text written as is: ``NaN``, ``Infinity``, ``1e400``, ``[[[...]]]``, ``01``..."""

    text: str


@dataclass(frozen=True)
class Ref:
    """A value only the live server knows, resolved at send time.

    ``order``: the ``arg``-th most recent order id the fuzzer saw created (0 = newest), or an
    id that does not exist yet when there are fewer. ``url``: robot ``arg``'s rosbridge URL.
    """

    kind: str
    arg: int | str


@dataclass(frozen=True)
class IdSlot:
    """The request ``id``: the harness writes a fresh integer here for each frame."""


@dataclass(frozen=True)
class Obj:
    """A JSON object as ordered pairs: keys may repeat (the server must refuse that)."""

    pairs: tuple[tuple[str, Node], ...]

    def names(self) -> list[str]:
        return [k for k, _ in self.pairs]

    def get(self, key: str, default: Node = None) -> Node:
        for k, v in self.pairs:
            if k == key:
                return v
        return default

    def without(self, key: str) -> Obj:
        return Obj(tuple(p for p in self.pairs if p[0] != key))

    def set(self, key: str, value: Node) -> Obj:
        if key in self.names():
            return Obj(tuple((k, value if k == key else v) for k, v in self.pairs))
        return Obj((*self.pairs, (key, value)))

    def add(self, key: str, value: Node) -> Obj:
        return Obj((*self.pairs, (key, value)))


Node: TypeAlias = (
    bool | int | float | str | Raw | Ref | IdSlot | Obj | tuple["Node", ...] | list["Node"] | None
)


def obj(**fields: Node) -> Obj:
    return Obj(tuple(fields.items()))


# --------------------------------------------------------------------------- steps


@dataclass(frozen=True)
class Send:
    """Send one frame on connection ``conn``.

    ``valid``: True if the frame is a well-formed request the server must not refuse as
    malformed (``bad_json``, ``unknown_message``, ``invalid_field``); False if it must be
    refused (any error); None if the fuzzer does not know. ``label`` names the verb (and
    sub-type) or the mutation, for statistics.
    """

    body: Node
    label: str
    valid: bool | None = True
    conn: int = 0
    binary: bool = False  # sent as a binary frame (UTF-8 bytes of the text)
    bad_utf8: bool = False  # binary, with bytes that are not UTF-8 appended
    cut: int | None = None  # keep only this many characters of the text (invalid JSON)
    pad: str = ""  # whitespace around the text (still valid JSON)
    verb: str = ""  # the valid message's label this frame came from (its ok payload)


@dataclass(frozen=True)
class Wait:
    """Wait (at most ``timeout`` wall seconds, never an error) for ``robot`` in ``statuses``."""

    robot: str
    statuses: frozenset[str]
    timeout: float


@dataclass(frozen=True)
class Relog:
    """On connection ``conn``: ``logout``, then ``probe`` (a valid request) must be refused as
    ``unauthorized`` and change nothing, then ``login`` with the connection's token again."""

    probe: Node
    label: str
    conn: int = 0


Step: TypeAlias = Send | Wait | Relog


# --------------------------------------------------------------------------- live names

#: The simulated robots of the fuzz restaurant, and names that are not robots.
ROBOTS = ("r1", "r2")
UNKNOWN_ROBOTS = ("r3", "r9", "R1", "robot 1", "\u00e9\u00e8", "r1\u200b")
TABLES = tuple(f"T{i}" for i in range(1, 17))
OTHER_WAYPOINTS = ("home1", "home2", "pass")
UNKNOWN_WAYPOINTS = ("T17", "T0", "t1", "kitchen", "\U0001f37d")
#: Names the fuzzer may create waypoints under (a small pool so the map stays small).
NEW_WAYPOINTS = ("W1", "W2", "W3", "T99")
#: Robots the fuzzer may register, with a URL on a closed loopback port: they stay Offline.
NEW_ROBOTS = ("r3", "r4")
DEAD_URL = "ws://127.0.0.1:9/"
KEYS = ("k1", "k2", "k3", "pos-123")
DISHES = ("Laksa", "Pho", "Satay", "Teh tarik", "Nasi lemak", "Roti", "Kaya toast")
STATUSES = tuple(s.value for s in RobotStatus)
#: Demo-room poses where a robot can stand (the waypoints'): calibration and goals mostly
#: land there, so the simulated robots stay useful for the rest of the run.
GOOD_POSES: tuple[tuple[float, float, float], ...] = (
    (4.0, 10.8, 1.570796),
    (5.0, 10.8, 1.570796),
    (8.0, 10.8, 1.570796),
    (2.4, 9.7, -1.570796),
    (6.1, 9.8, -1.570796),
    (9.9, 7.3, -1.570796),
    (12.5, 6.4, 0.0),
    (6.1, 5.0, -1.570796),
    (2.4, 2.5, -1.570796),
    (12.6, 1.6, 0.0),
)


@dataclass
class Live:
    """What the server has told the fuzzer so far: order ids, robot URLs, request ids."""

    orders: list[int] = field(default_factory=list)
    urls: dict[str, str] = field(default_factory=dict)
    next_id: int = 1
    keep: int = 256

    def saw_order(self, oid: int) -> None:
        if oid not in self.orders[-16:]:  # a resent create (same key) is the same order
            self.orders.append(oid)
            del self.orders[: -self.keep]

    def resolve(self, ref: Ref) -> Any:
        if ref.kind == "order":
            k = int(ref.arg)
            if k < len(self.orders):
                return self.orders[-1 - k]
            return 2**40 + k  # no such order (yet): distinct per k
        if ref.kind == "url":
            return self.urls.get(str(ref.arg), DEAD_URL)
        raise ValueError(f"unknown ref {ref}")


# --------------------------------------------------------------------------- encoding


def _str(s: str) -> str:
    # Raw UTF-8 where possible; a lone surrogate can only travel as a \u escape.
    try:
        s.encode("utf-8")
    except UnicodeEncodeError:
        return json.dumps(s, ensure_ascii=True)
    return json.dumps(s, ensure_ascii=False)


def encode(node: Node, live: Live, ids: list[int] | None = None) -> str:
    """The JSON text of ``node``; :class:`IdSlot` values take fresh ids (appended to ``ids``)."""
    if node is None:
        return "null"
    if node is True:
        return "true"
    if node is False:
        return "false"
    if isinstance(node, int):
        return str(node)
    if isinstance(node, float):
        if math.isnan(node):
            return "NaN"
        if math.isinf(node):
            return "Infinity" if node > 0 else "-Infinity"
        return repr(node)
    if isinstance(node, str):
        return _str(node)
    if isinstance(node, Raw):
        return node.text
    if isinstance(node, Ref):
        return json.dumps(live.resolve(node))
    if isinstance(node, IdSlot):
        rid = live.next_id
        live.next_id += 1
        if ids is not None:
            ids.append(rid)
        return str(rid)
    if isinstance(node, Obj):
        return "{" + ",".join(_str(k) + ":" + encode(v, live, ids) for k, v in node.pairs) + "}"
    return "[" + ",".join(encode(v, live, ids) for v in node) + "]"


# --------------------------------------------------------------------------- valid messages

_robot = st.sampled_from(ROBOTS)
_any_robot = st.one_of(_robot, _robot, _robot, st.sampled_from(UNKNOWN_ROBOTS))
_table = st.one_of(
    st.sampled_from(TABLES),
    st.sampled_from(TABLES),
    st.sampled_from(TABLES),
    st.sampled_from(OTHER_WAYPOINTS + UNKNOWN_WAYPOINTS),
)
_valid_text = st.text(
    st.characters(exclude_categories=("Cs", "Cc")), min_size=1, max_size=64
).filter(lambda s: 0 < len(s.strip()) <= 64)
_name = st.one_of(st.sampled_from(DISHES), _valid_text)
_key = st.one_of(st.sampled_from(KEYS), _valid_text)
_coord = st.one_of(
    st.floats(-10_000, 10_000, allow_nan=False),
    st.sampled_from((0.0, -0.0, 10_000.0, -10_000.0, 5e-324)),
    st.integers(-10_000, 10_000),
)
_yaw = st.one_of(
    st.floats(-1e6, 1e6, allow_nan=False),
    st.sampled_from((math.pi, -math.pi, 0.0, 1e300, -1e300)),
    st.integers(-100, 100),
)
_linear = st.one_of(st.floats(-2.0, 2.0), st.sampled_from((0.0, 2.0, -2.0, 0.2)))
_angular = st.one_of(st.floats(-4.0, 4.0), st.sampled_from((0.0, 4.0, -4.0, 0.5)))
_kind = st.sampled_from(("table", "home", "pass", "other"))


# Strategies are built once, at import: one made inside a draw costs hypothesis a validation
# each time (it was 3/4 of the generation time). Helpers taking ``draw`` are plain functions.


def _pick(draw: st.DrawFn, seq: Sequence[T]) -> T:
    """One item of ``seq`` (any sequence, built at draw time) without a new strategy."""
    return seq[draw(st.integers(0, len(seq) - 1))]


def _with(
    draw: st.DrawFn, fields: dict[str, Node], optional: dict[str, st.SearchStrategy[Any]]
) -> Obj:
    """``fields`` (and an ``id``) plus any subset of ``optional``, each drawn."""
    out: dict[str, Node] = {"id": IdSlot(), **fields}
    for name, strat in optional.items():
        if draw(_bool):
            out[name] = draw(strat)
    return Obj(tuple(out.items()))


_bool = st.booleans()
_jitter = st.floats(-0.2, 0.2)


def _pose(draw: st.DrawFn) -> tuple[float, float, float]:
    if draw(st.integers(0, 9)) < 8:
        x, y, yaw = _pick(draw, GOOD_POSES)
        jitter = draw(_jitter)
        return (x + jitter, y - jitter, yaw)
    return (draw(_coord), draw(_coord), draw(_yaw))


def data_msgs() -> st.SearchStrategy[Obj]:
    topic = st.one_of(
        st.sampled_from(P.STATE_TOPICS),
        st.builds(lambda k, r: f"{k}:{r}", st.sampled_from(P.ROBOT_TOPICS), _any_robot),
    )
    topics = st.lists(topic, min_size=1, max_size=8)
    return st.builds(
        lambda t, extra: Obj((("clientmsg", "data"), ("id", IdSlot()), ("topics", t), *extra)),
        topics,
        st.one_of(st.just(()), st.booleans().map(lambda b: (("unsubscribe", b),))),
    )


_quantity = st.one_of(st.integers(1, 99), st.sampled_from((1, 99)))
_note = st.one_of(
    st.sampled_from(("", "no chilli", "extra ice", " ")), st.text(max_size=200).map(str.strip)
).filter(lambda s: len(s) <= 200)
#: Dish names for the menu as the store takes them: 1-64 characters, no outer spaces.
_menu_name = st.one_of(st.sampled_from(DISHES), _valid_text.map(str.strip)).filter(bool)


@st.composite
def create_order(draw: st.DrawFn) -> Obj:
    return _with(
        draw,
        {"clientmsg": "create", "type": "order", "dish": draw(_name), "table": draw(_table)},
        {
            "key": _key,
            "quantity": _quantity,
            "note": _note,
            "status": st.sampled_from(("ordered", "pending")),
            "special": st.sampled_from(("Happy birthday, Ana!", "\u751f\u65e5\u5feb\u4e50")),
        },
    )


@st.composite
def create_dish(draw: st.DrawFn) -> Obj:
    """A menu entry (the owner's: the fuzz connections are staff's, so mostly forbidden)."""
    return _with(
        draw,
        {"clientmsg": "create", "type": "dish", "name": draw(_menu_name)},
        {
            "category": st.sampled_from(("", "Mains", "Drinks", "Desserts")),
            "price_cents": st.one_of(st.none(), st.integers(0, 10_000_000)),
            "available": _bool,
            "position": st.integers(0, 10_000),
        },
    )


_ORDER_STATUSES = tuple(s.value for s in OrderStatus)


@st.composite
def dish_msgs(draw: st.DrawFn) -> Obj:
    """A dish's step on a recent order (or one that does not exist), with what the client saw."""
    action = _pick(draw, ("cooking", "ready", "void", "edit"))
    fields: dict[str, Node] = {
        "clientmsg": "dish",
        "order": Ref("order", draw(st.integers(0, 12))),
        "action": action,
    }
    if action == "edit":  # an edit without a change is refused (invalid_field): give one
        if draw(_bool):
            fields["quantity"] = draw(_quantity)
        else:
            fields["note"] = draw(_note)
    return _with(
        draw,
        fields,
        # Mostly what a screen would show (the fuzzer's dishes are mostly ready at the pass)
        # and a table that exists, so that steps get through as well as refused.
        {"status": st.sampled_from(("pending", "pending", "ordered", *_ORDER_STATUSES))}
        | ({"table": _table} if action == "edit" else {})
        | ({"note": _note} if action == "edit" and "note" not in fields else {}),
    )


def _target_verb(verb: str) -> st.SearchStrategy[Obj]:
    """A command on a robot's trip, with or without the trip and stop the client saw."""

    @st.composite
    def build(draw: st.DrawFn) -> Obj:
        return _with(
            draw,
            {"clientmsg": verb, "robot": draw(_any_robot)},
            {"task": st.one_of(st.none(), st.integers(1, 40)), "stop": st.integers(0, 3)},
        )

    return build()


@st.composite
def create_task(draw: st.DrawFn) -> Obj:
    orders: list[Node] = [Ref("order", b) for b in draw(_backs)]
    if draw(st.integers(0, 9)) == 0:
        orders.append(_pick(draw, (2**53, 10**6 + 7)))  # never created
    fields: dict[str, st.SearchStrategy[Any]] = {"key": _key}
    if draw(st.integers(0, 3)) == 0:  # staff chose a tray for the first dish
        fields["trays"] = st.integers(1, 5).map(lambda t: [obj(order=orders[0], tray=t)])
    return _with(draw, {"clientmsg": "create", "type": "task", "orders": orders}, fields)


_backs = st.lists(st.integers(0, 12), min_size=1, max_size=6, unique=True)


@st.composite
def create_waypoint(draw: st.DrawFn) -> Obj:
    name = _pick(draw, NEW_WAYPOINTS + TABLES)
    fields: dict[str, Node] = {"clientmsg": "create", "type": "waypoint", "name": name}
    if draw(_bool):
        fields["robot"] = draw(_any_robot)
        return _with(draw, fields, {"kind": _kind, "replace": _bool})
    x, y, yaw = _pose(draw)
    fields.update(x=x, y=y)
    out = _with(draw, fields, {"kind": _kind, "replace": _bool})
    return out.set("yaw", yaw) if draw(_bool) else out


@st.composite
def create_robot(draw: st.DrawFn) -> Obj:
    if draw(_bool):  # an existing robot: same content (no-op) or other (conflict)
        name = draw(_robot)
        url: Node = _pick(draw, (Ref("url", name), DEAD_URL))
        fields: dict[str, Node] = {"clientmsg": "create", "type": "robot", "name": name}
        fields["url"] = url
        out = _with(draw, fields, {"kinematics": st.sampled_from(("omni", "diff"))})
        if draw(_bool):  # its own home (same content), another, or a table
            out = out.set("home", _pick(draw, (f"home{ROBOTS.index(name) + 1}", "home3", "T3")))
        return out
    return _with(
        draw,
        {"clientmsg": "create", "type": "robot", "name": _pick(draw, NEW_ROBOTS), "url": DEAD_URL},
        {
            "home": st.sampled_from(("home3", "home4")),
            "kinematics": st.just("diff"),
            "trays": st.integers(1, 12),
        },
    )


def _control(action: str, **fields: st.SearchStrategy[Node]) -> st.SearchStrategy[Obj]:
    return st.builds(
        lambda robot, **kw: obj(clientmsg="control", id=IdSlot(), robot=robot, action=action, **kw),
        _any_robot,
        **fields,
    )


@st.composite
def control_teleop(draw: st.DrawFn) -> Obj:
    robot = draw(_any_robot)
    return _with(
        draw,
        {
            "clientmsg": "control",
            "robot": robot,
            "action": "teleop",
            "vx": draw(_linear),
            "wz": draw(_angular),
        },
        {"vy": _linear},
    )


@st.composite
def control_pose(draw: st.DrawFn, action: str) -> Obj:
    x, y, yaw = _pose(draw)
    return obj(
        clientmsg="control", id=IdSlot(), robot=draw(_any_robot), action=action, x=x, y=y, yaw=yaw
    )


def _robot_verb(verb: str) -> st.SearchStrategy[Obj]:
    return st.builds(lambda r: obj(clientmsg=verb, id=IdSlot(), robot=r), _any_robot)


def order_msgs() -> st.SearchStrategy[Obj]:
    return st.one_of(
        st.builds(lambda t: obj(clientmsg="order", id=IdSlot(), table=t), _table),
        st.builds(lambda r: obj(clientmsg="order", id=IdSlot(), robot=r), _any_robot),
    )


def login_msgs() -> st.SearchStrategy[Obj]:
    """Well-formed logins that must fail: unknown users, wrong passwords, made-up tokens.

    The fuzz connections stay authenticated (a failed login changes nothing); once the
    address is locked the replies turn to ``rate_limited``, also a documented answer.
    """
    password = st.text(min_size=1, max_size=40)
    token = st.text(alphabet="abcdefghijklmnopqrstuvwxyz0123456789_-", min_size=8, max_size=60)
    return st.one_of(
        st.builds(
            lambda u, p: obj(clientmsg="login", id=IdSlot(), username=u, password=p),
            st.sampled_from(["owner", "staff", "nobody"]),
            password,
        ),
        st.builds(lambda t: obj(clientmsg="login", id=IdSlot(), token="srv_" + t), token),
    )


_USERS = st.sampled_from(["owner", "staff", "alice", "nobody", "\u00e9l\u00e9onore"])
_USER_ROLES = st.sampled_from(["owner", "staff"])


def _account(action: str, **fields: st.SearchStrategy[Node]) -> st.SearchStrategy[Obj]:
    """An owner's ``account`` request: the fuzz connections are staff, so ``forbidden``."""
    return st.fixed_dictionaries(fields).map(
        lambda f: obj(clientmsg="account", id=IdSlot(), action=action, **f)
    )


@st.composite
def account_create_token(draw: st.DrawFn) -> Obj:
    if draw(st.booleans()):
        return obj(
            clientmsg="account",
            id=IdSlot(),
            action="create_token",
            role="robot-screen",
            robot=draw(_any_robot),
        )
    return obj(
        clientmsg="account",
        id=IdSlot(),
        action="create_token",
        role="table-screen",
        table=draw(_table),
        label=draw(st.text(max_size=20)),
        base="http://127.0.0.1:8765",
    )


def _site(action: str, **fields: st.SearchStrategy[Node]) -> st.SearchStrategy[Obj]:
    """An owner's ``site`` request: the fuzz connections are staff, so ``forbidden`` (no robot
    or table of the fuzz restaurant is ever edited or removed)."""
    return st.fixed_dictionaries(fields).map(
        lambda f: obj(clientmsg="site", id=IdSlot(), action=action, **f)
    )


_TRAYS = st.none() | st.integers(1, 12)
_LANGUAGES = st.lists(st.sampled_from(P.LANGUAGES), min_size=1, max_size=3, unique=True)
_EDIT_ROBOT: dict[str, st.SearchStrategy[Any]] = {
    "url": st.sampled_from((DEAD_URL, "ws://10.0.0.21:9090", "wss://robot.local")),
    "home": st.none() | st.sampled_from((*OTHER_WAYPOINTS, "T3", "T17")),
    "kinematics": st.sampled_from(("omni", "diff")),
    "link": st.sampled_from((Obj(()), obj(ns="/r1"), obj(ros="2"))),
    "trays": _TRAYS,
    "dock": st.none() | st.sampled_from(("dock1", "T3", "T17")),
}
_SET_SETTINGS: dict[str, st.SearchStrategy[Any]] = {
    "table_timeout": st.none() | st.floats(10, 3600),
    "trays": st.integers(1, 12),
    "auto_depart": st.booleans(),
    "languages": _LANGUAGES,
    "language": st.sampled_from(P.LANGUAGES),
    "target_wait": st.floats(60, 3600),
    "call_escalate": st.floats(15, 3600),
    "bussing_wait": st.floats(10, 1800),
    "bussing_max_delay": st.floats(0, 1800),
    # Never crossing (charge_until <= charge_below is refused, as it should be).
    "charge_below": st.floats(0.05, 0.5),
    "charge_until": st.floats(0.55, 1.0),
    "cruise_pause": st.floats(0, 600),
    "cruise_resume": st.floats(5, 600),
}
_CALL_KINDS = st.sampled_from(("plates", "waiter", "bill"))
_tables = st.lists(st.sampled_from(TABLES[:6] + UNKNOWN_WAYPOINTS[:1]), min_size=1, max_size=3)


def _some_of(fields: dict[str, st.SearchStrategy[Any]]) -> st.SearchStrategy[dict[str, Any]]:
    """At least one of ``fields``, each drawn (an edit names something to change)."""
    return st.lists(st.sampled_from(sorted(fields)), min_size=1, unique=True).flatmap(
        lambda keys: st.fixed_dictionaries({k: fields[k] for k in keys})
    )


def _site_some(action: str, fields: dict[str, st.SearchStrategy[Any]]) -> st.SearchStrategy[Obj]:
    extra: dict[str, st.SearchStrategy[Any]] = (
        {"robot": _any_robot} if action == "edit_robot" else {}
    )
    return st.tuples(st.fixed_dictionaries(extra), _some_of(fields)).map(
        lambda kv: obj(clientmsg="site", id=IdSlot(), action=action, **kv[0], **kv[1])
    )


_DAY = st.dates(min_value=date(2025, 1, 1), max_value=date(2027, 12, 31)).map(date.isoformat)
_WHEN = st.one_of(
    _DAY,
    st.builds(lambda d, h, m: f"{d}T{h:02d}:{m:02d}", _DAY, st.integers(0, 23), st.integers(0, 59)),
)
_OFFSET = st.sampled_from(("+08:00", "+00:00", "-05:30", "+14:00"))


_RANGE: dict[str, st.SearchStrategy[Any]] = {"start": _WHEN, "end": _WHEN, "utc_offset": _OFFSET}


def _stats(
    action: str,
    optional: dict[str, st.SearchStrategy[Any]] | None = None,
    **fields: st.SearchStrategy[Node],
) -> st.SearchStrategy[Obj]:
    """An owner's ``stats`` request: ``forbidden`` for the fuzz connections (staff), so no
    statistics child process or forecast replay ever runs during a fuzz run. ``fields`` are
    always there, each of ``optional`` may be."""

    @st.composite
    def build(draw: st.DrawFn) -> Obj:
        given = {k: draw(v) for k, v in fields.items()}
        return _with(draw, {"clientmsg": "stats", "action": action, **given}, optional or {})

    return build()


#: Zones the fuzzer names (the fuzz restaurant has none: ``release`` is ``not_found``, and a
#: staff connection may not draw one).
ZONES = ("aisle", "door", "pass zone")
_POINT: st.SearchStrategy[Node] = st.tuples(_coord, _coord).map(lambda xy: [xy[0], xy[1]])


@st.composite
def create_zone(draw: st.DrawFn) -> Obj:
    """An owner's zone (scope ``site``): ``forbidden`` for the fuzz connections (staff)."""
    points: Node = draw(st.lists(_POINT, min_size=3, max_size=6))
    return _with(
        draw,
        {"clientmsg": "create", "type": "zone", "name": _pick(draw, ZONES), "points": points},
        {"capacity": st.integers(1, 8), "replace": st.booleans()},
    )


@st.composite
def release_msgs(draw: st.DrawFn) -> Obj:
    zone = _pick(draw, (*ZONES, "T3"))
    return _with(draw, {"clientmsg": "release", "zone": zone}, {"robot": _any_robot})


#: verb (or "verb sub-type") -> strategy of valid messages. One line per verb.
VERB_STRATEGIES: dict[str, st.SearchStrategy[Obj]] = {
    "login": login_msgs(),
    "ping": st.builds(lambda: obj(clientmsg="ping", id=IdSlot())),
    "data": data_msgs(),
    "create order": create_order(),
    "create task": create_task(),
    "create waypoint": create_waypoint(),
    "create robot": create_robot(),
    "control auto": _control("auto"),
    "control manual": _control("manual"),
    "control teleop": control_teleop(),
    "control initialpose": control_pose("initialpose"),
    "control goal": control_pose("goal"),
    "control goto": _control("goto", waypoint=_table),
    "ready": _robot_verb("ready"),
    "next": _robot_verb("next"),
    "stop": _robot_verb("stop"),
    "continue": _robot_verb("continue"),
    "cancel": _robot_verb("cancel"),
    "go": _target_verb("go"),
    "skip": _target_verb("skip"),
    "order": order_msgs(),
    "create dish": create_dish(),
    "dish": dish_msgs(),
    "ack": st.builds(lambda a: obj(clientmsg="ack", id=IdSlot(), alert=a), st.integers(1, 30)),
    "clear": st.builds(lambda t: obj(clientmsg="clear", id=IdSlot(), table=t), _table),
    "create zone": create_zone(),
    "release": release_msgs(),
    "camera": st.builds(
        lambda robot, watch: obj(clientmsg="camera", id=IdSlot(), robot=robot, watch=watch),
        _any_robot,
        st.booleans(),
    ),
    "account list_users": _account("list_users"),
    "account add_user": _account("add_user", username=_USERS, role=_USER_ROLES),
    "account set_role": _account("set_role", username=_USERS, role=_USER_ROLES),
    "account reset_password": _account("reset_password", username=_USERS),
    "account remove_user": _account("remove_user", username=_USERS),
    "account create_token": account_create_token(),
    "account list_tokens": _account("list_tokens", all=st.booleans()),
    "account revoke_token": _account("revoke_token", token=st.integers(1, 30)),
    "site edit_robot": _site_some("edit_robot", _EDIT_ROBOT),
    "site remove_robot": _site("remove_robot", robot=_any_robot),
    "site dependents": _site("dependents", waypoint=_table),
    "site rename_waypoint": _site(
        "rename_waypoint", waypoint=_table, name=st.sampled_from(NEW_WAYPOINTS)
    ),
    "site remove_waypoint": _site("remove_waypoint", waypoint=_table),
    "site remove_zone": _site("remove_zone", zone=st.sampled_from(ZONES)),
    "site settings": _site("settings"),
    "site set_settings": _site_some("set_settings", _SET_SETTINGS),
    "site audit": _site(
        "audit", verb=st.sampled_from(("site", "create", "next")), limit=st.integers(1, 500)
    ),
    "stats figures": _stats("figures", {**_RANGE, "by": st.sampled_from(("day", "hour"))}),
    "stats trips": _stats("trips", _RANGE),
    "stats forecast": _stats(
        "forecast",
        {"policy": st.sampled_from(("serveur", "baseline")), "utc_offset": _OFFSET},
        day=_DAY,
        robots=st.lists(st.integers(1, 12), min_size=1, max_size=6, unique=True),
    ),
    "stats forecast_cancel": _stats("forecast_cancel"),
    "call open": st.builds(
        lambda t, k: obj(clientmsg="call", id=IdSlot(), action="open", table=t, kind=k),
        # A home or the pass is refused with invalid_field (docs/protocol.md, call): not a
        # malformed frame, so the places named here are tables or unknown names (not_found).
        st.sampled_from(TABLES + UNKNOWN_WAYPOINTS),
        _CALL_KINDS,
    ),
    "call answer": st.builds(
        lambda c: obj(clientmsg="call", id=IdSlot(), action="answer", call=c), st.integers(1, 20)
    ),
    "call cancel": st.builds(
        lambda c: obj(clientmsg="call", id=IdSlot(), action="cancel", call=c), st.integers(1, 20)
    ),
    "create bussing": st.builds(
        lambda ts: obj(clientmsg="create", id=IdSlot(), type="bussing", tables=ts),
        _tables.map(lambda ts: list(dict.fromkeys(ts))),
    ),
    "charge": _robot_verb("charge"),
    "work": _robot_verb("work"),
    "cruise": st.builds(
        lambda r, ts: obj(clientmsg="cruise", id=IdSlot(), robot=r, route=ts),
        _any_robot,
        _tables.map(lambda ts: list(dict.fromkeys(ts))),
    ),
    "site add_button": _site(
        "add_button", name=st.sampled_from(("b1", "b2")), table=_table, kind=_CALL_KINDS
    ),
    "site buttons": _site("buttons"),
    "site revoke_button": _site("revoke_button", name=st.sampled_from(("b1", "b2", "b9"))),
    # The owner's: a fuzz connection (staff) is refused.
    "chain": st.builds(lambda: obj(clientmsg="chain", id=IdSlot())),
}


def _till(action: str, **fields: st.SearchStrategy[Node]) -> st.SearchStrategy[Obj]:
    """A ``till`` request. The fuzz connections are staff: ``state``, ``tickets`` and
    ``by_hand`` are theirs; the set-up (``setup``, ``propose``, ``preview``) and the menu's
    names are the owner's, so ``forbidden`` (no printer port is ever opened by a fuzz run)."""
    return st.fixed_dictionaries(fields).map(
        lambda f: obj(clientmsg="till", id=IdSlot(), action=action, **f)
    )


_TICKET_ID = st.integers(1, 30)
_MARK_AS = st.sampled_from(("table", "dish", "note", "ticket", "void", "ignore"))
_MARKS = st.lists(
    st.builds(lambda line, a: obj(line=line, **{"as": a}), st.integers(0, 40), _MARK_AS),
    min_size=1,
    max_size=6,
)
_PATTERN = st.builds(
    lambda t, d: obj(table=t, dish=d),
    st.sampled_from((r"^\s*Table:\s*(?P<table>\w+)", r"(?P<table>\w+)")),
    st.sampled_from((r"^(?P<qty>\d{1,2})\s+x\s+(?P<name>\w.*)$",)),
)
_TILL: dict[str, st.SearchStrategy[Obj]] = {
    "till state": _till("state"),
    "till tickets": _till("tickets", limit=st.integers(1, 200)),
    "till by_hand": _till("by_hand", ticket=_TICKET_ID),
    "till propose": _till("propose", ticket=_TICKET_ID, marks=_MARKS),
    "till preview": _till("preview", pattern=_PATTERN),
    "till setup": _till(
        "setup",
        port=st.just(0),
        printer=st.sampled_from(("", "127.0.0.1:9")),
        encoding=st.sampled_from(("auto", "cp437", "gb18030")),
    ),
    "till import_menu": _till(
        "import_menu", csv=st.sampled_from(("till,dish\nLAKSA,Laksa\n", "item\nKopi O\n"))
    ),
    "till map": _till(
        "map",
        names=st.dictionaries(
            st.sampled_from(("LAKSA", "Kopi O")), st.none() | _table, min_size=1
        ).map(lambda d: obj(**d)),
    ),
    "till unmapped": _till("unmapped"),
}
VERB_STRATEGIES.update(_TILL)


def valid_messages(labels: Sequence[str] | None = None) -> st.SearchStrategy[tuple[str, Obj]]:
    """``(label, message)`` for a valid message of one of ``labels`` (default: every verb)."""
    chosen = list(labels) if labels is not None else list(VERB_STRATEGIES)
    return st.one_of(*(VERB_STRATEGIES[lb].map(lambda m, lb=lb: (lb, m)) for lb in chosen))


_VALID = valid_messages()

# --------------------------------------------------------------------------- mutations

_NON_FINITE = st.sampled_from(
    (Raw("NaN"), Raw("Infinity"), Raw("-Infinity"), Raw("1e400"), Raw("-1e999"))
)
_WEIRD_STR = st.one_of(
    st.sampled_from(
        (
            "",
            " ",
            "\x00",
            "r1\n",
            "\u0085",
            "\ufeff",
            "\ud800",
            "\udfff\ud800",
            "\U0001f916",
            "a\u0301",
            "\u202eT3",
            "null",
            "1",
            "true",
            "T3 ",
            "' OR 1=1 --",
            "%s%n",
            "${jndi}",
            "<script>",
        )
    ),
    st.text(max_size=20),
    st.integers(65, 5000).map(lambda n: "x" * n),
    st.integers(60, 70).map(lambda n: "\U0001f37d" * n),
)
_WEIRD_NUM = st.one_of(
    st.sampled_from((0, -1, 1, 2**31, 2**53 + 1, 2**63, -(2**63), 10**64, 10**65, 0.5, -0.0)),
    st.floats(allow_nan=False, allow_infinity=False),
    st.integers(4000, 5000).map(lambda n: Raw("9" * n)),
    st.sampled_from((Raw("1e308"), Raw("-0"), Raw("1E2"), Raw("1.0e-400"))),
)
_WEIRD_SCALAR = st.one_of(st.none(), st.booleans(), _WEIRD_NUM, _WEIRD_STR)
#: Values no field accepts: objects, non-finite numbers, nesting beyond 20 levels.
_ALWAYS_INVALID = st.one_of(
    _NON_FINITE,
    st.builds(lambda v: Obj((("a", v),)), _WEIRD_SCALAR),
    st.just(Obj(())),
    st.integers(20, 20_000).map(lambda d: Raw("[" * d + "]" * d)),
    st.integers(20, 8_000).map(lambda d: Raw('{"a":' * d + "1" + "}" * d)),
    st.lists(st.just(Obj(())), min_size=1, max_size=3),
)
_WEIRD = st.one_of(
    _WEIRD_SCALAR,
    st.lists(_WEIRD_SCALAR, max_size=5),
    st.lists(st.integers(1, 60), min_size=0, max_size=60),
    st.lists(st.sampled_from((*P.STATE_TOPICS, "pose:r1", "scan:r2", "pose:", "x")), max_size=70),
)
_EXTRA_KEYS = st.sampled_from(
    ("vz", "extra", "", "ID", "clientMsg", "\ud800", "\U0001f916", "__proto__")
)


def _model(msg: Obj) -> type[Any] | None:
    verb = msg.get("clientmsg")
    sub = (
        {
            "create": "type",
            "control": "action",
            "account": "action",
            "site": "action",
            "stats": "action",
        }.get(verb)
        if isinstance(verb, str)
        else None
    )
    label = f"{verb} {msg.get(sub)}" if sub else verb
    return _MODELS.get(label) if isinstance(label, str) else None


_MODELS: dict[str, type[Any]] = {
    "login": P.LoginMsg,
    "ping": P.PingMsg,
    "data": P.DataMsg,
    "create order": P.CreateOrder,
    "create task": P.CreateTask,
    "create waypoint": P.CreateWaypoint,
    "create robot": P.CreateRobot,
    "control auto": P.ControlAuto,
    "control manual": P.ControlManual,
    "control teleop": P.ControlTeleop,
    "control initialpose": P.ControlInitialPose,
    "control goal": P.ControlGoal,
    "control goto": P.ControlGoto,
    "ready": P.ReadyMsg,
    "next": P.NextMsg,
    "stop": P.StopMsg,
    "continue": P.ContinueMsg,
    "cancel": P.CancelMsg,
    "order": P.OrderMsg,
    "create dish": P.CreateDish,
    "go": P.GoMsg,
    "skip": P.SkipMsg,
    "dish": P.DishMsg,
    "ack": P.AckMsg,
    "clear": P.ClearMsg,
    "account list_users": P.AccountListUsers,
    "account add_user": P.AccountAddUser,
    "account set_role": P.AccountSetRole,
    "account reset_password": P.AccountResetPassword,
    "account remove_user": P.AccountRemoveUser,
    "account create_token": P.AccountCreateToken,
    "account list_tokens": P.AccountListTokens,
    "account revoke_token": P.AccountRevokeToken,
    "site edit_robot": P.SiteEditRobot,
    "site remove_robot": P.SiteRemoveRobot,
    "site dependents": P.SiteDependents,
    "site rename_waypoint": P.SiteRenameWaypoint,
    "site remove_waypoint": P.SiteRemoveWaypoint,
    "site remove_zone": P.SiteRemoveZone,
    "create zone": P.CreateZone,
    "release": P.ReleaseMsg,
    "camera": P.CameraMsg,
    "site settings": P.SiteSettings,
    "site set_settings": P.SiteSetSettings,
    "site audit": P.SiteAudit,
    "stats figures": P.StatsFigures,
    "stats trips": P.StatsTrips,
    "stats forecast": P.StatsForecast,
    "stats forecast_cancel": P.StatsForecastCancel,
    "chain": P.ChainMsg,
}


def _required(msg: Obj) -> list[str]:
    model = _model(msg)
    if model is None:
        return []
    return [
        k for k in msg.names() if k in model.model_fields and model.model_fields[k].is_required()
    ]


def _safe_robot_create(msg: Obj) -> Obj:
    # A "create robot" that might still be valid after mutation must not register an unbounded
    # number of robots (each keeps a reconnecting link) nor point one at another host: keep the
    # name in the pool and the URL on loopback.
    if msg.get("clientmsg") != "create" or msg.get("type") != "robot":
        return msg
    name, url = msg.get("name"), msg.get("url")
    if isinstance(name, str) and name.strip() not in ROBOTS + NEW_ROBOTS:
        msg = msg.set("name", "r3")
    if isinstance(url, str) and url != DEAD_URL:
        msg = msg.set("url", DEAD_URL)
    return msg


_TAGS = (
    *P.VERBS,
    "waypoint",
    "order",
    "task",
    "robot",
    "dish",
    "auto",
    "teleop",
    "goto",
    "login",
    "void",
    "add_user",
    "revoke_token",
)
_BORROWED: tuple[tuple[str, Node], ...] = (
    ("robot", "r1"),
    ("table", "T3"),
    ("x", 1.0),
    ("key", "k1"),
    ("unsubscribe", True),
    ("replace", True),
    ("home", "home1"),
    ("orders", (1, 2)),
    ("vy", 0.0),
    ("waypoint", "T1"),
    ("topics", ("robots",)),
)
_SAME_OR_WEIRD = st.one_of(st.none(), _WEIRD_SCALAR)
_UNKNOWN_VERB = _WEIRD_STR.filter(lambda v: v not in P.VERBS)


def _neutral(draw: st.DrawFn, msg: Obj) -> Obj:
    """A change that may or may not keep the message valid."""
    keys = msg.names()
    how = draw(st.integers(0, 5))
    if how <= 2 and keys:  # replace a value by a weird one
        return msg.set(_pick(draw, keys), draw(_WEIRD))
    if how == 3 and keys:  # drop a field
        return msg.without(_pick(draw, keys))
    if how == 4:  # another verb's or sub-type's tag
        return msg.set(_pick(draw, ("clientmsg", "type", "action")), _pick(draw, _TAGS))
    key, value = _pick(draw, _BORROWED)  # a field from another message
    return msg.set(key, value)


def _invalidate(draw: st.DrawFn, msg: Obj) -> tuple[Obj, str]:
    """A change after which the message is certainly refused."""
    keys = msg.names()
    required = _required(msg)
    how = draw(st.integers(0, 5))
    if how == 0 and keys:
        return msg.set(_pick(draw, keys), draw(_ALWAYS_INVALID)), "invalid value"
    if how == 1 and keys:  # the same key twice: with its own value or another
        key = _pick(draw, keys)
        value = draw(_SAME_OR_WEIRD)
        return msg.add(key, msg.get(key) if value is None else value), "duplicate key"
    if how == 2 and required:
        return msg.without(_pick(draw, required)), "missing field"
    if how == 3:
        return msg.set("clientmsg", draw(_UNKNOWN_VERB)), "unknown verb"
    model = _model(msg)
    extra = draw(_EXTRA_KEYS)
    if model is not None and extra not in model.model_fields:
        return msg.add(extra, draw(_WEIRD_SCALAR)), "unknown field"
    return msg.set("clientmsg", _pick(draw, (1, None, True, ("data",)))), "bad verb type"


def _mutate(draw: st.DrawFn, msg: Obj) -> tuple[Obj, str, bool | None]:
    label = "mutated"
    valid: bool | None = True
    for _ in range(draw(st.integers(0, 2))):
        msg = _neutral(draw, msg)
        valid = None
    if valid is True or draw(_bool):
        msg, label = _invalidate(draw, msg)
        valid = False
    return _safe_robot_create(msg), label, valid


@st.composite
def mutated(draw: st.DrawFn, msg: Obj) -> tuple[Obj, str, bool | None]:
    """``(message, label, valid)``: 0-2 neutral changes, then maybe one invalidating change."""
    return _mutate(draw, msg)


_NOT_OBJECTS = st.sampled_from(
    (
        "[]",
        "[1,2]",
        '["clientmsg","data"]',
        '"data"',
        "1",
        "-0",
        "1e400",
        "NaN",
        "true",
        "null",
        '[{"clientmsg":"data","topics":["robots"]}]',
    )
)
_GARBAGE = st.one_of(
    st.sampled_from(
        (
            "",
            " ",
            "{",
            "}",
            "{}}",
            "{]",
            '{"clientmsg"}',
            "{'clientmsg': 'data'}",
            '{"clientmsg":"data",}',
            '{"id":7,"clientmsg":"da',
            "\x00",
            "\ufeff{}",
            '{"a":1}{"b":2}',
            '{"clientmsg":"data"\x00}',
            "\u2028",
            "/* */{}",
        )
    ),
    st.text(max_size=40),
)


@st.composite
def frames(draw: st.DrawFn, conns: int = 2) -> Send:
    """One frame: valid (about half), mutated, not an object, or not JSON at all."""
    conn = draw(st.integers(0, conns - 1))
    kind = draw(st.integers(0, 19))
    if kind < 10:
        label, msg = draw(_VALID)
        step = Send(msg, label, True, conn, verb=label)
    elif kind < 16:
        label, msg = draw(_VALID)
        msg, how, valid = _mutate(draw, msg)
        step = Send(msg, f"{label}: {how}", valid, conn, verb=label)
    elif kind < 18:
        step = Send(Raw(draw(_NOT_OBJECTS)), "not an object", False, conn)
    else:
        step = Send(Raw(draw(_GARBAGE)), "not JSON", False, conn)
    return _framing(draw, step)


def _framing(draw: st.DrawFn, step: Send) -> Send:
    """How the frame travels: text or binary, padded, truncated, or not UTF-8."""
    how = draw(st.integers(0, 19))
    if how < 14:
        return step
    if how < 16:
        return _replace(step, binary=True)
    if how == 16:
        return _replace(step, pad=_pick(draw, (" ", "\n", "\t \r\n", "  ")))
    if how == 17:
        return _replace(step, binary=True, bad_utf8=True, valid=False, label="not UTF-8")
    # Shorter than the text: refused (no prefix of a JSON object is a whole object); the
    # harness keeps ``valid`` when the cut is past the end.
    return _replace(step, cut=draw(st.integers(0, 200)), label=f"{step.label}: truncated")


def _replace(step: Send, **changes: Any) -> Send:
    return dataclasses.replace(step, **changes)


# --------------------------------------------------------------------------- flows


def _send(label: str, body: Obj, conn: int) -> Send:
    return Send(body, label, True, conn, verb=label)


@st.composite
def deliver(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """Dishes for 1-3 tables, their cart confirmed, a wait for a robot to take the trip."""
    conn = draw(st.integers(0, conns - 1))
    tables = draw(_tables)
    steps: list[Step] = [
        _send(
            "create order",
            obj(clientmsg="create", id=IdSlot(), type="order", dish=draw(_name), table=t),
            conn,
        )
        for t in tables
    ]
    orders: list[Node] = [Ref("order", k) for k in range(len(tables))]
    steps.append(
        _send("create task", obj(clientmsg="create", id=IdSlot(), type="task", orders=orders), conn)
    )
    # A robot takes it at the pass (Loading); staff load the trays and press Go.
    steps.append(Wait(draw(_robot), frozenset({"Loading", "Delivering"}), draw(_timeout)))
    steps += [_send("go", obj(clientmsg="go", id=IdSlot(), robot=r), conn) for r in ROBOTS]
    return steps


_tables = st.lists(st.sampled_from(TABLES), min_size=1, max_size=3)
#: Wall seconds a Wait gives a robot; robots keep moving between examples anyway.
_timeout = st.sampled_from((0.02, 0.1, 0.3))


@st.composite
def activate(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """Bring a robot back to automatic: ready (from Manual/Awaiting), auto (from Ready)."""
    conn, robot = draw(st.integers(0, conns - 1)), draw(_robot)
    return [
        _send("ready", obj(clientmsg="ready", id=IdSlot(), robot=robot), conn),
        _send(
            "control auto", obj(clientmsg="control", id=IdSlot(), robot=robot, action="auto"), conn
        ),
    ]


@st.composite
def serve(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """Wait for a robot at a table, then "food collected" (or the table skipped)."""
    conn, robot = draw(st.integers(0, conns - 1)), draw(_robot)
    verb = _pick(draw, ("next", "next", "skip"))
    return [
        Wait(robot, frozenset({"Delivered"}), draw(_timeout)),
        _send(verb, obj(clientmsg=verb, id=IdSlot(), robot=robot), conn),
    ]


@st.composite
def interrupt(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """Stop a moving robot, then continue, cancel or take it over manually."""
    conn, robot = draw(st.integers(0, conns - 1)), draw(_robot)
    then = _pick(draw, ("continue", "cancel", "manual"))
    last = (
        obj(clientmsg="control", id=IdSlot(), robot=robot, action="manual")
        if then == "manual"
        else obj(clientmsg=then, id=IdSlot(), robot=robot)
    )
    return [
        Wait(robot, frozenset({"Delivering", "Transit"}), draw(_timeout)),
        _send("stop", obj(clientmsg="stop", id=IdSlot(), robot=robot), conn),
        _send("control manual" if then == "manual" else then, last, conn),
    ]


@st.composite
def manual_session(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """Manual control: teleop, go-to, calibrate at a real pose, hand back."""
    conn, robot = draw(st.integers(0, conns - 1)), draw(_robot)
    x, y, yaw = _pick(draw, GOOD_POSES)
    return [
        _send(
            "control manual",
            obj(clientmsg="control", id=IdSlot(), robot=robot, action="manual"),
            conn,
        ),
        _send(
            "control teleop",
            obj(clientmsg="control", id=IdSlot(), robot=robot, action="teleop", vx=0.3, wz=0.2),
            conn,
        ),
        _send(
            "control goto",
            obj(
                clientmsg="control",
                id=IdSlot(),
                robot=robot,
                action="goto",
                waypoint=_pick(draw, TABLES),
            ),
            conn,
        ),
        _send(
            "control initialpose",
            obj(
                clientmsg="control",
                id=IdSlot(),
                robot=robot,
                action="initialpose",
                x=x,
                y=y,
                yaw=yaw,
            ),
            conn,
        ),
        _send("ready", obj(clientmsg="ready", id=IdSlot(), robot=robot), conn),
    ]


@st.composite
def kitchen(draw: st.DrawFn, conns: int = 2) -> list[Step]:
    """A dish taken for the kitchen, started, maybe edited, then ready at the pass or voided."""
    conn = draw(st.integers(0, conns - 1))
    newest = Ref("order", 0)
    steps: list[Step] = [
        _send(
            "create order",
            obj(
                clientmsg="create",
                id=IdSlot(),
                type="order",
                dish=draw(_name),
                table=_pick(draw, TABLES),
                quantity=draw(_quantity),
                status="ordered",
            ),
            conn,
        ),
        _send(
            "dish",
            obj(clientmsg="dish", id=IdSlot(), order=newest, action="cooking", status="ordered"),
            conn,
        ),
    ]
    if draw(_bool):
        edit = obj(clientmsg="dish", id=IdSlot(), order=newest, action="edit", note=draw(_note))
        steps.append(_send("dish", edit, conn))
    last = _pick(draw, ("ready", "ready", "void"))
    steps.append(_send("dish", obj(clientmsg="dish", id=IdSlot(), order=newest, action=last), conn))
    return steps


def _single(conns: int) -> st.SearchStrategy[list[Step]]:
    return frames(conns).map(lambda f: [f])


def _wait(conns: int) -> st.SearchStrategy[list[Step]]:
    return st.builds(
        lambda r, s, t: [Wait(r, frozenset({s}), t)], _robot, st.sampled_from(STATUSES), _timeout
    )


def _relog(conns: int) -> st.SearchStrategy[list[Step]]:
    probes = valid_messages([lb for lb in VERB_STRATEGIES if lb != "login"])
    return st.builds(
        lambda c, probe: [Relog(probe[1], probe[0], c)], st.integers(0, conns - 1), probes
    )


def examples(conns: int = 2, max_groups: int = 8) -> st.SearchStrategy[list[Step]]:
    """One fuzz example: a few groups of steps (single frames, or short flows), flattened."""
    groups: list[tuple[int, st.SearchStrategy[list[Step]]]] = [
        (12, _single(conns)),
        (2, deliver(conns)),
        (1, activate(conns)),
        (1, serve(conns)),
        (1, interrupt(conns)),
        (1, manual_session(conns)),
        (1, kitchen(conns)),
        (1, _wait(conns)),
        (1, _relog(conns)),
    ]
    weighted = [strat for weight, strat in groups for _ in range(weight)]
    group = st.integers(0, len(weighted) - 1).flatmap(lambda i: weighted[i])
    return st.lists(group, min_size=1, max_size=max_groups).map(
        lambda gs: [s for g in gs for s in g]
    )


#: For tests: every label a valid message can have.
LABELS: tuple[str, ...] = tuple(VERB_STRATEGIES)
