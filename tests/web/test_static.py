"""The web UI over plain HTTP, without a browser: routes, types, caching, headers, traversal."""

from __future__ import annotations

import asyncio
import json
import re
from pathlib import Path

import pytest
from websockets.datastructures import Headers
from websockets.http11 import Request

from serveur.web.static import WEB_ROOT, StaticSite
from tests.conftest import Restaurant

PAGES = {
    "/": "staff.html",
    "/staff": "staff.html",
    "/staff.html": "staff.html",
    "/robot/r1": "robot.html",
    "/robot/r%201": "robot.html",
    "/robot.html?robot=r1": "robot.html",
    "/table/T3": "table.html",
    "/table/T3?x=1": "table.html",
}

TRAVERSALS = [
    "/../pyproject.toml",
    "/js/../../static.py",
    "/%2e%2e/static.py",
    "/%2E%2E/%2e%2e/pyproject.toml",
    "/js/%2e%2e/%2e%2e/server.py",
    "/js/..%2f..%2fserver.py",
    "/js%2f..%2f..%2fserver.py",
    "//etc/passwd",
    "/etc/passwd",
    "/" + str(WEB_ROOT / "staff.html"),
    "/js/./ws.js",
    "/js//ws.js",
    "/js\\ws.js",
    "/%00",
    "/%ff",
    "/robot/..",
    "/robot/%2e%2e",
    "/robot/a%2fb",
    "/robot/",
    "/table/T3/extra",
    "/robot",
    "staff.html",
]


def get(
    site: StaticSite, path: str, method: str = "GET", **headers: str
) -> tuple[int, Headers, bytes]:
    req = Request(path, Headers(list(headers.items())), method=method)
    resp = site.respond(req)
    return resp.status_code, resp.headers, resp.body


@pytest.fixture(scope="module")
def site() -> StaticSite:
    return StaticSite.load(WEB_ROOT)


def test_pages_and_their_types(site: StaticSite) -> None:
    for path, file in PAGES.items():
        status, headers, body = get(site, path)
        assert status == 200, path
        assert headers["Content-Type"] == "text/html; charset=utf-8"
        assert body == (WEB_ROOT / file).read_bytes(), path
    assert get(site, "/js/ws.js")[1]["Content-Type"] == "text/javascript; charset=utf-8"
    assert get(site, "/css/base.css")[1]["Content-Type"] == "text/css; charset=utf-8"
    assert get(site, "/favicon.svg")[1]["Content-Type"] == "image/svg+xml"


def test_every_file_is_served_with_security_headers(site: StaticSite) -> None:
    files = [p for p in WEB_ROOT.rglob("*") if p.is_file()]
    assert len(files) >= 10
    for p in files:
        status, headers, body = get(site, "/" + p.relative_to(WEB_ROOT).as_posix())
        assert status == 200 and body == p.read_bytes(), p
        assert int(headers["Content-Length"]) == len(body)
        csp = headers["Content-Security-Policy"]
        assert "default-src 'self'" in csp and "connect-src 'self' ws:" in csp
        assert "unsafe-inline" not in csp and "http" not in csp
        assert headers["X-Content-Type-Options"] == "nosniff"
        assert headers["X-Frame-Options"] == "DENY"
        assert headers["Cache-Control"] == "no-cache"


def test_no_cdn_nothing_fetched_from_elsewhere() -> None:
    for p in WEB_ROOT.rglob("*"):
        if p.suffix in (".html", ".js", ".css"):
            # SVG's XML namespace is a name, never fetched (document.createElementNS).
            text = p.read_text().replace('"http://www.w3.org/2000/svg"', "")
            assert "http://" not in text and "https://" not in text, p
            assert "//cdn" not in text, p


def test_head_has_the_headers_and_no_body(site: StaticSite) -> None:
    status, headers, body = get(site, "/js/ws.js", "HEAD")
    _, g_headers, g_body = get(site, "/js/ws.js")
    assert (status, body) == (200, b"")
    assert headers["Content-Length"] == str(len(g_body)) == g_headers["Content-Length"]
    assert headers["ETag"] == g_headers["ETag"]
    status, _, body = get(site, "/nope", "HEAD")
    assert (status, body) == (404, b"")


def test_etag_revalidation(site: StaticSite) -> None:
    _, headers, _ = get(site, "/")
    etag = headers["ETag"]
    assert etag.startswith('"') and etag.endswith('"')
    assert get(site, "/", **{"If-None-Match": etag})[0] == 304
    assert get(site, "/", **{"If-None-Match": f"W/{etag}"})[0] == 304
    assert get(site, "/", **{"If-None-Match": f'"other", {etag}'})[0] == 304
    assert get(site, "/", **{"If-None-Match": "*"})[0] == 304
    status, _, body = get(site, "/", **{"If-None-Match": '"stale"'})
    assert status == 200 and body
    # Different files, different tags.
    assert get(site, "/js/ws.js")[1]["ETag"] != etag


def test_other_methods_are_refused(site: StaticSite) -> None:
    for method in ("POST", "PUT", "DELETE", "OPTIONS"):
        status, headers, _ = get(site, "/", method)
        assert status == 405 and headers["Allow"] == "GET, HEAD"


def test_unknown_paths_and_traversal_are_404(site: StaticSite) -> None:
    for path in ["/nope", "/js/nope.js", "/staff.htm", "/STAFF.HTML", *TRAVERSALS]:
        status, headers, body = get(site, path)
        assert status == 404, path
        assert body == b"not found\n"
        assert headers["X-Content-Type-Options"] == "nosniff"


def test_served_from_memory_only(tmp_path: Path) -> None:
    root = tmp_path / "web"
    (root / "js").mkdir(parents=True)
    (root / "staff.html").write_text("<p>hi</p>")
    (root / "js" / "a.js").write_text("export {};")
    (root / ".hidden").write_text("secret")
    secret = tmp_path / "secret.txt"
    secret.write_text("top secret")
    (root / "link.txt").symlink_to(secret)  # points outside the web root: never served
    site = StaticSite.load(root)
    assert sorted(site.assets) == ["/js/a.js", "/staff.html"]
    (root / "staff.html").unlink()
    (root / "js" / "a.js").write_text("changed")
    assert get(site, "/")[2] == b"<p>hi</p>"
    assert get(site, "/js/a.js")[2] == b"export {};"
    assert get(site, "/link.txt")[0] == 404
    assert get(site, "/.hidden")[0] == 404


async def raw_http(port: int, request: bytes) -> tuple[int, dict[str, str], bytes]:
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(request)
    await writer.drain()
    data = await asyncio.wait_for(reader.read(), 10)
    writer.close()
    head, _, body = data.partition(b"\r\n\r\n")
    lines = head.decode("latin-1").split("\r\n")
    headers = {}
    for line in lines[1:]:
        k, _, v = line.partition(":")
        headers[k.strip().lower()] = v.strip()
    return int(lines[0].split()[1]), headers, body


async def test_served_by_the_real_server(one_robot: Restaurant) -> None:
    server = one_robot.app.server
    assert server is not None
    port = server.port

    async def fetch(path: str, method: str = "GET") -> tuple[int, dict[str, str], bytes]:
        req = f"{method} {path} HTTP/1.1\r\nHost: localhost\r\n\r\n".encode()
        return await raw_http(port, req)

    status, headers, body = await fetch("/")
    assert status == 200 and body == (WEB_ROOT / "staff.html").read_bytes()
    assert headers["content-type"] == "text/html; charset=utf-8"
    assert headers["x-frame-options"] == "DENY"
    status, headers, body = await fetch("/robot/r1", "HEAD")
    assert status == 200 and body == b""
    assert int(headers["content-length"]) == len((WEB_ROOT / "robot.html").read_bytes())
    assert (await fetch("/js/ws.js"))[1]["content-type"] == "text/javascript; charset=utf-8"
    for path in TRAVERSALS:
        if " " not in path and not path.startswith("staff"):
            assert (await fetch(path))[0] == 404, path
    assert (await fetch("/nope"))[0] == 404
    status, _, body = await fetch("/healthz")
    assert status == 200 and b'"status": "ok"' in body
    # And the websocket still answers on /ws, on the same port.
    c = await one_robot.client()
    await c.subscribe("robots")


def served_table(body: bytes) -> dict[str, set[str]]:
    """The allowed-actions table as /js/status-table.js writes it: status -> its actions."""
    rows = re.findall(r'^  "(\w+)": (\[.*\]),$', body.decode(), re.M)
    return {status: set(json.loads(actions)) for status, actions in rows}


def test_the_ui_takes_the_allowed_actions_table_from_the_server() -> None:
    """The pages' table is the server's (serveur.status.ALLOWED), row by row: served, not copied."""
    from serveur.status import ALLOWED, Action, RobotStatus
    from serveur.web.static import STATUS_TABLE, default_site, status_table_js

    status, headers, body = get(default_site(), STATUS_TABLE)
    assert status == 200 and headers["Content-Type"] == "text/javascript; charset=utf-8"
    assert served_table(body) == {s.value: {a.value for a in ALLOWED[s]} for s in RobotStatus}
    assert not (WEB_ROOT / STATUS_TABLE.lstrip("/")).exists()  # made by the server, no file
    # status.js reads it and holds no copy: no action of the table is named there.
    js = (WEB_ROOT / "js" / "status.js").read_text()
    assert 'import { ALLOWED } from "./status-table.js";' in js
    assert [a.value for a in Action if f'"{a.value}"' in js] == []
    # A change to the table in status.py is what the pages get.
    changed = {**ALLOWED, RobotStatus.OFFLINE: frozenset({Action.STOP})}
    assert served_table(status_table_js(changed))["Offline"] == {"stop"}
    assert status_table_js(changed) != body


def test_text_files_are_gzipped_for_a_client_that_accepts_it(site: StaticSite) -> None:
    import gzip

    for path in ("/", "/js/ws.js", "/css/staff.css", "/i18n/en.json"):
        status, plain_h, plain = get(site, path)
        status_gz, headers, body = get(site, path, **{"Accept-Encoding": "gzip, deflate, br"})
        assert status == status_gz == 200
        assert "Content-Encoding" not in plain_h
        assert headers["Content-Encoding"] == "gzip" and headers["Vary"] == "Accept-Encoding"
        assert gzip.decompress(body) == plain and len(body) < len(plain) / 2
        assert headers["Content-Length"] == str(len(body))
        # Two representations, two tags; each revalidates to a 304.
        assert headers["ETag"] != plain_h["ETag"]
        ims = {"If-None-Match": headers["ETag"], "Accept-Encoding": "gzip"}
        assert get(site, path, **ims)[0] == 304
    # Refused (q=0) or not offered: the plain body.
    for enc in ("gzip;q=0", "identity", "br"):
        assert "Content-Encoding" not in get(site, "/", **{"Accept-Encoding": enc})[1]
    # HEAD: the gzipped length, no body.
    status, headers, body = get(site, "/js/ws.js", "HEAD", **{"Accept-Encoding": "gzip"})
    assert (status, body) == (200, b"") and headers["Content-Encoding"] == "gzip"


def test_last_modified_revalidation_and_no_stale_page_after_an_upgrade(
    tmp_path: Path,
) -> None:
    import email.utils
    import time

    (tmp_path / "staff.html").write_text("<p>v1</p>")
    (tmp_path / "i18n").mkdir()
    (tmp_path / "i18n" / "en.json").write_text('{"a": "one"}')
    old = StaticSite.load(tmp_path)
    for path in ("/", "/i18n/en.json"):
        _, headers, _ = get(old, path)
        assert headers["Cache-Control"] == "no-cache"  # always asked again, never stale
        since = headers["Last-Modified"]
        assert email.utils.parsedate_to_datetime(since).timestamp() <= time.time()
        assert get(old, path, **{"If-Modified-Since": since})[0] == 304
        assert get(old, path, **{"If-Modified-Since": "Thu, 01 Jan 1970 00:00:00 GMT"})[0] == 200
        assert get(old, path, **{"If-Modified-Since": "garbage"})[0] == 200
    # The upgrade: new files, same names. The browser's tag no longer matches: 200, new body
    # (If-None-Match decides even when If-Modified-Since alone would say "not modified").
    _, headers, _ = get(old, "/i18n/en.json")
    (tmp_path / "staff.html").write_text("<p>v2</p>")
    (tmp_path / "i18n" / "en.json").write_text('{"a": "uno"}')
    new = StaticSite.load(tmp_path)
    cond = {"If-None-Match": headers["ETag"], "If-Modified-Since": "Fri, 01 Jan 2100 00:00:00 GMT"}
    status, _, body = get(new, "/i18n/en.json", **cond)
    assert status == 200 and body == b'{"a": "uno"}'
    assert get(new, "/")[2] == b"<p>v2</p>"


async def test_the_real_server_sends_gzip(one_robot: Restaurant) -> None:
    import gzip

    server = one_robot.app.server
    assert server is not None
    req = b"GET /js/ws.js HTTP/1.1\r\nHost: localhost\r\nAccept-Encoding: gzip\r\n\r\n"
    status, headers, body = await raw_http(server.port, req)
    assert status == 200 and headers["content-encoding"] == "gzip"
    assert gzip.decompress(body) == (WEB_ROOT / "js" / "ws.js").read_bytes()
