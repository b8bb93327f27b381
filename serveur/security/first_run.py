"""The first start of a restaurant nobody has set up: one setup link, on the terminal and as a
QR code, for the owner's tablet.

``serveur run`` on a database without users makes a one-time setup code
(:meth:`serveur.security.sessions.Sessions.prepare_setup`) and prints the link to the setup
page with it: the owner scans the QR code with a tablet on the restaurant's Wi-Fi and chooses
their password there (no password is ever printed). The link names the box by an address a
tablet can reach: the address given with ``--host``, or, when the server listens on every
interface (``0.0.0.0``), the box's own address on its network — never 127.0.0.1, which a
tablet would take for itself. The owner then sets the restaurant's public address, which every
screen's setup link and QR code uses from then on.
"""

from __future__ import annotations

import contextlib
import socket
from typing import TextIO

import segno

__all__ = ["lan_address", "print_setup_link", "setup_url"]

_ANY = ("", "0.0.0.0", "::")


def lan_address() -> str:
    """This box's address on its network: the source address of a route out (a UDP socket
    connected to a private address sends nothing), else its host name."""
    with contextlib.suppress(OSError), socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
        s.connect(("10.255.255.255", 9))
        address = str(s.getsockname()[0])
        if not address.startswith("127."):
            return address
    return socket.gethostname()


def setup_url(host: str, port: int, code: str, *, tls: bool = False) -> str:
    """The setup page's link for a server listening on ``host``:``port``."""
    reachable = lan_address() if host in _ANY else host
    if ":" in reachable and not reachable.startswith("["):
        reachable = f"[{reachable}]"  # an IPv6 address in a URL
    scheme = "https" if tls else "http"
    return f"{scheme}://{reachable}:{port}/setup.html#setup={code}"


def print_setup_link(url: str, out: TextIO) -> None:
    """The link and its QR code, drawn with text blocks (any terminal, any font)."""
    print("First start: set this restaurant up from a tablet or phone on its Wi-Fi:", file=out)
    print(f"  {url}", file=out)
    segno.make(url, error="m").terminal(out=out, compact=True)
    out.flush()
