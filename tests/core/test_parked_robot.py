"""A parked robot costs an idle server nothing it does not need (issue 31): its pose is stored
once when it stops, not again every period while AMCL's noise says the same thing.

Ten parked robots used to be ten SQLite writes (and their hand-overs to the store's thread and
back) every five seconds, for rows that did not change: part of why an idle server measured
1.3 % of a core against a 1 % goal (docs/performance.md, "Server").
"""

from __future__ import annotations

import math
from typing import Any, cast

from serveur.clock import FakeClock
from serveur.core.events import PersistPose, RobotEvent
from serveur.core.hub import Hub
from serveur.core.link_reports import LinkReports, worth_saving
from serveur.core.runtime import CoreConfig, Runtime
from serveur.status import RobotState


class _Handler:
    def __init__(self) -> None:
        self.moves = 0

    async def on_event(self, rt: Runtime, event: RobotEvent) -> None:
        raise AssertionError("not called: the events stay queued in this test")

    def moved(self, name: str, x: float, y: float) -> None:
        self.moves += 1

    def localisation_changed(self, name: str) -> None:
        pass

    def battery_changed(self, name: str) -> None:
        pass


def _queued(rt: Runtime) -> list[RobotEvent]:
    out = []
    while not rt.events.empty():
        out.append(rt.events.get_nowait())
    return out


async def test_a_parked_robot_is_stored_once_not_every_period() -> None:
    clock = FakeClock()
    rt = Runtime("r1", RobotState())
    reports = LinkReports(
        {"r1": rt},
        _Handler(),
        hub=Hub(),
        clock=clock,
        config=CoreConfig(pose_persist_period=5.0),
        places=cast(Any, None),
        publisher=cast(Any, None),
    )
    rt.battery = 0.8
    # A minute parked: AMCL at 10 Hz, its noise a centimetre and half a degree.
    for i in range(600):
        jitter = 0.01 * math.sin(i)
        reports.pose("r1", 4.0 + jitter, 10.8 - jitter, 1.57 + jitter / 2, clock.now())
        await clock.advance(0.1)
    saves = [e for e in _queued(rt) if isinstance(e, PersistPose)]
    assert len(saves) == 1  # where it stopped; then nothing for a minute

    # It drives off: stored again, at most once a period, while it moves.
    for i in range(100):
        reports.pose("r1", 4.0 + 0.05 * i, 10.8, 1.57, clock.now())
        await clock.advance(0.1)
    assert 2 <= sum(isinstance(e, PersistPose) for e in _queued(rt)) <= 3

    # Parked at charge: the battery climbs by a percent, so the row is written again.
    rt.battery = 0.81
    await clock.advance(6.0)
    reports.pose("r1", 4.0 + 0.05 * 99, 10.8, 1.57, clock.now())
    assert [type(e) for e in _queued(rt)] == [PersistPose]


def test_what_is_worth_storing_again() -> None:
    saved = (1.0, 2.0, 0.0, 0.5)
    assert worth_saving(None, saved)
    assert not worth_saving(saved, (1.03, 2.03, 0.05, 0.505))  # AMCL's noise
    assert worth_saving(saved, (1.1, 2.0, 0.0, 0.5))  # moved 10 cm
    assert worth_saving(saved, (1.0, 2.0, 0.1, 0.5))  # turned ~6 degrees
    assert not worth_saving((1.0, 2.0, math.pi - 0.01, 0.5), (1.0, 2.0, -math.pi + 0.01, 0.5))
    assert worth_saving(saved, (1.0, 2.0, 0.0, 0.49))  # a percent of battery
    assert worth_saving(saved, (1.0, 2.0, 0.0, None))  # the battery no longer reported
