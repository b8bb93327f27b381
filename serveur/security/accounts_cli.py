"""``serveur user …``, ``serveur token …`` and ``serveur audit``: accounts from the shell.

These commands work on the database directly, so they need no running server and no
network: whoever can run them on the Pi can read the database file anyway. A running server
notices a revoked token, a removed user or a changed password within its sweep period
(a few seconds) and closes the affected connections.

Passwords are read from the terminal without echo (or one line from stdin for scripts) and
never passed as arguments, where ``ps`` and shell history would show them. Tokens are printed
once, at creation; only their digest is stored.
"""

from __future__ import annotations

import argparse
import asyncio
import getpass
import os
import re
import sys
import time
from datetime import UTC, datetime

from serveur.errors import ServeurError
from serveur.security import auth
from serveur.store.base import Store
from serveur.store.factory import open_store

__all__ = ["add_accounts_parsers", "parse_duration"]

_DURATION = re.compile(r"^\s*(\d+(?:\.\d+)?)\s*([smhd]?)\s*$")
_UNITS = {"": 1.0, "s": 1.0, "m": 60.0, "h": 3600.0, "d": 86400.0}


def parse_duration(text: str) -> float | None:
    """``30d``, ``12h``, ``45m``, ``90s`` or ``never`` (None) as seconds."""
    if text.strip().lower() in ("never", "none", ""):
        return None
    m = _DURATION.match(text.lower())
    if m is None or float(m[1]) <= 0:
        raise argparse.ArgumentTypeError(f"not a duration: {text!r} (e.g. 30d, 12h, never)")
    return float(m[1]) * _UNITS[m[2]]


def _when(ts: float | None) -> str:
    if ts is None:
        return "-"
    return datetime.fromtimestamp(ts, UTC).strftime("%Y-%m-%d %H:%M")


def _read_password(ns: argparse.Namespace) -> str:
    if ns.random:
        password = auth.new_password()
        print(f"password: {password}")
        return password
    if sys.stdin.isatty():
        first = getpass.getpass("new password: ")
        if getpass.getpass("again: ") != first:
            raise SystemExit("the passwords differ")
        password = first
    else:
        password = sys.stdin.readline().rstrip("\r\n")
    auth.check_password_strength(password)
    return password


async def _with_store(ns: argparse.Namespace, work: object) -> int:
    store = open_store(ns.db)
    try:
        await store.open()
        assert callable(work)
        result = await work(store)
        return int(result or 0)
    except ServeurError as exc:
        print(f"serveur: {exc.message}", file=sys.stderr)
        return 1
    finally:
        await store.close()


# -- users -------------------------------------------------------------------------------


async def _user_add(ns: argparse.Namespace) -> int:
    password = _read_password(ns)
    pw_hash = await asyncio.to_thread(auth.hash_password, password)

    async def work(store: Store) -> int:
        await store.accounts.add_user(ns.name, ns.role, pw_hash, now=time.time())
        print(f"user {ns.name} ({ns.role}) added")
        return 0

    return await _with_store(ns, work)


async def _user_list(ns: argparse.Namespace) -> int:
    async def work(store: Store) -> int:
        for u in await store.accounts.list_users():
            print(
                f"{u.name}\t{u.role}\tcreated {_when(u.created_at)}\t"
                f"password changed {_when(u.changed_at)}"
            )
        return 0

    return await _with_store(ns, work)


async def _user_remove(ns: argparse.Namespace) -> int:
    async def work(store: Store) -> int:
        ended = await store.accounts.remove_user(ns.name)
        print(f"user {ns.name} removed ({len(ended)} sessions ended)")
        return 0

    return await _with_store(ns, work)


async def _user_passwd(ns: argparse.Namespace) -> int:
    password = _read_password(ns)
    pw_hash = await asyncio.to_thread(auth.hash_password, password)

    async def work(store: Store) -> int:
        ended = await store.accounts.set_password(ns.name, pw_hash, now=time.time())
        print(f"password of {ns.name} changed ({len(ended)} sessions ended)")
        return 0

    return await _with_store(ns, work)


# -- tokens ------------------------------------------------------------------------------


async def _token_create(ns: argparse.Namespace) -> int:
    from serveur.clock import ScaledClock
    from serveur.security.sessions import Sessions

    async def work(store: Store) -> int:
        sessions = Sessions(store, ScaledClock(1.0))
        token, rec = await sessions.create_token(
            ns.role,
            robot=ns.robot,
            table=ns.table,
            scopes=ns.scope.split(",") if ns.scope else (),
            label=ns.label,
            ttl=ns.expires,
        )
        print(token)
        where = {"robot-screen": f"/robot/{ns.robot}", "table-screen": f"/table/{ns.table}"}
        page = where.get(rec.role, "/")
        print(
            f"token {rec.id} ({rec.role}"
            + (f" {rec.robot}" if rec.robot else "")
            + (f" {rec.table}" if rec.table else "")
            + (f", scopes {','.join(rec.scopes)}" if rec.scopes else "")
            + f", expires {_when(rec.expires_at) if rec.expires_at else 'never'})."
            f" Shown once: keep it safe.\n"
            f"  a screen: open http://<server>{page}#token=<token> once (it remembers it)\n"
            f"  a script: send the header 'Authorization: Bearer <token>' on the handshake",
            file=sys.stderr,
        )
        return 0

    return await _with_store(ns, work)


async def _token_list(ns: argparse.Namespace) -> int:
    async def work(store: Store) -> int:
        now = time.time()
        for t in await store.accounts.list_tokens(include_ended=ns.all, now=now):
            state = (
                "revoked"
                if t.revoked_at is not None
                else "expired"
                if not t.usable(now)
                else "active"
            )
            bound = t.robot or t.table or ",".join(t.scopes) or "-"
            print(
                f"{t.id}\t{t.kind}\t{t.role}\t{bound}\t{t.user or '-'}\t{state}\t"
                f"expires {_when(t.expires_at)}\tlast used {_when(t.last_used_at)}\t{t.label}"
            )
        return 0

    return await _with_store(ns, work)


async def _token_revoke(ns: argparse.Namespace) -> int:
    async def work(store: Store) -> int:
        for tid in ns.ids:
            await store.accounts.revoke_token(tid, now=time.time())
            print(f"token {tid} revoked")
        return 0

    return await _with_store(ns, work)


async def _audit(ns: argparse.Namespace) -> int:
    async def work(store: Store) -> int:
        for a in await store.audit.recent_audit(ns.limit):
            extra = f"\t{a.data}" if a.data else ""
            print(
                f"{_when(a.ts)}\t{a.actor}\t{a.role}\t{a.peer}\t{a.verb}\t"
                f"{a.target or '-'}\t{a.outcome}{extra}"
            )
        return 0

    return await _with_store(ns, work)


def _db_arg(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--db",
        default=os.environ.get("SERVEUR_DB", "./serveur.db"),
        help="the server's database (default: $SERVEUR_DB, else ./serveur.db)",
    )


def add_accounts_parsers(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``user``, ``token`` and ``audit`` (called once from :mod:`serveur.cli`)."""
    user = sub.add_parser("user", help="people who log in: add, list, remove, passwd")
    us = user.add_subparsers(dest="user_command", required=True)
    add = us.add_parser("add", help="add a user (password from the terminal or stdin)")
    add.add_argument("name")
    add.add_argument("--role", choices=["owner", "staff"], default="staff")
    add.add_argument("--random", action="store_true", help="generate and print a password")
    add.set_defaults(func=_user_add, is_async=True)
    ls = us.add_parser("list", help="list users")
    ls.set_defaults(func=_user_list, is_async=True)
    rm = us.add_parser("remove", help="remove a user and end their sessions")
    rm.add_argument("name")
    rm.set_defaults(func=_user_remove, is_async=True)
    pw = us.add_parser("passwd", help="change a password and end that user's sessions")
    pw.add_argument("name")
    pw.add_argument("--random", action="store_true", help="generate and print a password")
    pw.set_defaults(func=_user_passwd, is_async=True)
    for p in (add, ls, rm, pw):
        _db_arg(p)

    token = sub.add_parser("token", help="tokens for screens and scripts: create, list, revoke")
    ts = token.add_subparsers(dest="token_command", required=True)
    mk = ts.add_parser("create", help="create a token (printed once)")
    mk.add_argument("--role", required=True, choices=[r.value for r in auth.DEVICE_ROLES])
    mk.add_argument("--robot", help="the robot a robot-screen token is bound to")
    mk.add_argument("--table", help="the table a table-screen token is bound to")
    mk.add_argument(
        "--scope",
        help="integration scopes, comma-separated: "
        + ", ".join(s.value for s in auth.Scope if s is not auth.Scope.ACCOUNTS),
    )
    mk.add_argument("--label", default="", help="a note: which device or script")
    mk.add_argument(
        "--expires", type=parse_duration, default=None, help="e.g. 90d, 12h (default: never)"
    )
    mk.set_defaults(func=_token_create, is_async=True)
    tl = ts.add_parser("list", help="list tokens (active ones; --all for every one)")
    tl.add_argument("--all", action="store_true")
    tl.set_defaults(func=_token_list, is_async=True)
    rv = ts.add_parser("revoke", help="revoke tokens by id (live connections are closed)")
    rv.add_argument("ids", type=int, nargs="+")
    rv.set_defaults(func=_token_revoke, is_async=True)
    for p in (mk, tl, rv):
        _db_arg(p)

    au = sub.add_parser("audit", help="the latest entries of the audit trail")
    au.add_argument("--limit", type=int, default=50)
    au.set_defaults(func=_audit, is_async=True)
    _db_arg(au)
