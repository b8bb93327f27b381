"""The till's messages over ``/ws`` (``till`` state / tickets / by_hand / propose / preview /
setup / import_menu / map / unmapped) and the order-intake API's request body.

What a ticket from the till becomes is :class:`serveur.core.ticket_desk.TicketDesk`'s; how a
ticket is read, :mod:`serveur.till.pattern`'s. These are only the shapes a client may send.
"""

from __future__ import annotations

from typing import Annotated, Any, Literal, TypeAlias

from pydantic import BaseModel, ConfigDict, Field

from serveur.wire.base import ClientModel
from serveur.wire.fields import Name

__all__ = [
    "ENCODING_NAMES",
    "IntakeDish",
    "IntakeOrder",
    "TillByHand",
    "TillImportMenu",
    "TillMap",
    "TillMark",
    "TillMessage",
    "TillPattern",
    "TillPreview",
    "TillPropose",
    "TillSetup",
    "TillState",
    "TillTickets",
    "TillUnmapped",
]

#: The printer's code page before any command (serveur.till.escpos.ENCODINGS).
ENCODING_NAMES: TypeAlias = Literal["auto", "cp437", "cp850", "cp1252", "gb18030", "utf-8"]
TicketId = Annotated[int, Field(ge=1, le=2**53)]
#: A pattern's rule: a regular expression (checked when the pattern is built).
_Rule = Annotated[str, Field(max_length=500)]
#: ``host:port`` of the kitchen printer (an IPv4 address or a name; IPv6 in brackets).
#: The port is 1-65535: one digit to four, or five up to 65535.
_PORT = r"(?:[1-9]\d{0,3}|[1-5]\d{4}|6[0-4]\d{3}|65[0-4]\d{2}|655[0-2]\d|6553[0-5])"
Printer = Annotated[
    str,
    Field(
        max_length=255,
        pattern=r"^(?:$|(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9.-]+):" + _PORT + r")$",
    ),
]


class _Part(BaseModel):
    """A part of a message (no ``id`` of its own)."""

    model_config = ConfigDict(
        extra="forbid", frozen=True, strict=True, hide_input_in_errors=True, populate_by_name=True
    )


class _TillMsg(ClientModel):
    clientmsg: Literal["till"]


class TillState(_TillMsg):
    """The printer port, the kitchen printer, the code page, the pattern, and how they are."""

    action: Literal["state"]


class TillTickets(_TillMsg):
    """The tickets kept, newest first (``before``: the ids below it, for the next page)."""

    action: Literal["tickets"]
    before: TicketId | None = None
    limit: Annotated[int, Field(ge=1, le=200)] = 50
    status: (
        Annotated[
            list[Literal["unread", "ordered", "reprint", "void", "by_hand"]],
            Field(min_length=1, max_length=5),
        ]
        | None
    ) = None


class TillByHand(_TillMsg):
    """Staff added an unread ticket's dishes themselves: it is dealt with."""

    action: Literal["by_hand"]
    ticket: TicketId


class TillMark(_Part):
    """The owner's mark on one line of a ticket (``line``: 0 for the first)."""

    line: Annotated[int, Field(ge=0, le=399)]
    as_: Literal["table", "dish", "note", "ticket", "void", "ignore"] = Field(alias="as")
    table: Name | None = Field(default=None, description="with as=table: the table it holds")


class TillPattern(_Part):
    """A ticket pattern, as ``propose`` returned it (the owner may edit its rules)."""

    table: _Rule
    dish: _Rule
    table_prefix: Annotated[str, Field(max_length=16)] = ""
    note: _Rule | None = None
    ticket: _Rule | None = None
    void: _Rule | None = None
    ignore: Annotated[list[_Rule], Field(max_length=50)] = []

    def rules(self) -> dict[str, Any]:
        return self.model_dump(exclude_none=True)


class TillPropose(_TillMsg):
    """The pattern the owner's marks on one ticket mean, and what it reads on every ticket."""

    action: Literal["propose"]
    ticket: TicketId
    marks: Annotated[list[TillMark], Field(min_length=1, max_length=60)]


class TillPreview(_TillMsg):
    """What a pattern reads on the latest tickets."""

    action: Literal["preview"]
    pattern: TillPattern


class TillSetup(_TillMsg):
    """The owner's settings; omitted fields are kept. A pattern saved reads the tickets that
    were waiting for one."""

    action: Literal["setup"]
    port: Annotated[int, Field(ge=0, le=65535)] | None = Field(
        default=None, description="the printer port serveur listens on; 0: off"
    )
    printer: Printer | None = Field(
        default=None, description='"host:port" of the kitchen printer; "": serveur is a second one'
    )
    encoding: ENCODING_NAMES | None = None
    pattern: TillPattern | None = None
    clear_pattern: bool = False


class TillImportMenu(_TillMsg):
    """The till's menu as CSV: its item names, and serveur's dish for each where known."""

    action: Literal["import_menu"]
    csv: Annotated[str, Field(min_length=1, max_length=200_000)]


class TillMap(_TillMsg):
    """Map the till's names to dishes (null: forget the mapping)."""

    action: Literal["map"]
    names: Annotated[
        dict[Annotated[str, Field(min_length=1, max_length=200)], Name | None],
        Field(min_length=1, max_length=500),
    ]


class TillUnmapped(_TillMsg):
    """The names the tickets printed that are neither on the menu nor mapped."""

    action: Literal["unmapped"]


TillMessage: TypeAlias = Annotated[
    TillState
    | TillTickets
    | TillByHand
    | TillPropose
    | TillPreview
    | TillSetup
    | TillImportMenu
    | TillMap
    | TillUnmapped,
    Field(discriminator="action"),
]


class IntakeDish(_Part):
    dish: Annotated[str, Field(min_length=1, max_length=200)]
    quantity: Annotated[int, Field(ge=1, le=99)] = 1
    note: Annotated[str, Field(max_length=200)] | None = None


class IntakeOrder(_Part):
    """``POST /api/orders``: a ticket's dishes for a table, under the integration's key."""

    key: Annotated[str, Field(min_length=1, max_length=64)]
    table: Name
    dishes: Annotated[list[IntakeDish], Field(min_length=1, max_length=50)]
    ticket: Annotated[str, Field(min_length=1, max_length=64)] | None = None
    void: bool = False
