"""The owner's ticket pattern: which printed line holds the table, which lines are dishes.

Every point of sale lays its kitchen ticket out its own way (Epson's kitchen display ships a
parser per POS for that reason). serveur does not guess a layout: the owner shows it one real
ticket, marks the line that holds the table (and says which table it is), one dish line, and
if they like a note under a dish, the line with the ticket's number, the words of a void
ticket and lines to ignore. :func:`propose` turns those marks into a :class:`TicketPattern`
of regular expressions; :meth:`TicketPattern.read` applies it to any ticket, and the console
previews it on every ticket kept, so the owner sees before saving what it reads and what it
does not.

What a pattern reads (:class:`Reading`):

* the **table**: the value after the table line's label (``Table: 12``, ``TBL 12``, ``桌 12``),
  with the prefix that makes it a waypoint's name (the owner said ``12`` is ``T12``: prefix
  ``T``);
* **dishes**: lines shaped like the marked one: the quantity first (``2 x Laksa``, ``2 Laksa``,
  ``2  Laksa   12.50``) or last (``Laksa x2``), at the marked line's indentation; a price at
  the end is not part of the name;
* **notes**: lines under a dish, indented deeper or led by a mark (``- no chilli``,
  ``  + extra egg``, ``> well done``);
* the **ticket's number** (optional): what makes two rounds of one check two tickets;
* **void**: a ticket holding the void line's words withdraws its dishes instead of ordering
  them.

A ticket without a table or without a dish is not understood: the problem is said in words
and staff see the ticket as it printed.
"""

from __future__ import annotations

import hashlib
import json
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any, Final

__all__ = [
    "DishLine",
    "Mark",
    "MarkAs",
    "PatternError",
    "Reading",
    "TicketPattern",
    "propose",
]

#: A note line: deeper than the dishes, or led by one of these marks.
_NOTE_MARKS: Final = "-+*>~•=("
#: A price at a dish line's end (``12.50``, ``RM12.50``, ``$ 3,00``): not part of the name.
_PRICE: Final = r"(?:\s+[^\s\d]{0,3}\s?\d+[.,]\d{2})?"
#: "x", "X", U+00D7 (the multiplication sign tills print) or "*" between a quantity and a name.
_TIMES: Final = "[xX\u00d7*]"
#: A dish's name: it holds a letter somewhere ("100 Plus", a drink, starts with digits).
_NAME: Final = r"(?P<name>(?=[^\n]*[^\W\d_])[^\W_][^\n]*?)"
_QTY_FIRST: Final = r"(?P<qty>\d{1,2})(?:\s*" + _TIMES + r")?\s+" + _NAME + _PRICE + r"\s*$"
_QTY_LAST: Final = _NAME + r"\s*" + _TIMES + r"\s*(?P<qty>\d{1,2})" + _PRICE + r"\s*$"
_SHAPES: Final = (_QTY_FIRST, _QTY_LAST)
_MAX_LINES: Final = 400
#: A note line, unless the owner marked one: led by a mark, or indented two spaces or more.
#: A note holds a letter or a digit: a rule of dashes under the dishes is not a note.
_NOTE_TEXT: Final = r"(?P<note>[^\s\w]*\w.*?)"
DEFAULT_NOTE: Final = r"^(?:\s*[-+*>~•=(]+\s*|\s{2,})" + _NOTE_TEXT + r"\s*$"


class PatternError(ValueError):
    """The marks do not make a pattern (said in words for the owner)."""


class MarkAs(StrEnum):
    TABLE = "table"
    DISH = "dish"
    NOTE = "note"
    TICKET = "ticket"
    VOID = "void"
    IGNORE = "ignore"


@dataclass(frozen=True, slots=True)
class Mark:
    """The owner's mark on one line of a ticket; ``table`` is the waypoint a table line means."""

    line: int
    as_: MarkAs
    table: str | None = None


@dataclass(frozen=True, slots=True)
class DishLine:
    quantity: int
    name: str
    notes: tuple[str, ...] = ()
    line: int = 0

    def as_dict(self) -> dict[str, Any]:
        return {
            "quantity": self.quantity,
            "name": self.name,
            "notes": list(self.notes),
            "line": self.line,
        }


@dataclass(frozen=True, slots=True)
class Reading:
    """What a pattern read on one ticket. ``problem`` set: not understood."""

    table: str | None
    dishes: tuple[DishLine, ...]
    ticket: str | None = None
    void: bool = False
    problem: str | None = None

    @property
    def understood(self) -> bool:
        return self.problem is None

    def key(self) -> str:
        """The ticket's identity: a reprint reads the same, a second round of the same check
        differs (other dishes, or another ticket number)."""
        body = json.dumps(
            [
                self.ticket,
                self.table,
                self.void,
                [(d.quantity, d.name, d.notes) for d in self.dishes],
            ],
            ensure_ascii=False,
        )
        return "till-" + hashlib.sha256(body.encode()).hexdigest()[:32]

    def as_dict(self) -> dict[str, Any]:
        return {
            "table": self.table,
            "ticket": self.ticket,
            "void": self.void,
            "dishes": [d.as_dict() for d in self.dishes],
            "problem": self.problem,
        }


def _compile(expr: str | None, what: str) -> re.Pattern[str] | None:
    if not expr:
        return None
    try:
        return re.compile(expr, re.IGNORECASE)
    except re.error as exc:
        raise PatternError(f"the {what} rule is not a valid expression: {exc}") from None


@dataclass(frozen=True, slots=True)
class TicketPattern:
    """Regular expressions (Python's ``re``, case-insensitive) over a ticket's lines."""

    table: str
    dish: str
    table_prefix: str = ""
    note: str = DEFAULT_NOTE
    ticket: str | None = None
    void: str | None = None
    ignore: tuple[str, ...] = ()
    _compiled: dict[str, Any] = field(default_factory=dict, compare=False, repr=False)

    def __post_init__(self) -> None:
        c = self._compiled
        c["table"] = _compile(self.table, "table")
        c["dish"] = _compile(self.dish, "dish")
        c["note"] = _compile(self.note, "note")
        c["ticket"] = _compile(self.ticket, "ticket number")
        c["void"] = _compile(self.void, "void")
        c["ignore"] = [_compile(x, "ignore") for x in self.ignore]
        for name, group in (("table", "table"), ("dish", "name"), ("note", "note")):
            rx = c[name]
            if rx is None or group not in rx.groupindex:
                raise PatternError(f"the {name} rule must capture (?P<{group}>...)")
        if "qty" not in c["dish"].groupindex:
            raise PatternError("the dish rule must capture (?P<qty>...)")
        if c["ticket"] is not None and "ticket" not in c["ticket"].groupindex:
            raise PatternError("the ticket number rule must capture (?P<ticket>...)")

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> TicketPattern:
        known = {"table", "dish", "table_prefix", "note", "ticket", "void", "ignore"}
        extra = set(data) - known
        if extra:
            raise PatternError(f"a pattern has no {', '.join(sorted(extra))}")
        try:
            return cls(
                table=str(data["table"]),
                dish=str(data["dish"]),
                table_prefix=str(data.get("table_prefix") or ""),
                note=str(data.get("note") or DEFAULT_NOTE),
                ticket=data.get("ticket") or None,
                void=data.get("void") or None,
                ignore=tuple(str(x) for x in data.get("ignore") or ()),
            )
        except KeyError as exc:
            raise PatternError(f"a pattern needs its {exc.args[0]} rule") from None

    def as_dict(self) -> dict[str, Any]:
        return {
            "table": self.table,
            "dish": self.dish,
            "table_prefix": self.table_prefix,
            "note": self.note,
            "ticket": self.ticket,
            "void": self.void,
            "ignore": list(self.ignore),
        }

    def read(self, lines: Sequence[str]) -> Reading:
        """Read a ticket's lines (as :mod:`serveur.till.escpos` printed them)."""
        c = self._compiled
        table: str | None = None
        ticket: str | None = None
        void = False
        dishes: list[DishLine] = []
        notes: list[str] = []
        for i, line in enumerate(lines[:_MAX_LINES]):
            if any(rx.search(line) for rx in c["ignore"]):
                continue
            if c["void"] is not None and c["void"].search(line):
                void = True
                continue
            if ticket is None and c["ticket"] is not None:
                m = c["ticket"].search(line)
                if m:
                    ticket = m.group("ticket").strip()
                    continue
            if table is None:
                m = c["table"].search(line)
                if m:
                    table = self.table_prefix + m.group("table").strip()
                    continue
            m = c["dish"].match(line)
            if m:
                if dishes:
                    dishes[-1] = _with_notes(dishes[-1], notes)
                notes = []
                qty = int(m.group("qty"))
                name = " ".join(m.group("name").split())
                if qty >= 1:
                    dishes.append(DishLine(qty, name, (), i))
                continue
            if dishes:
                m = c["note"].match(line)
                if m:
                    notes.append(" ".join(m.group("note").split()))
        if dishes:
            dishes[-1] = _with_notes(dishes[-1], notes)
        problem = None
        if table is None:
            problem = "no line holds the table"
        elif not dishes:
            problem = "no line reads as a dish"
        return Reading(table, tuple(dishes), ticket, void, problem)


def _with_notes(dish: DishLine, notes: list[str]) -> DishLine:
    return DishLine(dish.quantity, dish.name, tuple(notes), dish.line) if notes else dish


def _flexible(text: str) -> str:
    """``text`` as a literal, any run of spaces matching any run, digits matching digits."""
    parts = [re.escape(p) for p in text.split()]
    expr = r"\s+".join(parts)
    return re.sub(r"(?:\d)+", r"\\d+", expr)


def _label_rule(line: str, value_at: int, group: str) -> str:
    """A rule that finds ``(?P<group>...)`` after the line's label (what precedes the value)."""
    label = line[:value_at].strip()
    if not label:
        return rf"^\s*(?P<{group}>\w{{1,8}})\s*$"
    # The label's last characters are punctuation often (``Table:``, ``Tbl#``, a full-width colon).
    return rf"^\s*{_flexible(label)}\s*(?P<{group}>\w+)"


def _table_rule(line: str, table: str) -> tuple[str, str]:
    """(rule, prefix) for a line the owner says holds ``table``."""
    want = table.casefold()
    words = list(re.finditer(r"\w+", line))
    for m in reversed(words):
        if m.group().casefold() == want:
            return _label_rule(line, m.start(), "table"), ""
    ends = [m for m in words if want.endswith(m.group().casefold())]
    if ends:  # the longest: "12" in "Table 12, guests 2" for T12, not the "2"
        m = max(ends, key=lambda w: (len(w.group()), w.start()))
        return _label_rule(line, m.start(), "table"), table[: len(table) - len(m.group())]
    raise PatternError(f"the line {line.strip()!r} does not hold the table {table}")


def _dish_rule(line: str) -> str:
    indent = len(line) - len(line.lstrip(" "))
    lead = rf"^ {{{indent}}}(?=\S)" if indent else r"^(?=\S)"
    for shape in _SHAPES:
        rule = lead + shape
        if re.match(rule, line):
            return rule
    raise PatternError(
        f"the line {line.strip()!r} does not read as a dish: it needs a quantity first"
        " (2 x Laksa, 2 Laksa) or last (Laksa x2)"
    )


def _note_rule(line: str, dish_indent: int) -> str:
    stripped = line.lstrip()
    indent = len(line) - len(stripped)
    if stripped and stripped[0] in _NOTE_MARKS:
        mark = re.escape(stripped[0])
        return rf"^\s*{mark}+\s*{_NOTE_TEXT}\s*$"
    if indent > dish_indent:
        return rf"^\s{{{indent}}}{_NOTE_TEXT}\s*$"
    raise PatternError(
        f"the line {line.strip()!r} is not set apart from the dishes: a note is indented"
        " deeper or led by a mark (-, +, >)"
    )


def propose(lines: Sequence[str], marks: Sequence[Mark]) -> TicketPattern:
    """The pattern the owner's marks on one ticket mean. It needs a table and a dish mark."""

    def line_of(mark: Mark) -> str:
        if not 0 <= mark.line < len(lines):
            raise PatternError(f"the ticket has no line {mark.line + 1}")
        return lines[mark.line]

    by = {m.as_: m for m in marks}
    table_mark, dish_mark = by.get(MarkAs.TABLE), by.get(MarkAs.DISH)
    if table_mark is None or not table_mark.table:
        raise PatternError("mark the line that holds the table, and say which table it is")
    if dish_mark is None:
        raise PatternError("mark one line that is a dish")
    table, prefix = _table_rule(line_of(table_mark), table_mark.table)
    dish_line = line_of(dish_mark)
    dish = _dish_rule(dish_line)
    rest: dict[str, Any] = {}
    note_mark = by.get(MarkAs.NOTE)
    if note_mark is not None:
        dish_indent = len(dish_line) - len(dish_line.lstrip(" "))
        rest["note"] = _note_rule(line_of(note_mark), dish_indent)
    ticket_mark = by.get(MarkAs.TICKET)
    if ticket_mark is not None:
        text = line_of(ticket_mark)
        numbers = list(re.finditer(r"\w*\d\w*", text))
        if not numbers:
            raise PatternError(f"the line {text.strip()!r} holds no ticket number")
        rest["ticket"] = _label_rule(text, numbers[-1].start(), "ticket")
    void_mark = by.get(MarkAs.VOID)
    if void_mark is not None:
        words = re.sub(r"[^\w\s]", " ", line_of(void_mark)).split()
        if not words:
            raise PatternError("the void line holds no words")
        rest["void"] = r"\b" + r"\W+".join(re.escape(w) for w in words) + r"\b"
    ignore = [
        rf"^\s*{_flexible(line_of(m))}\s*$"
        for m in marks
        if m.as_ is MarkAs.IGNORE and line_of(m).strip()
    ]
    pattern = TicketPattern(
        table=table, dish=dish, table_prefix=prefix, ignore=tuple(ignore), **rest
    )
    got = pattern.read(lines)
    if got.table != table_mark.table:
        raise PatternError(
            f"with these marks the ticket reads table {got.table}, not {table_mark.table}:"
            " mark lines above the table line that look like it as ignored"
        )
    if all(d.line != dish_mark.line for d in got.dishes):
        raise PatternError("with these marks the dish line is not read as a dish")
    return pattern
