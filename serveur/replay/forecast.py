""" "How many robots do I need?": a recorded service day replayed with other fleets, for the owner.

The owner picks a day and fleet sizes in the console (``stats`` ``forecast``); the server takes
that day's dishes from its own database (:func:`~serveur.replay.recorded.recorded_orders`, as
``serveur orders --from-db`` does), writes them as an order log beside the site's own map and
waypoints, and runs ``serveur replay`` once per fleet size — each in a child process, one
after the other, so a forecast costs one core at most and never the event loop. Each fleet's
result (waits, dishes delivered) is published on the ``forecast`` topic as it finishes, so the
console fills its table row by row; the owner may cancel.

One forecast at a time per server: a second request while one runs is a ``conflict``. The
replay runs the real server and simulated robots on loopback in virtual time: minutes of CPU
for a busy evening on a Pi, which is why it is the owner's button, not something the server
does on its own during service.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import logging
import shutil
import sys
import tempfile
from collections.abc import Awaitable, Callable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from serveur.domain import Order
from serveur.errors import Conflict, NotFound, ServeurError
from serveur.replay.orders import LogOrder, format_orders
from serveur.replay.recorded import recorded_orders

__all__ = ["FleetResult", "Forecast", "Forecaster", "SiteFiles"]

log = logging.getLogger(__name__)

#: Longest one fleet's replay may take (wall seconds) before the forecast gives up.
FLEET_TIMEOUT = 1800.0


@dataclass
class FleetResult:
    """One fleet size's replay of the day: its waits (seconds) and dishes."""

    robots: int
    state: str = "waiting"  # waiting | running | done | failed
    delivered: int | None = None
    undelivered: int | None = None
    wait_mean: float | None = None
    wait_p95: float | None = None
    wait_max: float | None = None
    trips: int | None = None


@dataclass
class Forecast:
    """A forecast under way or finished (the ``forecast`` topic's record)."""

    id: int
    day: str
    policy: str
    dishes: int
    state: str = "running"  # running | done | failed | cancelled
    error: str | None = None
    fleets: list[FleetResult] = field(default_factory=list)

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


@dataclass(frozen=True, slots=True)
class SiteFiles:
    """What a replay of this site needs besides the orders: the map YAML (its waypoints in
    ``<stem>_waypoints.json`` beside it) and the server's settings that shape a service."""

    map_yaml: Path
    table_timeout: float | None
    trays: int


def _num(v: Any) -> float | None:
    return float(v) if isinstance(v, int | float) and not isinstance(v, bool) else None


class Forecaster:
    """Runs the owner's forecasts for one server, one at a time.

    ``orders`` reads the store's orders; ``site`` writes the site's map and waypoints into a
    folder and says the settings; ``publish`` puts a forecast's record on the topic.
    """

    def __init__(
        self,
        orders: Callable[[], Awaitable[list[Order]]],
        site: Callable[[Path], SiteFiles],
        publish: Callable[[dict[str, Any]], None],
    ) -> None:
        self._orders = orders
        self._site = site
        self._publish = publish
        self._job: asyncio.Task[None] | None = None
        self.current: Forecast | None = None
        self._next_id = 1

    async def start(
        self, day: str, start: float, end: float, robots: list[int], policy: str
    ) -> Forecast:
        """Start replaying the day ``[start, end)`` with each fleet size in ``robots``."""
        if self._job is not None and not self._job.done():
            assert self.current is not None
            raise Conflict(
                f"a forecast of {self.current.day} is running: wait for it or cancel it",
                forecast=self.current.id,
            )
        rows = recorded_orders(await self._orders(), start, end)
        if not rows:
            raise NotFound(f"no dish was ready at the pass on {day}", day=day)
        fc = Forecast(
            id=self._next_id,
            day=day,
            policy=policy,
            dishes=len(rows),
            fleets=[FleetResult(n) for n in robots],
        )
        self._next_id += 1
        self.current = fc
        folder = Path(tempfile.mkdtemp(prefix="serveur-forecast-"))
        try:
            (folder / "orders.csv").write_text(
                format_orders(LogOrder(*r) for r in rows), encoding="utf-8"
            )
            files = self._site(folder)
        except BaseException:
            shutil.rmtree(folder, ignore_errors=True)
            raise
        self._job = asyncio.create_task(self._run(fc, folder, files), name="forecast")
        self._publish(fc.as_dict())
        return fc

    async def cancel(self) -> Forecast:
        """Stop the forecast under way (its finished fleets stay in the record)."""
        if self._job is None or self._job.done() or self.current is None:
            raise NotFound("no forecast is running")
        self._job.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._job
        return self.current

    async def close(self) -> None:
        """Server shutdown: a running forecast is stopped with its child."""
        if self._job is not None and not self._job.done():
            self._job.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await self._job

    async def _run(self, fc: Forecast, folder: Path, files: SiteFiles) -> None:
        try:
            for fleet in fc.fleets:
                fleet.state = "running"
                self._publish(fc.as_dict())
                await self._replay(fleet, fc.policy, folder, files)
                self._publish(fc.as_dict())
            fc.state = "failed" if any(f.state == "failed" for f in fc.fleets) else "done"
        except asyncio.CancelledError:
            fc.state = "cancelled"
            for f in fc.fleets:
                if f.state in ("waiting", "running"):
                    f.state = "cancelled"
            raise
        except Exception as exc:  # the job's end must be told, whatever it was
            log.exception("forecast %d failed", fc.id)
            fc.state, fc.error = "failed", str(exc)
        finally:
            shutil.rmtree(folder, ignore_errors=True)
            self._publish(fc.as_dict())

    async def _replay(
        self, fleet: FleetResult, policy: str, folder: Path, files: SiteFiles
    ) -> None:
        out = folder / f"fleet-{fleet.robots}"
        args = [
            sys.executable,
            "-m",
            "serveur.cli",
            "replay",
            str(folder / "orders.csv"),
            "--robots",
            str(fleet.robots),
            "--policy",
            policy,
            "--map",
            str(files.map_yaml),
            "--capacity",
            str(files.trays),
            "--table-timeout",
            str(files.table_timeout or 0),
            "--out",
            str(out),
            "--quiet",
            # The day's dishes as recorded; guests' calls and bussing are not replayed (the
            # site's map may have no dish return, and the owner asks about deliveries).
            "--no-calls",
        ]
        proc = await asyncio.create_subprocess_exec(
            *args, stdout=asyncio.subprocess.DEVNULL, stderr=asyncio.subprocess.PIPE
        )
        try:
            _, err = await asyncio.wait_for(proc.communicate(), FLEET_TIMEOUT)
        finally:
            if proc.returncode is None:  # cancelled or too long: the child goes too
                proc.kill()
                await proc.wait()
        report = out / "report.json"
        if not report.is_file():  # exit 1 only says a dish was left undelivered
            tail = err.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
            fleet.state = "failed"
            raise ServeurError(f"the replay with {fleet.robots} robot(s) failed: {tail[0]}")
        summary = json.loads(report.read_text("utf-8"))["policies"][policy]["summary"]
        fleet.delivered = int(summary["delivered"])
        fleet.undelivered = int(summary["undelivered"])
        fleet.wait_mean = _num(summary["wait_mean"])
        fleet.wait_p95 = _num(summary["wait_p95"])
        fleet.wait_max = _num(summary["wait_max"])
        fleet.trips = int(summary["trips"])
        fleet.state = "done"
