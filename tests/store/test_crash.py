"""SIGKILL the server at 20 seeded moments of a service: nothing lost, nothing twice.

The service, the kill points and the checks are described in tests/crash_service.py;
``python bench/crash.py`` runs longer services with more kills.
"""

from __future__ import annotations

import os
from pathlib import Path

from tests.crash_service import CrashConfig, run_crash

#: Set SERVEUR_CRASH_SEED to try other kill schedules.
SEED = int(os.environ.get("SERVEUR_CRASH_SEED", "1"))


async def test_sigkill_at_twenty_points_of_a_service(tmp_path: Path) -> None:
    report = await run_crash(tmp_path, CrashConfig(seed=SEED, kills=20, carts=5))
    assert report.kills >= 20 and report.checks == 2 * report.kills
    assert report.delivered == report.orders == 15
    # The kills fell during the service, not after it: deliveries happened between them.
    assert report.delivered_at_kill[0] < report.orders
    assert report.integrity == "ok"
