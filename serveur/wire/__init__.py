"""The pieces :mod:`serveur.protocol` is made of: field types and limits, server frames.

Owns: :mod:`~serveur.wire.fields` (the annotated pydantic types every message is built from,
with their limits) and :mod:`~serveur.wire.frames` (the server's reply, error and update
models and the hot-path framing). :mod:`serveur.protocol` re-exports what a client of the
contract needs, so code outside speaks of ``serveur.protocol``. Pure: no I/O, no event loop.

May import: serveur.domain, serveur.errors.
"""

__all__: list[str] = []
