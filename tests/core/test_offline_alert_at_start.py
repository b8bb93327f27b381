"""A server that starts is not told its robots are offline before it has tried to reach them.

The alert check starts with the server, before the robot links; a robot's Offline counted from
its registration (or from before the restart), so the start's own work — planning the paths
between the waypoints, 15 s of a demo's clock at ``--time-scale 5`` — raised a ``robot_offline``
alert per robot and cleared it a second later, before any client could see it (issue 26). The
alert now counts from when the link was started; a robot still unreachable is still reported.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from serveur.store.factory import open_store
from tests.conftest import restaurant


async def _offline_alerts(db: Path) -> list[str]:
    async with open_store(str(db)) as store:
        return [
            e.kind
            for e in await store.events.list_events()
            if e.kind.startswith("alert.") and e.data.get("kind") == "robot_offline"
        ]


async def test_a_start_raises_no_offline_alert_for_robots_that_connect(tmp_path: Path) -> None:
    # At 200x the start's path planning alone is minutes of the server's clock.
    async with restaurant(tmp_path, robots=2, time_scale=200.0) as r:
        staff = await r.client()
        await staff.subscribe("robots", "alerts")
        await staff.status("r1", "Ready")
        await staff.status("r2", "Ready")
        assert not staff.records.get("alerts")
    assert await _offline_alerts(tmp_path / "serveur.db") == []


@pytest.mark.cuts_links
async def test_a_robot_that_never_answers_is_still_reported(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, time_scale=50.0) as r:
        staff = await r.client()
        await staff.subscribe("robots", "alerts")
        await staff.status("r1", "Ready")
        await r.sim.close()  # the robot goes away for good
        await staff.until(
            lambda: any(
                a["kind"] == "robot_offline" and a["cleared_at"] is None
                for a in staff.records.get("alerts", {}).values()
            ),
            what="the offline alert of a robot gone for good",
        )
