"""Users, access tokens and the audit trail: two parts of :class:`~serveur.store.base.Store`,
written once for every backend.

These tables have no cross-row invariants beyond what the schema's constraints enforce, so
their SQL is plain: one unit of work per method, in the SQL of :mod:`serveur.store.sql`.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from serveur.domain import AuditRecord
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.store import rows
from serveur.store.live import ROBOT_NAMED, WAYPOINT_NAMED
from serveur.store.sql import Db, Tx, one

__all__ = ["Accounts", "Audit", "AuditQuery", "TokenRecord", "UserRecord"]

_USER_ROLES = ("owner", "staff")
_USER = "SELECT name, role, created_at, changed_at FROM users"
_TOKEN = (
    "SELECT id, kind, user_name, role, robot, tbl, scopes, label, created_at, expires_at,"
    " revoked_at, last_used_at FROM tokens"
)
_AUDIT = "SELECT id, ts, actor, role, peer, verb, target, outcome, data FROM audit"


@dataclass(frozen=True, slots=True)
class UserRecord:
    name: str
    role: str
    created_at: float
    changed_at: float


@dataclass(frozen=True, slots=True)
class TokenRecord:
    """A token as stored (without the token itself: only its digest is kept)."""

    id: int
    kind: str  # "session" (a person's login) or "device" (screens, scripts, kiosks)
    user: str | None
    role: str
    robot: str | None
    table: str | None
    scopes: tuple[str, ...]
    label: str
    created_at: float
    expires_at: float | None
    revoked_at: float | None
    last_used_at: float | None

    def usable(self, now: float) -> bool:
        return self.revoked_at is None and (self.expires_at is None or now < self.expires_at)


def _user(row: dict[str, Any]) -> UserRecord:
    return UserRecord(row["name"], row["role"], row["created_at"], row["changed_at"])


def _token(row: dict[str, Any]) -> TokenRecord:
    scopes = tuple(s for s in str(row["scopes"]).split(",") if s)
    return TokenRecord(
        id=int(row["id"]),
        kind=row["kind"],
        user=row["user_name"],
        role=row["role"],
        robot=row["robot"],
        table=row["tbl"],
        scopes=scopes,
        label=row["label"],
        created_at=row["created_at"],
        expires_at=row["expires_at"],
        revoked_at=row["revoked_at"],
        last_used_at=row["last_used_at"],
    )


def _audit(row: dict[str, Any]) -> AuditRecord:
    return AuditRecord(
        id=int(row["id"]),
        ts=row["ts"],
        actor=row["actor"],
        role=row["role"],
        peer=row["peer"],
        verb=row["verb"],
        target=row["target"],
        outcome=row["outcome"],
        data=json.loads(row["data"]),
    )


@dataclass(frozen=True, slots=True)
class AuditQuery:
    """A search of the audit trail: every given field must match; newest first."""

    actor: str | None = None
    verb: str | None = None
    outcome: str | None = None
    target: str | None = None
    since: float | None = None
    until: float | None = None
    before_id: int | None = None
    limit: int = 100


class Accounts:
    """User and token methods of the store (``store.accounts``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    # -- users ------------------------------------------------------------------------------

    async def add_user(self, name: str, role: str, pw_hash: str, *, now: float) -> UserRecord:
        if role not in _USER_ROLES:
            raise InvalidField(f"a user's role is owner or staff, not {role!r}", role=role)
        if not name or len(name) > 64 or name != name.strip():
            raise InvalidField("a user name has 1 to 64 characters, no outer spaces")

        async def work(tx: Tx) -> UserRecord:
            if await one(tx, f"{_USER} WHERE name = ?", (name,)):
                raise Conflict(f"user {name!r} already exists", user=name)
            await tx.run(
                "INSERT INTO users (name, role, pw_hash, created_at, changed_at)"
                " VALUES (?, ?, ?, ?, ?)",
                (name, role, pw_hash, now, now),
            )
            return UserRecord(name, role, now, now)

        return await self._db.transact(work, "write")

    async def user_credentials(self, name: str) -> tuple[UserRecord, str] | None:
        """The user and their password hash, or None (for login only)."""

        async def work(tx: Tx) -> tuple[UserRecord, str] | None:
            row = await one(
                tx,
                "SELECT name, role, created_at, changed_at, pw_hash FROM users WHERE name = ?",
                (name,),
            )
            return None if row is None else (_user(row), str(row["pw_hash"]))

        return await self._db.transact(work, "read")

    async def list_users(self) -> list[UserRecord]:
        async def work(tx: Tx) -> list[UserRecord]:
            return [_user(r) for r in await tx.all(f"{_USER} ORDER BY name")]

        return await self._db.transact(work, "read")

    async def count_users(self) -> int:
        async def work(tx: Tx) -> int:
            row = await one(tx, "SELECT COUNT(*) AS n FROM users", ())
            return int(row["n"]) if row else 0

        return await self._db.transact(work, "read")

    async def remove_user(self, name: str) -> list[int]:
        """Delete a user and their sessions; the ids of the sessions that ended."""

        async def work(tx: Tx) -> list[int]:
            user = await one(tx, f"{_USER} WHERE name = ?", (name,))
            if user is None:
                raise NotFound(f"no user named {name!r}", user=name)
            if user["role"] == "owner":
                owners = await tx.all("SELECT name FROM users WHERE role = 'owner'", ())
                if len(owners) == 1:
                    raise Conflict("cannot remove the last owner", user=name)
            ids = [
                int(r["id"])
                for r in await tx.all("SELECT id FROM tokens WHERE user_name = ?", (name,))
            ]
            await tx.run("DELETE FROM tokens WHERE user_name = ?", (name,))
            await tx.run("DELETE FROM users WHERE name = ?", (name,))
            return ids

        return await self._db.transact(work, "write")

    async def set_role(self, name: str, role: str, *, now: float) -> tuple[UserRecord, list[int]]:
        """Make a user owner or staff; their sessions end (a session carries its role).

        The last owner cannot become staff (``conflict``); an unchanged role changes nothing
        and ends no session.
        """
        if role not in _USER_ROLES:
            raise InvalidField(f"a user's role is owner or staff, not {role!r}", role=role)

        async def work(tx: Tx) -> tuple[UserRecord, list[int]]:
            user = await one(tx, f"{_USER} WHERE name = ?", (name,))
            if user is None:
                raise NotFound(f"no user named {name!r}", user=name)
            if user["role"] == role:
                return _user(user), []
            if user["role"] == "owner":
                owners = await tx.all("SELECT name FROM users WHERE role = 'owner'", ())
                if len(owners) == 1:
                    raise Conflict("cannot demote the last owner", user=name)
            await tx.run("UPDATE users SET role = ? WHERE name = ?", (role, name))
            ended = await rows.revoke_where(tx, "user_name = ? AND kind = 'session'", (name,), now)
            row = await one(tx, f"{_USER} WHERE name = ?", (name,))
            assert row is not None
            return _user(row), ended

        return await self._db.transact(work, "write")

    async def set_password(self, name: str, pw_hash: str, *, now: float) -> list[int]:
        """Change a password and end every session of that user (ids returned)."""

        async def work(tx: Tx) -> list[int]:
            n = await tx.run(
                "UPDATE users SET pw_hash = ?, changed_at = ? WHERE name = ?",
                (pw_hash, now, name),
            )
            if n != 1:
                raise NotFound(f"no user named {name!r}", user=name)
            return await rows.revoke_where(tx, "user_name = ? AND kind = 'session'", (name,), now)

        return await self._db.transact(work, "write")

    # -- tokens -----------------------------------------------------------------------------

    async def add_token(
        self,
        digest: str,
        *,
        kind: str,
        role: str,
        now: float,
        user: str | None = None,
        robot: str | None = None,
        table: str | None = None,
        scopes: Sequence[str] = (),
        label: str = "",
        expires_at: float | None = None,
    ) -> TokenRecord:
        async def work(tx: Tx) -> TokenRecord:
            if robot is not None and not await one(tx, ROBOT_NAMED, (robot,)):
                raise NotFound(f"no robot named {robot!r}", robot=robot)
            if table is not None and not await one(
                tx, f"{WAYPOINT_NAMED} AND kind = 'table'", (table,)
            ):
                raise NotFound(f"no table named {table!r}", table=table)
            tid = await tx.insert(
                "INSERT INTO tokens (digest, kind, user_name, role, robot, tbl, scopes, label,"
                " created_at, expires_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    digest,
                    kind,
                    user,
                    role,
                    robot,
                    table,
                    ",".join(sorted(scopes)),
                    label,
                    now,
                    expires_at,
                ),
            )
            row = await one(tx, f"{_TOKEN} WHERE id = ?", (tid,))
            assert row is not None
            return _token(row)

        return await self._db.transact(work, "write")

    async def token_by_digest(self, digest: str) -> TokenRecord | None:
        async def work(tx: Tx) -> TokenRecord | None:
            row = await one(tx, f"{_TOKEN} WHERE digest = ?", (digest,))
            return None if row is None else _token(row)

        return await self._db.transact(work, "read")

    async def touch_token(self, token_id: int, *, now: float) -> None:
        async def work(tx: Tx) -> None:
            await tx.run("UPDATE tokens SET last_used_at = ? WHERE id = ?", (now, token_id))

        await self._db.transact(work, "write")

    async def list_tokens(
        self, *, include_ended: bool = False, now: float = 0.0, kind: str | None = None
    ) -> list[TokenRecord]:
        """Tokens by id; active ones unless ``include_ended``; of one ``kind`` if given."""

        async def work(tx: Tx) -> list[TokenRecord]:
            where: list[str] = []
            params: list[Any] = []
            if not include_ended:
                where.append("revoked_at IS NULL AND (expires_at IS NULL OR expires_at > ?)")
                params.append(now)
            if kind is not None:
                where.append("kind = ?")
                params.append(kind)
            cond = f" WHERE {' AND '.join(where)}" if where else ""
            rows = await tx.all(f"{_TOKEN}{cond} ORDER BY id", params)
            return [_token(r) for r in rows]

        return await self._db.transact(work, "read")

    async def revoke_token(self, token_id: int, *, now: float) -> TokenRecord:
        async def work(tx: Tx) -> TokenRecord:
            if not await rows.revoke_where(tx, "id = ?", (token_id,), now):
                row = await one(tx, f"{_TOKEN} WHERE id = ?", (token_id,))
                if row is None:
                    raise NotFound(f"no token {token_id}", token=token_id)
            row = await one(tx, f"{_TOKEN} WHERE id = ?", (token_id,))
            assert row is not None
            return _token(row)

        return await self._db.transact(work, "write")

    async def tokens_alive(self, token_ids: Sequence[int], *, now: float) -> set[int]:
        """Which of ``token_ids`` still exist, unrevoked and unexpired (for sweeps)."""
        ids = [int(t) for t in token_ids]
        if not ids:
            return set()

        async def work(tx: Tx) -> set[int]:
            marks = ", ".join("?" * len(ids))
            rows = await tx.all(
                f"SELECT id FROM tokens WHERE id IN ({marks}) AND revoked_at IS NULL"
                " AND (expires_at IS NULL OR expires_at > ?)",
                (*ids, now),
            )
            return {int(r["id"]) for r in rows}

        return await self._db.transact(work, "read")


class Audit:
    """Audit-trail methods of the store (``store.audit``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    # -- the trail ------------------------------------------------------------------------------

    async def add_audit(
        self,
        *,
        ts: float,
        actor: str,
        role: str,
        peer: str,
        verb: str,
        outcome: str,
        target: str | None = None,
        data: dict[str, Any] | None = None,
    ) -> AuditRecord:
        body = json.dumps(data or {}, separators=(",", ":"), allow_nan=False, default=str)

        async def work(tx: Tx) -> AuditRecord:
            aid = await tx.insert(
                "INSERT INTO audit (ts, actor, role, peer, verb, target, outcome, data)"
                " VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                (ts, actor[:255], role[:16], peer[:255], verb[:32], target, outcome[:32], body),
            )
            return AuditRecord(
                id=aid,
                ts=ts,
                actor=actor[:255],
                role=role[:16],
                peer=peer[:255],
                verb=verb[:32],
                target=target,
                outcome=outcome[:32],
                data=json.loads(body),
            )

        return await self._db.transact(work, "write")

    async def list_audit(self, *, since_id: int = 0, limit: int = 1000) -> list[AuditRecord]:
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")

        async def work(tx: Tx) -> list[AuditRecord]:
            rows = await tx.all(f"{_AUDIT} WHERE id > ? ORDER BY id LIMIT ?", (since_id, limit))
            return [_audit(r) for r in rows]

        return await self._db.transact(work, "read")

    async def recent_audit(self, limit: int = 100) -> list[AuditRecord]:
        """The latest ``limit`` audit records, oldest first."""
        if isinstance(limit, bool) or not isinstance(limit, int) or limit < 1:
            raise InvalidField("limit must be a positive integer", field="limit")

        async def work(tx: Tx) -> list[AuditRecord]:
            rows = await tx.all(f"{_AUDIT} ORDER BY id DESC LIMIT ?", (limit,))
            return [_audit(r) for r in reversed(rows)]

        return await self._db.transact(work, "read")

    # -- the audit trail, searched ----------------------------------------------------------

    async def search_audit(self, q: AuditQuery) -> list[AuditRecord]:
        """Audit records matching ``q``, newest first (page on with ``before_id``)."""
        if not 1 <= q.limit <= 500:
            raise InvalidField("limit is from 1 to 500", field="limit")
        where: list[str] = []
        params: list[Any] = []
        texts: tuple[tuple[str, str | None], ...] = (
            ("actor", q.actor),
            ("verb", q.verb),
            ("outcome", q.outcome),
            ("target", q.target),
        )
        for column, value in texts:
            if value is not None:
                where.append(f"{column} = ?")
                params.append(value)
        bounds: tuple[tuple[str, float | None], ...] = (
            ("ts >= ?", q.since),
            ("ts < ?", q.until),
            ("id < ?", q.before_id),
        )
        for cond, bound in bounds:
            if bound is not None:
                where.append(cond)
                params.append(bound)
        clause = f" WHERE {' AND '.join(where)}" if where else ""

        async def work(tx: Tx) -> list[AuditRecord]:
            rows = await tx.all(
                "SELECT id, ts, actor, role, peer, verb, target, outcome, data FROM audit"
                f"{clause} ORDER BY id DESC LIMIT ?",
                (*params, q.limit),
            )
            return [_audit(r) for r in rows]

        return await self._db.transact(work, "read")
