"""The till on the Pi budget: what a restaurant's kitchen tickets cost the server (issue 33).

Two parts.

1. **Pure cost** (no sockets, this process): :func:`serveur.till.escpos.decode_job` and
   :meth:`serveur.till.pattern.TicketPattern.read` per ticket, for four tickets as points of
   sale print them with python-escpos: a 10-line ticket, a 40-line one, the 10-line one after a
   576x200 raster logo (``GS v 0``) and a QR code (``GS ( k``), and a Chinese ticket in GB18030
   (the printer's double-byte mode, ``FS &`` ... ``FS .``). Each ticket's pattern is
   :func:`serveur.till.pattern.propose` on its own lines, as the owner's marks make it. The
   median over ``--reps`` repetitions, in µs per ticket and per kB (1,000 bytes) of the job.

2. **End to end under a CPU quota**: a real ``serveur run`` child (SQLite, the demo map and its
   tables T1-T16, the order-intake API on ``--intake-port``) confined to 25 %, 50 % and 100 % of a
   core (``--quota``; a cgroup v1 ``cpu`` group, bench/bench_camera.py's ``limit``; without
   cgroups the server runs unconfined and the output says so), given the deployed unit's CPU
   weight (``Nice=-5``, as bench/bench_pi.py). The owner logs in over ``/ws``, opens the printer
   port in mirror mode (``till setup``), the till prints a first ticket and a void of one of its
   dishes, the owner marks the void ticket's lines (``till propose``) and saves the pattern
   (``till setup``), as tests/test_till.py does. Then:

   * **quiet** (5 s): nothing but the probe below;
   * **lunch rush** (``--duration`` s, ``--rate`` tickets a minute, Poisson, ``--seed``): the till
     prints each job on a TCP connection of its own, as a POS does (connect, send, close its
     side, read until the server closes). Each job is a new ticket (1-6 dishes, 1-3 of each,
     some with notes, a few accented names), or, drawn with the seed, a **reprint** (8 %: the
     same ticket under a ``** REPRINT **`` line, of a ticket whose orders the console has seen),
     a **void** (4 %: one dish of such a ticket withdrawn) or **garbled** (3 %: line noise, no
     command, cut: nobody can read it);
   * **intake** (``--intake`` POSTs to ``/api/orders``, ~10 a second): 75 % once, 20 % retried
     with the same key after the answer (a lost answer), 5 % sent twice at once.

   Measured: **ticket -> order latency** (from the job's last byte sent to the ``orders`` update
   naming its ticket reaching a staff console subscribed to ``orders`` and ``tickets``),
   **ticket -> tickets update** (any job: the console learns how it read), the server's
   **request latency** (a ``ping`` every 100 ms from another tablet, quiet and during the rush),
   the intake API's latency per POST, the server's CPU and the quota's throttling over the rush;
   for the slowest pings and tickets, what the server's loop thread did meanwhile (CPU, waiting
   for a CPU, throttled: bench_pi's ``Sampler``) and how late this process's own loop was, so
   that a tail is put down to the server, the quota, the host or the bench.

   Checked, from the server's database at the end (SQLite, read-only): every job sent is one
   ticket, each new ticket ``ordered`` with one order per dish line, each reprint ``reprint`` of
   its original with no order, each void ``void``, each garbled job ``unread`` with no order; the
   dishes per table (quantities of the orders not voided, names case-folded) equal what was
   sent; each intake key made one ticket and its orders once, its first answer 201 and every
   other 200 naming the same ticket. Any mismatch is printed and the exit status is 1.

Each quota gets a fresh server and database. Loopback only; every wait is bounded; the server
runs in a process group of its own, stopped (SIGINT, then SIGKILL to the group) when the bench
ends, however it ends.

Run: ``flock /tmp/bench.lock python3 bench/bench_till.py`` (about 4 minutes with the defaults;
``--duration 30`` for a quick look; ``--json FILE`` writes everything).
"""

from __future__ import annotations

import argparse
import asyncio
import atexit
import collections
import contextlib
import io
import json
import os
import random
import signal
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from escpos.printer import Dummy
from PIL import Image, ImageDraw
from websockets.asyncio.client import connect

sys.path.insert(0, str(Path(__file__).resolve().parent))
from bench_camera import CGROUP, limit, unlimit  # the cgroup v1 quota helpers
from bench_pi import NICE_MINUS_5, Conn, Sampler, _cli, _cpu_stat, _weigh, open_conn
from bench_server import _free_port, _proc_stats, pct

from serveur.maps.navigation import demo_map_path
from serveur.till.escpos import decode_job
from serveur.till.names import fold
from serveur.till.pattern import Mark, MarkAs, TicketPattern, propose

WAIT = 30.0  # seconds any one request, job or settling may take before the bench gives up
RULE = "-" * 42
FW = "\N{FULLWIDTH COLON}"  # as Chinese tickets print it (桌号, then the table)
TABLES = [f"T{i}" for i in range(1, 17)]  # the demo map's tables
DISHES = [
    "Nasi Lemak",
    "Teh Tarik",
    "Laksa",
    "Satay",
    "Char Kway Teow",
    "Roti Canai",
    "Mee Goreng",
    "Kopi O",
    "Cendol",
    "Beef Rendang",
    "Hainanese Chicken Rice",
    "Fish & Chips",
    "Crème brûlée",
    "Cheeseburger",
    "Jalapeño Poppers",
    "Ice Lemon Tea",
]
NOTES = ["no chilli", "extra egg", "less sweet", "no ice", "well done", "takeaway"]
REPRINT, VOID, GARBLED = 0.08, 0.04, 0.03  # shares of the rush's jobs
OWNER_PASSWORD = "bench-till-owner-password"

Dish = tuple[int, str, tuple[str, ...]]  # quantity, the till's name, notes


# -- tickets as a point of sale prints them -----------------------------------------------------


def square_ticket(
    number: int,
    table: str,
    dishes: list[Dish],
    *,
    banner: str | None = None,
    logo: bool = False,
) -> bytes:
    """A Square-like kitchen ticket (python-escpos, as tests/test_till.py's): the big KITCHEN,
    an optional banner (``** REPRINT **``, ``*** VOID ***``), ``Order #``, ``Table: 12``, the
    dishes ``2 x Laksa`` with notes ``   - no chilli``, a cut. ``logo``: a 576x200 raster logo
    (``GS v 0``) and a QR code (``GS ( k``) first, as some POS print their brand."""
    p = Dummy()
    if logo:
        img = Image.new("1", (576, 200), 1)
        draw = ImageDraw.Draw(img)
        draw.rectangle((8, 8, 567, 191), outline=0, width=6)
        draw.ellipse((40, 30, 180, 170), fill=0)
        draw.text((220, 90), "RESTORAN SERVEUR", fill=0)
        with contextlib.redirect_stdout(io.StringIO()), contextlib.redirect_stderr(io.StringIO()):
            p.image(img, impl="bitImageRaster")  # GS v 0, 72 bytes x 200 dots
        p.qr(f"https://pos.example/check/{number}", native=True, size=6)  # GS ( k
    p.set(align="center", bold=True, double_height=True)
    p.text("KITCHEN\n")
    if banner:
        p.text(banner + "\n")
    p.set(align="left", bold=False, double_height=False, normal_textsize=True)
    p.text(f"Order #{number}\n")
    p.text(f"Table: {table.removeprefix('T')}   Guests: {2 + number % 4}\n")
    p.text("Server: Aisha\n")
    p.text(RULE + "\n")
    for qty, name, notes in dishes:
        p.text(f"{qty} x {name}\n")
        for note in notes:
            p.text(f"   - {note}\n")
    p.text(RULE + "\n")
    p.cut()
    return bytes(p.output)


def chinese_ticket() -> bytes:
    """A Chinese POS's ticket: GB18030 inside the printer's double-byte mode (FS & ... FS .)."""
    p = Dummy()

    def line(text: str) -> None:
        if text.isascii():
            p.text(text + "\n")
        else:
            p._raw(b"\x1c&" + text.encode("gb18030") + b"\x1c.\n")

    p.hw("INIT")
    p.set_with_default(align="center", double_height=True, double_width=True)
    line("厨房单")
    p.set_with_default(align="left", custom_size=True, width=2, height=2)
    line(f"桌号{FW}5")
    p.set_with_default()
    for text in (f"单号{FW}0087", f"人数{FW}4", f"时间{FW}12:41", "-" * 32):
        line(text)
    for text in ("2 叉烧包", "  > 少辣", "1 海南鸡饭", "  > 不要葱", "3 Teh Tarik", "1 炒粿条"):
        line(text)
    line("-" * 32)
    p.cut(mode="PART", feed=False)
    return bytes(p.output)


def garbled_job(rng: random.Random) -> bytes:
    """Line noise: bytes no command starts (no ESC, GS, FS, DLE), broken into lines, then a cut
    (the job's end came through): one ticket nobody can read."""
    out = bytearray()
    for _ in range(rng.randint(6, 14)):
        out += bytes(rng.choice(range(0x20, 0x100)) for _ in range(rng.randint(8, 40)))
        out += b"\n"
    return bytes(out) + b"\x1dV\x00"


def lines_of(job: bytes) -> tuple[str, ...]:
    """The one ticket a job prints, line by line (as the server's decoder reads it)."""
    (ticket,) = decode_job(job, "auto")
    return ticket.lines


def _index(lines: tuple[str, ...], start: str) -> int:
    return next(i for i, s in enumerate(lines) if s.startswith(start))


def square_pattern(lines: tuple[str, ...], table: str, *, void: bool = False) -> TicketPattern:
    """The owner's marks on a Square-like ticket: the table line, the first dish, the number."""
    marks = [
        Mark(next(i for i, s in enumerate(lines) if s.startswith("Table:")), MarkAs.TABLE, table),
        Mark(next(i for i, s in enumerate(lines) if " x " in s), MarkAs.DISH),
        Mark(next(i for i, s in enumerate(lines) if s.startswith("Order #")), MarkAs.TICKET),
    ]
    if void:
        marks.append(Mark(lines.index("*** VOID ***"), MarkAs.VOID))
    return propose(lines, marks)


# -- 1. pure cost -------------------------------------------------------------------------------


def pure_cost(reps: int) -> list[dict[str, Any]]:
    """Median µs of decode_job, read, and both, per ticket and per kB, for four tickets."""
    ten: list[Dish] = [
        (2, "Nasi Lemak", ("no chilli",)),
        (1, "Teh Tarik", ()),
        (1, "Crème brûlée", ()),
    ]
    forty: list[Dish] = [(1 + i % 3, DISHES[i % len(DISHES)], (NOTES[i % 6],)) for i in range(17)]
    cases: list[tuple[str, bytes, Callable[[tuple[str, ...]], TicketPattern], int]] = [
        ("10 lines", square_ticket(1042, "T12", ten), lambda ls: square_pattern(ls, "T12"), 3),
        ("40 lines", square_ticket(1043, "T12", forty), lambda ls: square_pattern(ls, "T12"), 17),
        (
            "10 lines + 576x200 logo (GS v 0) + QR (GS ( k)",
            square_ticket(1044, "T12", ten, logo=True),
            lambda ls: square_pattern(ls, "T12"),
            3,
        ),
        (
            "GB18030, 13 lines (FS & ... FS .)",
            chinese_ticket(),
            lambda ls: propose(
                ls,
                [
                    Mark(ls.index(f"桌号{FW}5"), MarkAs.TABLE, "T5"),
                    Mark(ls.index("2 叉烧包"), MarkAs.DISH),
                    Mark(ls.index(f"单号{FW}0087"), MarkAs.TICKET),
                ],
            ),
            4,
        ),
    ]
    out = []
    for name, job, make_pattern, dishes in cases:
        lines = lines_of(job)
        pattern = make_pattern(lines)
        reading = pattern.read(lines)
        if not reading.understood or len(reading.dishes) != dishes:
            raise RuntimeError(f"{name}: reads {reading.as_dict()}")
        n = reps if len(job) < 4000 else max(50, reps // 10)
        dec, rd, both = [], [], []
        for _ in range(n):
            t0 = time.perf_counter_ns()
            (ticket,) = decode_job(job, "auto")
            t1 = time.perf_counter_ns()
            pattern.read(ticket.lines)
            t2 = time.perf_counter_ns()
            dec.append((t1 - t0) / 1e3)
            rd.append((t2 - t1) / 1e3)
            both.append((t2 - t0) / 1e3)
        total = statistics.median(both)
        out.append(
            {
                "ticket": name,
                "bytes": len(job),
                "lines": len(lines),
                "reps": n,
                "decode_us": round(statistics.median(dec), 1),
                "read_us": round(statistics.median(rd), 1),
                "total_us": round(total, 1),
                "us_per_kb": round(total / (len(job) / 1000), 1),
            }
        )
    return out


def pure_table(rows: list[dict[str, Any]]) -> str:
    head = (
        "| ticket | job bytes | lines | decode_job | read | both | per kB |\n"
        "|---|---:|---:|---:|---:|---:|---:|\n"
    )
    return head + "\n".join(
        f"| {r['ticket']} | {r['bytes']:,} | {r['lines']} | {r['decode_us']} µs"
        f" | {r['read_us']} µs | {r['total_us']} µs | {r['us_per_kb']} µs |"
        for r in rows
    )


# -- 2. end to end: the server, its group, its tablets ------------------------------------------

_GROUPS: set[int] = set()  # process groups started: killed at exit whatever happens
_CGROUPS: set[int] = set()  # servers put under a quota: their cgroups removed at exit


def _limit(pid: int, quota: float) -> str:
    _CGROUPS.add(pid)
    return limit(pid, quota)


def _unlimit(pid: int) -> None:
    """Remove the quota's group once its processes are gone (a killed child of the server
    may take a moment to leave it)."""
    group = CGROUP / f"serveur-bench-{os.getpid()}-{pid}"
    for _ in range(40):
        unlimit(pid)
        if not group.exists():
            break
        time.sleep(0.05)
    _CGROUPS.discard(pid)


def _cleanup() -> None:
    """Kill every process group started, then remove every quota group made."""
    for pgid in list(_GROUPS):
        with contextlib.suppress(ProcessLookupError, PermissionError):
            os.killpg(pgid, signal.SIGKILL)
        _GROUPS.discard(pgid)
    for pid in list(_CGROUPS):
        _unlimit(pid)


atexit.register(_cleanup)


async def _stop_group(proc: asyncio.subprocess.Process) -> None:
    """SIGINT (a clean shutdown) and 15 s for it; then SIGKILL to the whole group."""
    if proc.returncode is None:
        with contextlib.suppress(ProcessLookupError):
            proc.send_signal(signal.SIGINT)
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(proc.wait(), 15)
    with contextlib.suppress(ProcessLookupError, PermissionError):
        os.killpg(proc.pid, signal.SIGKILL)
    _GROUPS.discard(proc.pid)
    if proc.returncode is None:
        await asyncio.wait_for(proc.wait(), 5)


def _run_cli(*args: str, stdin: str | None = None) -> str:
    done = subprocess.run(
        _cli(*args), input=stdin, check=True, capture_output=True, text=True, timeout=60
    )
    return done.stdout


@dataclass
class Sent:
    """One job the till printed."""

    kind: str  # new, reprint, void, garbled
    lines: tuple[str, ...]
    number: int = 0
    table: str = ""
    dishes: list[Dish] = field(default_factory=list)
    of: Sent | None = None  # a reprint's or void's ticket
    last_byte: float = 0.0
    error: str | None = None
    ticket_id: int | None = None  # from the tickets topic
    ticket_seen: float | None = None
    status_seen: str | None = None
    orders_seen: float | None = None


class Console:
    """The staff console: ``orders`` and ``tickets``, each update's arrival time noted."""

    def __init__(self, conn: Conn) -> None:
        self.conn = conn
        # A ticket's lines -> the jobs sent with them not yet seen, oldest first (a ticket
        # reprinted twice prints the same lines twice).
        self.by_lines: dict[tuple[str, ...], list[Sent]] = collections.defaultdict(list)
        self.by_id: dict[int, Sent] = {}
        self.first_order: dict[int, float] = {}  # ticket id -> first orders update naming it
        self.changed = asyncio.Event()
        conn.on_update = self._update

    def _update(self, topic: str, data: dict[str, Any]) -> None:
        now = time.monotonic()
        if topic == "tickets":
            waiting = self.by_lines.get(tuple(data["lines"]))
            known = data["id"] in self.by_id
            sent = waiting.pop(0) if waiting and not known else None
            if sent is not None:
                sent.ticket_id = data["id"]
                sent.ticket_seen = now
                sent.status_seen = data["status"]
                self.by_id[data["id"]] = sent
        elif topic == "orders" and data.get("ticket") is not None:
            tid = int(data["ticket"])
            if tid not in self.first_order:
                self.first_order[tid] = now
                sent = self.by_id.get(tid)
                if sent is not None and sent.orders_seen is None:
                    sent.orders_seen = now
        self.changed.set()

    def expect(self, sent: Sent) -> None:
        self.by_lines[sent.lines].append(sent)


async def print_job(port: int, data: bytes, sent: Sent) -> None:
    """A POS prints: connect, send the job, close its side, read until the server closes."""
    try:
        reader, writer = await asyncio.wait_for(asyncio.open_connection("127.0.0.1", port), WAIT)
        try:
            writer.write(data)
            await writer.drain()
            writer.write_eof()
            sent.last_byte = time.monotonic()
            await asyncio.wait_for(reader.read(), WAIT)
        finally:
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()
    except (OSError, TimeoutError) as exc:
        sent.error = f"{type(exc).__name__}: {exc}"


class LoopLag:
    """This process's own event loop: how late a 10 ms sleep wakes (a late bench delays every
    reply it times, whatever the server did)."""

    def __init__(self) -> None:
        self.rows: list[tuple[float, float]] = []  # (woke at, seconds late)
        self.task = asyncio.create_task(self._run())

    async def _run(self) -> None:
        while True:
            t0 = time.monotonic()
            await asyncio.sleep(0.01)
            woke = time.monotonic()
            self.rows.append((woke, woke - t0 - 0.01))

    def between(self, t0: float, t1: float) -> list[float]:
        return [late for at, late in self.rows if t0 <= at <= t1]

    async def stop(self) -> None:
        self.task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.task


class Probe:
    """A tablet that sends ``ping`` every 100 ms: (phase, sent at, seconds to the reply)."""

    def __init__(self, conn: Conn) -> None:
        self.conn = conn
        self.phase = "setup"
        self.rows: list[tuple[str, float, float]] = []
        self.task = asyncio.create_task(self._run())

    async def _run(self) -> None:
        next_at = time.monotonic()
        while True:
            next_at += 0.1
            t0 = time.monotonic()
            with contextlib.suppress(TimeoutError):
                await self.conn.call("ping")
                self.rows.append((self.phase, t0, time.monotonic() - t0))
            await asyncio.sleep(max(0.0, next_at - time.monotonic()))

    def of(self, phase: str) -> list[float]:
        return [r[2] for r in self.rows if r[0] == phase]

    async def stop(self) -> None:
        self.task.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self.task


async def post_order(port: int, token: str, body: dict[str, Any]) -> tuple[int, Any, float]:
    """``POST /api/orders`` on a connection of its own: (status, JSON answer, seconds)."""
    payload = json.dumps(body).encode()
    head = (
        f"POST /api/orders HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\n"
        f"Authorization: Bearer {token}\r\nContent-Type: application/json\r\n"
        f"Content-Length: {len(payload)}\r\nConnection: close\r\n\r\n"
    ).encode()

    async def exchange() -> tuple[int, Any]:
        reader, writer = await asyncio.open_connection("127.0.0.1", port)
        try:
            writer.write(head + payload)
            await writer.drain()
            status = int((await reader.readline()).split()[1])
            length = 0
            while (line := await reader.readline()) not in (b"\r\n", b""):
                name, _, value = line.decode("latin-1").partition(":")
                if name.strip().lower() == "content-length":
                    length = int(value)
            return status, json.loads(await reader.readexactly(length))
        finally:
            writer.close()
            with contextlib.suppress(OSError):
                await writer.wait_closed()

    t0 = time.monotonic()
    status, answer = await asyncio.wait_for(exchange(), WAIT)
    return status, answer, time.monotonic() - t0


class Rush:
    """The till's jobs over the rush: seeded kinds and contents, Poisson times."""

    def __init__(self, console: Console, port: int, rate_per_min: float, seed: int) -> None:
        self.console = console
        self.port = port
        self.rate = rate_per_min / 60.0
        self.rng = random.Random(seed)
        self.number = 1000
        self.sent: list[Sent] = []
        self.voided: set[int] = set()
        self.tasks: set[asyncio.Task[None]] = set()

    def _dishes(self) -> list[Dish]:
        names = self.rng.sample(DISHES, self.rng.randint(1, 6))
        out: list[Dish] = []
        for name in names:
            qty = self.rng.choices((1, 2, 3), (6, 3, 1))[0]
            notes = (self.rng.choice(NOTES),) if self.rng.random() < 0.25 else ()
            out.append((qty, name, notes))
        return out

    def _done(self) -> list[Sent]:
        """New tickets whose orders the console has seen: what a reprint or void may name."""
        return [s for s in self.sent[-200:] if s.kind == "new" and s.orders_seen is not None]

    def next_job(self) -> tuple[Sent, bytes]:
        roll = self.rng.random()
        done = self._done()
        if roll < GARBLED:
            job = garbled_job(self.rng)
            return Sent("garbled", lines_of(job)), job
        target: list[Sent] = []
        if roll < GARBLED + VOID and done:
            target = [s for s in done if s.number not in self.voided]
        if roll < GARBLED + VOID and done and target:
            of = self.rng.choice(target[-20:])
            self.voided.add(of.number)
            qty, name, notes = self.rng.choice(of.dishes)
            dishes = [(self.rng.randint(1, qty), name, notes)]
            job = square_ticket(of.number, of.table, dishes, banner="*** VOID ***")
            return Sent("void", lines_of(job), of.number, of.table, dishes, of), job
        if roll < GARBLED + VOID + REPRINT and done:
            of = self.rng.choice(done[-20:])
            job = square_ticket(of.number, of.table, of.dishes, banner="** REPRINT **")
            return Sent("reprint", lines_of(job), of.number, of.table, of.dishes, of), job
        self.number += 1
        table, dishes = self.rng.choice(TABLES), self._dishes()
        job = square_ticket(self.number, table, dishes)
        return Sent("new", lines_of(job), self.number, table, dishes), job

    async def run(self, duration: float) -> None:
        t_end = time.monotonic() + duration
        at = time.monotonic() + self.rng.expovariate(self.rate)
        while at < t_end:
            await asyncio.sleep(max(0.0, at - time.monotonic()))
            sent, job = self.next_job()
            self.console.expect(sent)
            self.sent.append(sent)
            task = asyncio.create_task(print_job(self.port, job, sent))
            self.tasks.add(task)
            task.add_done_callback(self.tasks.discard)
            at += self.rng.expovariate(self.rate)
        if self.tasks:  # each job is bounded (connect, then the server's close): 2 x WAIT
            _, late = await asyncio.wait(self.tasks, timeout=2 * WAIT + 5)
            for task in late:
                task.cancel()


@dataclass
class IntakeKey:
    key: str
    body: dict[str, Any]
    how: str  # once, retry, twice
    answers: list[tuple[int, int | None]] = field(default_factory=list)  # status, ticket id
    took: list[float] = field(default_factory=list)  # seconds, each POST in the order sent


async def intake(port: int, token: str, n: int, seed: int) -> tuple[list[IntakeKey], list[float]]:
    """``n`` tickets through the order-intake API, ~10 a second (Poisson)."""
    rng = random.Random(seed + 1)
    keys: list[IntakeKey] = []
    took: list[float] = []
    tasks: list[asyncio.Task[None]] = []

    async def send(k: IntakeKey) -> None:
        async def one() -> None:
            try:
                status, answer, s = await post_order(port, token, k.body)
            except (OSError, TimeoutError, ValueError, IndexError) as exc:
                k.answers.append((-1, None))
                print(f"intake {k.key}: {type(exc).__name__}: {exc}", file=sys.stderr)
                return
            took.append(s)
            k.took.append(s)
            ticket = answer.get("ticket", {}).get("id") if isinstance(answer, dict) else None
            k.answers.append((status, ticket))

        if k.how == "twice":
            await asyncio.gather(one(), one())
        else:
            await one()
            if k.how == "retry":
                await one()

    for i in range(n):
        dishes = [
            {"dish": name, "quantity": rng.choices((1, 2, 3), (6, 3, 1))[0]}
            for name in rng.sample(DISHES, rng.randint(1, 4))
        ]
        body = {
            "key": f"bench-{seed}-{i}",
            "table": rng.choice(TABLES),
            "ticket": f"A{i}",
            "dishes": dishes,
        }
        roll = rng.random()
        how = "twice" if roll < 0.05 else "retry" if roll < 0.25 else "once"
        k = IntakeKey(body["key"], body, how)
        keys.append(k)
        tasks.append(asyncio.create_task(send(k)))
        await asyncio.sleep(rng.expovariate(10.0))
    await asyncio.wait(tasks, timeout=WAIT * 2)
    return keys, took


# -- the check, from the database -----------------------------------------------------------------


def _db_rows(db: Path) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]]]:
    con = sqlite3.connect(f"file:{db}?mode=ro", uri=True, timeout=10)
    try:
        tickets = con.execute(
            "SELECT id, text, status, of_ticket, problem FROM till_ticket ORDER BY id"
        ).fetchall()
        orders = con.execute(
            "SELECT id, res_table, dish, quantity, status, ticket_id FROM orders ORDER BY id"
        ).fetchall()
        return tickets, orders
    finally:
        con.close()


def check(
    db: Path, jobs: list[Sent], keys: list[IntakeKey], setup: list[Sent]
) -> tuple[list[str], dict[str, int]]:
    """Every mismatch between what was sent and what the server made of it, in words."""
    tickets, orders = _db_rows(db)
    wrong: list[str] = []
    by_text: dict[str, list[tuple[Any, ...]]] = collections.defaultdict(list)
    for t in tickets:
        by_text[t[1]].append(t)
    orders_of: dict[int, list[tuple[Any, ...]]] = collections.defaultdict(list)
    for o in orders:
        if o[5] is not None:
            orders_of[o[5]].append(o)
    expected: collections.Counter[tuple[str, str]] = collections.Counter()
    ids: dict[int, int] = {}  # ticket number -> the id of the ticket that ordered it
    counts = collections.Counter(s.kind for s in jobs)
    sent_with = collections.Counter("\n".join(s.lines) for s in [*setup, *jobs])
    for s in [*setup, *jobs]:
        text = "\n".join(s.lines)
        what = f"{s.kind} job #{s.number or '-'} {s.table or ''}".rstrip()
        if s.error:
            wrong.append(f"{what}: the till's send failed: {s.error}")
        found = by_text.get(text, [])
        if len(found) != sent_with[text]:  # each job sent is one ticket: none lost, none twice
            wrong.append(
                f"{what}: {len(found)} tickets in the database, {sent_with[text]} sent"
                f" (tickets {[t[0] for t in found]})"
            )
            sent_with[text] = 0  # said once
        if not found:
            continue
        tid, _, status, of_ticket, problem = found.pop(0)  # the same lines: in the order sent
        made = orders_of.get(tid, [])
        if s.kind == "new":
            ids[s.number] = tid
            for qty, name, _ in s.dishes:
                expected[s.table, fold(name)] += qty
            if status != "ordered":
                wrong.append(f"{what}: ticket {tid} is {status} ({problem}), not ordered")
            if len(made) != len(s.dishes):
                wrong.append(f"{what}: ticket {tid} made {len(made)} orders for {len(s.dishes)}")
        elif s.kind == "reprint":
            assert s.of is not None
            if status != "reprint" or of_ticket != ids.get(s.of.number):
                wrong.append(
                    f"{what}: ticket {tid} is {status} of {of_ticket}, not a reprint of"
                    f" {ids.get(s.of.number)}"
                )
            if made:
                wrong.append(f"{what}: the reprint {tid} made {len(made)} orders")
        elif s.kind == "void":
            for qty, name, _ in s.dishes:
                expected[s.table, fold(name)] -= qty
            if status != "void" or problem:
                wrong.append(f"{what}: ticket {tid} is {status} ({problem}), not void")
            if made:
                wrong.append(f"{what}: the void {tid} made {len(made)} orders")
        elif s.kind == "garbled":
            if status != "unread":
                wrong.append(f"{what}: ticket {tid} is {status}, not unread")
            if made:
                wrong.append(f"{what}: the garbled ticket {tid} made {len(made)} orders")
    for k in keys:
        statuses = sorted(a[0] for a in k.answers)
        want = {"once": [201], "retry": [200, 201], "twice": [200, 201]}[k.how]
        if statuses != want:
            wrong.append(f"intake {k.key} ({k.how}): answered {statuses}, not {want}")
        made_ids = {a[1] for a in k.answers}
        if len(made_ids) != 1 or None in made_ids:
            wrong.append(
                f"intake {k.key} ({k.how}): answers name tickets {sorted(made_ids, key=str)}"
            )
            continue
        (tid,) = made_ids
        assert tid is not None
        for d in k.body["dishes"]:
            expected[k.body["table"], fold(d["dish"])] += d["quantity"]
        if len(orders_of.get(tid, [])) != len(k.body["dishes"]):
            wrong.append(
                f"intake {k.key}: ticket {tid} made {len(orders_of.get(tid, []))} orders"
                f" for {len(k.body['dishes'])}"
            )
    got: collections.Counter[tuple[str, str]] = collections.Counter()
    for _, table, dish, qty, status, _ in orders:
        if status != "voided":
            got[table, fold(dish)] += qty
    for key in sorted(set(expected) | set(got)):
        if expected[key] != got[key]:
            wrong.append(f"{key[0]} {key[1]}: {got[key]} ordered, {expected[key]} sent")
    counts["tickets_in_db"] = len(tickets)
    counts["orders_in_db"] = len(orders)
    return wrong, dict(counts)


# -- one quota ---------------------------------------------------------------------------------


def _ms(values: list[float], q: float) -> float | None:
    return round(1e3 * pct(values, q), 1) if values else None


async def _until(cond: Callable[[], bool], console: Console, limit_s: float) -> bool:
    end = time.monotonic() + limit_s
    while not cond():
        if time.monotonic() > end:
            return False
        console.changed.clear()
        with contextlib.suppress(TimeoutError):
            await asyncio.wait_for(console.changed.wait(), 0.5)
    return True


async def one_quota(ns: argparse.Namespace, quota: float, tmp: Path) -> dict[str, Any]:
    db = tmp / "till.db"
    result: dict[str, Any] = {"quota": quota}
    server: asyncio.subprocess.Process | None = None
    conns: list[Conn] = []
    probe: Probe | None = None
    try:
        dbs = str(db)
        owner_add = ["user", "add", "owner", "--role", "owner", "--db", dbs]
        await asyncio.to_thread(_run_cli, *owner_add, stdin=OWNER_PASSWORD + "\n")
        staff_args = ["token", "create", "--role", "staff", "--db", dbs]
        staff = (await asyncio.to_thread(_run_cli, *staff_args)).strip()
        pos_args = ["token", "create", "--role", "integration", "--scope", "orders"]
        pos_args += ["--label", "pos bridge", "--db", dbs]
        pos = (await asyncio.to_thread(_run_cli, *pos_args)).split()[0]
        port, intake_port, printer_port = _free_port(), _free_port(), _free_port()
        waypoints = demo_map_path().with_name("demo_waypoints.json")
        cmd = _cli("run", "--port", str(port), "--db", dbs, "--map", str(demo_map_path()))
        cmd += ["--waypoints", str(waypoints), "--intake-port", str(intake_port)]
        cmd += ["--backups", "off"]
        log = tmp / "server.log"
        with open(log, "wb") as out:  # noqa: ASYNC230 - before anything is measured
            server = await asyncio.create_subprocess_exec(
                *cmd, stdout=out, stderr=out, start_new_session=True
            )
        _GROUPS.add(server.pid)
        end = time.monotonic() + 90
        while "listening on" not in log.read_text(errors="replace"):
            if time.monotonic() > end or server.returncode is not None:
                raise RuntimeError(f"the server did not start: {log.read_text()[-2000:]}")
            await asyncio.sleep(0.2)
        result["quota_applied"] = _limit(server.pid, quota)
        result["weight"] = _weigh(server.pid, ns.shares)
        url = f"ws://127.0.0.1:{port}/ws"

        # The owner: log in, open the printer port (mirror), a first ticket and its void.
        owner_ws = await connect(url, compression=None, max_size=2**24, open_timeout=WAIT)
        owner = Conn(owner_ws, "owner")
        conns.append(owner)
        reply = await owner.call("login", username="owner", password=OWNER_PASSWORD)
        if reply.get("servermsg") != "ok":
            raise RuntimeError(f"owner login: {reply}")
        kitchen = await open_conn(url, staff, "kitchen")
        conns.append(kitchen)
        console = Console(kitchen)
        await kitchen.subscribe(["orders", "tickets"])
        probe_conn = await open_conn(url, staff, "probe")
        conns.append(probe_conn)
        probe = Probe(probe_conn)
        reply = await owner.call("till", action="setup", port=printer_port)
        if reply.get("servermsg") != "ok" or not reply["till"]["listening"]:
            raise RuntimeError(f"till setup: {reply}")
        first_dishes: list[Dish] = [(1, "Laksa", ()), (1, "Teh Tarik", ())]
        job_a = square_ticket(1000, "T12", first_dishes)
        job_b = square_ticket(1000, "T12", [(1, "Teh Tarik", ())], banner="*** VOID ***")
        setup = [
            Sent("new", lines_of(job_a), 1000, "T12", first_dishes),
            Sent("void", lines_of(job_b), 1000, "T12", [(1, "Teh Tarik", ())]),
        ]
        for sent, job in zip(setup, (job_a, job_b), strict=True):
            console.expect(sent)
            await print_job(printer_port, job, sent)
            if not await _until(lambda s=sent: s.ticket_id is not None, console, WAIT):
                raise RuntimeError("the till's first tickets never reached the console")
        b_id = setup[1].ticket_id
        lines_b = setup[1].lines
        marks = [
            {"line": _index(lines_b, "Table:"), "as": "table", "table": "T12"},
            {"line": lines_b.index("1 x Teh Tarik"), "as": "dish"},
            {"line": lines_b.index("Order #1000"), "as": "ticket"},
            {"line": lines_b.index("*** VOID ***"), "as": "void"},
        ]
        proposal = await owner.call("till", action="propose", ticket=b_id, marks=marks)
        if proposal.get("servermsg") != "ok":
            raise RuntimeError(f"till propose: {proposal}")
        saved = await owner.call("till", action="setup", pattern=proposal["pattern"])
        if saved.get("servermsg") != "ok":
            raise RuntimeError(f"till setup pattern: {saved}")
        result["pattern"] = proposal["pattern"]
        result["read_at_save"] = saved["read"]

        # Quiet, then the rush.
        probe.phase = "quiet"
        await asyncio.sleep(5.0)
        rush = Rush(console, printer_port, ns.rate, ns.seed)
        probe.phase = "rush"
        sampler = Sampler(server.pid, period=0.01)
        lag = LoopLag()
        cpu0, _ = _proc_stats(server.pid)
        stat0 = _cpu_stat(server.pid)
        t0 = time.monotonic()
        await asyncio.wait_for(rush.run(ns.duration), ns.duration + 2 * WAIT)
        window = time.monotonic() - t0
        cpu1, rss = _proc_stats(server.pid)
        stat1 = _cpu_stat(server.pid)
        sampler.stop()
        await lag.stop()
        probe.phase = "settle"
        settled = await _until(
            lambda: (
                all(s.ticket_seen is not None for s in rush.sent)
                and all(s.orders_seen is not None for s in rush.sent if s.kind == "new")
            ),
            console,
            WAIT,
        )
        probe.phase = "intake"
        keys, intake_took = await intake(intake_port, pos, ns.intake, ns.seed)
        probe.phase = "done"
        await asyncio.sleep(1.0)
        wrong, counts = await asyncio.to_thread(check, db, rush.sent, keys, setup)
        if not settled:
            wrong.append(
                "not every job reached the console within 30 s: "
                f"{sum(s.ticket_seen is None for s in rush.sent)} tickets,"
                f" {sum(s.orders_seen is None for s in rush.sent if s.kind == 'new')} orders"
            )
        new = [s for s in rush.sent if s.kind == "new" and s.orders_seen is not None]
        to_order = [s.orders_seen - s.last_byte for s in new if s.orders_seen is not None]
        to_ticket = [
            s.ticket_seen - s.last_byte
            for s in rush.sent
            if s.ticket_seen is not None and s.last_byte
        ]
        throttled = {k: stat1.get(k, 0) - stat0.get(k, 0) for k in stat1}
        server_log = log.read_text(errors="replace")
        result.update(
            {
                "window_s": round(window, 1),
                "jobs": counts,
                "ticket_to_order_ms": {
                    "n": len(to_order),
                    "p50": _ms(to_order, 50),
                    "p99": _ms(to_order, 99),
                    "max": _ms(to_order, 100),
                },
                "ticket_to_tickets_update_ms": {
                    "n": len(to_ticket),
                    "p50": _ms(to_ticket, 50),
                    "p99": _ms(to_ticket, 99),
                    "max": _ms(to_ticket, 100),
                },
                "ping_quiet_ms": {
                    "n": len(probe.of("quiet")),
                    "p50": _ms(probe.of("quiet"), 50),
                    "p99": _ms(probe.of("quiet"), 99),
                    "max": _ms(probe.of("quiet"), 100),
                },
                "ping_rush_ms": {
                    "n": len(probe.of("rush")),
                    "p50": _ms(probe.of("rush"), 50),
                    "p99": _ms(probe.of("rush"), 99),
                    "max": _ms(probe.of("rush"), 100),
                },
                "ping_intake_ms": {
                    "n": len(probe.of("intake")),
                    "p50": _ms(probe.of("intake"), 50),
                    "p99": _ms(probe.of("intake"), 99),
                },
                "intake_ms": {
                    "posts": len(intake_took),
                    "keys": len(keys),
                    "retried": sum(k.how == "retry" for k in keys),
                    "twice": sum(k.how == "twice" for k in keys),
                    "p50": _ms(intake_took, 50),
                    "p99": _ms(intake_took, 99),
                    "max": _ms(intake_took, 100),
                    "each_ms": [[k.how, [round(1e3 * x, 1) for x in k.took]] for k in keys],
                },
                "server_cpu_pct": round(100 * (cpu1 - cpu0) / window, 1),
                "rss_mb": round(rss / 2**20, 1),
                "cpu_stat": throttled,
                "throttled_periods_pct": round(
                    100 * throttled.get("nr_throttled", 0) / max(1, throttled.get("nr_periods", 0)),
                    1,
                ),
                "throttled_s": round(throttled.get("throttled_time", 0) / 1e9, 2),
                "console_seq_gaps": kitchen.gaps,
                # The slowest pings of the rush, and what the server's loop thread did
                # meanwhile (CPU, run-queue wait, the group's throttling) and how late this
                # process's own loop was: the server's doing, the host's or the bench's.
                "slowest_pings": [
                    {
                        "at_s": round(r[1] - t0, 2),
                        "ms": round(1e3 * r[2], 1),
                        **sampler.between(r[1], r[1] + r[2]),
                        "bench_loop_late_ms": round(
                            1e3 * max(lag.between(r[1], r[1] + r[2] + 0.02), default=0.0), 1
                        ),
                    }
                    for r in sorted((r for r in probe.rows if r[0] == "rush"), key=lambda r: -r[2])[
                        :5
                    ]
                ],
                "slowest_tickets": [
                    {
                        "at_s": round(s.last_byte - t0, 2),
                        "ms": round(1e3 * (s.orders_seen - s.last_byte), 1),
                        **sampler.between(s.last_byte, s.orders_seen),
                        "bench_loop_late_ms": round(
                            1e3 * max(lag.between(s.last_byte, s.orders_seen + 0.02), default=0.0),
                            1,
                        ),
                    }
                    for s in sorted(
                        (s for s in new if s.orders_seen is not None),
                        key=lambda s: s.last_byte - (s.orders_seen or 0.0),
                    )[:5]
                    if s.orders_seen is not None
                ],
                "bench_loop_late_ms": {
                    "p99": _ms(lag.between(t0, t0 + window), 99),
                    "max": _ms(lag.between(t0, t0 + window), 100),
                },
                "till_send_errors": sum(1 for s in rush.sent if s.error),
                "server_log_errors": [
                    line
                    for line in server_log.splitlines()
                    if "ERROR" in line or "Traceback" in line
                ][:10],
                "mismatches": len(wrong),
                "mismatches_first": wrong[:20],
            }
        )
        return result
    finally:
        if probe is not None:
            await probe.stop()
        for c in conns:
            with contextlib.suppress(Exception):
                await asyncio.wait_for(c.ws.close(), 5)
        if server is not None:
            try:
                await _stop_group(server)
            finally:
                _unlimit(server.pid)


def e2e_table(results: list[dict[str, Any]]) -> str:
    head = (
        "| share of a core | jobs: new / reprint / void / garbled | ticket -> order p50 / p99 /"
        " max | ticket -> tickets update p50 / p99 | ping quiet p50 / p99 | ping in the rush"
        " p50 / p99 / max | intake POSTs, p50 / p99 / max | server CPU in the rush | throttled"
        " periods, time | mismatches |\n"
        "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n"
    )
    rows = []
    for r in results:
        j, o, t = r["jobs"], r["ticket_to_order_ms"], r["ticket_to_tickets_update_ms"]
        q, p, i = r["ping_quiet_ms"], r["ping_rush_ms"], r["intake_ms"]
        share = (
            f"{100 * r['quota']:.0f} %"
            if r["quota_applied"].endswith("of a core")
            else f"unconfined ({r['quota_applied']})"
        )
        rows.append(
            f"| {share} | {j.get('new', 0)} / {j.get('reprint', 0)} / {j.get('void', 0)} /"
            f" {j.get('garbled', 0)} | {o['p50']} / {o['p99']} / {o['max']} ms"
            f" | {t['p50']} / {t['p99']} ms | {q['p50']} / {q['p99']} ms"
            f" | {p['p50']} / {p['p99']} / {p['max']} ms"
            f" | {i['posts']}, {i['p50']} / {i['p99']} / {i['max']} ms"
            f" | {r['server_cpu_pct']} % | {r['throttled_periods_pct']} %, {r['throttled_s']} s"
            f" | {r['mismatches']} |"
        )
    return head + "\n".join(rows)


async def main(ns: argparse.Namespace) -> int:
    # SIGTERM and SIGINT cancel the run: every finally stops what it started.
    task = asyncio.current_task()
    assert task is not None
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGTERM, signal.SIGINT):
        loop.add_signal_handler(sig, task.cancel)
    load0 = os.getloadavg()
    pure = await asyncio.to_thread(pure_cost, ns.reps)
    print("Pure cost (this process, no sockets; medians):\n")
    print(pure_table(pure) + "\n", flush=True)
    results: list[dict[str, Any]] = []
    for quota in ns.quota:
        with tempfile.TemporaryDirectory(prefix="serveur-bench-till-") as tmp:
            r = await one_quota(ns, quota, Path(tmp))
        print(json.dumps(r), file=sys.stderr, flush=True)
        results.append(r)
        if not r["quota_applied"].endswith("of a core"):
            print(
                f"NOTE: no CPU quota could be set ({r['quota_applied']}): the server ran"
                " unconfined, once; the other shares were not run\n"
            )
            break
    load1 = os.getloadavg()
    print(
        f"{ns.rate:g} tickets a minute for {ns.duration:g} s (seed {ns.seed}), {ns.intake}"
        f" intake tickets; load average before {load0[0]:.2f}, after {load1[0]:.2f}\n"
    )
    print(e2e_table(results))
    print()
    for r in results:
        slow = "; ".join(
            f"{p['ms']} ms at {p['at_s']} s (server loop: CPU {p['cpu_ms']} ms, waiting for a"
            f" CPU {p['wait_ms']} ms, throttled {p['throttled_ms']} ms; bench loop late"
            f" {p['bench_loop_late_ms']} ms)"
            for p in r["slowest_pings"][:3]
        )
        lag = r["bench_loop_late_ms"]
        print(
            f"at {100 * r['quota']:.0f} %: slowest pings in the rush: {slow}. This process's"
            f" loop late p99 {lag['p99']} ms, max {lag['max']} ms; RSS {r['rss_mb']} MB;"
            f" console seq gaps {r['console_seq_gaps']}"
        )
        slow = "; ".join(
            f"{p['ms']} ms at {p['at_s']} s (server loop: CPU {p['cpu_ms']} ms, waiting for a"
            f" CPU {p['wait_ms']} ms, throttled {p['throttled_ms']} ms; bench loop late"
            f" {p['bench_loop_late_ms']} ms)"
            for p in r["slowest_tickets"][:3]
        )
        print(f"at {100 * r['quota']:.0f} %: slowest tickets -> orders: {slow}")
    failed = [(r["quota"], w) for r in results for w in r["mismatches_first"]]
    for quota, w in failed:
        print(f"MISMATCH at {100 * quota:.0f} % of a core: {w}")
    for r in results:
        for line in r["server_log_errors"]:
            print(f"server log at {100 * r['quota']:.0f} %: {line}")
    if ns.json:
        Path(ns.json).write_text(  # noqa: ASYNC240 - at the end
            json.dumps({"pure": pure, "e2e": results, "load": [load0, load1]}, indent=1)
        )
    if any(r["mismatches"] for r in results):
        return 1
    print("\nevery ticket made its orders once; reprints none; garbled ones kept unread")
    return 0


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--quota", type=float, nargs="+", default=[0.25, 0.5, 1.0])
    ap.add_argument("--duration", type=float, default=60.0, help="seconds of lunch rush")
    ap.add_argument("--rate", type=float, default=300.0, help="tickets a minute (Poisson)")
    ap.add_argument("--intake", type=int, default=60, help="tickets through the intake API")
    ap.add_argument("--reps", type=int, default=2000, help="repetitions of the pure cost")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument(
        "--shares",
        type=int,
        default=NICE_MINUS_5,
        help="the server's cgroup cpu.shares (default 3121: the deployed Nice=-5)",
    )
    ap.add_argument("--json")
    args = ap.parse_args()
    try:
        code = asyncio.run(main(args))
    except (asyncio.CancelledError, KeyboardInterrupt):
        print("stopped by a signal: everything it started is stopped", file=sys.stderr)
        code = 130
    finally:
        _cleanup()
    sys.exit(code)
