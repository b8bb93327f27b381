"""TLS contexts: the server's (https + wss on its one port) and the robot links' (``wss://``).

Staff tablets send orders and robot commands over Wi-Fi that guests may share, so a restaurant
can give the server a certificate (usually from its own small CA, see docs/security.md) and
robots that speak rosbridge over TLS can be reached at ``wss://`` URLs.

Both contexts start from :func:`ssl.create_default_context` so they follow Python's vetted
defaults (cipher suites, no compression, certificate and hostname checks for clients), and pin
TLS 1.2 as the floor: every browser a tablet runs and every rosbridge_server build speaks it.
Bad files become :class:`~serveur.errors.TlsError` here, at the boundary, so the CLI reports
one clear line instead of a traceback from deep inside ``ssl``.
"""

from __future__ import annotations

import ssl

from serveur.errors import TlsError

__all__ = ["client_context", "server_context"]


def server_context(certfile: str, keyfile: str) -> ssl.SSLContext:
    """The context the server listens with: ``certfile`` (PEM, the chain, leaf first) and
    ``keyfile`` (its PEM private key, unencrypted: the server starts unattended)."""
    ctx = ssl.create_default_context(ssl.Purpose.CLIENT_AUTH)
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    try:
        ctx.load_cert_chain(certfile, keyfile)
    except FileNotFoundError as exc:
        raise TlsError(
            f"certificate or key file not found ({certfile}, {keyfile})",
            certfile=certfile,
            keyfile=keyfile,
        ) from exc
    except ssl.SSLError as exc:
        # Raised for unreadable PEM and for a key that does not match the certificate.
        raise TlsError(
            f"cannot use certificate {certfile} with key {keyfile}: {exc.reason or exc}",
            certfile=certfile,
            keyfile=keyfile,
        ) from exc
    except OSError as exc:
        raise TlsError(
            f"cannot read certificate or key: {exc.strerror or exc}",
            certfile=certfile,
            keyfile=keyfile,
        ) from exc
    return ctx


def client_context(cafile: str | None = None) -> ssl.SSLContext:
    """The context robot links verify ``wss://`` robots with.

    ``cafile`` is a PEM bundle of the CA(s) that signed the robots' certificates (a local CA);
    ``None`` trusts the system store. Certificate and hostname checks stay on either way: a
    robot link that accepted any certificate would let anyone on the Wi-Fi drive the robots.
    """
    try:
        ctx = ssl.create_default_context(ssl.Purpose.SERVER_AUTH, cafile=cafile)
    except FileNotFoundError as exc:
        raise TlsError(f"CA file not found: {cafile}", cafile=cafile) from exc
    except ssl.SSLError as exc:
        raise TlsError(f"cannot use CA file {cafile}: {exc.reason or exc}", cafile=cafile) from exc
    except OSError as exc:
        raise TlsError(
            f"cannot read CA file {cafile}: {exc.strerror or exc}", cafile=cafile
        ) from exc
    ctx.minimum_version = ssl.TLSVersion.TLSv1_2
    return ctx
