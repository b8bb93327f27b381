"""The owner's view of the chain over ``/ws`` (``chain``: issue 34) and the record its reply
carries.

A site in a restaurant chain ships every event it records, numbered, to the chain's broker
(:mod:`serveur.chain.shipper`); the owner's console asks ``chain`` to say whether the head
office is reached and how much is still waiting on the box (the outbox). Events are numbered
from the start, chain or not, so a site with no chain answers the outbox's numbers too.
"""

from __future__ import annotations

from typing import Literal

from pydantic import BaseModel, ConfigDict, Field

from serveur.wire.base import ClientModel

__all__ = ["ChainInfo", "ChainMsg", "OutboxInfo"]


class ChainMsg(ClientModel):
    """Is this site in a chain, is its broker reached, and where does its outbox stand?"""

    clientmsg: Literal["chain"]


class _Record(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)


class OutboxInfo(_Record):
    """Where the site's outbox stands (``store.outbox.state()``): numbers of events."""

    head: int = Field(description="the last number an event was given")
    sent: int = Field(description="the last number the chain's broker acknowledged")
    confirmed: int = Field(description="the last number the head office said it stored")
    unsent: int = Field(description="events the broker has not acknowledged: head - sent")
    size: int = Field(description="rows the outbox keeps (deleted once confirmed and a week old)")
    oldest_unsent_at: float | None = Field(
        description="when the oldest unsent event was recorded (epoch s); null: all sent"
    )
    sent_at: float | None = Field(
        description="when the broker last acknowledged events (epoch s); null: never"
    )


class ChainInfo(_Record):
    """The ``chain`` reply: the site's place in a chain and its outbox."""

    configured: bool = Field(description="the server was started with --chain")
    site: str | None = Field(description="this site's name in the chain; null: no chain")
    broker: str | None = Field(
        description="the chain's broker, mqtts://SITE@HOST:PORT (never the password);"
        " null: no chain"
    )
    connected: bool = Field(description="the broker is connected now (false: no chain)")
    outbox: OutboxInfo
