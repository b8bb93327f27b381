"""The forecast's explanation tells the replay's real numbers (issue 30, point 8).

The Statistics tab explains why a forecast's waits differ from the day's record by what the
replay simulates instead of the day's people and robots: staff load a trip in about 10 s plus
4 s a plate, guests take mostly 6 to 20 s to lift their plates (a few up to 40 s), 3 parties in
100 are away. Those numbers live in the page (``REPLAY_MODEL`` in
js/staff/stats/forecast.js), the replay's own in :mod:`serveur.replay.model`. Here the page's
are read and checked against what a forecast's ``serveur replay`` child really runs with: the
command the forecaster builds, parsed by ``serveur replay``'s own parser into its options, and
the guests' dwell drawn as the replay draws it. Were the replay's model changed, this fails
until the words are.
"""

from __future__ import annotations

import argparse
import asyncio
import json
import re
from pathlib import Path
from typing import Any

import pytest

from serveur.replay import forecast as fc_module
from serveur.replay.cli import add_replay_parser
from serveur.replay.forecast import FleetResult, Forecaster, SiteFiles
from serveur.replay.model import dish_dwell

FORECAST_JS = Path(__file__).resolve().parents[2] / "serveur/web/site/js/staff/stats/forecast.js"


def page_model() -> dict[str, float]:
    """``REPLAY_MODEL`` as forecast.js writes it (a one-line object of numbers)."""
    text = FORECAST_JS.read_text("utf-8")
    m = re.search(r"export const REPLAY_MODEL = (\{[^}]*\});", text)
    assert m, "REPLAY_MODEL not found in forecast.js"
    body = re.sub(r"(\w+):", r'"\1":', m.group(1))
    model: dict[str, float] = json.loads(body)
    return model


class _Stop(Exception):
    """Raised instead of starting the child: the command is all this test wants."""


def forecast_command(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    """The ``serveur replay`` command a forecast runs for one fleet size."""
    seen: list[str] = []

    async def fake_exec(*args: Any, **kw: Any) -> Any:
        seen.extend(str(a) for a in args)
        raise _Stop

    monkeypatch.setattr(fc_module.asyncio, "create_subprocess_exec", fake_exec)

    async def orders() -> list[Any]:
        return []

    forecaster = Forecaster(orders, lambda folder: SiteFiles(folder / "m.yaml", 180.0, 4), print)
    files = SiteFiles(tmp_path / "site.yaml", 180.0, 4)
    with pytest.raises(_Stop):
        asyncio.run(forecaster._replay(FleetResult(2), "serveur", tmp_path, files))
    return seen


def test_the_pages_words_are_the_replays_numbers(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    model = page_model()
    cmd = forecast_command(tmp_path, monkeypatch)
    assert cmd[1:4] == ["-m", "serveur.cli", "replay"], cmd
    parser = argparse.ArgumentParser()
    add_replay_parser(parser.add_subparsers())
    ns = parser.parse_args(cmd[3:])
    # Staff at the pass, and parties away: what the forecast's replay runs with.
    assert (ns.load_fixed, ns.load_per_dish) == (model["loadFixed"], model["loadPerPlate"])
    assert round(ns.away * 100) == model["awayPer100"]
    assert ns.seed == 0  # one seed for every fleet: the same guests whatever the fleet
    # Guests: mostly dwellMin..dwellMax, none longer than dwellLongest.
    dwell = [dish_dwell(ns.seed, line) for line in range(5000)]
    assert min(dwell) >= model["dwellMin"] and min(dwell) < model["dwellMin"] + 0.5
    assert max(dwell) == model["dwellLongest"]
    within = sum(1 for d in dwell if d <= model["dwellMax"]) / len(dwell)
    assert 0.75 < within < 0.95, within  # "mostly", and a tail ("a few") beyond
