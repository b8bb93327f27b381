"""Kitchen-ticket print jobs as points of sale send them, and what each should read as.

A till prints a kitchen ticket by sending ESC/POS to the printer's port 9100. The jobs here are
made the way a POS makes them, with python-escpos (``Dummy`` collects the bytes a printer would
receive); where python-escpos has no command for what a POS sends, the bytes are written by
hand and a comment says which command and why.

Three layouts, as three kinds of POS lay their tickets out:

* ``square``: a Square-like ticket: a big bold ``Table 12``, ``2 x Item`` lines, modifiers
  indented with ``- ``; its text in PC437 (python-escpos selects it with ``ESC t 0``);
* ``tm_chinese``: a Chinese/Malaysian restaurant POS on an Epson TM-style printer: ``桌号：5``,
  ``2 叉烧包``, notes ``  > 少辣``; its Chinese in GB18030, in the printer's double-byte mode
  (``FS &`` … ``FS .``), or by the printer's own setting, or in UTF-8 (``FS ( C`` function 48);
* ``lightspeed``: a Lightspeed/Toast-like check: ``Check #1042``, ``Table: T7``, the quantity
  last with the price (``Laksa x2   12.50``), a logo (``GS v 0``) and a QR code (``GS ( k``)
  before the text, a barcode after it; its text in WPC1252 (``ESC t 16``) or PC850 (``ESC t 2``).

Each :class:`Job` carries its bytes and, per ticket (split at the cuts), the lines as the paper
shows them, the table, the dishes, the ticket's number and whether it is a void. Each
:class:`Layout` carries the marks its owner makes on one of its tickets.
"""

# The Chinese tickets print the full-width colon (桌号：5) as Chinese points of sale do.
# ruff: noqa: RUF001, RUF002, RUF003

from __future__ import annotations

import contextlib
import io
import random
from collections.abc import Sequence
from dataclasses import dataclass

from escpos.printer import Dummy
from PIL import Image, ImageDraw

from serveur.till.pattern import Mark, MarkAs

__all__ = [
    "GARBLED",
    "JOBS",
    "LAYOUTS",
    "STATUS_REQUEST",
    "TRUNCATED",
    "Dish",
    "Job",
    "Layout",
    "Ticket",
]

# Commands python-escpos cannot send (each one's format from Epson's ESC/POS reference).
#: DLE EOT 1: "transmit printer status", a real-time request a POS sends before printing to
#: learn whether the printer is online (python-escpos only sends it from ``query_status``,
#: which waits for the reply on a real device).
STATUS_REQUEST = b"\x10\x04\x01"
#: DLE EOT 4: "transmit roll paper sensor status" (is there paper?).
PAPER_REQUEST = b"\x10\x04\x04"
#: FS &: enter the double-byte (Chinese) character mode; FS .: leave it. python-escpos's text()
#: knows single-byte code pages only, so a Chinese POS's text is written by hand.
KANJI_ON = b"\x1c&"
KANJI_OFF = b"\x1c."
#: FS ( C pL pH fn=48 m=2: select the UTF-8 character encoding (Epson TM-m30 and later).
UTF8_ON = b"\x1c(C\x02\x000\x02"

RULE = "-" * 42  # a 42-column rule (font A on 80 mm paper)
RULE_58 = "-" * 32  # a 32-column rule (58 mm paper, as small Chinese kitchen printers)


@dataclass(frozen=True, slots=True)
class Dish:
    quantity: int
    name: str
    notes: tuple[str, ...] = ()


@dataclass(frozen=True, slots=True)
class Ticket:
    """One ticket of a job: its lines as printed, and what it should read as."""

    lines: tuple[str, ...]
    table: str | None
    dishes: tuple[Dish, ...]
    number: str | None = None
    void: bool = False
    cut: bool = True


@dataclass(frozen=True, slots=True)
class Job:
    """One print job: what the POS sent, and its tickets."""

    name: str
    about: str
    data: bytes
    tickets: tuple[Ticket, ...]
    layout: str | None = None
    #: the printer's setting the site chooses (``auto`` unless the printer is set otherwise)
    encoding: str = "auto"
    #: the job selects every code page it uses itself: any printer setting decodes it alike
    in_band: bool = True
    #: DLE EOT n requests it holds
    status_requests: int = 0

    @property
    def ticket(self) -> Ticket:
        (only,) = self.tickets
        return only

    @property
    def lines(self) -> tuple[str, ...]:
        return self.ticket.lines

    @property
    def table(self) -> str | None:
        return self.ticket.table

    @property
    def dishes(self) -> tuple[Dish, ...]:
        return self.ticket.dishes


@dataclass(frozen=True, slots=True)
class Layout:
    """A POS's ticket layout: its jobs, and the owner's marks on the ticket of ``sample``."""

    name: str
    about: str
    jobs: tuple[Job, ...]
    sample: Job
    marks: tuple[Mark, ...]

    @property
    def tickets(self) -> tuple[Ticket, ...]:
        return tuple(t for job in self.jobs for t in job.tickets)


def _mark(lines: Sequence[str], text: str, as_: MarkAs, table: str | None = None) -> Mark:
    """The owner's mark on the line that reads ``text``."""
    return Mark(list(lines).index(text), as_, table)


# --- Square-like: big bold table, "2 x Item", modifiers "   - ...", PC437 --------------------

_Order = Sequence[tuple[int, str, Sequence[str]]]


def _square_ticket(
    p: Dummy, table: str, order: str, when: str, dishes: _Order, *, void: bool = False
) -> None:
    p.hw("INIT")  # ESC @
    p.set_with_default(align="center")
    p.text("KITCHEN\n")
    if void:
        p.set(invert=True, bold=True)  # GS B 1, ESC E 1
        p.text("*** VOID ***\n")
        p.set(invert=False, bold=False)
    p.set(bold=True, double_height=True, double_width=True)  # ESC ! 0x30: a "0" parameter
    p.text(f"Table {table}\n")
    p.set_with_default(align="left")
    p.text(f"Order #{order}\n{when}\nServer: Aisha\n{RULE}\n")
    for quantity, name, notes in dishes:
        p.set(bold=True)
        p.text(f"{quantity} x ")  # the quantity in bold: commands in the middle of the line
        p.set(bold=False)
        p.text(f"{name}\n")
        for note in notes:
            p.text(f"   - {note}\n")
    p.text(f"{RULE}\n")
    p.cut()  # ESC d 6, GS V 0


def _square(*tickets: tuple[str, str, str, _Order, bool]) -> bytes:
    p = Dummy()
    for table, order, when, dishes, void in tickets:
        _square_ticket(p, table, order, when, dishes, void=void)
    return bytes(p.output)


_SQUARE_ORDER: _Order = (
    (2, "Crème brûlée", ("Extra berries",)),
    (1, "Jalapeño Poppers", ("No sour cream", "Side of ranch")),
    (1, "Cheeseburger", ("Medium rare",)),
)

SQUARE_ORDER = Job(
    "square_order",
    "a Square-like ticket: three dishes with modifiers, accented names in PC437",
    _square(("12", "1042", "Jun 10, 2024 12:41 PM", _SQUARE_ORDER, False)),
    (
        Ticket(
            (
                "KITCHEN",
                "Table 12",
                "Order #1042",
                "Jun 10, 2024 12:41 PM",
                "Server: Aisha",
                RULE,
                "2 x Crème brûlée",
                "   - Extra berries",
                "1 x Jalapeño Poppers",
                "   - No sour cream",
                "   - Side of ranch",
                "1 x Cheeseburger",
                "   - Medium rare",
                RULE,
            ),
            "T12",
            (
                Dish(2, "Crème brûlée", ("Extra berries",)),
                Dish(1, "Jalapeño Poppers", ("No sour cream", "Side of ranch")),
                Dish(1, "Cheeseburger", ("Medium rare",)),
            ),
            "1042",
        ),
    ),
    layout="square",
)

SQUARE_VOID = Job(
    "square_void",
    "the Square-like POS voids the poppers of order 1042",
    _square(
        (
            "12",
            "1042",
            "Jun 10, 2024 12:52 PM",
            ((1, "Jalapeño Poppers", ("No sour cream", "Side of ranch")),),
            True,
        )
    ),
    (
        Ticket(
            (
                "KITCHEN",
                "*** VOID ***",
                "Table 12",
                "Order #1042",
                "Jun 10, 2024 12:52 PM",
                "Server: Aisha",
                RULE,
                "1 x Jalapeño Poppers",
                "   - No sour cream",
                "   - Side of ranch",
                RULE,
            ),
            "T12",
            (Dish(1, "Jalapeño Poppers", ("No sour cream", "Side of ranch")),),
            "1042",
            void=True,
        ),
    ),
    layout="square",
)

SQUARE_TWO = Job(
    "square_two_tickets",
    "two orders sent in one job: two tickets, each ended by its cut",
    _square(
        (
            "3",
            "1044",
            "Jun 10, 2024 12:58 PM",
            ((1, "Fish & Chips", ("Extra tartare",)),),
            False,
        ),
        (
            "14",
            "1045",
            "Jun 10, 2024 12:59 PM",
            ((2, "Cheeseburger", ("No pickles",)), (1, "Jalapeño Poppers", ())),
            False,
        ),
    ),
    (
        Ticket(
            (
                "KITCHEN",
                "Table 3",
                "Order #1044",
                "Jun 10, 2024 12:58 PM",
                "Server: Aisha",
                RULE,
                "1 x Fish & Chips",
                "   - Extra tartare",
                RULE,
            ),
            "T3",
            (Dish(1, "Fish & Chips", ("Extra tartare",)),),
            "1044",
        ),
        Ticket(
            (
                "KITCHEN",
                "Table 14",
                "Order #1045",
                "Jun 10, 2024 12:59 PM",
                "Server: Aisha",
                RULE,
                "2 x Cheeseburger",
                "   - No pickles",
                "1 x Jalapeño Poppers",
                RULE,
            ),
            "T14",
            (Dish(2, "Cheeseburger", ("No pickles",)), Dish(1, "Jalapeño Poppers")),
            "1045",
        ),
    ),
    layout="square",
    # python-escpos sends ESC t 0 once per printer object: after the second ticket's ESC @ the
    # printer is back to its own page, which must then be PC437 (the factory setting) or auto
    in_band=False,
)


# --- Epson TM-style Chinese/Malaysian POS: 桌号：5, "2 叉烧包", notes "  > 少辣" -------------


def _tm(
    table: str,
    number: str,
    when: str,
    guests: int,
    dishes: _Order,
    *,
    chinese: str,
    status: bool = False,
    cut: bool = True,
) -> bytes:
    """``chinese``: ``fs`` (GB18030 inside FS & … FS .), ``printer`` (GB18030, the printer
    being in Chinese mode from power-on, as the site says) or ``utf8`` (FS ( C)."""
    p = Dummy()
    if status:
        p._raw(STATUS_REQUEST + PAPER_REQUEST)  # the POS asks whether the printer is ready

    def line(text: str) -> None:
        if text.isascii():
            p.text(text + "\n")
        elif chinese == "fs":
            p._raw(KANJI_ON + text.encode("gb18030") + KANJI_OFF + b"\n")
        elif chinese == "printer":
            p._raw(text.encode("gb18030") + b"\n")
        else:
            p._raw(text.encode("utf-8") + b"\n")

    p.hw("INIT")  # ESC @
    if chinese == "utf8":
        p._raw(UTF8_ON)
    p.buzzer(3, 2)  # ESC B 3 2: the kitchen printer beeps
    p.set_with_default(align="center", double_height=True, double_width=True)
    line("厨房单")
    p.set_with_default(align="left", custom_size=True, width=2, height=2)  # GS ! 0x11
    line(f"桌号：{table}")
    p.set_with_default()
    line(f"单号：{number}")
    line(f"人数：{guests}")
    line(f"时间：{when}")
    line(RULE_58)
    for quantity, name, notes in dishes:
        p.set(bold=True)  # ESC E 1
        line(f"{quantity} {name}")
        p.set(bold=False)
        for note in notes:
            line(f"  > {note}")
    line(RULE_58)
    if cut:
        p.cut(mode="PART", feed=False)  # GS V 66 0: feed to the cutter and cut ("B", 0)
    else:
        p.print_and_feed(4)  # ESC d 4: feed, no cut (the staff tear the ticket off)
    return bytes(p.output)


TM_FS = Job(
    "tm_gb18030_fs",
    "a Chinese POS: GB18030 in the printer's double-byte mode (FS & … FS .)",
    _tm(
        "5",
        "0087",
        "2024-06-10 12:41",
        4,
        (
            (2, "叉烧包", ("少辣",)),
            (1, "海南鸡饭", ("不要葱", "打包")),
            (3, "Teh Tarik", ()),
        ),
        chinese="fs",
    ),
    (
        Ticket(
            (
                "厨房单",
                "桌号：5",
                "单号：0087",
                "人数：4",
                "时间：2024-06-10 12:41",
                RULE_58,
                "2 叉烧包",
                "  > 少辣",
                "1 海南鸡饭",
                "  > 不要葱",
                "  > 打包",
                "3 Teh Tarik",
                RULE_58,
            ),
            "T5",
            (
                Dish(2, "叉烧包", ("少辣",)),
                Dish(1, "海南鸡饭", ("不要葱", "打包")),
                Dish(3, "Teh Tarik"),
            ),
            "0087",
        ),
    ),
    layout="tm_chinese",
)

TM_STATUS = Job(
    "tm_status_no_cut",
    "the POS asks the printer's status first (DLE EOT 1, DLE EOT 4), prints GB18030 on a"
    " printer set to Chinese from power-on, and sends no cut",
    _tm(
        "8",
        "0088",
        "2024-06-10 12:47",
        2,
        ((2, "Nasi Lemak", ("加蛋",)), (1, "炒粿条", ("不要辣",))),
        chinese="printer",
        status=True,
        cut=False,
    ),
    (
        Ticket(
            (
                "厨房单",
                "桌号：8",
                "单号：0088",
                "人数：2",
                "时间：2024-06-10 12:47",
                RULE_58,
                "2 Nasi Lemak",
                "  > 加蛋",
                "1 炒粿条",
                "  > 不要辣",
                RULE_58,
            ),
            "T8",
            (Dish(2, "Nasi Lemak", ("加蛋",)), Dish(1, "炒粿条", ("不要辣",))),
            "0088",
            cut=False,
        ),
    ),
    layout="tm_chinese",
    encoding="gb18030",
    in_band=False,
    status_requests=2,
)

TM_UTF8 = Job(
    "tm_utf8",
    "a newer POS on a UTF-8 printer: FS ( C function 48 selects UTF-8",
    _tm(
        "11",
        "0089",
        "2024-06-10 12:50",
        3,
        ((1, "肉骨茶", ("多汤",)), (2, "Roti Canai", ("咖喱分开",))),
        chinese="utf8",
    ),
    (
        Ticket(
            (
                "厨房单",
                "桌号：11",
                "单号：0089",
                "人数：3",
                "时间：2024-06-10 12:50",
                RULE_58,
                "1 肉骨茶",
                "  > 多汤",
                "2 Roti Canai",
                "  > 咖喱分开",
                RULE_58,
            ),
            "T11",
            (Dish(1, "肉骨茶", ("多汤",)), Dish(2, "Roti Canai", ("咖喱分开",))),
            "0089",
        ),
    ),
    layout="tm_chinese",
)


TM_DRINKS = Job(
    "tm_drinks",
    "drinks whose names begin with digits, as Malaysia's 100 Plus",
    _tm(
        "6",
        "0090",
        "2024-06-10 12:55",
        2,
        ((2, "100 Plus", ()), (1, "Milo Ais", ("少糖",))),
        chinese="fs",
    ),
    (
        Ticket(
            (
                "厨房单",
                "桌号：6",
                "单号：0090",
                "人数：2",
                "时间：2024-06-10 12:55",
                RULE_58,
                "2 100 Plus",
                "1 Milo Ais",
                "  > 少糖",
                RULE_58,
            ),
            "T6",
            (Dish(2, "100 Plus"), Dish(1, "Milo Ais", ("少糖",))),
            "0090",
        ),
    ),
    layout="tm_chinese",
)


# --- Lightspeed/Toast-like: logo, QR code, "Check #1042", "Laksa x2   12.50" ---------------


def _logo() -> Image.Image:
    """The restaurant's logo, 96 by 24 dots: a frame, with a band whose raster bytes are LF,
    ESC, GS V 0 (a cut), FF, FS & and ESC @. Any real logo's raster holds such bytes; this one
    holds them for certain, so a decoder that does not skip the image's data breaks a line,
    cuts or switches to Chinese there."""
    img = Image.new("1", (96, 24), 1)
    ImageDraw.Draw(img).rectangle((0, 0, 95, 23), outline=0)
    band = b"\n\x1b\x1dV\x00\x0c\x1c&\x1b@\n\n"
    # GS v 0 prints a 1 bit black; python-escpos inverts PIL's "1" mode (1 is white) for it
    img.paste(Image.frombytes("1", (96, 1), bytes(b ^ 0xFF for b in band)), (0, 12))
    return img


def _priced(left: str, price: str) -> str:
    return left.ljust(42 - len(price)) + price


def _check(
    check: str,
    table: str,
    guests: int,
    when: str,
    dishes: Sequence[tuple[str, int, str, Sequence[str]]],
    *,
    page: str = "CP1252",
    header: str | None = None,
) -> bytes:
    p = Dummy()
    p.hw("INIT")
    quiet = contextlib.redirect_stdout(io.StringIO())  # python-escpos prints notes on stdout
    with quiet:
        p.image(_logo(), impl="bitImageRaster")  # GS v 0
    p.qr(f"https://pos.example/check/{check}", native=True)  # GS ( k: model, size, data, print
    p.charcode(page)  # ESC t 16 (WPC1252) or ESC t 2 (PC850)
    if header:
        p.set_with_default(align="center", bold=True)
        p.text(f"{header}\n")
    p.set_with_default(align="center", bold=True, double_height=True, double_width=True)
    p.text("KITCHEN\n")
    p.set_with_default(align="left")
    p.text(f"Check #{check}\n")
    p.set(bold=True)
    p.text(f"Table: {table}")
    p.set(bold=False)
    p.text(f"      Guests: {guests}\nServer: Marco\n{when}\n{RULE}\n")
    for name, quantity, price, notes in dishes:
        left = f"{name} x{quantity}"
        p.set(underline=1)  # ESC - 1: the dish underlined, its price not
        p.text(left)
        p.set(underline=0)
        p.text(_priced(left, price)[len(left) :] + "\n")
        for note in notes:
            p.text(f"   {note}\n")
    p.text(f"{RULE}\n")
    # the check's barcode, without its human-readable digits (GS H 0), then GS k 73 n data
    with quiet:
        p.barcode("{B" + check, "CODE128", function_type="B", pos="OFF")
    p.cut(mode="PART")  # ESC d 6, GS V 66 0
    return bytes(p.output)


_FIRST_ROUND = (
    ("Laksa", 2, "12.50", ("No chilli",)),
    ("Jalapeño Burger", 1, "18.00", ("Extra cheese", "No onion")),
    ("Crème brûlée", 1, "9.00", ()),
)
_FIRST_LINES = (
    "KITCHEN",
    "Check #1042",
    "Table: T7      Guests: 4",
    "Server: Marco",
    "10/06/2024 12:41",
    RULE,
    "Laksa x2                             12.50",
    "   No chilli",
    "Jalapeño Burger x1                   18.00",
    "   Extra cheese",
    "   No onion",
    "Crème brûlée x1                       9.00",
    RULE,
)
_FIRST_DISHES = (
    Dish(2, "Laksa", ("No chilli",)),
    Dish(1, "Jalapeño Burger", ("Extra cheese", "No onion")),
    Dish(1, "Crème brûlée"),
)

CHECK_FIRST = Job(
    "check_first_round",
    "a Lightspeed/Toast-like check: logo, QR code, quantity last with prices, WPC1252",
    _check("1042", "T7", 4, "10/06/2024 12:41", _FIRST_ROUND),
    (Ticket(_FIRST_LINES, "T7", _FIRST_DISHES, "1042"),),
    layout="lightspeed",
)

CHECK_REPRINT = Job(
    "check_reprint",
    "the same check printed again from the POS, under a REPRINT header",
    _check("1042", "T7", 4, "10/06/2024 12:41", _FIRST_ROUND, header="** REPRINT **"),
    (Ticket(("** REPRINT **", *_FIRST_LINES), "T7", _FIRST_DISHES, "1042"),),
    layout="lightspeed",
)

CHECK_SECOND = Job(
    "check_second_round",
    "a second round on the same check: other dishes, the same check number",
    _check(
        "1042",
        "T7",
        4,
        "10/06/2024 13:05",
        (("Teh Tarik", 2, "8.00", ("Less sugar",)), ("Crème brûlée", 1, "9.00", ())),
    ),
    (
        Ticket(
            (
                "KITCHEN",
                "Check #1042",
                "Table: T7      Guests: 4",
                "Server: Marco",
                "10/06/2024 13:05",
                RULE,
                "Teh Tarik x2                          8.00",
                "   Less sugar",
                "Crème brûlée x1                       9.00",
                RULE,
            ),
            "T7",
            (Dish(2, "Teh Tarik", ("Less sugar",)), Dish(1, "Crème brûlée")),
            "1042",
        ),
    ),
    layout="lightspeed",
)

CHECK_CP850 = Job(
    "check_cp850",
    "another till of the same POS, its printer driver set to PC850 (ESC t 2)",
    _check(
        "1043",
        "T12",
        2,
        "10/06/2024 13:10",
        (("Pão de queijo", 3, "7.50", ("Warm",)), ("Crème brûlée", 2, "18.00", ())),
        page="CP850",
    ),
    (
        Ticket(
            (
                "KITCHEN",
                "Check #1043",
                "Table: T12      Guests: 2",
                "Server: Marco",
                "10/06/2024 13:10",
                RULE,
                "Pão de queijo x3                      7.50",
                "   Warm",
                "Crème brûlée x2                      18.00",
                RULE,
            ),
            "T12",
            (Dish(3, "Pão de queijo", ("Warm",)), Dish(2, "Crème brûlée")),
            "1043",
        ),
    ),
    layout="lightspeed",
)


# --- The layouts and the owner's marks ----------------------------------------------------

_VOID_LINES = SQUARE_VOID.lines
_TM_LINES = TM_FS.lines

LAYOUTS: dict[str, Layout] = {
    "square": Layout(
        "square",
        "Square-like: big bold table, 2 x Item, modifiers led by '- '",
        (SQUARE_ORDER, SQUARE_VOID, SQUARE_TWO),
        # the owner marks the void ticket: it shows the void line besides the rest
        SQUARE_VOID,
        (
            _mark(_VOID_LINES, "Table 12", MarkAs.TABLE, "T12"),
            _mark(_VOID_LINES, "1 x Jalapeño Poppers", MarkAs.DISH),
            _mark(_VOID_LINES, "   - No sour cream", MarkAs.NOTE),
            _mark(_VOID_LINES, "Order #1042", MarkAs.TICKET),
            _mark(_VOID_LINES, "*** VOID ***", MarkAs.VOID),
            _mark(_VOID_LINES, RULE, MarkAs.IGNORE),
        ),
    ),
    "tm_chinese": Layout(
        "tm_chinese",
        "Epson TM-style Chinese/Malaysian POS: 桌号：5, 2 叉烧包, notes '  > 少辣'",
        (TM_FS, TM_STATUS, TM_UTF8, TM_DRINKS),
        TM_FS,
        (
            _mark(_TM_LINES, "桌号：5", MarkAs.TABLE, "T5"),
            _mark(_TM_LINES, "2 叉烧包", MarkAs.DISH),
            _mark(_TM_LINES, "  > 少辣", MarkAs.NOTE),
            _mark(_TM_LINES, "单号：0087", MarkAs.TICKET),
        ),
    ),
    "lightspeed": Layout(
        "lightspeed",
        "Lightspeed/Toast-like: Check #1042, Table: T7, Laksa x2   12.50",
        (CHECK_FIRST, CHECK_REPRINT, CHECK_SECOND, CHECK_CP850),
        CHECK_FIRST,
        (
            _mark(_FIRST_LINES, "Table: T7      Guests: 4", MarkAs.TABLE, "T7"),
            _mark(_FIRST_LINES, "Laksa x2                             12.50", MarkAs.DISH),
            _mark(_FIRST_LINES, "   No chilli", MarkAs.NOTE),
            _mark(_FIRST_LINES, "Check #1042", MarkAs.TICKET),
        ),
    ),
}


# --- Jobs that are no ticket of any layout --------------------------------------------------

#: Commands cut short by the end of a job (a POS that crashed, a connection that dropped): each
#: claims parameters or data the job does not hold.
TRUNCATED: dict[str, bytes] = {
    "ESC alone": b"\x1b",
    "ESC ! without n": b"\x1b!",
    "ESC t without n": b"\x1bt",
    "ESC * image short of its columns": b"\x1b*\x21\xc8\x00\xff\xff",
    "GS v 0 short of its size": b"\x1dv0\x00\x30",
    "GS v 0 short of its data": b"\x1dv0\x00\xff\xff\xff\xff\x00\x01",
    "GS ( k short of its data": b"\x1d(k\xff\xff1P0https",
    "GS k barcode without its NUL": b"\x1dk\x041042",
    "GS V 66 without n": b"\x1dVB",
    "FS ( C short": b"\x1c(C\x02",
    "FS q short of its image": b"\x1cq\x01\x10\x00\x10\x00\xff",
    "DLE EOT without n": b"\x10\x04",
    "DLE DC4 short": b"\x10\x14\x08\x01",
    "ESC & short of its characters": b"\x1b&\x03\x20\x7e\x0c",
}


def _garbled() -> bytes:
    """Line noise: random bytes (a fixed seed), and a command cut short at the end."""
    rng = random.Random(33)
    return rng.randbytes(1500) + TRUNCATED["GS ( k short of its data"]


#: Random bytes from a fixed seed, ending in a truncated command: no ticket of anyone's.
GARBLED = Job(
    "garbled",
    "random bytes (seed 33) ending in a GS ( k cut short",
    _garbled(),
    (),
    in_band=False,
)

#: Every job that is a ticket of a layout.
JOBS: tuple[Job, ...] = tuple(job for layout in LAYOUTS.values() for job in layout.jobs)
