"""Periods of a service in local time: hours, service days, and dates given on a command line.

Pure. Events carry epoch seconds (UTC); the restaurant thinks in its own clock. ``tz`` is a
fixed offset (:func:`parse_offset`, ``--utc-offset +02:00``) or ``None`` for the machine's
local time (daylight saving included). A *service day* runs from ``day_start`` (hours after
midnight, 4 by default) to the same hour the next day, so that a dinner that ends after
midnight stays one service: its label is the date it began.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta, timezone, tzinfo

__all__ = ["Period", "local", "parse_offset", "parse_when", "period_of", "to_epoch"]

BY = ("hour", "day")


@dataclass(frozen=True, slots=True)
class Period:
    """``[start, end)`` in epoch seconds, with the label a reader sees."""

    label: str
    start: float
    end: float


def parse_offset(text: str) -> timezone:
    """``+02:00``, ``-0530``, ``+2``, ``UTC`` or ``Z`` as a fixed offset from UTC."""
    t = text.strip()
    if t.upper() in ("UTC", "Z", "GMT"):
        return UTC
    m = re.fullmatch(r"([+-])(\d{1,2})(?::?(\d{2}))?", t)
    if m is None or int(m.group(2)) > 14 or int(m.group(3) or 0) >= 60:
        raise ValueError(f"a UTC offset looks like +02:00, -0530 or UTC, not {text!r}")
    minutes = int(m.group(2)) * 60 + int(m.group(3) or 0)
    return timezone(timedelta(minutes=-minutes if m.group(1) == "-" else minutes))


def local(ts: float, tz: tzinfo | None) -> datetime:
    """``ts`` as a naive local datetime (``tz`` None: the machine's)."""
    if tz is None:
        return datetime.fromtimestamp(ts)
    return datetime.fromtimestamp(ts, tz).replace(tzinfo=None)


def to_epoch(when: datetime, tz: tzinfo | None) -> float:
    """A naive local datetime back to epoch seconds."""
    if when.tzinfo is not None:
        return when.timestamp()
    return (when if tz is None else when.replace(tzinfo=tz)).timestamp()


def _day(d: date, tz: tzinfo | None, day_start: int) -> Period:
    start = datetime(d.year, d.month, d.day, day_start)
    return Period(d.isoformat(), to_epoch(start, tz), to_epoch(start + timedelta(days=1), tz))


def period_of(ts: float, by: str, tz: tzinfo | None, day_start: int = 4) -> Period:
    """The hour or service day (``by``) holding ``ts``."""
    t = local(ts, tz)
    if by == "hour":
        h = t.replace(minute=0, second=0, microsecond=0)
        end = to_epoch(h + timedelta(hours=1), tz)
        return Period(h.strftime("%Y-%m-%d %H:00"), to_epoch(h, tz), end)
    if by == "day":
        return _day((t - timedelta(hours=day_start)).date(), tz, day_start)
    raise ValueError(f"by must be one of {BY}, not {by!r}")


def parse_when(text: str, tz: tzinfo | None, day_start: int = 4, *, end: bool = False) -> float:
    """A ``--from``/``--to`` value as epoch seconds.

    A date alone (``2026-05-01``) is that service day: its start, or with ``end`` its end (so
    ``--to 2026-05-01`` includes the whole service of that day). A date and time
    (``2026-05-01 18:30`` or ISO with ``T``, optionally with an offset) is that instant.
    """
    t = text.strip()
    try:
        if re.fullmatch(r"\d{4}-\d{2}-\d{2}", t):
            day = _day(date.fromisoformat(t), tz, day_start)
            return day.end if end else day.start
        return to_epoch(datetime.fromisoformat(t), tz)
    except ValueError as exc:
        raise ValueError(f"a date looks like 2026-05-01 or 2026-05-01 18:30, not {text!r}") from exc
