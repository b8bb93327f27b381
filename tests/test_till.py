"""Orders from the till (issue 33), over real sockets: the printer port, the kitchen printer it
forwards to (a fake printer on loopback that records every byte), the owner's pattern set-up
over ``/ws``, and the order-intake API over HTTP.

The till's jobs are made with python-escpos (what POS software sends: ESC/POS text, code page
commands, cuts); tests/till/ reads many more layouts without sockets.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import socket
import urllib.error
import urllib.request
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest
from escpos.printer import Dummy
from websockets.asyncio.client import connect

from serveur.app import App
from serveur.till.tap import PrinterTap
from tests.conftest import WAIT, Client, budget, intake_app, poll_until
from tests.till.jobs import GARBLED as GARBLED_JOB
from tests.till.jobs import LAYOUTS

pytestmark = pytest.mark.timeout(120)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def ticket(*lines: str, table: str = "12", number: str = "1042", cut: bool = True) -> bytes:
    """A Square-like kitchen ticket, as python-escpos writes it."""
    p = Dummy()
    p.set(align="center", bold=True, double_height=True)
    p.text("KITCHEN\n")
    p.set(align="left", bold=False, double_height=False, normal_textsize=True)
    p.text(f"Order #{number}\n")
    p.text(f"Table: {table}   Guests: 3\n")
    p.text("-" * 32 + "\n")
    for line in lines:
        p.text(line + "\n")
    if cut:
        p.cut()
    return bytes(p.output)


FIRST = ticket("2 x Nasi Lemak", "   - no chilli", "1 x Teh Tarik")
SECOND = ticket("1 x Laksa", table="7", number="1043")
THIRD = ticket("3 x Satay", "1 x Crème brûlée", table="3", number="1044")
GARBLED = bytes((i * 37 + 11) % 256 for i in range(300)) + b"\x1d(k"


@dataclass
class FakePrinter:
    """A kitchen printer on loopback: what it received, one entry per connection."""

    server: asyncio.Server | None = None
    port: int = 0
    jobs: list[bytes] = field(default_factory=list)
    got: asyncio.Event = field(default_factory=asyncio.Event)

    async def start(self, port: int = 0) -> FakePrinter:
        async def serve(reader: asyncio.StreamReader, writer: asyncio.StreamWriter) -> None:
            data = await reader.read()
            if data:
                self.jobs.append(data)
                self.got.set()
            writer.close()

        self.server = await asyncio.start_server(serve, "127.0.0.1", port)
        self.port = int(self.server.sockets[0].getsockname()[1])
        return self

    async def stop(self) -> None:
        assert self.server is not None
        self.server.close()
        await self.server.wait_closed()

    async def wait_jobs(self, n: int) -> None:
        async def wait() -> None:
            while len(self.jobs) < n:
                self.got.clear()
                await self.got.wait()

        await asyncio.wait_for(wait(), budget(WAIT))


async def print_job(port: int, data: bytes) -> bytes:
    """Send one job as a POS does (connect, write, close its side) and read any answer."""
    reader, writer = await asyncio.open_connection("127.0.0.1", port)
    writer.write(data)
    await writer.drain()
    writer.write_eof()
    answer = await asyncio.wait_for(reader.read(), budget(WAIT))
    writer.close()
    return answer


@dataclass
class Site:
    app: App
    owner: Client
    staff: Client
    port: int
    clients: list[Client] = field(default_factory=list)

    def tickets(self) -> dict[Any, dict[str, Any]]:
        return self.staff.records.get("tickets", {})

    def alerts(self, kind: str) -> list[dict[str, Any]]:
        return [
            a
            for a in self.staff.records.get("alerts", {}).values()
            if a["kind"] == kind and a.get("cleared_at") is None
        ]

    @property
    def api(self) -> str:
        assert self.app.intake is not None
        return f"http://127.0.0.1:{self.app.intake.port}/api/orders"


@contextlib.asynccontextmanager
async def till_site(tmp_path: Path) -> AsyncIterator[Site]:
    async with intake_app(tmp_path) as app:
        owner = Client(await connect(app.url, max_size=2**24))
        await owner.ok("login", username="owner", password=app.first_owner_password)
        token = await app.issue_token("staff", label="kitchen")
        headers = {"Authorization": f"Bearer {token}"}
        staff = Client(await connect(app.url, additional_headers=headers))
        await staff.subscribe("tickets", "orders", "alerts", "till")
        site = Site(app, owner, staff, free_port(), [owner, staff])
        try:
            yield site
        finally:
            for c in site.clients:
                await c.close()


async def marks_pattern(site: Site, ticket_id: int) -> dict[str, Any]:
    """The owner marks the first ticket: line 2 holds table T12, line 4 is a dish."""
    lines = site.tickets()[ticket_id]["lines"]
    assert lines[2].startswith("Table: 12") and lines[4] == "2 x Nasi Lemak", lines
    marks = [
        {"line": 2, "as": "table", "table": "T12"},
        {"line": 4, "as": "dish"},
        {"line": 1, "as": "ticket"},
    ]
    return await site.owner.ok("till", action="propose", ticket=ticket_id, marks=marks)


async def test_forwarded_tickets_become_orders_once_and_the_kitchen_paper_is_unchanged(
    tmp_path: Path,
) -> None:
    printer = await FakePrinter().start()
    async with till_site(tmp_path) as site:
        await site.owner.ok(
            "till", action="setup", port=site.port, printer=f"127.0.0.1:{printer.port}"
        )
        await site.staff.until(lambda: (site.staff.streams.get("till") or {}).get("listening"))
        for job in (FIRST, SECOND, THIRD, GARBLED):
            await print_job(site.port, job)
        await printer.wait_jobs(4)
        # The kitchen's paper: every byte, in order, one job per connection.
        assert printer.jobs == [FIRST, SECOND, THIRD, GARBLED]
        # Kept before any pattern: unread, in words, nothing ordered.
        await site.staff.until(lambda: len(site.tickets()) == 4, what="four tickets kept")
        first_id = min(site.tickets())
        assert {t["status"] for t in site.tickets().values()} == {"unread"}
        assert "no ticket pattern" in site.tickets()[first_id]["problem"]
        assert not site.staff.records.get("orders")

        proposal = await marks_pattern(site, first_id)
        reading = {p["ticket"]: p["reading"] for p in proposal["preview"]}
        assert reading[first_id]["table"] == "T12" and reading[first_id]["ticket"] == "1042"
        assert [(d["quantity"], d["name"], d["notes"]) for d in reading[first_id]["dishes"]] == [
            (2, "Nasi Lemak", ["no chilli"]),
            (1, "Teh Tarik", []),
        ]
        assert [d["name"] for d in reading[first_id + 2]["dishes"]] == ["Satay", "Crème brûlée"]
        assert reading[first_id + 3]["problem"] is not None  # the garbled one

        saved = await site.owner.ok("till", action="setup", pattern=proposal["pattern"])
        assert sorted(saved["read"]) == [first_id, first_id + 1, first_id + 2]
        orders = await site.staff.until(
            lambda: len(site.staff.records.get("orders", {})) == 5 and site.staff.records["orders"]
        )
        got = sorted(
            (o["table"], o["dish"], o["quantity"], o["note"], o["status"]) for o in orders.values()
        )
        # The till's "Nasi Lemak" is the menu's "Nasi lemak" (case aside): the menu's name.
        assert got == [
            ("T12", "Nasi lemak", 2, "no chilli", "ordered"),
            ("T12", "Teh tarik", 1, None, "ordered"),
            ("T3", "Crème brûlée", 1, None, "ordered"),
            ("T3", "Satay", 3, None, "ordered"),
            ("T7", "Laksa", 1, None, "ordered"),
        ]
        assert {o["ticket"] for o in orders.values()} == {first_id, first_id + 1, first_id + 2}

        # A reprint: kept, printed, no new order.
        reprint = ticket("2 x Nasi Lemak", "   - no chilli", "1 x Teh Tarik")
        await print_job(site.port, b"\x1b@REPRINT\n" + reprint)
        await printer.wait_jobs(5)
        await site.staff.until(
            lambda: any(t["status"] == "reprint" for t in site.tickets().values())
        )
        [again] = [t for t in site.tickets().values() if t["status"] == "reprint"]
        assert again["of_ticket"] == first_id
        assert len(await site.app.store.orders.list_orders()) == 5

        # The garbled job: shown to staff as printed, an alert until done by hand.
        garbled = first_id + 3
        assert site.tickets()[garbled]["status"] == "unread"
        await site.staff.until(lambda: site.alerts("ticket_unread"), what="the unread alert")
        await site.staff.ok("till", action="by_hand", ticket=garbled)
        await site.staff.until(lambda: not site.alerts("ticket_unread"), what="alert cleared")
        await site.staff.error("till", "conflict", action="by_hand", ticket=garbled)
        assert (await site.app.store.tickets.job_bytes(garbled)) == GARBLED
    await printer.stop()


async def test_a_void_ticket_withdraws_what_the_kitchen_has_not_sent(tmp_path: Path) -> None:
    async with till_site(tmp_path) as site:
        await site.owner.ok("till", action="setup", port=site.port)  # mirror: no printer
        await print_job(site.port, FIRST)
        await site.staff.until(lambda: site.tickets())
        proposal = await marks_pattern(site, min(site.tickets()))
        void_job = ticket("*** VOID ***", "1 x Nasi Lemak", "1 x Teh Tarik")
        await print_job(site.port, void_job)
        await site.staff.until(lambda: len(site.tickets()) == 2)
        void_id = max(site.tickets())
        lines = site.tickets()[void_id]["lines"]
        marks = [
            {"line": 2, "as": "table", "table": "T12"},
            {"line": 5, "as": "dish"},
            {"line": 1, "as": "ticket"},
            {"line": lines.index("*** VOID ***"), "as": "void"},
        ]
        proposal = await site.owner.ok("till", action="propose", ticket=void_id, marks=marks)
        await site.owner.ok("till", action="setup", pattern=proposal["pattern"])
        orders = await site.staff.until(
            lambda: (
                {o["dish"]: o for o in site.staff.records.get("orders", {}).values()}.get(
                    "Teh tarik", {}
                ).get("status")
                == "voided"
                and site.staff.records["orders"]
            )
        )
        by_dish = {o["dish"]: o for o in orders.values()}
        assert (
            by_dish["Nasi lemak"]["quantity"] == 1 and by_dish["Nasi lemak"]["status"] == "ordered"
        )
        assert site.tickets()[void_id]["status"] == "void"


async def test_a_printer_that_is_down_is_reported_and_the_till_sees_the_failure(
    tmp_path: Path,
) -> None:
    dead = free_port()  # nothing listens there
    async with till_site(tmp_path) as site:
        await site.owner.ok("till", action="setup", port=site.port, printer=f"127.0.0.1:{dead}")
        with pytest.raises((ConnectionError, OSError)):
            answer = await print_job(site.port, FIRST)
            assert answer == b"", answer  # an orderly close would be a lie: it must reset
            raise ConnectionResetError("closed")
        await site.staff.until(lambda: site.alerts("printer_down"), what="the printer alert")
        assert site.staff.streams["till"]["printer_up"] is False
        assert not site.tickets()  # the till prints it again: nothing half-kept
        printer = await FakePrinter().start(dead)
        await print_job(site.port, FIRST)
        await printer.wait_jobs(1)
        await site.staff.until(lambda: not site.alerts("printer_down"), what="alert cleared")
        await printer.stop()


async def test_mirror_mode_answers_a_status_request_as_an_online_printer(tmp_path: Path) -> None:
    async with till_site(tmp_path) as site:
        await site.owner.ok("till", action="setup", port=site.port)
        answer = await print_job(site.port, b"\x10\x04\x01" + SECOND)
        assert answer == b"\x12"
        await site.staff.until(lambda: site.tickets())


def post(
    url: str, body: Any, token: str | None, ctype: str = "application/json"
) -> tuple[int, Any]:
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    headers = {"Content-Type": ctype}
    if token:
        headers["Authorization"] = f"Bearer {token}"
    req = urllib.request.Request(url, data=data, headers=headers, method="POST")
    try:
        with urllib.request.urlopen(req, timeout=10) as resp:
            return resp.status, json.loads(resp.read())
    except urllib.error.HTTPError as exc:
        return exc.code, json.loads(exc.read())


async def test_the_order_intake_api_is_idempotent_under_retries(tmp_path: Path) -> None:
    async with till_site(tmp_path) as site:
        token = await site.app.issue_token("integration", label="pos bridge", scopes=["orders"])
        body = {
            "key": "pos-1042-1",
            "table": "T12",
            "ticket": "1042",
            "dishes": [{"dish": "Laksa", "quantity": 2, "note": "no chilli"}, {"dish": "Satay"}],
        }
        status, first = await asyncio.to_thread(post, site.api, body, token)
        assert status == 201, first
        assert [(o["dish"], o["quantity"], o["status"]) for o in first["orders"]] == [
            ("Laksa", 2, "ordered"),
            ("Satay", 1, "ordered"),
        ]
        # Retries, some at once: the same answer, nothing new.
        again = await asyncio.gather(
            *(asyncio.to_thread(post, site.api, body, token) for _ in range(5))
        )
        assert {s for s, _ in again} == {200}
        assert all(r["orders"] == first["orders"] for _, r in again)
        assert len(await site.app.store.orders.list_orders()) == 2
        # The same key for another order: refused, nothing changes.
        other = {**body, "dishes": [{"dish": "Laksa"}]}
        status, err = await asyncio.to_thread(post, site.api, other, token)
        assert status == 409 and err["code"] == "conflict", err
        # Bad input, each with its status and a structured error; nothing stored.
        cases = [
            (b"{not json", token, "application/json", 400, "bad_json"),
            ({**body, "key": "k2", "dishes": []}, token, "application/json", 400, "invalid_field"),
            ({**body, "key": "k3", "table": "T99"}, token, "application/json", 404, "not_found"),
            (body, None, "application/json", 401, "unauthorized"),
            (body, "srv_nonsense", "application/json", 401, "unauthorized"),
            (body, token, "text/plain", 415, "invalid_field"),
        ]
        for payload, tok, ctype, want, code in cases:
            status, err = await asyncio.to_thread(post, site.api, payload, tok, ctype)
            assert (status, err["code"]) == (want, code), (payload, err)
        reader_only = await site.app.issue_token("integration", label="reader", scopes=["read"])
        status, err = await asyncio.to_thread(post, site.api, body, reader_only)
        assert (status, err["code"]) == (403, "forbidden")
        status, err = await asyncio.to_thread(post, site.api, b"x" * 70_000, token)
        assert status == 413
        assert len(await site.app.store.orders.list_orders()) == 2
        # The kitchen screen shows the API's ticket like a printed one.
        await site.staff.until(lambda: site.tickets())
        [t] = site.tickets().values()
        assert t["lines"] == ["Ticket 1042", "Table T12", "2 x Laksa", "  - no chilli", "1 x Satay"]
        assert t["source"] == "api pos bridge"


async def test_the_tills_names_map_to_the_menu_with_suggestions(tmp_path: Path) -> None:
    async with till_site(tmp_path) as site:
        for dish in ("Nasi lemak ayam", "Teh tarik", "Laksa"):
            await site.owner.ok("create", type="dish", name=dish)
        csv = "till,dish\nNASI LEMAK AYAM,\nAyam nasi lemak,\nTEH TARIK,Teh tarik\nKopi O,\n"
        reply = await site.owner.ok("till", action="import_menu", csv=csv)
        rows = {r["till"]: r for r in reply["rows"]}
        assert rows["NASI LEMAK AYAM"]["status"] == "mapped"
        assert rows["NASI LEMAK AYAM"]["dish"] == "Nasi lemak ayam"
        assert rows["Ayam nasi lemak"]["status"] == "suggested"
        assert rows["Ayam nasi lemak"]["suggestions"][0] == "Nasi lemak ayam"
        assert rows["Kopi O"]["status"] == "unknown"
        assert reply["names"]["TEH TARIK"] == "Teh tarik"
        await site.owner.ok("till", action="map", names={"Ayam nasi lemak": "Nasi lemak ayam"})
        await site.owner.error("till", "not_found", action="map", names={"Kopi O": "Kopi"})
        await site.owner.error("till", "invalid_field", action="import_menu", csv="a,b\n1,2\n")
        # A ticket printing the till's names orders the menu's dishes.
        await site.owner.ok("till", action="setup", port=site.port)
        await print_job(site.port, ticket("1 x Ayam nasi lemak", "2 x TEH TARIK", "1 x Kopi O"))
        await site.staff.until(lambda: site.tickets())
        await marks_pattern_on(site, "1 x Ayam nasi lemak")
        orders = await site.staff.until(
            lambda: len(site.staff.records.get("orders", {})) == 3 and site.staff.records["orders"]
        )
        assert sorted(o["dish"] for o in orders.values()) == [
            "Kopi O",
            "Nasi lemak ayam",
            "Teh tarik",
        ]
        unmapped = await site.owner.ok("till", action="unmapped")
        assert [u["till"] for u in unmapped["unmapped"]] == ["Kopi O"]
        # Staff may read tickets, never set the till up.
        await site.staff.error("till", "forbidden", action="setup", port=0)


async def marks_pattern_on(site: Site, dish_line: str) -> None:
    [t] = site.tickets().values()
    lines = t["lines"]
    marks = [
        {"line": 2, "as": "table", "table": "T12"},
        {"line": lines.index(dish_line), "as": "dish"},
    ]
    proposal = await site.owner.ok("till", action="propose", ticket=t["id"], marks=marks)
    await site.owner.ok("till", action="setup", pattern=proposal["pattern"])


#: The printer's code page a site with each layout's till sets (the Chinese printer's own
#: setting is GB18030: one of its jobs relies on it).
LAYOUT_ENCODING = {"square": "auto", "tm_chinese": "gb18030", "lightspeed": "auto"}


@pytest.mark.parametrize("name", sorted(LAYOUTS))
async def test_every_job_of_a_layout_through_the_port_orders_exactly_once(
    tmp_path: Path, name: str
) -> None:
    """tests/till/jobs.py's recorded-style jobs of one POS layout (code pages, notes, a void,
    a reprint, a second round, two tickets in a job) and the garbled job, printed to the port
    in forward mode: the kitchen printer gets every byte as sent, the owner marks the sample
    ticket, and the orders are exactly the dishes printed, once, less those voided; the
    garbled job is kept and shown unread."""
    layout = LAYOUTS[name]
    printer = await FakePrinter().start()
    async with till_site(tmp_path) as site:
        await site.owner.ok(
            "till",
            action="setup",
            port=site.port,
            printer=f"127.0.0.1:{printer.port}",
            encoding=LAYOUT_ENCODING[name],
        )
        jobs = [*layout.jobs, GARBLED_JOB]
        for job in jobs:
            await print_job(site.port, job.data)
        await printer.wait_jobs(len(jobs))
        assert printer.jobs == [job.data for job in jobs]
        printed = sum(len(job.tickets) for job in layout.jobs) + 1
        await site.staff.until(lambda: len(site.tickets()) == printed, what="every ticket kept")
        kept = [site.tickets()[i] for i in sorted(site.tickets())]
        assert [t["lines"] for t in kept[:-1]] == [
            list(t.lines) for job in layout.jobs for t in job.tickets
        ]
        [sample] = [t for t in kept if t["lines"] == list(layout.sample.ticket.lines)]
        marks = [
            {"line": m.line, "as": m.as_.value, **({"table": m.table} if m.table else {})}
            for m in layout.marks
        ]
        proposal = await site.owner.ok("till", action="propose", ticket=sample["id"], marks=marks)
        await site.owner.ok("till", action="setup", pattern=proposal["pattern"])

        menu = {m.dish.casefold(): m.dish for m in await site.app.store.service.list_menu()}
        want: dict[tuple[str, str], int] = {}
        seen: set[tuple[Any, ...]] = set()
        for t in layout.tickets:
            same = (
                t.number,
                t.table,
                t.void,
                tuple((d.quantity, d.name, d.notes) for d in t.dishes),
            )
            if same in seen:
                continue  # a reprint
            seen.add(same)
            for d in t.dishes:
                assert t.table is not None
                key = (t.table, menu.get(d.name.casefold(), d.name))
                want[key] = want.get(key, 0) + (-d.quantity if t.void else d.quantity)
        want = {k: q for k, q in want.items() if q}

        def live() -> dict[tuple[str, str], int]:
            got: dict[tuple[str, str], int] = {}
            for o in site.staff.records.get("orders", {}).values():
                if o["status"] != "voided":
                    got[(o["table"], o["dish"])] = (
                        got.get((o["table"], o["dish"]), 0) + o["quantity"]
                    )
            return got

        await site.staff.until(lambda: live() == want, what=f"the orders {want}")
        stored = await site.app.store.orders.list_orders()
        assert sum(o.quantity for o in stored if o.status.value != "voided") == sum(want.values())
        statuses = [site.tickets()[t["id"]]["status"] for t in kept]
        assert statuses[-1] == "unread"  # the garbled job, kept and shown
        assert (await site.app.store.tickets.job_bytes(kept[-1]["id"])) == GARBLED_JOB.data
        assert statuses.count("reprint") == len(layout.tickets) - len(seen)
    await printer.stop()


async def test_a_till_that_keeps_its_connection_open_and_one_that_goes_silent() -> None:
    """Some tills keep one connection open and print ticket after ticket: a pause ends a job.
    A till that goes off the Wi-Fi without closing is let go after a silence, so it holds no
    connection slot for ever."""
    got: list[bytes] = []
    handed = asyncio.Event()

    async def sink(source: str, data: bytes) -> None:
        got.append(data)
        handed.set()

    tap = PrinterTap(sink, host="127.0.0.1", idle_end=0.2, idle_close=1.0)
    port = free_port()
    await tap.configure(port, "")
    try:
        assert tap.status().listening and tap.bound_port == port
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        for job in (FIRST, SECOND):
            handed.clear()
            writer.write(job)
            await writer.drain()
            await asyncio.wait_for(handed.wait(), budget(WAIT))
        assert got == [FIRST, SECOND]
        # Then silence: the port closes the connection (EOF here), nothing more handed.
        assert await asyncio.wait_for(reader.read(), budget(WAIT)) == b""
        assert got == [FIRST, SECOND]
        writer.close()
        # A port taken by something else: said in words, not raised.
        with socket.socket() as taken:
            taken.bind(("127.0.0.1", 0))
            taken.listen()
            await tap.configure(taken.getsockname()[1], "")
            assert not tap.status().listening
            assert "cannot be opened" in (tap.status().error or "")
    finally:
        await tap.close()


async def test_a_full_printer_port_resets_the_till_rather_than_pretend_it_printed() -> None:
    """At most MAX_CONNECTIONS tills at once; one more is reset unread (an orderly close would
    tell its till the ticket printed, and the till would not print it again)."""
    from serveur.till.tap import MAX_CONNECTIONS

    async def sink(source: str, data: bytes) -> None:
        pass

    tap = PrinterTap(sink, host="127.0.0.1", idle_end=30.0, idle_close=60.0)
    port = free_port()
    await tap.configure(port, "")
    held = []
    try:
        for _ in range(MAX_CONNECTIONS):
            held.append(await asyncio.open_connection("127.0.0.1", port))
        await poll_until(lambda: tap._slots.locked(), WAIT, "every slot taken")
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        writer.write(FIRST)
        with pytest.raises(ConnectionResetError):
            await asyncio.wait_for(reader.read(), budget(WAIT))
            await writer.drain()
    finally:
        for _, w in held:
            w.close()
        await tap.close()
