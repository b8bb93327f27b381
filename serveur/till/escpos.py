"""A kitchen printer's job read back as text: ESC/POS commands stripped, code pages decoded.

A point of sale prints a kitchen ticket by opening a raw TCP connection to the printer (port
9100) and sending ESC/POS: text bytes in the printer's current code page, mixed with commands
(bold, double size, alignment, a logo, a barcode, the cut). What the kitchen reads on paper is
the text; this module recovers it, line by line, as the printer would print it.

What it models, from Epson's ESC/POS command reference (the TM-series "Commands" chapters, as
mirrored by the manuals of compatible printers: HPRT, POSBANK, Citizen):

* every command's length, so that a command's parameters are never taken for text: fixed
  parameters (``ESC ! n``), counted data (``GS v 0`` raster images, ``GS ( k`` QR codes,
  ``ESC *`` bit images), NUL-terminated data (``GS k`` barcodes of the first kind,
  ``ESC D`` tab stops);
* the character code table: ``ESC t n`` selects a single-byte page (``n`` as Epson numbers
  them, 0 = PC437, 2 = PC850, 16 = WPC1252...), ``FS &`` / ``FS .`` enter and leave the
  double-byte mode in which Chinese printers read GB18030, and ``FS ( C`` function 48 selects
  UTF-8; before any of them the printer's own setting applies (the site says which). A
  printer set to Chinese is in double-byte mode from power-on: ``ESC t`` changes only the
  single-byte page it uses once ``FS .`` leaves that mode (PC437 until then). ``ESC @`` clears
  the line not yet printed and goes back to the printer's own setting, as at power-on;
* ``ESC d n`` prints the line and feeds ``n`` lines: the blank ones are lines of the ticket
  (up to 8: a longer feed comes before a cut);
* the cut (``GS V``, and the older ``ESC i`` / ``ESC m``) ends a ticket: a job may carry
  several tickets, and the text after the last cut is a ticket only if it holds any;
* real-time status requests (``DLE EOT n``): a POS may ask whether the printer is online
  before it sends; :func:`status_replies` says what an online printer with paper answers, for
  the tap that stands in for a printer (mirror mode).

An unknown command is skipped (its two bytes) and counted, never shown as text: a ticket full
of them is reported as not understood by the pattern, not silently misread. No control
character reaches the text (a DEL, or a C1 control in UTF-8, prints nothing here).

Not modelled: where ``ESC $`` / ``ESC \\`` (absolute and relative print positions) move the
text along the line, and the international character sets of ``ESC R``. Points of sale pad
their columns with spaces; one that positions them by command prints its columns run together
here.
"""

from __future__ import annotations

import codecs
import unicodedata
from dataclasses import dataclass, field
from typing import Final

__all__ = [
    "CODE_PAGES",
    "ENCODINGS",
    "PrintedTicket",
    "decode_job",
    "status_replies",
]

ESC: Final = 0x1B
GS: Final = 0x1D
FS: Final = 0x1C
DLE: Final = 0x10

#: ``ESC t n``: Epson's numbers for the single-byte pages Python can decode.
CODE_PAGES: Final[dict[int, str]] = {
    0: "cp437",
    2: "cp850",
    3: "cp860",
    4: "cp863",
    5: "cp865",
    13: "cp857",
    14: "cp737",
    15: "iso8859_7",
    16: "cp1252",
    17: "cp866",
    18: "cp852",
    19: "cp858",
    32: "cp720",
    33: "cp775",
    34: "cp855",
    35: "cp861",
    36: "cp862",
    37: "cp864",
    38: "cp869",
    39: "iso8859_2",
    40: "iso8859_15",
    44: "cp1125",
    45: "cp1250",
    46: "cp1251",
    47: "cp1253",
    48: "cp1254",
    49: "cp1255",
    50: "cp1256",
    51: "cp1257",
    52: "cp1258",
}
#: What the site may say its printer uses before any command: ``auto`` is UTF-8 where the
#: bytes are valid UTF-8, else PC437 (the factory setting of Epson's printers).
ENCODINGS: Final = ("auto", "cp437", "cp850", "cp1252", "gb18030", "utf-8")

# Commands of fixed length: the number of parameter bytes after ``ESC x`` / ``GS x`` / ``FS x``.
_ESC_FIXED: Final[dict[int, int]] = {
    **dict.fromkeys(b"2<LSivm", 0),
    **dict.fromkeys(b"!-EGMaRKe3{Vr %T=?Uun", 1),
    **dict.fromkeys(b"$\\cB", 2),
    ord("p"): 3,
    ord("W"): 8,
}
_GS_FIXED: Final[dict[int, int]] = {
    **dict.fromkeys(b":", 0),
    **dict.fromkeys(b"!BHhwfarIb/ET", 1),
    **dict.fromkeys(b"LW$\\PA", 2),
    ord("^"): 3,
    ord("g"): 4,  # GS g 0 m nL nH, GS g 2 m nL nH: maintenance counters (Epson, "GS g 0")
}
_FS_FIXED: Final[dict[int, int]] = {
    **dict.fromkeys(b"&.", 0),
    **dict.fromkeys(b"!-CW", 1),
    **dict.fromkeys(b"Sp", 2),
}
_CUTS_ESC: Final = frozenset(b"im")
#: Blank lines ``ESC d n`` adds at most: a longer feed is paper before a cut, not a ticket's
#: lines (and a job of ``ESC d 255`` would otherwise make 85 lines of each of its bytes).
_MAX_FEED: Final = 8
_UNPRINTED: Final = frozenset(("Cc", "Zl", "Zp"))


@dataclass(frozen=True, slots=True)
class PrintedTicket:
    """One ticket of a job, as it printed: its lines (trailing blanks trimmed), whether a cut
    ended it, and how many commands were not recognised (a garbled job has many)."""

    lines: tuple[str, ...]
    cut: bool
    unknown: int = 0

    @property
    def text(self) -> str:
        return "\n".join(self.lines)


#: The single-byte page of a printer whose own setting is double-byte or UTF-8 (Epson's
#: factory setting, which Chinese printers keep for their single-byte table).
_FACTORY_PAGE: Final = "cp437"


@dataclass(slots=True)
class _Reader:
    fallback: str  # the printer's own setting (ENCODINGS)
    page: str | None = None  # chosen by ESC t, else the setting's single-byte page
    double: bool = False  # FS &: GB18030
    utf8: bool = False  # FS ( C fn 48
    runs: list[tuple[bytes, str]] = field(default_factory=list)
    run: bytearray = field(default_factory=bytearray)
    run_enc: str = ""
    lines: list[str] = field(default_factory=list)
    tickets: list[PrintedTicket] = field(default_factory=list)
    unknown: int = 0

    def __post_init__(self) -> None:
        self.power_on()

    def power_on(self) -> None:
        """The modes the printer's own setting gives it, before any command (and after ESC @).

        A printer set to Chinese "enters Chinese character mode automatically" at power-on
        and reads every byte one at a time only after FS . (HCC POS80B and SurePrint SP91
        manuals, FS & / FS .); ESC @ "resets the printer modes to those in effect when the
        power was turned on" (Epson TM-T88III specification)."""
        self.page = None
        self.double = self.fallback == "gb18030"
        self.utf8 = self.fallback == "utf-8"

    def encoding(self) -> str:
        if self.utf8:
            return "utf-8"
        if self.double:
            return "gb18030"
        if self.page is not None:
            return self.page
        if self.fallback in ("gb18030", "utf-8"):
            return _FACTORY_PAGE
        return self.fallback

    def clear_line(self) -> None:
        """ESC @ clears the print buffer: the line not yet printed is never printed."""
        self.run = bytearray()
        self.runs = []

    def text(self, byte: int) -> None:
        enc = self.encoding()
        if enc != self.run_enc:
            self._close_run()
            self.run_enc = enc
        self.run.append(byte)

    def _close_run(self) -> None:
        if self.run:
            self.runs.append((bytes(self.run), self.run_enc))
            self.run = bytearray()

    def end_line(self) -> None:
        self._close_run()
        text = "".join(_decode(b, enc) for b, enc in self.runs).expandtabs(8)
        self.lines.append(_printable(text).rstrip())
        self.runs = []

    def cut(self, *, by_cut: bool) -> None:
        if self.run or self.runs:
            self.end_line()
        printed = [k for k, line in enumerate(self.lines) if line.strip()]
        if printed:  # blank lines before the first and after the last are paper, not lines
            lines = tuple(self.lines[printed[0] : printed[-1] + 1])
            self.tickets.append(PrintedTicket(lines, by_cut, self.unknown))
        self.lines = []
        self.unknown = 0


def _printable(text: str) -> str:
    """``text`` without control characters (a printer prints nothing for them) nor Unicode's
    line and paragraph separators (a line stays one line wherever it is shown)."""
    if text.isprintable():
        return text
    return "".join(c for c in text if unicodedata.category(c) not in _UNPRINTED)


def _decode(data: bytes, enc: str) -> str:
    if enc == "auto":
        try:
            return data.decode("utf-8")
        except UnicodeDecodeError:
            enc = "cp437"
    return codecs.decode(data, enc, errors="replace")


def _at(data: bytes, i: int) -> int:
    return data[i] if i < len(data) else 0


def _until_nul(data: bytes, i: int) -> int:
    end = data.find(b"\x00", i)
    return len(data) if end < 0 else end + 1


def _counted(data: bytes, i: int, width: int = 2) -> int:
    """Index after ``pL pH [...]`` data at ``i`` (little-endian length of ``width`` bytes)."""
    size = int.from_bytes(data[i : i + width], "little")
    return i + width + size


def _esc(r: _Reader, data: bytes, i: int) -> int:
    """Carry out the ESC command at ``data[i]`` (the ESC byte); return the index after it."""
    op = _at(data, i + 1)
    if op == ord("@"):  # ESC @: clears the print buffer, modes as at power-on
        r.clear_line()
        r.power_on()
        return i + 2
    if op == ord("t"):
        page = _at(data, i + 2)
        r.page = CODE_PAGES.get(page)
        if r.page is None:
            r.unknown += 1
        return i + 3
    if op in _CUTS_ESC:
        r.cut(by_cut=True)
        return i + 2
    if op == ord("d"):  # ESC d n: print the line, feed n lines (n = 0: print, no feed)
        r.end_line()
        for _ in range(min(_at(data, i + 2), _MAX_FEED) - 1):
            r.end_line()
        return i + 3
    if op == ord("J"):  # ESC J n: print the line, feed n dots
        r.end_line()
        return i + 3
    if op in _ESC_FIXED:
        return i + 2 + _ESC_FIXED[op]
    if op == ord("*"):  # bit image: m nL nH, then n columns of 1 (8-dot) or 3 (24-dot) bytes
        m = _at(data, i + 2)
        columns = int.from_bytes(data[i + 3 : i + 5], "little")
        return i + 5 + columns * (1 if m in (0, 1) else 3)
    if op == ord("D"):  # tab stops, NUL-terminated
        return _until_nul(data, i + 2)
    if op == ord("("):  # ESC ( fn pL pH data
        return _counted(data, i + 3)
    if op == ord("&"):  # user-defined characters: y c1 c2, then per character x and y*x bytes
        y, c1, c2 = _at(data, i + 2), _at(data, i + 3), _at(data, i + 4)
        j = i + 5
        for _ in range(max(0, c2 - c1 + 1)):
            j += 1 + y * _at(data, j)
        return j
    r.unknown += 1
    return i + 2


def _gs(r: _Reader, data: bytes, i: int) -> int:
    op = _at(data, i + 1)
    if op == ord("V"):  # cut: m, and n after m in 65, 66, 97, 98, 103, 104
        m = _at(data, i + 2)
        r.cut(by_cut=True)
        return i + (4 if m in (65, 66, 97, 98, 103, 104) else 3)
    if op in _GS_FIXED:
        return i + 2 + _GS_FIXED[op]
    if op == ord("v"):  # GS v 0 m xL xH yL yH: raster image of x bytes by y dots
        x = int.from_bytes(data[i + 4 : i + 6], "little")
        y = int.from_bytes(data[i + 6 : i + 8], "little")
        return i + 8 + x * y
    if op == ord("("):  # GS ( fn pL pH data: QR codes, graphics, settings
        return _counted(data, i + 3)
    if op == ord("8"):  # GS 8 L p1 p2 p3 p4 data: large graphics
        return _counted(data, i + 3, width=4)
    if op == ord("k"):  # barcode: m 0-6 NUL-terminated, m 65-79 counted by n
        m = _at(data, i + 2)
        if m <= 6:
            return _until_nul(data, i + 3)
        return i + 4 + _at(data, i + 3)
    if op == ord("*"):  # downloaded bit image: x y, then x*y*8 bytes
        return i + 4 + _at(data, i + 2) * _at(data, i + 3) * 8
    r.unknown += 1
    return i + 2


def _fs(r: _Reader, data: bytes, i: int) -> int:
    op = _at(data, i + 1)
    if op == ord("&"):
        r.double = True
    elif op == ord("."):
        r.double = False
    if op in _FS_FIXED:
        return i + 2 + _FS_FIXED[op]
    if op == ord("("):  # FS ( fn pL pH data; FS ( C fn=48 m: 1 one-byte, 2 UTF-8
        end = _counted(data, i + 3)
        if _at(data, i + 2) == ord("C") and _at(data, i + 5) == 48:
            m = _at(data, i + 6)
            if m in (2, 50):
                r.utf8 = True
            elif m in (1, 49):
                r.utf8 = False
        return end
    if op == ord("2"):  # a user-defined Kanji character: c1 c2 and 72 bytes
        return i + 4 + 72
    if op == ord("q"):  # FS q n [xL xH yL yH d1...dk]1...n, k = x*y*8 (Epson TM spec, FS q)
        j = i + 3
        for _ in range(_at(data, i + 2)):
            if j >= len(data):
                break
            x = int.from_bytes(data[j : j + 2], "little")
            y = int.from_bytes(data[j + 2 : j + 4], "little")
            j += 4 + x * y * 8
        return j
    r.unknown += 1
    return i + 2


def _dle(r: _Reader, data: bytes, i: int) -> int:
    op = _at(data, i + 1)
    if op in (0x04, 0x05):  # DLE EOT n, DLE ENQ n: real-time requests, nothing printed
        return i + 3
    # DLE DC4 fn m t: pulse, power off; fn = 8, clear buffers: fn d1...d7 (Epson's ESC/POS
    # reference, "DLE DC4 (fn = 8)")
    if op == 0x14:
        return i + (10 if _at(data, i + 2) == 8 else 5)
    r.unknown += 1
    return i + 2


_COMMANDS: Final = {ESC: _esc, GS: _gs, FS: _fs, DLE: _dle}


def decode_job(data: bytes, encoding: str = "auto") -> list[PrintedTicket]:
    """The tickets of one print job, as printed. ``encoding`` is the printer's setting before
    any code page command (:data:`ENCODINGS`)."""
    if encoding not in ENCODINGS:
        raise ValueError(f"unknown printer encoding {encoding!r}")
    r = _Reader(fallback=encoding)
    i, n = 0, len(data)
    while i < n:
        b = data[i]
        command = _COMMANDS.get(b)
        if command is not None:
            i = command(r, data, i)
            continue
        if b == 0x0A or b == 0x0C:  # LF; FF ends a page-mode page
            r.end_line()
        elif b == 0x09 or b >= 0x20:
            r.text(b)
        # CR and the other control bytes print nothing
        i += 1
    r.cut(by_cut=False)
    return r.tickets


def status_replies(data: bytes) -> bytes:
    """What an online printer with paper and no error answers to the real-time status
    requests in ``data`` (``DLE EOT n``): one byte each, bits 1 and 4 set as Epson fixes them,
    every flag clear (0x12). Other bytes ask nothing."""
    out = bytearray()
    start = 0
    while (i := data.find(b"\x10\x04", start)) >= 0 and i + 2 < len(data):
        if 1 <= data[i + 2] <= 5:
            out.append(0x12)
        start = i + 3
    return bytes(out)
