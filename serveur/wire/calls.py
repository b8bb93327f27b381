"""Guests' calls and the Wi-Fi call buttons over ``/ws`` (``call`` open / answer / cancel;
``site`` add_button / buttons / revoke_button).

A call is what a guest asks for from a table: a robot to take the used plates, a waiter, the
bill. Its rules (one open call per table and kind, a button's rate limit, escalation) are in
:mod:`serveur.core.calls`; these are only the shapes a client may send.
"""

from __future__ import annotations

from typing import Annotated, Literal, TypeAlias

from pydantic import Field

from serveur.wire.base import ClientModel
from serveur.wire.fields import Name

__all__ = [
    "CALL_KINDS",
    "CallAnswer",
    "CallCancel",
    "CallMessage",
    "CallOpen",
    "SiteAddButton",
    "SiteButtons",
    "SiteRevokeButton",
]

#: What a guest may call for (serveur.domain.CallKind).
CALL_KINDS = ("plates", "waiter", "bill")
CallKindName: TypeAlias = Literal["plates", "waiter", "bill"]
CallId = Annotated[int, Field(ge=1, le=2**53)]


class _CallMsg(ClientModel):
    clientmsg: Literal["call"]


class CallOpen(_CallMsg):
    """A guest calls from ``table`` (a table screen for its own table, or staff for a guest):
    a second call of the same kind while one is open is merged into it."""

    action: Literal["open"]
    table: Name
    kind: CallKindName


class CallAnswer(_CallMsg):
    """Staff answer a call (they went to the table); a plates call is also answered by the
    robot sent for it when it reaches the table."""

    action: Literal["answer"]
    call: CallId


class CallCancel(_CallMsg):
    """Staff cancel a call (pressed by mistake, or dealt with another way); a bussing trip
    sent for it and not yet under way is cancelled too."""

    action: Literal["cancel"]
    call: CallId


CallMessage: TypeAlias = Annotated[
    CallOpen | CallAnswer | CallCancel, Field(discriminator="action")
]


class SiteAddButton(ClientModel):
    """Register a Wi-Fi call button for ``table``: the reply holds its token and the address
    the button requests (``GET /call/<token>``), shown once."""

    clientmsg: Literal["site"]
    action: Literal["add_button"]
    name: Name
    table: Name
    kind: CallKindName = "waiter"


class SiteButtons(ClientModel):
    """The call buttons, revoked ones included (never their tokens)."""

    clientmsg: Literal["site"]
    action: Literal["buttons"]


class SiteRevokeButton(ClientModel):
    """Revoke a button's token: its presses are refused from now on."""

    clientmsg: Literal["site"]
    action: Literal["revoke_button"]
    name: Name
