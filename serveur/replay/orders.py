"""Order logs: the dishes of a service, read from CSV or generated, for ``serveur replay``.

An order log is what a kitchen display or point-of-sale system can export: one line per dish,
``ready_at,table,dish``, where ``ready_at`` is the second of the service (from opening) the
dish was ready at the pass and ``table`` a table waypoint of the map. Replaying a log through
the real server answers "how long do guests wait with N robots?", so the reader is strict:

* every bad row is reported with its line number, all of them at once (a 1,000-line export
  with three typos should cost one round of fixes, not three);
* nothing is half-loaded: a log with one bad row gives no orders at all, because a replay of
  most of a service would report waits for a service that never happened;
* tables must be waypoints of the map the replay runs on (checked here, not mid-replay).

:func:`generate_orders` writes a realistic service for when no export is at hand: parties
arrive as a Poisson process whose rate has a lunch and a dinner peak, each party sits at a
free table of the map, and the kitchen sends a party's dishes out together (a few seconds
apart), which is what makes batching tables on one trip worth anything. Everything is drawn
from one ``random.Random(seed)``: the same arguments give the same log, byte for byte.

:func:`guest_calls` adds what no log says: what each party calls for once served (the plates
cleared, a waiter, the bill) and when, seeded per party, for the replay's calls and bussing.
"""

from __future__ import annotations

import argparse
import csv
import io
import math
import random
import re
import sys
from collections.abc import Collection, Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, TextIO

__all__ = [
    "HEADER",
    "LogOrder",
    "OrderLogError",
    "PartyCalls",
    "add_orders_parser",
    "demo_tables",
    "format_orders",
    "generate_orders",
    "guest_calls",
    "map_tables",
    "parse_orders",
    "parties",
    "read_orders",
]

HEADER = ("ready_at", "table", "dish")
_MAX_NAME = 64  # the protocol's limit for a dish or table name
_CONTROL = re.compile(r"[\x00-\x1f\x7f]")
#: Longest service a log may describe (a day); catches milliseconds written as seconds.
_MAX_READY_AT = 24 * 3600.0

_MENU = (
    "Laksa", "Nasi lemak", "Chicken rice", "Char kway teow", "Satay", "Rendang", "Roti prata",
    "Mee goreng", "Hokkien mee", "Fish head curry", "Chilli crab", "Bak kut teh", "Popiah",
    "Kaya toast", "Cendol", "Teh tarik", "Kopi", "Ice kachang", "Otak-otak", "Carrot cake",
)  # fmt: skip


@dataclass(frozen=True, slots=True)
class LogOrder:
    """One dish of a log. ``line`` is its line in the file (0 for generated orders)."""

    ready_at: float
    table: str
    dish: str
    line: int = 0


class OrderLogError(ValueError):
    """A log with bad rows; ``problems`` lists ``(line, message)`` for every one of them."""

    def __init__(self, source: str, problems: Sequence[tuple[int, str]]) -> None:
        self.source = source
        self.problems = list(problems)
        shown = "\n".join(f"  line {n}: {msg}" for n, msg in self.problems[:20])
        more = len(self.problems) - 20
        tail = f"\n  ... and {more} more" if more > 0 else ""
        super().__init__(
            f"{source}: {len(self.problems)} bad row(s), nothing loaded:\n{shown}{tail}"
        )


def _check_name(value: str, what: str) -> str | None:
    if not value:
        return f"{what} is empty"
    if len(value) > _MAX_NAME:
        return f"{what} is longer than {_MAX_NAME} characters"
    if _CONTROL.search(value):
        return f"{what} contains control characters"
    return None


def parse_orders(
    text: str, *, tables: Collection[str] | None = None, source: str = "<orders>"
) -> list[LogOrder]:
    """Parse a whole log; the orders sorted by ``ready_at`` (stable), or :class:`OrderLogError`.

    ``tables``: the table names the map has; ``None`` skips that check (no map at hand).
    Blank lines are ignored; everything else must be a valid row.
    """
    problems: list[tuple[int, str]] = []
    orders: list[LogOrder] = []
    reader = csv.reader(io.StringIO(text, newline=""), strict=True)
    header_seen = False
    try:
        for row in reader:
            line = reader.line_num
            if not row or all(not c.strip() for c in row):
                continue
            cells = [c.strip() for c in row]
            if not header_seen:
                header_seen = True
                if tuple(c.lower() for c in cells) != HEADER:
                    problems.append((line, f"the header must be {','.join(HEADER)}, not {row}"))
                continue
            if len(cells) != len(HEADER):
                problems.append((line, f"expected 3 fields (ready_at,table,dish), got {len(row)}"))
                continue
            ready_s, table, dish = cells
            why: list[str] = []
            try:
                ready_at = float(ready_s)
                if not math.isfinite(ready_at) or not 0.0 <= ready_at <= _MAX_READY_AT:
                    why.append(f"ready_at {ready_s!r} is not between 0 and {_MAX_READY_AT:.0f} s")
            except ValueError:
                ready_at = 0.0
                why.append(f"ready_at {ready_s!r} is not a number of seconds")
            for value, what in ((table, "table"), (dish, "dish")):
                bad = _check_name(value, what)
                if bad:
                    why.append(bad)
            if table and tables is not None and table not in tables:
                why.append(f"table {table!r} is not a table waypoint of the map")
            if why:
                problems.append((line, "; ".join(why)))
            else:
                orders.append(LogOrder(ready_at, table, dish, line))
    except csv.Error as exc:
        problems.append((reader.line_num, f"unreadable CSV: {exc}"))
    if not header_seen:
        problems.append((1, f"empty log: the first line must be the header {','.join(HEADER)}"))
    if problems:
        raise OrderLogError(source, problems)
    orders.sort(key=lambda o: o.ready_at)
    return orders


def read_orders(path: str | Path, *, tables: Collection[str] | None = None) -> list[LogOrder]:
    """Read a log file (UTF-8, optional BOM); see :func:`parse_orders`."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8-sig")
    except (OSError, UnicodeDecodeError) as exc:
        raise OrderLogError(str(p), [(0, f"cannot read the file: {exc}")]) from exc
    return parse_orders(text, tables=tables, source=str(p))


#: Dishes for one table less than this apart (s) belong to one party (a generated party's
#: dishes leave within :data:`_SPREAD` of each other; a table's next party sits down 45 min on).
PARTY_GAP = 600.0


def parties(orders: Iterable[LogOrder], gap: float = PARTY_GAP) -> list[list[LogOrder]]:
    """The log's parties: each table's dishes, cut where ``gap`` seconds pass without one.

    A log has no party column (a kitchen display exports dishes), so a party is read off the
    times: its dishes come out together. Parties in the order of their first dish.
    """
    open_: dict[str, list[LogOrder]] = {}
    out: list[list[LogOrder]] = []
    for o in sorted(orders, key=lambda o: (o.ready_at, o.line)):
        party = open_.get(o.table)
        if party is None or o.ready_at - party[-1].ready_at > gap:
            party = open_[o.table] = []
            out.append(party)
        party.append(o)
    return out


def format_orders(orders: Iterable[LogOrder]) -> str:
    """The CSV text of a log (``ready_at`` to a tenth of a second)."""
    out = io.StringIO(newline="")
    w = csv.writer(out, lineterminator="\n")
    w.writerow(HEADER)
    for o in orders:
        w.writerow((f"{o.ready_at:.1f}", o.table, o.dish))
    return out.getvalue()


def _natural(name: str) -> tuple[str, int, str]:
    m = re.match(r"(\D*)(\d+)(.*)", name)
    return (m.group(1), int(m.group(2)), m.group(3)) if m else (name, -1, "")


def map_tables(waypoints_path: str | Path | None = None) -> list[str]:
    """Table waypoint names (T1, T2, ..., T10 in natural order) of a waypoints file or the demo."""
    from serveur.maps.mapio import demo_waypoints_path, load_waypoints

    wps = load_waypoints(waypoints_path or demo_waypoints_path())
    return sorted((w.name for w in wps.values() if w.kind == "table"), key=_natural)


def demo_tables() -> list[str]:
    """The demo restaurant's tables."""
    return map_tables(None)


# -- the generator -----------------------------------------------------------------------------

#: Party sizes and how often they come (couples and groups of four dominate).
_PARTY_SIZES = (1, 2, 3, 4, 5, 6)
_PARTY_WEIGHTS = (0.10, 0.38, 0.17, 0.25, 0.06, 0.04)
_DISHES_PER_GUEST = 1.3  # a main each, sometimes a side or a drink from the pass
_SEATED = (45 * 60.0, 80 * 60.0)  # a party keeps its table this long (uniform)
_SPREAD = 40.0  # s: a party's dishes leave the kitchen within this window
_KITCHEN = (12 * 60.0, 25 * 60.0)  # s from sitting down to the party's food at the pass


def _intensity(t: float, duration: float) -> float:
    """Relative party arrival rate: a base load plus a lunch and a dinner peak.

    The peaks sit at a quarter and three quarters of the service, each a Gaussian a tenth of
    the service wide and three times the base load at its top, so a 4-hour service has rushes
    around hours 1 and 3 and quieter spells at the start, the middle and the end.
    """
    width = duration / 10.0
    peak = sum(math.exp(-0.5 * ((t - c * duration) / width) ** 2) for c in (0.25, 0.75))
    return 1.0 + 3.0 * peak


def generate_orders(
    tables: Sequence[str], hours: float, rate: float, seed: int = 0
) -> list[LogOrder]:
    """A service of ``hours`` with on average ``rate`` dishes an hour, on ``tables``.

    Parties arrive by thinning a Poisson process to :func:`_intensity` (scaled so that the
    expected number of dishes is ``rate * hours``), sit at a free table (any table if all are
    taken: a second seating squeezed in), order one to two dishes a guest, and the kitchen
    sends those dishes out within :data:`_SPREAD` seconds of each other, 12-25 minutes after
    the party sat down. Dishes ready after closing are dropped, so counts are a little under
    ``rate * hours``; ``ready_at`` is rounded to 0.1 s so the CSV round-trips exactly.
    """
    if not tables:
        raise ValueError("no tables to seat parties at")
    if not hours > 0 or not rate > 0:
        raise ValueError("hours and rate must be > 0")
    rng = random.Random(seed)
    duration = hours * 3600.0
    mean_size = sum(s * w for s, w in zip(_PARTY_SIZES, _PARTY_WEIGHTS, strict=True))
    dishes_per_party = mean_size * _DISHES_PER_GUEST
    steps = 2000
    mean_intensity = sum(_intensity((i + 0.5) * duration / steps, duration) for i in range(steps))
    mean_intensity /= steps
    peak_intensity = 4.0 + 1e-9  # 1 + 3 * (at most ~1.0 from the two bumps)
    base = rate / dishes_per_party / 3600.0 / mean_intensity  # parties / s at intensity 1
    free_at = dict.fromkeys(tables, 0.0)
    orders: list[LogOrder] = []
    # Parties sit down a kitchen time before their food is ready: arrivals run from one mean
    # kitchen time before opening to one before closing, so dishes fill the service evenly.
    lag = sum(_KITCHEN) / 2
    t = -lag
    while True:
        t += rng.expovariate(base * peak_intensity)
        if t >= duration - lag:
            break
        if rng.random() * peak_intensity > _intensity(t + lag, duration):
            continue
        free = [tb for tb in tables if free_at[tb] <= t]
        table = rng.choice(free) if free else min(tables, key=lambda tb: (free_at[tb], tb))
        free_at[table] = t + rng.uniform(*_SEATED)
        size = rng.choices(_PARTY_SIZES, _PARTY_WEIGHTS)[0]
        n = sum(1 + (rng.random() < _DISHES_PER_GUEST - 1.0) for _ in range(size))
        out = t + rng.uniform(*_KITCHEN)
        for _ in range(n):
            ready = round(out + rng.uniform(0.0, _SPREAD), 1)
            dish = rng.choice(_MENU)
            if 0.0 <= ready < duration:
                orders.append(LogOrder(ready, table, dish))
    orders.sort(key=lambda o: (o.ready_at, _natural(o.table), o.dish))
    return orders


# -- the guests' calls -------------------------------------------------------------------------

#: Minutes from a party's last dish collected to its call for the plates to be cleared: the
#: meal (uniform). With the kitchen's 12-25 min and a table kept 45-80 min (above), the plates
#: go 25-55 min after sitting down and the bill after them, before the party leaves.
EAT = (12 * 60.0, 30 * 60.0)
#: Seconds from the end of the meal (its plates call, made or not) to the call for the bill.
PAY = (3 * 60.0, 12 * 60.0)
#: Seconds after the food at the earliest that a party calls a waiter (another drink, a
#: question); at the latest, the end of the meal.
WAITER_FROM = 120.0


@dataclass(frozen=True, slots=True)
class PartyCalls:
    """What one party calls for once its last dish was collected: each call's kind and
    seconds after that moment. ``line``: its first dish's log line (the party's key);
    ``lines``: all its dishes' lines; ``plates``: how many plates it has to clear."""

    table: str
    line: int
    lines: tuple[int, ...]
    calls: tuple[tuple[float, str], ...]

    @property
    def plates(self) -> int:
        return len(self.lines)


def guest_calls(
    orders: Sequence[LogOrder],
    seed: int,
    *,
    plates: float = 0.8,
    waiter: float = 0.3,
    bill: float = 0.5,
    eat: tuple[float, float] = EAT,
    pay: tuple[float, float] = PAY,
) -> list[PartyCalls]:
    """The calls of every party of the log (:func:`parties`), seeded per party by its first
    dish's line: the same guests call the same way whatever the fleet or the policy.

    Each party eats for ``eat`` seconds (uniform) from its last dish collected; then, with
    probability ``plates``, it calls for the plates to be cleared (a robot comes when the
    restaurant has a dish return); with probability ``waiter`` it calls a waiter once during
    the meal (from :data:`WAITER_FROM` s on, uniform); with probability ``bill`` it calls for
    the bill ``pay`` seconds after the meal (the others pay at the counter or ask in passing).
    None of it is measured: these are assumptions (docs/statistics.md, *the replay's calls*).
    """
    out = []
    for party in parties(orders):
        first = party[0]
        rng = random.Random(f"calls:{seed}:{first.line}")
        meal = rng.uniform(*eat)
        # Every draw is made whatever the probabilities, so that switching one kind of call
        # off leaves the others' times as they were.
        wants = [rng.random() for _ in range(3)]
        at_waiter = rng.uniform(min(WAITER_FROM, meal / 2), meal)
        at_bill = meal + rng.uniform(*pay)
        calls = []
        if wants[0] < plates:
            calls.append((round(meal, 1), "plates"))
        if wants[1] < waiter:
            calls.append((round(at_waiter, 1), "waiter"))
        if wants[2] < bill:
            calls.append((round(at_bill, 1), "bill"))
        calls.sort()
        out.append(PartyCalls(first.table, first.line, tuple(o.line for o in party), tuple(calls)))
    return out


# -- command line ------------------------------------------------------------------------------


def _cmd_orders(ns: argparse.Namespace) -> int:
    if ns.from_db:
        return _cmd_recorded(ns)
    try:
        all_tables = map_tables(ns.waypoints)
    except Exception as exc:  # a bad waypoints file: say so, no traceback
        print(f"serveur orders: {exc}", file=sys.stderr)
        return 2
    if not 1 <= ns.tables <= len(all_tables):
        print(
            f"serveur orders: --tables must be 1..{len(all_tables)} (the map's tables)",
            file=sys.stderr,
        )
        return 2
    try:
        orders = generate_orders(all_tables[: ns.tables], ns.hours, ns.rate, ns.seed)
    except ValueError as exc:
        print(f"serveur orders: {exc}", file=sys.stderr)
        return 2
    out: TextIO = sys.stdout
    out.write(format_orders(orders))
    out.flush()
    return 0


def _cmd_recorded(ns: argparse.Namespace) -> int:
    """``serveur orders --from-db DB --day D``: a recorded service day as an order log."""
    import asyncio
    import time

    from serveur.errors import ServeurError
    from serveur.replay.recorded import recorded_orders
    from serveur.stats.periods import parse_offset, parse_when, period_of
    from serveur.store.factory import open_store

    try:
        tz = parse_offset(ns.utc_offset) if ns.utc_offset else None
        if ns.day == "today":  # the service day now running (it began at 04:00)
            ns.day = period_of(time.time(), "day", tz).label
        start = parse_when(ns.day, tz)
        end = parse_when(ns.day, tz, end=True)
    except ValueError as exc:
        print(f"serveur orders: {exc}", file=sys.stderr)
        return 2

    async def read() -> list[Any]:
        async with open_store(ns.from_db) as store:
            return await store.orders.list_orders()

    try:
        log = [LogOrder(*row) for row in recorded_orders(asyncio.run(read()), start, end)]
    except ServeurError as exc:
        print(f"serveur orders: {exc}", file=sys.stderr)
        return 1
    if not log:
        print(f"serveur orders: no dish was ready on {ns.day} in {ns.from_db}", file=sys.stderr)
        return 1
    sys.stdout.write(format_orders(log))
    sys.stdout.flush()
    return 0


def add_orders_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur orders`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "orders",
        help="generate an order log (CSV ready_at,table,dish) for serveur replay",
        description="Write a generated service's order log to stdout: parties at the map's "
        "tables, lunch and dinner peaks, several dishes per party. Deterministic per --seed.",
    )
    p.add_argument("--tables", type=int, default=16, help="use the first T tables (default 16)")
    p.add_argument("--hours", type=float, default=4.0, help="service length (default 4)")
    p.add_argument("--rate", type=float, default=120.0, help="mean dishes an hour (default 120)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument(
        "--waypoints", default=None, help="waypoints JSON whose tables to use (default: the demo)"
    )
    g = p.add_argument_group(
        "a recorded service instead (replay the restaurant's own night with another fleet)"
    )
    g.add_argument("--from-db", metavar="DB", help="the restaurant's database (path or URL)")
    g.add_argument(
        "--day",
        default="today",
        help="the service day to take (YYYY-MM-DD; a day runs 04:00 to 04:00; default today)",
    )
    g.add_argument("--utc-offset", help="the restaurant's time zone (default: this machine's)")
    p.set_defaults(func=_cmd_orders, is_async=False)
