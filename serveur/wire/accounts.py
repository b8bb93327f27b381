"""The owner's ``account`` verb of the ``/ws`` protocol: people who log in and screen tokens.

Part of :mod:`serveur.protocol` (which puts these messages in the client-message union and
re-exports them); kept apart like :mod:`serveur.wire.owner`, as the owner's business rather
than the dinner service's.
"""

from __future__ import annotations

from typing import Annotated, Literal, TypeAlias

from pydantic import Field, model_validator
from pydantic_core import PydanticCustomError

from serveur.wire.base import ClientModel as _ClientMsg
from serveur.wire.fields import Name, OrderId

__all__ = [
    "AccountAddUser",
    "AccountCreateToken",
    "AccountListTokens",
    "AccountListUsers",
    "AccountMessage",
    "AccountRemoveUser",
    "AccountResetPassword",
    "AccountRevokeToken",
    "AccountSetRole",
]

#: The roles a person's account may have.
UserRole: TypeAlias = Literal["owner", "staff"]
#: The screens the console makes tokens for, and programs (a till's bridge: ``integration``,
#: with the scopes it needs); staff devices' tokens stay on the command line.
ScreenRole: TypeAlias = Literal["robot-screen", "table-screen", "integration"]
#: What an integration token may be given (never ``accounts``: security.auth.Scope).
IntegrationScope: TypeAlias = Literal[
    "read", "orders", "tasks", "control", "waypoints", "robots", "audit", "menu", "site", "stats"
]
Label = Annotated[str, Field(max_length=64)]


class _AccountMsg(_ClientMsg):
    clientmsg: Literal["account"]


class AccountListUsers(_AccountMsg):
    """The people who log in (names and roles, never a password)."""

    action: Literal["list_users"]


class AccountAddUser(_AccountMsg):
    """Add a person; the server generates a strong password, returned once."""

    action: Literal["add_user"]
    username: Name
    role: UserRole = "staff"


class AccountSetRole(_AccountMsg):
    """Make a person owner or staff (their sessions end: they log in again)."""

    action: Literal["set_role"]
    username: Name
    role: UserRole


class AccountResetPassword(_AccountMsg):
    """Give a person a new generated password, returned once; their sessions end."""

    action: Literal["reset_password"]
    username: Name


class AccountRemoveUser(_AccountMsg):
    """Remove a person and end their sessions (never the last owner)."""

    action: Literal["remove_user"]
    username: Name


class AccountCreateToken(_AccountMsg):
    """A token for a robot's or a table's screen (returned once, with its setup link), or for
    a program (``integration``, with ``scopes``: a till's bridge posting orders)."""

    action: Literal["create_token"]
    role: ScreenRole
    robot: Name | None = None
    table: Name | None = None
    label: Label = ""
    scopes: Annotated[list[IntegrationScope], Field(min_length=1, max_length=10)] | None = Field(
        default=None, description="integration only: what the program may do"
    )
    base: Annotated[str, Field(max_length=200, pattern=r"^https?://[^\s/#?]+$")] | None = Field(
        default=None,
        description="The server's address as the screen will type it (http://host:port):"
        " the QR code holds base + link; without it, only the link",
    )

    @model_validator(mode="after")
    def _bound(self) -> AccountCreateToken:
        if (self.role == "robot-screen") != (self.robot is not None) or (
            self.role == "table-screen"
        ) != (self.table is not None):
            raise PydanticCustomError(
                "screen_target", "a robot-screen token needs robot, a table-screen token table"
            )
        if (self.role == "integration") != (self.scopes is not None):
            raise PydanticCustomError(
                "token_scopes", "an integration token needs scopes, and only it takes them"
            )
        return self


class AccountListTokens(_AccountMsg):
    """The active device tokens (never the token itself); ``all``: revoked and expired too."""

    action: Literal["list_tokens"]
    all: bool = False


class AccountRevokeToken(_AccountMsg):
    """Revoke a token by id: its connections are closed."""

    action: Literal["revoke_token"]
    token: OrderId


AccountMessage: TypeAlias = Annotated[
    AccountListUsers
    | AccountAddUser
    | AccountSetRole
    | AccountResetPassword
    | AccountRemoveUser
    | AccountCreateToken
    | AccountListTokens
    | AccountRevokeToken,
    Field(discriminator="action"),
]
