"""Who may do what: roles, scopes, the authorisation rules, password and token hashing.

Pure code, no I/O: the server asks :func:`authorize` before every instruction and
:func:`visible` (through a screen's :class:`ScreenView`) before pushing a record, and the
tests check the whole table without sockets.

The roles (docs/security.md has the threat model behind them):

* **owner** — everything, including registering robots, reading the audit trail and managing
  accounts and screen tokens (scope ``accounts``, which only an owner's session carries);
* **staff** — orders, carts (tasks), robot control, waypoints, every topic;
* **robot-screen** — bound to one robot: its own record, trip and tray, and
  next / stop / continue / cancel for that robot only (it sits in the dining room, where
  guests can touch it);
* **table-screen** — bound to one table: read that table's cart and the trips coming to it,
  and press "food collected" (``next``) for the robot standing at that table (the core
  checks where the robot is);
* **integration** — scripted clients, with exactly the scopes the owner gave its token.

Passwords are hashed with scrypt (memory-hard, in the standard library: no compiled
dependency to build on a Pi), parameters stored in the hash so they can be raised later.
Tokens are 256 random bits; only their SHA-256 is stored, so a copied database file does not
hand out live sessions. A slow KDF is pointless for tokens that cannot be guessed anyway.
"""

from __future__ import annotations

import base64
import hashlib
import hmac
import secrets
from collections import OrderedDict
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Final

from serveur.errors import Forbidden, InvalidField, RateLimited, Unauthorized

__all__ = [
    "DEVICE_ROLES",
    "OWNER_SCOPES",
    "STAFF_SCOPES",
    "TOKEN_PREFIX",
    "LoginThrottle",
    "Principal",
    "RateLimiter",
    "Role",
    "Scope",
    "ScreenView",
    "authorize",
    "check_password_strength",
    "hash_password",
    "new_password",
    "new_token",
    "parse_scopes",
    "required_scope",
    "token_digest",
    "topic_allowed",
    "verify_password",
    "visible",
]


class Role(StrEnum):
    OWNER = "owner"
    STAFF = "staff"
    ROBOT_SCREEN = "robot-screen"
    TABLE_SCREEN = "table-screen"
    INTEGRATION = "integration"


class Scope(StrEnum):
    """What an instruction needs. Integration tokens carry a chosen subset."""

    READ = "read"  # subscribe to topics, list orders
    ORDERS = "orders"  # create orders
    TASKS = "tasks"  # confirm carts; next / stop / continue / cancel
    CONTROL = "control"  # auto / manual / teleop / initialpose / goal / goto / ready
    WAYPOINTS = "waypoints"  # create or replace waypoints
    ROBOTS = "robots"  # register robots
    AUDIT = "audit"  # read the audit trail
    MENU = "menu"  # edit the menu
    ACCOUNTS = "accounts"  # people and screen tokens (owners only: never a token's scope)
    SITE = "site"  # edit or remove robots and waypoints, the site's settings
    STATS = "stats"  # statistics and trip history


STAFF_SCOPES: Final = frozenset(
    {Scope.READ, Scope.ORDERS, Scope.TASKS, Scope.CONTROL, Scope.WAYPOINTS}
)
OWNER_SCOPES: Final = frozenset(Scope)
#: Roles given to tokens (devices and scripts) rather than to people with passwords.
DEVICE_ROLES: Final = (Role.STAFF, Role.ROBOT_SCREEN, Role.TABLE_SCREEN, Role.INTEGRATION)
TOKEN_PREFIX: Final = "srv_"

# What a robot screen may do to its own robot.
_ROBOT_SCREEN_VERBS: Final = frozenset({"next", "stop", "continue", "cancel", "go", "skip"})


@dataclass(frozen=True, slots=True)
class Principal:
    """An authenticated connection's identity: a user's session or a device/script token."""

    role: Role
    token_id: int
    user: str | None = None
    robot: str | None = None
    table: str | None = None
    scopes: frozenset[Scope] = field(default_factory=frozenset)
    expires_at: float | None = None
    label: str = ""

    @property
    def actor(self) -> str:
        """Who, for the audit trail: ``user:alice`` or ``token:7``."""
        return f"user:{self.user}" if self.user else f"token:{self.token_id}"

    def expired(self, now: float) -> bool:
        return self.expires_at is not None and now >= self.expires_at

    def public(self) -> dict[str, Any]:
        """What the client is told about itself (never the token)."""
        return {
            "user": self.user,
            "role": self.role.value,
            "robot": self.robot,
            "table": self.table,
            "scopes": sorted(s.value for s in self.scopes),
            "expires": self.expires_at,
        }


def parse_scopes(text: str | Iterable[str]) -> frozenset[Scope]:
    items = text.split(",") if isinstance(text, str) else list(text)
    out: set[Scope] = set()
    for raw in items:
        name = raw.strip()
        if not name:
            continue
        try:
            out.add(Scope(name))
        except ValueError:
            known = ", ".join(s.value for s in Scope)
            raise InvalidField(f"unknown scope {name!r} (known: {known})", scope=name) from None
    return frozenset(out)


_BACKUP_ACTIONS = frozenset({"backups", "backup_now", "download_backup", "restore"})
#: The till's actions: reading tickets is staff's, marking one done by hand is an order's
#: step, the printer port and the pattern are the site's, the till's item names the menu's.
_TILL_SCOPES: Final = {
    "state": Scope.READ,
    "tickets": Scope.READ,
    "by_hand": Scope.ORDERS,
    "propose": Scope.SITE,
    "preview": Scope.SITE,
    "setup": Scope.SITE,
    "import_menu": Scope.MENU,
    "map": Scope.MENU,
    "unmapped": Scope.MENU,
}


def required_scope(msg: Any) -> Scope:
    """The scope an instruction needs (``login``/``logout``/``ping`` need none, not asked)."""
    verb = msg.clientmsg
    if verb in ("data", "order"):
        return Scope.READ
    if verb == "create":
        return {
            "order": Scope.ORDERS,
            "task": Scope.TASKS,
            "waypoint": Scope.WAYPOINTS,
            "robot": Scope.ROBOTS,
            "dish": Scope.MENU,
            "zone": Scope.SITE,  # the owner's drawing of the room
            "bussing": Scope.TASKS,
        }[msg.type]
    if verb == "dish":
        return Scope.ORDERS
    if verb in ("go", "skip", "ack", "clear", "release"):
        return Scope.TASKS
    if verb in ("control", "ready", "camera"):  # watching a camera is part of manual control
        return Scope.CONTROL
    if verb in ("next", "stop", "continue", "cancel", "call", "charge", "work", "cruise"):
        return Scope.TASKS
    if verb == "account":
        return Scope.ACCOUNTS
    if verb == "site":
        if msg.action == "audit":
            return Scope.AUDIT
        if msg.action in _BACKUP_ACTIONS:
            # A backup holds every account (password hashes, token digests) and restoring one
            # sets them all: as much as the accounts themselves, which no token can be given.
            return Scope.ACCOUNTS
        return Scope.SITE
    if verb == "stats":
        return Scope.STATS
    if verb == "till":
        return _TILL_SCOPES[msg.action]
    if verb == "chain":  # the site's place in a restaurant chain: its set-up, read
        return Scope.SITE
    raise Forbidden(f"no rule for {verb!r}")  # a new verb must get a rule before anyone uses it


def topic_allowed(p: Principal, topic: str) -> bool:
    """May ``p`` subscribe to ``topic``? Screens see filtered views of a few topics."""
    kind, _, robot = topic.partition(":")
    if p.role is Role.ROBOT_SCREEN:
        return topic in ("robots", "tasks", "orders", "settings") or (
            kind == "pose" and robot == p.robot
        )
    if p.role is Role.TABLE_SCREEN:
        return topic in ("orders", "tasks", "menu", "settings", "calls")
    if topic == "audit":
        return Scope.AUDIT in p.scopes
    if topic == "forecast":
        return Scope.STATS in p.scopes
    return Scope.READ in p.scopes


def authorize(p: Principal | None, msg: Any) -> None:
    """Raise Unauthorized/Forbidden unless ``p`` may carry out ``msg``; return quietly if so."""
    verb = msg.clientmsg
    if verb == "login":
        return
    if p is None:
        raise Unauthorized("log in first: send a login message")
    if verb in ("logout", "ping"):
        return
    if p.role is Role.ROBOT_SCREEN:
        robot = getattr(msg, "robot", None)
        if verb == "data":
            _topics(p, msg.topics)
            return
        if verb in _ROBOT_SCREEN_VERBS or (verb == "order" and robot is not None):
            if robot != p.robot:
                raise Forbidden(f"this screen belongs to robot {p.robot}", robot=robot)
            return
        raise Forbidden(f"a robot screen may not send {verb!r}")
    if p.role is Role.TABLE_SCREEN:
        if verb == "data":
            _topics(p, msg.topics)
            return
        if verb == "order" and getattr(msg, "table", None) is not None:
            if msg.table != p.table:
                raise Forbidden(f"this screen belongs to table {p.table}", table=msg.table)
            return
        if verb == "next":
            return  # only for the robot at this table: the core checks (Core.handle)
        if verb == "call" and msg.action == "open":
            if msg.table != p.table:
                raise Forbidden(f"this screen belongs to table {p.table}", table=msg.table)
            return
        raise Forbidden(f"a table screen may not send {verb!r}")
    if verb == "data":
        _topics(p, msg.topics)
        return
    need = required_scope(msg)
    if need not in p.scopes:
        raise Forbidden(f"{verb!r} needs the {need.value!r} scope", scope=need.value)


def _topics(p: Principal, topics: Iterable[str]) -> None:
    for t in topics:
        if not topic_allowed(p, t):
            raise Forbidden(f"role {p.role.value} may not read topic {t!r}", topic=t)


def visible(p: Principal, topic: str, record: Any, task_robot: Callable[[int], str | None]) -> bool:
    """Does this pushed or snapshot record belong in ``p``'s view of ``topic``?

    Staff, owners and integrations see everything they may subscribe to. A robot screen
    sees its robot, its trips and the dishes on them; a table screen its table's dishes.
    ``task_robot`` maps a task id to the robot doing it (the core knows).
    """
    if p.role is Role.ROBOT_SCREEN:
        if topic == "robots":
            return bool(getattr(record, "name", None) == p.robot)
        if topic == "tasks":
            return bool(getattr(record, "robot", None) == p.robot)
        if topic == "orders":
            tid = getattr(record, "task_id", None)
            return tid is not None and task_robot(tid) == p.robot
        return True  # pose:<own robot>, already checked by topic_allowed
    if p.role is Role.TABLE_SCREEN:
        if topic == "tasks":
            return any(s.table == p.table for s in getattr(record, "stops", ()))
        if topic in ("menu", "settings"):
            return True
        return topic in ("orders", "calls") and getattr(record, "table", None) == p.table
    return True


#: Records a screen's view remembers having shown (a night's dishes and trips are hundreds).
_VIEW_MEMORY: Final = 10_000


class ScreenView:
    """A screen's view of its topics: :func:`visible`, plus the update that moves a record out.

    A robot screen showed a dish on its trip; the trip is cancelled and the dish goes back to
    ``pending`` with no trip. By :func:`visible` alone that update is not the screen's any
    more, so it was filtered out and the screen kept the dish ``assigned`` for good. The view
    remembers which records it has let through (by topic and id or name) and lets the one
    update that takes such a record out of scope through too, then forgets it.
    """

    def __init__(
        self, p: Principal, task_robot: Callable[[int], str | None], *, memory: int = _VIEW_MEMORY
    ) -> None:
        self.principal = p
        self._task_robot = task_robot
        self._memory = memory
        self._shown: OrderedDict[tuple[str, object], None] = OrderedDict()

    def __call__(self, topic: str, record: Any) -> bool:
        """Does this pushed update go to the screen? In scope, or leaving it."""
        key = _record_key(topic, record)
        if visible(self.principal, topic, record, self._task_robot):
            self._remember(key)
            return True
        if key is not None and key in self._shown:
            del self._shown[key]
            return True
        return False

    def snapshot(self, topic: str, records: list[Any]) -> list[Any]:
        """The records of a snapshot in scope now (remembered as shown)."""
        out = [r for r in records if visible(self.principal, topic, r, self._task_robot)]
        for r in out:
            self._remember(_record_key(topic, r))
        return out

    def _remember(self, key: tuple[str, object] | None) -> None:
        if key is None:
            return
        self._shown[key] = None
        self._shown.move_to_end(key)
        while len(self._shown) > self._memory:
            self._shown.popitem(last=False)


def _record_key(topic: str, record: Any) -> tuple[str, object] | None:
    """What names a record across its updates: a dish's or trip's id, a robot's name."""
    key = getattr(record, "id", None) if topic in ("orders", "tasks") else None
    if topic == "robots":
        key = getattr(record, "name", None)
    return None if key is None else (topic, key)


# --------------------------------------------------------------------------- secrets

# scrypt N=2**15, r=8, p=1: 32 MiB of memory per hash, about 0.1 s on a laptop core and a few
# tenths on a Pi 4 — once per login, in a worker thread. Raise N here; old hashes keep theirs.
_SCRYPT_N: Final = 2**15
_SCRYPT_R: Final = 8
_SCRYPT_P: Final = 1
_MIN_PASSWORD: Final = 8


def _scrypt(password: str, salt: bytes, n: int, r: int, p: int) -> bytes:
    return hashlib.scrypt(
        password.encode(), salt=salt, n=n, r=r, p=p, maxmem=256 * r * n + 2**20, dklen=32
    )


def hash_password(password: str, *, n: int | None = None) -> str:
    """``scrypt$N$r$p$salt$hash`` (base64): self-describing, so parameters can change later.
    ``n`` is the module's N unless given."""
    n = _SCRYPT_N if n is None else n
    salt = secrets.token_bytes(16)
    dk = _scrypt(password, salt, n, _SCRYPT_R, _SCRYPT_P)
    b64 = base64.b64encode
    return f"scrypt${n}${_SCRYPT_R}${_SCRYPT_P}${b64(salt).decode()}${b64(dk).decode()}"


def verify_password(password: str, stored: str) -> bool:
    """Constant-time check of ``password`` against :func:`hash_password`'s output."""
    try:
        algo, n, r, p, salt, dk = stored.split("$")
        if algo != "scrypt":
            return False
        want = base64.b64decode(dk)
        got = _scrypt(password, base64.b64decode(salt), int(n), int(r), int(p))
    except (ValueError, TypeError):
        return False
    return hmac.compare_digest(got, want)


def check_password_strength(password: str) -> None:
    if len(password) < _MIN_PASSWORD:
        raise InvalidField(f"a password needs at least {_MIN_PASSWORD} characters")
    if len(password) > 1024:
        raise InvalidField("a password may have at most 1024 characters")


def new_password() -> str:
    """A random password for first-run and demo accounts (~96 bits, easy to type).

    Never starting with "-": one in 64 did, and ``first_trip.py --password -x...`` (the README's
    command) then read it as an option and stopped (a CI run hit it).
    """
    while True:
        password = secrets.token_urlsafe(12)
        if not password.startswith("-"):
            return password


def new_token() -> str:
    return TOKEN_PREFIX + secrets.token_urlsafe(32)


def token_digest(token: str) -> str:
    """What is stored and looked up: SHA-256 of the token, hex."""
    return hashlib.sha256(token.encode()).hexdigest()


# --------------------------------------------------------------------------- throttles


class LoginThrottle:
    """Slows down password guessing, per address and per user name.

    The first ``free`` failures cost nothing extra; after that every attempt within the lock
    is refused with ``rate_limited`` and the lock doubles with each further failure, up to
    ``cap`` seconds. A success clears the key. Memory is bounded: the oldest keys go first.
    """

    def __init__(
        self, *, free: int = 5, base: float = 1.0, cap: float = 300.0, max_keys: int = 10_000
    ) -> None:
        self.free, self.base, self.cap, self.max_keys = free, base, cap, max_keys
        # key -> (failures, locked until)
        self._keys: OrderedDict[str, tuple[int, float]] = OrderedDict()

    def check(self, keys: Iterable[str], now: float) -> None:
        """Raise RateLimited if any key is locked at ``now``."""
        wait = max((self._keys.get(k, (0, 0.0))[1] - now for k in keys), default=0.0)
        if wait > 0:
            raise RateLimited(
                "too many failed logins: wait before trying again", wait=wait, step=0.1
            )

    def failure(self, keys: Iterable[str], now: float) -> None:
        for k in keys:
            n, _ = self._keys.pop(k, (0, 0.0))
            n += 1
            until = now + min(self.cap, self.base * 2 ** (n - self.free)) if n >= self.free else 0
            self._keys[k] = (n, until)
            while len(self._keys) > self.max_keys:
                self._keys.popitem(last=False)

    def success(self, keys: Iterable[str]) -> None:
        for k in keys:
            self._keys.pop(k, None)


class RateLimiter:
    """A token bucket: ``rate`` requests per second on average, bursts up to ``burst``."""

    def __init__(self, rate: float, burst: float, now: float) -> None:
        self.rate, self.burst = rate, burst
        self._tokens = burst
        self._at = now

    def allow(self, now: float) -> float:
        """0 if this request may go ahead (and count it), else seconds until one may."""
        self._tokens = min(self.burst, self._tokens + (now - self._at) * self.rate)
        self._at = now
        if self._tokens >= 1.0:
            self._tokens -= 1.0
            return 0.0
        return (1.0 - self._tokens) / self.rate
