"""The ``account`` verb: an owner manages people and screen tokens over the protocol.

What ``serveur user …`` and ``serveur token …`` do from a shell, for the console's Accounts
tab: list, add and remove people, change a role, reset a password (the server generates it,
like ``serveur user add --random``, and returns it once), make a token for a robot's or a
table's screen (returned once, with its setup link and a QR code of it), list and revoke
tokens. :func:`~serveur.security.auth.authorize` lets only owners through (scope
``accounts``); every request is audited by the server like any other.

Every refusal changes nothing: the checks and the change are one store transaction.
"""

from __future__ import annotations

import asyncio
import io
from typing import Any
from urllib.parse import quote

import segno

from serveur import protocol as P
from serveur.errors import Conflict
from serveur.security import auth
from serveur.security.auth import Principal
from serveur.security.sessions import Sessions
from serveur.store.base import TokenRecord, UserRecord

__all__ = ["handle_account", "qr_svg", "setup_link"]


def _user(u: UserRecord) -> dict[str, Any]:
    return {"name": u.name, "role": u.role, "created_at": u.created_at, "changed_at": u.changed_at}


def _token(t: TokenRecord) -> dict[str, Any]:
    return {
        "id": t.id,
        "role": t.role,
        "robot": t.robot,
        "table": t.table,
        "scopes": list(t.scopes),
        "label": t.label,
        "created_at": t.created_at,
        "expires_at": t.expires_at,
        "revoked_at": t.revoked_at,
        "last_used_at": t.last_used_at,
    }


def setup_link(rec: TokenRecord, token: str) -> str:
    """The page a screen opens once: ``/robot/r1#token=…`` or ``/table/T3#token=…``.

    The token rides in the fragment, which browsers never send to the server (no log has it).
    """
    if rec.robot is not None:
        return f"/robot/{quote(rec.robot, safe='')}#token={token}"
    if rec.table is not None:
        return f"/table/{quote(rec.table, safe='')}#token={token}"
    return f"/#token={token}"


def qr_svg(text: str) -> str:
    """An SVG QR code of ``text`` (segno; error correction M survives a smudged print)."""
    buf = io.BytesIO()
    segno.make(text, error="m").save(
        buf, kind="svg", xmldecl=False, svgns=True, scale=4, border=4, title="QR"
    )
    return buf.getvalue().decode()


async def handle_account(
    sessions: Sessions, p: Principal | None, msg: Any, *, public_url: str | None = None
) -> dict[str, Any]:
    """Carry out one ``account`` request (already authorized) and return the reply fields.

    ``public_url``: the restaurant's address as its tablets reach it (the owner's setting); a
    screen's QR code holds it rather than the ``base`` the asking page saw (a page opened on
    the box itself sees 127.0.0.1, which no tablet can open)."""
    store, now = sessions.store, sessions.clock.epoch()
    if isinstance(msg, P.AccountListUsers):
        return {"users": [_user(u) for u in await store.accounts.list_users()]}
    if isinstance(msg, P.AccountAddUser):
        password = auth.new_password()
        pw_hash = await asyncio.to_thread(auth.hash_password, password)
        user = await store.accounts.add_user(msg.username, msg.role, pw_hash, now=now)
        return {"user": _user(user), "password": password}
    if isinstance(msg, P.AccountSetRole):
        user, ended = await store.accounts.set_role(msg.username, msg.role, now=now)
        sessions.end(ended, "your role changed: log in again")
        return {"user": _user(user)}
    if isinstance(msg, P.AccountResetPassword):
        password = auth.new_password()
        pw_hash = await asyncio.to_thread(auth.hash_password, password)
        ended = await store.accounts.set_password(msg.username, pw_hash, now=now)
        sessions.end(ended, "password changed: log in again")
        found = await store.accounts.user_credentials(msg.username)
        assert found is not None
        return {"user": _user(found[0]), "password": password}
    if isinstance(msg, P.AccountRemoveUser):
        found = await store.accounts.user_credentials(msg.username)
        ended = await store.accounts.remove_user(msg.username)
        sessions.end(ended, "user removed")
        assert found is not None  # remove_user raised not_found otherwise
        return {"user": _user(found[0])}
    if isinstance(msg, P.AccountCreateToken):
        token, rec = await sessions.create_token(
            msg.role, robot=msg.robot, table=msg.table, label=msg.label, scopes=msg.scopes or ()
        )
        if msg.role == "integration":  # a program is given its token, not a page to open
            return {"device": _token(rec), "token": token}
        link = setup_link(rec, token)
        qr = await asyncio.to_thread(qr_svg, (public_url or msg.base or "") + link)
        return {"device": _token(rec), "token": token, "link": link, "qr": qr}
    if isinstance(msg, P.AccountListTokens):
        recs = await store.accounts.list_tokens(include_ended=msg.all, now=now, kind="device")
        return {"tokens": [_token(t) for t in recs]}
    if isinstance(msg, P.AccountRevokeToken):
        if p is not None and msg.token == p.token_id:
            raise Conflict("this is your own session: log out instead", token=msg.token)
        rec = await store.accounts.revoke_token(msg.token, now=now)
        sessions.end([rec.id], "token revoked")
        return {"device": _token(rec)}
    raise AssertionError(f"unhandled account action {msg.action!r}")
