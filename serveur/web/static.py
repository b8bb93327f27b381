"""The web UI's static files, served over plain HTTP by the websocket server's ``process_request``.

Every file under ``serveur/web/site/`` is read into memory once, when the site is loaded at start,
so answering a request never touches the disk (nor blocks the event loop). A request can only
ever get one of those in-memory files: the path is looked up in a dict of known names, so
``..``, ``%2e%2e``, absolute paths or symlinks cannot reach anything else.

Pages: ``/`` and ``/staff`` (staff console), ``/robot/<name>`` (a robot's screen; also
``/robot.html?robot=<name>``) and ``/table/<name>`` (a table's screen). The page's script reads
the name from its own URL, so the server does not template anything. Nor does it pick a language:
the pages' words are in the catalogs ``/i18n/<lang>.json`` (plain files, ``application/json``),
which ``js/i18n.js`` fetches and applies in the browser.

Caching: every answer carries an ``ETag`` (a hash of the body) and a ``Last-Modified`` (when
this server loaded the site) with ``Cache-Control: no-cache``: a browser keeps its copy but
asks each time, and gets a body-less 304 while the file is unchanged. So a page, a script or
a catalog never goes stale after an upgrade (new body, new ETag; a restart, a new
Last-Modified), and a reload costs a few hundred bytes a file. Text files (pages, scripts,
styles, catalogs, SVG) are gzipped once at load and sent compressed to a client that accepts
gzip (``Vary: Accept-Encoding``; the gzipped body has its own ETag).

Made, not copied: ``/js/status-table.js`` is no file of ``site/``. It is written from
:data:`serveur.status.ALLOWED` (which instructions each robot status accepts) when the site is
loaded (:func:`generated`), and served like the other scripts (same ETag, gzip, 304s); the
pages' ``js/status.js`` imports it. So the browser greys out exactly the buttons the server
would refuse, and a change to the table in ``status.py`` reaches the pages at the next start.
"""

from __future__ import annotations

import email.utils
import functools
import gzip
import hashlib
import http
import json
import time
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from urllib.parse import unquote

from websockets.datastructures import Headers
from websockets.http11 import Request, Response

from serveur.status import ALLOWED, Action, RobotStatus

__all__ = [
    "SECURITY_HEADERS",
    "STATUS_TABLE",
    "Asset",
    "StaticSite",
    "default_site",
    "generated",
    "status_table_js",
]

WEB_ROOT = Path(__file__).with_name("site")

# The UI loads only its own scripts, styles and images, and talks only to its own server's
# websocket: nothing else is needed offline, and nothing else can be injected. ``blob:`` images
# are the robots' camera pictures, made by the page's own script from its websocket's binary
# messages (docs/protocol.md, "Camera frames").
CONTENT_SECURITY_POLICY = (
    "default-src 'self'; script-src 'self'; style-src 'self'; img-src 'self' data: blob:; "
    "connect-src 'self' ws: wss:; object-src 'none'; base-uri 'none'; form-action 'self'; "
    "frame-ancestors 'none'"
)
SECURITY_HEADERS = (
    ("Content-Security-Policy", CONTENT_SECURITY_POLICY),
    ("X-Content-Type-Options", "nosniff"),
    ("X-Frame-Options", "DENY"),
    ("Referrer-Policy", "no-referrer"),
)

CONTENT_TYPES = {
    ".html": "text/html; charset=utf-8",
    ".js": "text/javascript; charset=utf-8",
    ".css": "text/css; charset=utf-8",
    ".svg": "image/svg+xml",
    ".png": "image/png",
    ".json": "application/json",
    ".txt": "text/plain; charset=utf-8",
    ".ico": "image/x-icon",
    ".woff2": "font/woff2",
}

# Pages whose last path segment is a robot's or table's name, read by the page's own script.
NAMED_PAGES = {"robot": "/robot.html", "table": "/table.html"}
ALIASES = {"/": "/staff.html", "/staff": "/staff.html", "/setup": "/setup.html"}
MAX_NAME = 64


#: The allowed-actions table as a script (status_table_js), served at this path.
STATUS_TABLE = "/js/status-table.js"


def status_table_js(
    allowed: Mapping[RobotStatus, frozenset[Action]] = ALLOWED,
) -> bytes:
    """``allowed`` (the server's table) as an ES module: ``ALLOWED``, status -> its actions.

    Statuses and actions come in the order ``status.py`` declares them, so the same table
    always makes the same bytes (and ETag).
    """
    rows = {s.value: [a.value for a in Action if a in allowed[s]] for s in RobotStatus}
    lines = [
        "// Made by serveur/web/static.py from serveur/status.py (ALLOWED) when the server",
        "// started: which instructions a robot accepts in each status. No file holds it.",
        f"export const ACTIONS = {json.dumps([a.value for a in Action])};",
        "export const ALLOWED = {",
        *(f"  {json.dumps(status)}: {json.dumps(actions)}," for status, actions in rows.items()),
        "};",
        "",
    ]
    return "\n".join(lines).encode()


def generated() -> dict[str, bytes]:
    """The site's files made from the server's own code (path -> body), not read from disk."""
    return {STATUS_TABLE: status_table_js()}


# Worth compressing: text. Images and fonts are compressed already.
COMPRESSIBLE = (".html", ".js", ".css", ".svg", ".json", ".txt")


@dataclass(frozen=True)
class Asset:
    body: bytes
    content_type: str
    etag: str
    gzipped: bytes | None = None  # the body gzipped, when that is smaller
    modified: float = 0.0  # Unix time for Last-Modified

    @classmethod
    def of(cls, name: str, body: bytes, modified: float | None = None) -> Asset:
        suffix = Path(name).suffix.lower()
        ctype = CONTENT_TYPES.get(suffix, "application/octet-stream")
        gz = gzip.compress(body, compresslevel=9, mtime=0) if suffix in COMPRESSIBLE else None
        if gz is not None and len(gz) >= len(body):
            gz = None
        etag = '"' + hashlib.sha256(body).hexdigest()[:32] + '"'
        return cls(body, ctype, etag, gz, time.time() if modified is None else modified)

    @property
    def gzip_etag(self) -> str:
        return self.etag[:-1] + '-gz"'


def _response(status: http.HTTPStatus, headers: list[tuple[str, str]], body: bytes) -> Response:
    return Response(status.value, status.phrase, Headers(headers), body)


def _plain(
    status: http.HTTPStatus, text: str, *extra: tuple[str, str], head: bool = False
) -> Response:
    body = text.encode()
    headers = [
        ("Content-Type", "text/plain; charset=utf-8"),
        ("Content-Length", str(len(body))),
        ("Cache-Control", "no-store"),
        ("Connection", "close"),
        *SECURITY_HEADERS,
        *extra,
    ]
    return _response(status, headers, b"" if head else body)


def _valid_name(segment: str) -> bool:
    return (
        0 < len(segment) <= MAX_NAME
        and segment not in (".", "..")
        and segment.strip() == segment
        and not any(ch in segment for ch in "/\\")
        and all(ch.isprintable() for ch in segment)
    )


class StaticSite:
    """A fixed set of files in memory, answered by path."""

    def __init__(self, assets: Mapping[str, Asset]) -> None:
        self.assets = dict(assets)

    @classmethod
    def load(cls, root: Path = WEB_ROOT, made: Mapping[str, bytes] | None = None) -> StaticSite:
        """Read every regular file under ``root`` (not following symlinks out of it), plus
        ``made`` (path -> body: files written by the server, such as :func:`generated`)."""
        assets: dict[str, Asset] = {}
        base = root.resolve()
        loaded = float(int(time.time()))  # Last-Modified: HTTP dates have whole seconds
        for path in sorted(root.rglob("*")):
            if not path.is_file() or path.name.startswith("."):
                continue
            real = path.resolve()
            if not real.is_relative_to(base):
                continue  # a symlink pointing outside the web root is not served
            name = "/" + path.relative_to(root).as_posix()
            assets[name] = Asset.of(name, real.read_bytes(), loaded)
        for name, body in (made or {}).items():
            if name in assets:
                raise ValueError(f"{name} is made by the server and is also a file of {root}")
            assets[name] = Asset.of(name, body, loaded)
        return cls(assets)

    def resolve(self, raw_path: str) -> Asset | None:
        """The asset for a request path (query string ignored), or None for a 404."""
        path = raw_path.split("?", 1)[0].split("#", 1)[0]
        if not path.startswith("/"):
            return None
        if path in ALIASES:
            return self.assets.get(ALIASES[path])
        segments = path[1:].split("/")
        if len(segments) == 2 and segments[0] in NAMED_PAGES:
            name = unquote(segments[1], errors="strict") if "%" in segments[1] else segments[1]
            return self.assets.get(NAMED_PAGES[segments[0]]) if _valid_name(name) else None
        # Plain files: the decoded path must be exactly one of the loaded names. Reject
        # dot segments explicitly too, so a mistake here can never turn into a traversal.
        try:
            decoded = unquote(path, errors="strict")
        except UnicodeDecodeError:
            return None
        if any(seg in ("", ".", "..") for seg in decoded[1:].split("/")) or "\\" in decoded:
            return None
        return self.assets.get(decoded)

    def respond(self, request: Request) -> Response:
        """The HTTP response for a GET or HEAD request of a UI file (404 for anything else)."""
        head = request.method == "HEAD"
        if request.method not in ("GET", "HEAD"):
            return _plain(
                http.HTTPStatus.METHOD_NOT_ALLOWED, "method not allowed\n", ("Allow", "GET, HEAD")
            )
        try:
            asset = self.resolve(request.path)
        except UnicodeDecodeError:
            asset = None
        if asset is None:
            return _plain(http.HTTPStatus.NOT_FOUND, "not found\n", head=head)
        zipped = asset.gzipped is not None and _accepts_gzip(
            request.headers.get("Accept-Encoding", "")
        )
        etag = asset.gzip_etag if zipped else asset.etag
        headers = [
            ("Content-Type", asset.content_type),
            ("ETag", etag),
            ("Last-Modified", email.utils.formatdate(asset.modified, usegmt=True)),
            # Revalidate every time (a 304 is cheap on a LAN): a tablet never keeps running an
            # old UI against an upgraded server.
            ("Cache-Control", "no-cache"),
            ("Connection", "close"),
            *SECURITY_HEADERS,
        ]
        if asset.gzipped is not None:
            headers.append(("Vary", "Accept-Encoding"))
        if _not_modified(request.headers, asset, etag):
            return _response(http.HTTPStatus.NOT_MODIFIED, headers, b"")
        body = asset.gzipped if zipped and asset.gzipped is not None else asset.body
        if zipped:
            headers.append(("Content-Encoding", "gzip"))
        headers.append(("Content-Length", str(len(body))))
        return _response(http.HTTPStatus.OK, headers, b"" if head else body)


def _not_modified(headers: Headers, asset: Asset, etag: str) -> bool:
    """RFC 9110 13.2.2: If-None-Match decides when present, else If-Modified-Since."""
    if "If-None-Match" in headers:
        tags = _etags(headers.get("If-None-Match", ""))
        return etag in tags or "*" in tags
    since = headers.get("If-Modified-Since")
    if since:
        try:
            when = email.utils.parsedate_to_datetime(since).timestamp()
        except (TypeError, ValueError, IndexError, OverflowError):
            return False
        return asset.modified <= when
    return False


def _accepts_gzip(header: str) -> bool:
    """``Accept-Encoding`` names gzip (or ``*``) with a q-value above zero."""
    for item in header.split(","):
        coding, _, params = item.strip().partition(";")
        if coding.strip().lower() not in ("gzip", "x-gzip", "*"):
            continue
        q = 1.0
        for param in params.split(";"):
            key, _, value = param.strip().partition("=")
            if key.strip().lower() == "q":
                try:
                    q = float(value)
                except ValueError:
                    q = 0.0
        return q > 0
    return False


def _etags(header: str) -> set[str]:
    # Weak comparison (RFC 9110 13.1.2): W/"x" matches "x".
    return {t.strip().removeprefix("W/") for t in header.split(",") if t.strip()}


@functools.cache
def default_site() -> StaticSite:
    """The packaged UI, read from disk once per process (at the first server's start), with
    the files made from the server's code (the allowed-actions table)."""
    return StaticSite.load(WEB_ROOT, generated())
