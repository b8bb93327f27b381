"""The till's names for items matched to the dishes on serveur's menu.

A till prints what its own menu calls an item ("NASI LEMAK AYAM", "Nasi lemak (ayam)", "NL
Ayam"); serveur's menu may say "Nasi lemak ayam". The owner maps the one to the other once,
from an import of the till's menu as CSV or from the names the tickets printed; this module
says which menu dish a till name means when the owner has not said (the same letters, case and
spacing aside) and suggests the likeliest dishes when it cannot tell.

Suggestions are rapidfuzz's ``WRatio`` (a weighted mix of whole, partial and token-sorted
ratios: "Ayam nasi lemak" against "Nasi lemak ayam" scores as a match where a plain edit
distance would not), best first, from a score of :data:`SUGGEST_FROM` of 100.
"""

from __future__ import annotations

import csv
import io
from collections.abc import Iterable, Mapping
from dataclasses import dataclass
from typing import Final

from rapidfuzz import fuzz, process, utils

__all__ = ["SUGGEST_FROM", "MenuRow", "dish_for", "fold", "parse_menu_csv", "suggest"]

SUGGEST_FROM: Final = 60.0
MAX_ROWS: Final = 2000
_TILL_COLUMNS: Final = ("till", "pos", "pos name", "pos_name", "item", "name", "till name")
_DISH_COLUMNS: Final = ("dish", "serveur", "menu", "serveur dish")


def fold(name: str) -> str:
    """A name as compared: case and runs of spaces aside."""
    return " ".join(name.split()).casefold()


def dish_for(name: str, names: Mapping[str, str], menu: Iterable[str]) -> str | None:
    """The menu dish a till name means: the owner's mapping, else a menu dish spelt the same
    (case and spacing aside), else None."""
    key = fold(name)
    for till, dish in names.items():
        if fold(till) == key:
            return dish
    for dish in menu:
        if fold(dish) == key:
            return dish
    return None


def suggest(name: str, menu: Iterable[str], limit: int = 3) -> list[str]:
    """The menu dishes most like ``name``, best first."""
    found = process.extract(
        name,
        list(menu),
        scorer=fuzz.WRatio,
        processor=utils.default_process,
        limit=limit,
        score_cutoff=SUGGEST_FROM,
    )
    return [str(choice) for choice, _, _ in found]


@dataclass(frozen=True, slots=True)
class MenuRow:
    till: str
    dish: str | None


def parse_menu_csv(text: str) -> list[MenuRow]:
    """The rows of a till's menu export: a header row naming the till's item column (``till``,
    ``pos``, ``item``, ``name``...) and, optionally, serveur's dish (``dish``). Raises
    ValueError, in words, when no column holds the till's names."""
    sample = text[:4096]
    try:
        dialect: type[csv.Dialect] | csv.Dialect = csv.Sniffer().sniff(sample, ",;\t")
    except csv.Error:
        dialect = csv.excel
    reader = csv.reader(io.StringIO(text), dialect)
    header = next(reader, None)
    if header is None:
        raise ValueError("the file is empty")
    cols = [fold(h) for h in header]
    till_col = next((cols.index(c) for c in _TILL_COLUMNS if c in cols), None)
    if till_col is None:
        raise ValueError(
            "no column of the first row is named for the till's items (till, pos, item or name)"
        )
    dish_col = next((cols.index(c) for c in _DISH_COLUMNS if c in cols), None)
    rows: list[MenuRow] = []
    seen: set[str] = set()
    for record in reader:
        if len(rows) >= MAX_ROWS:
            raise ValueError(f"the file has more than {MAX_ROWS} items")
        till = " ".join(record[till_col].split()) if till_col < len(record) else ""
        if not till or fold(till) in seen:
            continue
        seen.add(fold(till))
        dish = record[dish_col].strip() if dish_col is not None and dish_col < len(record) else ""
        rows.append(MenuRow(till[:200], dish[:200] or None))
    return rows
