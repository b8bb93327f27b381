"""Logging in, tokens, revocation and the audit trail: the I/O around :mod:`serveur.security.auth`.

A connection becomes a :class:`~serveur.security.auth.Principal` by presenting a token (on the
websocket handshake as ``Authorization: Bearer``, or in a ``login`` message) or a user name
and password (``login``; the reply carries a new session token the client keeps).

Revocation reaches live connections two ways: at once for a logout on this server, and within
``SecurityConfig.sweep_every`` seconds for what another process did to the database (the
``serveur token revoke`` / ``user passwd`` / ``user remove`` CLI) and for expiries: a sweep
asks the store which of the live connections' tokens are still valid and closes the others'
connections with code 4001.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import hmac
import logging
import re
import time
from collections.abc import Callable, Coroutine, Sequence
from dataclasses import dataclass, field
from typing import Any

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.hub import Hub
from serveur.errors import Conflict, InvalidField, ServeurError, Unauthorized
from serveur.security import auth
from serveur.security.auth import Principal, Role, Scope
from serveur.store.base import Store, TokenRecord

__all__ = ["CLOSE_AUTH", "RedactSecrets", "SecurityConfig", "Sessions", "install_redaction"]

log = logging.getLogger(__name__)

#: Close code for "authentication needed, expired or revoked": log in again.
CLOSE_AUTH = 4001

_SECRET = re.compile(
    r"srv_[A-Za-z0-9_-]{8,}"  # our tokens, wherever they appear
    r"|(?i:authorization)\s*[:=]\s*\S+(?:\s+\S+)?"  # a header line, whatever the scheme
    r'|"password"\s*:\s*"(?:[^"\\]|\\.)*"'  # a login frame's password
)


_FRAME_LOG = re.compile(r"^([<>] (?:TEXT|BINARY|CONT)) .*?(\[\d+ bytes\])?$", re.S)


class RedactSecrets(logging.Filter):
    """Scrubs tokens, Authorization headers and JSON passwords from log records.

    websockets logs every handshake header at DEBUG (``serveur -vv``), Authorization included;
    a frame logged while debugging could hold a login's password. Nothing secret may reach a
    log file, whatever the level, so the records are rewritten before any handler sees them.
    """

    def filter(self, record: logging.LogRecord) -> bool:
        text = record.getMessage()
        frame = _FRAME_LOG.match(text)
        if frame is not None:
            # websockets shortens long frames from the middle, which can cut a password's key
            # off and keep its value: a frame's payload is never logged, only its size.
            record.msg, record.args = f"{frame[1]} [payload not logged] {frame[2] or ''}", None
            return True
        clean = _SECRET.sub("[redacted]", text)
        if clean != text:
            record.msg, record.args = clean, None
        return True


def install_redaction() -> None:
    """Attach :class:`RedactSecrets` to the loggers that could see secrets (idempotent)."""
    for name in ("websockets", "websockets.server", "websockets.client", "serveur"):
        logger = logging.getLogger(name)
        if not any(isinstance(f, RedactSecrets) for f in logger.filters):
            logger.addFilter(RedactSecrets())


@dataclass(frozen=True)
class SecurityConfig:
    """The knobs of the security layer; the defaults suit one restaurant's Wi-Fi."""

    #: A password login's session lasts a long shift (app-clock seconds).
    session_ttl: float = 14 * 3600.0
    #: An unauthenticated connection must log in within this many wall seconds.
    login_deadline: float = 15.0
    #: A connection with no subscription that sends nothing for this long (wall seconds) is
    #: closed (code 4003); subscribed screens are never idle.
    idle_timeout: float = 600.0
    #: Requests per second per connection, on average, and the burst allowed on top.
    rate: float = 50.0
    burst: float = 200.0
    #: Open websocket connections one IP address may hold.
    max_per_address: int = 64
    #: Extra origins allowed on browser handshakes besides the page's own (same-origin).
    allowed_origins: tuple[str, ...] = ()
    #: How often (wall seconds) ended tokens are looked up to close their connections.
    sweep_every: float = 5.0
    #: Failed logins per address or user name before attempts are slowed down.
    free_failures: int = 5
    #: Verbs that are not written to the audit trail: reads, and teleop's stream of
    #: velocity frames (taking manual control, which teleop needs, is audited).
    unaudited: frozenset[str] = field(default_factory=lambda: frozenset({"data", "order", "ping"}))


Closer = Callable[[int, str], Coroutine[Any, Any, None]]


class Sessions:
    """Authentication state of one server: live principals, throttles, the audit writer."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: SecurityConfig | None = None,
        *,
        hub: Hub | None = None,
        monotonic: Callable[[], float] = time.monotonic,
    ) -> None:
        self.store = store
        self.clock = clock
        self.config = config or SecurityConfig()
        self.hub = hub
        self.monotonic = monotonic
        self.throttle = auth.LoginThrottle(free=self.config.free_failures)
        #: The first start's one-time setup code (:meth:`prepare_setup`), None once used.
        self.setup_code: str | None = None
        self._live: dict[int, set[Closer]] = {}
        self._sweeper: asyncio.Task[None] | None = None
        install_redaction()

    # -- lifecycle --------------------------------------------------------------------------

    def start(self) -> None:
        self._sweeper = asyncio.create_task(self._sweep_loop(), name="token-sweeper")

    async def close(self) -> None:
        task, self._sweeper = self._sweeper, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    # -- first run --------------------------------------------------------------------------

    async def prepare_setup(self) -> str | None:
        """On an empty user table, a one-time setup code (in the setup link the CLI prints),
        kept in memory only: each start of a server nobody has set up prints a new one.
        None when users exist."""
        if await self.store.accounts.count_users():
            self.setup_code = None
            return None
        self.setup_code = auth.new_token()
        return self.setup_code

    async def _first_owner(self, code: str, username: str, password: str) -> None:
        """``login`` with ``setup``: the owner the setup link's holder chose, created once."""
        expected = self.setup_code
        if expected is None or not hmac.compare_digest(code, expected):
            raise Unauthorized("this setup link is not valid (already used? open the newest)")
        auth.check_password_strength(password)
        if await self.store.accounts.count_users():
            self.setup_code = None
            raise Unauthorized("this restaurant is set up already: log in")
        pw_hash = await asyncio.to_thread(auth.hash_password, password)
        try:
            await self.store.accounts.add_user(username, "owner", pw_hash, now=self.clock.epoch())
        except Conflict:  # two setup pages at once: the first one won
            raise Unauthorized("this restaurant is set up already: log in") from None
        self.setup_code = None

    async def ensure_owner(self, name: str = "owner") -> str | None:
        """On an empty user table, create an owner with a random password and return it.

        Returns None when users exist: the password is shown once, at the first start only.
        """
        if await self.store.accounts.count_users():
            return None
        password = auth.new_password()
        pw_hash = await asyncio.to_thread(auth.hash_password, password)
        try:
            await self.store.accounts.add_user(name, "owner", pw_hash, now=self.clock.epoch())
        except Conflict:  # another process won the race: it prints the password, not us
            return None
        return password

    # -- tokens -----------------------------------------------------------------------------

    async def create_token(
        self,
        role: Role | str,
        *,
        robot: str | None = None,
        table: str | None = None,
        scopes: Sequence[str] = (),
        label: str = "",
        ttl: float | None = None,
    ) -> tuple[str, TokenRecord]:
        """A device/script token. The token is returned once; only its digest is kept."""
        role = Role(role)
        if role not in auth.DEVICE_ROLES:
            raise InvalidField(f"tokens are for {', '.join(auth.DEVICE_ROLES)}, not {role}")
        if (role is Role.ROBOT_SCREEN) != (robot is not None):
            raise InvalidField("a robot-screen token needs --robot (and only it does)")
        if (role is Role.TABLE_SCREEN) != (table is not None):
            raise InvalidField("a table-screen token needs --table (and only it does)")
        chosen = auth.parse_scopes(scopes)
        if chosen and role is not Role.INTEGRATION:
            raise InvalidField("only integration tokens take scopes; other roles have fixed ones")
        if Scope.ACCOUNTS in chosen:
            raise InvalidField(
                "the accounts scope is an owner's, never a token's", scope="accounts"
            )
        if role is Role.INTEGRATION and not chosen:
            raise InvalidField("an integration token needs at least one scope")
        now = self.clock.epoch()
        token = auth.new_token()
        rec = await self.store.accounts.add_token(
            auth.token_digest(token),
            kind="device",
            role=role.value,
            robot=robot,
            table=table,
            scopes=[s.value for s in chosen],
            label=label,
            now=now,
            expires_at=None if ttl is None else now + ttl,
        )
        return token, rec

    # -- logging in -------------------------------------------------------------------------

    async def authenticate_token(self, token: str) -> Principal:
        """The principal of a presented token, or Unauthorized (unknown, revoked, expired)."""
        if not token.startswith(auth.TOKEN_PREFIX) or len(token) > P.MAX_TOKEN:
            raise Unauthorized("unknown token")
        rec = await self.store.accounts.token_by_digest(auth.token_digest(token))
        now = self.clock.epoch()
        if rec is None or not rec.usable(now):
            raise Unauthorized("unknown, expired or revoked token")
        with contextlib.suppress(ServeurError):  # bookkeeping must not refuse a valid login
            await self.store.accounts.touch_token(rec.id, now=now)
        return principal_of(rec)

    async def login(self, msg: P.LoginMsg, peer: str) -> tuple[Principal, str | None]:
        """Check a ``login``; the principal and, for a password login, its new session token.

        Failed attempts are counted per address and per user name; past the free ones the
        key is locked for a doubling time and attempts get ``rate_limited`` meanwhile.
        """
        host = peer.rsplit(":", 1)[0] if peer.count(":") == 1 else peer
        keys = [f"addr:{host}"] + ([f"user:{msg.username}"] if msg.username else [])
        self.throttle.check(keys, self.monotonic())
        try:
            if msg.token is not None:
                p = await self.authenticate_token(msg.token)
                token = None
            elif msg.setup is not None:
                assert msg.username is not None and msg.password is not None
                await self._first_owner(msg.setup, msg.username, msg.password)
                p, token = await self._password_login(msg.username, msg.password)
            else:
                assert msg.username is not None and msg.password is not None
                p, token = await self._password_login(msg.username, msg.password)
        except Unauthorized:
            self.throttle.failure(keys, self.monotonic())
            raise
        self.throttle.success(keys)
        return p, token

    async def _password_login(self, username: str, password: str) -> tuple[Principal, str]:
        found = await self.store.accounts.user_credentials(username)
        # Hash even for an unknown user, so the reply time does not tell which names exist.
        stored = found[1] if found else _dummy_hash()
        ok = await asyncio.to_thread(auth.verify_password, password, stored)
        if found is None or not ok:
            raise Unauthorized("wrong user name or password")
        user = found[0]
        token = auth.new_token()
        now = self.clock.epoch()
        rec = await self.store.accounts.add_token(
            auth.token_digest(token),
            kind="session",
            role=user.role,
            user=user.name,
            label="login",
            now=now,
            expires_at=now + self.config.session_ttl,
        )
        return principal_of(rec), token

    async def logout(self, p: Principal) -> None:
        """End a password session for good; a device token stays valid (revoke it instead)."""
        if p.user is not None:
            await self.store.accounts.revoke_token(p.token_id, now=self.clock.epoch())
            self._kick([p.token_id], "logged out")

    # -- live connections -------------------------------------------------------------------

    def bind(self, p: Principal, close: Closer) -> None:
        self._live.setdefault(p.token_id, set()).add(close)

    def unbind(self, p: Principal, close: Closer) -> None:
        closers = self._live.get(p.token_id)
        if closers is not None:
            closers.discard(close)
            if not closers:
                del self._live[p.token_id]

    def end(self, token_ids: Sequence[int], why: str) -> None:
        """Close the live connections of these (revoked) tokens now, code 4001."""
        self._kick(token_ids, why)

    def _kick(self, token_ids: Sequence[int], why: str) -> None:
        for tid in token_ids:
            for close in list(self._live.pop(tid, ())):
                asyncio.get_running_loop().create_task(close(CLOSE_AUTH, why))

    async def sweep(self) -> None:
        """Close the connections of tokens that ended since the last sweep."""
        live_ids = list(self._live)
        alive = await self.store.accounts.tokens_alive(live_ids, now=self.clock.epoch())
        live = [t for t in live_ids if t not in alive]
        if live:
            log.info("closing connections of %d ended tokens", len(live))
            self._kick(live, "session ended: log in again")

    async def _sweep_loop(self) -> None:
        while True:
            await asyncio.sleep(self.config.sweep_every)
            try:
                await self.sweep()
            except ServeurError as exc:
                log.warning("token sweep failed: %s", exc)

    # -- audit ------------------------------------------------------------------------------

    async def audit(
        self,
        p: Principal | None,
        peer: str,
        verb: str,
        outcome: str,
        *,
        target: str | None = None,
        data: dict[str, Any] | None = None,
    ) -> None:
        """Record one instruction. An audit failure is logged, never fails the request."""
        try:
            rec = await self.store.audit.add_audit(
                ts=self.clock.epoch(),
                actor=p.actor if p else "anonymous",
                role=p.role.value if p else "-",
                peer=peer,
                verb=verb,
                target=target,
                outcome=outcome,
                data=data,
            )
        except ServeurError as exc:
            log.error("could not write the audit trail: %s", exc)
            return
        if self.hub is not None and self.hub.watched("audit"):
            self.hub.publish("audit", P.dump(rec), rec)


def principal_of(rec: TokenRecord) -> Principal:
    role = Role(rec.role)
    if role is Role.OWNER:
        scopes = auth.OWNER_SCOPES
    elif role is Role.STAFF:
        scopes = auth.STAFF_SCOPES
    elif role is Role.INTEGRATION:
        known = {s.value for s in Scope} - {Scope.ACCOUNTS.value}
        scopes = frozenset(Scope(s) for s in rec.scopes if s in known)
    else:
        scopes = frozenset()
    return Principal(
        role=role,
        token_id=rec.id,
        user=rec.user,
        robot=rec.robot,
        table=rec.table,
        scopes=scopes,
        expires_at=rec.expires_at,
        label=rec.label,
    )


@functools.cache
def _dummy_hash() -> str:
    """A real hash of a random password: checking against it costs what a real check costs."""
    return auth.hash_password(auth.new_password())
