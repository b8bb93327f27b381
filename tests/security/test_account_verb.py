"""The ``account`` verb: an owner manages people and screen tokens over the protocol.

Each action against a real server and database, and each refusal: who may not ask, bad
input, the last owner, one's own session. A refused request changes nothing.
"""

from __future__ import annotations

import contextlib
import sqlite3
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import ClientConnection, connect

from serveur.app import App
from serveur.security.sessions import CLOSE_AUTH
from tests.security.test_security import audit_rows, bare_server, closed_code, login, request


def _account(action: str, **fields: Any) -> dict[str, Any]:
    return {"clientmsg": "account", "action": action, **fields}


async def _owner(app: App) -> tuple[ClientConnection, dict[str, Any]]:
    ws = await connect(app.url)
    reply = await login(ws, username="owner", password=app.first_owner_password)
    assert reply["servermsg"] == "ok", reply
    return ws, reply["session"]


def _db(tmp_path: Path) -> list[tuple[Any, ...]]:
    with contextlib.closing(sqlite3.connect(tmp_path / "s.db")) as conn:
        return [
            *conn.execute("SELECT name, role, pw_hash FROM users ORDER BY name"),
            *conn.execute("SELECT id, revoked_at FROM tokens ORDER BY id"),
        ]


async def test_people_added_reset_promoted_and_removed(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws, _ = await _owner(app)
        added = await request(ws, _account("add_user", username="alice"))
        assert added["user"]["name"] == "alice" and added["user"]["role"] == "staff"
        first = added["password"]
        assert len(first) >= 12
        listed = await request(ws, _account("list_users"))
        assert [(u["name"], u["role"]) for u in listed["users"]] == [
            ("alice", "staff"),
            ("owner", "owner"),
        ]
        assert "password" not in str(listed["users"])
        # Alice logs in; a reset ends her session (4001) and only the new password works.
        async with connect(app.url) as alice:
            assert (await login(alice, username="alice", password=first))["servermsg"] == "ok"
            reset = await request(ws, _account("reset_password", username="alice"))
            second = reset["password"]
            assert second != first and reset["user"]["name"] == "alice"
            assert await closed_code(alice) == CLOSE_AUTH
        async with connect(app.url) as alice:
            assert (await login(alice, username="alice", password=first))["code"] == "unauthorized"
            assert (await login(alice, username="alice", password=second))["servermsg"] == "ok"
            # Promoted: her staff session ends; she logs in again as an owner.
            up = await request(ws, _account("set_role", username="alice", role="owner"))
            assert up["user"]["role"] == "owner"
            assert await closed_code(alice) == CLOSE_AUTH
        async with connect(app.url) as alice:
            session = (await login(alice, username="alice", password=second))["session"]
            assert session["role"] == "owner" and "accounts" in session["scopes"]
        removed = await request(ws, _account("remove_user", username="alice"))
        assert removed["user"]["name"] == "alice"
        async with connect(app.url) as alice:
            assert (await login(alice, username="alice", password=second))["code"] == "unauthorized"
        await ws.close()
    trail = [(a["verb"], a["target"], a["outcome"]) for a in audit_rows(tmp_path / "s.db")]
    for target in ("alice",):
        assert ("account", target, "ok") in trail
    assert sum(1 for v, _, o in trail if v == "account" and o == "ok") == 5
    assert not any(first in str(a) or second in str(a) for a in audit_rows(tmp_path / "s.db"))


async def test_screen_tokens_created_listed_and_revoked(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws, _ = await _owner(app)
        made = await request(
            ws,
            _account(
                "create_token",
                role="table-screen",
                table="T3",
                label="by the window",
                base="http://192.168.1.10:8765",
            ),
        )
        token = made["token"]
        assert made["link"] == f"/table/T3#token={token}"
        assert made["qr"].startswith("<svg") and "</svg>" in made["qr"]
        device = made["device"]
        assert device["role"] == "table-screen" and device["table"] == "T3"
        assert device["label"] == "by the window" and device["last_used_at"] is None
        async with connect(app.url) as screen:
            session = (await login(screen, token=token))["session"]
            assert session["role"] == "table-screen" and session["table"] == "T3"
            listed = await request(ws, _account("list_tokens"))
            assert [t["id"] for t in listed["tokens"]] == [device["id"]]  # no sessions
            assert listed["tokens"][0]["last_used_at"] is not None
            assert token not in str(listed)
            revoked = await request(ws, _account("revoke_token", token=device["id"]))
            assert revoked["device"]["revoked_at"] is not None
            assert await closed_code(screen) == CLOSE_AUTH
        async with connect(app.url) as screen:
            assert (await login(screen, token=token))["code"] == "unauthorized"
        assert (await request(ws, _account("list_tokens")))["tokens"] == []
        every = await request(ws, _account("list_tokens", all=True))
        assert [t["id"] for t in every["tokens"]] == [device["id"]]
        await ws.close()


async def test_refusals_change_nothing(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws, _ = await _owner(app)
        await request(ws, _account("add_user", username="bob"))
        before = _db(tmp_path)
        refusals: list[tuple[dict[str, Any], str]] = [
            (_account("add_user", username="bob"), "conflict"),
            (_account("add_user", username="carol", role="admin"), "invalid_field"),
            (_account("add_user", username="  "), "invalid_field"),
            (_account("add_user", username="carol", password="chosen-by-me"), "invalid_field"),
            (_account("set_role", username="nobody", role="staff"), "not_found"),
            (_account("set_role", username="owner", role="staff"), "conflict"),
            (_account("remove_user", username="owner"), "conflict"),
            (_account("remove_user", username="nobody"), "not_found"),
            (_account("reset_password", username="nobody"), "not_found"),
            (_account("create_token", role="table-screen", table="T99"), "not_found"),
            (_account("create_token", role="robot-screen", robot="r9"), "not_found"),
            (_account("create_token", role="table-screen"), "invalid_field"),
            (
                _account("create_token", role="table-screen", table="T3", robot="r1"),
                "invalid_field",
            ),
            (_account("create_token", role="integration", table="T3"), "invalid_field"),
            (_account("create_token", role="staff"), "invalid_field"),
            (
                _account("create_token", role="table-screen", table="T3", base="javascript:x"),
                "invalid_field",
            ),
            (_account("revoke_token", token=999), "not_found"),
            (_account("revoke_token", token=own_session_id(tmp_path)), "conflict"),
            (_account("delete_everything"), "invalid_field"),
        ]
        for body, code in refusals:
            reply = await request(ws, body)
            assert reply.get("code") == code, (body, reply)
        assert _db(tmp_path) == before
        # Staff and screens may not ask at all.
        password = (await request(ws, _account("reset_password", username="bob")))["password"]
        before = _db(tmp_path)
        async with connect(app.url) as bob:
            assert (await login(bob, username="bob", password=password))["servermsg"] == "ok"
            for body in (
                _account("list_users"),
                _account("add_user", username="mallory", role="owner"),
                _account("set_role", username="bob", role="owner"),
                _account("list_tokens"),
            ):
                reply = await request(bob, body)
                assert reply["code"] == "forbidden" and reply["details"] == {"scope": "accounts"}
        made = await request(ws, _account("create_token", role="table-screen", table="T3"))
        async with connect(app.url) as screen:
            await login(screen, token=made["token"])
            reply = await request(screen, _account("list_users"))
            assert reply["code"] == "forbidden"
        await ws.close()
    with contextlib.closing(sqlite3.connect(tmp_path / "s.db")) as conn:
        assert [r[0] for r in conn.execute("SELECT name FROM users ORDER BY name")] == [
            "bob",
            "owner",
        ]
    trail = [(a["actor"], a["verb"], a["outcome"]) for a in audit_rows(tmp_path / "s.db")]
    assert ("user:bob", "account", "forbidden") in trail
    assert ("user:owner", "account", "conflict") in trail
    assert ("user:owner", "account", "not_found") in trail


def own_session_id(tmp_path: Path) -> int:
    """The id of the owner's session token (the one asking), from the database."""
    with contextlib.closing(sqlite3.connect(tmp_path / "s.db")) as conn:
        (tid,) = conn.execute(
            "SELECT id FROM tokens WHERE user_name = 'owner' AND revoked_at IS NULL"
        ).fetchone()
        return int(tid)


async def test_an_owner_may_hand_over_then_step_down(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws, _ = await _owner(app)
        await request(ws, _account("add_user", username="alice", role="owner"))
        down = await request(ws, _account("set_role", username="owner", role="staff"))
        assert down["user"]["role"] == "staff"
        assert await closed_code(ws) == CLOSE_AUTH  # their own owner session ended


async def test_no_token_ever_carries_the_accounts_scope(tmp_path: Path) -> None:
    from serveur.errors import InvalidField
    from serveur.security import auth

    async with bare_server(tmp_path) as app:
        assert app.sessions is not None
        before = _db(tmp_path)
        with pytest.raises(InvalidField, match="owner's, never a token's"):
            await app.sessions.create_token("integration", scopes=["accounts", "read"])
        assert _db(tmp_path) == before
        # Even one written straight into the database would not grant it.
        await app.store.accounts.add_token(
            auth.token_digest("srv_planted-token-0000"),
            kind="device",
            role="integration",
            scopes=["accounts", "read"],
            now=0.0,
        )
        async with connect(app.url) as ws:
            session = (await login(ws, token="srv_planted-token-0000"))["session"]
            assert session["scopes"] == ["read"]
            reply = await request(ws, _account("list_users"))
            assert reply["code"] == "forbidden"
