"""The chain broker's address: ``mqtts://USER[:PASSWORD]@HOST[:PORT]`` and a CA file.

``USER`` is the site's name for a site (the broker's ACL lets it write only under
``chain/USER/``) and ``hq`` for the centre. A URL without a password reads
``$SERVEUR_CHAIN_PASSWORD`` (so it stays out of ``ps`` and the unit file). ``mqtts`` is TLS
(port 8883 by default), verified against ``ca`` (the chain's own CA) or the system's CAs;
``mqtt`` (1883) is refused unless ``insecure`` is said: a chain crosses the internet.
"""

from __future__ import annotations

import os
import ssl
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import aiomqtt
from urllib.parse import unquote, urlsplit

__all__ = ["ChainAddress"]


@dataclass(frozen=True, slots=True)
class ChainAddress:
    host: str
    port: int
    user: str
    password: str | None
    tls: bool
    ca: str | None = None

    @classmethod
    def parse(cls, url: str, *, ca: str | None = None, insecure: bool = False) -> ChainAddress:
        parts = urlsplit(url)
        if parts.scheme not in ("mqtts", "mqtt") or not parts.hostname or not parts.username:
            raise ValueError(f"a chain broker is mqtts://USER[:PASSWORD]@HOST[:PORT], not {url!r}")
        if parts.scheme == "mqtt" and not insecure:
            raise ValueError("a chain broker is reached over TLS (mqtts://): mqtt:// is plain text")
        if parts.path.strip("/") or parts.query:
            raise ValueError("a chain broker's URL has no path: topics are chain/<site>/...")
        tls = parts.scheme == "mqtts"
        password = unquote(parts.password) if parts.password else None
        return cls(
            parts.hostname,
            parts.port or (8883 if tls else 1883),
            unquote(parts.username),
            password if password is not None else os.environ.get("SERVEUR_CHAIN_PASSWORD"),
            tls,
            ca,
        )

    def ssl_context(self) -> ssl.SSLContext | None:
        if not self.tls:
            return None
        return ssl.create_default_context(cafile=self.ca)

    def client(self, identifier: str, **options: Any) -> aiomqtt.Client:
        """An aiomqtt client for this broker as ``identifier`` (the site's shipper and the
        centre's consumer both), with ``options`` for what differs between them."""
        import aiomqtt  # only where a chain is configured

        return aiomqtt.Client(
            self.host,
            self.port,
            username=self.user,
            password=self.password,
            identifier=identifier,
            tls_context=self.ssl_context(),
            timeout=10,
            keepalive=30,
            **options,
        )

    def describe(self) -> str:
        return f"{'mqtts' if self.tls else 'mqtt'}://{self.user}@{self.host}:{self.port}"
