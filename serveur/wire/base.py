"""The base of every client message of the ``/ws`` protocol.

Strict types (a string is not a number), unknown fields refused (a typo is an error, not a
silently ignored field), immutable once parsed, and the request's ``id`` echoed in the reply.
:mod:`serveur.protocol` and the owner's message modules (:mod:`serveur.wire.owner`,
:mod:`serveur.wire.accounts`) all build on it, so they cannot drift apart.
"""

from __future__ import annotations

from pydantic import BaseModel, ConfigDict, Field

from serveur.wire.fields import RequestId

__all__ = ["ClientModel"]


class ClientModel(BaseModel):
    """Common base: strict types, unknown fields refused, immutable once parsed."""

    model_config = ConfigDict(extra="forbid", frozen=True, strict=True, hide_input_in_errors=True)

    id: RequestId | None = Field(
        default=None, description="Echoed in the reply so the client can match it"
    )
