"""Assembling a running serveur: store + core + websocket server (+ simulated robots for demos).

The CLI, the tests and the replay tool all start the system through :class:`App`, so there is
one way to wire it and the tests exercise the same path that production uses.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import shutil
import ssl as ssl_module
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from serveur.chain.address import ChainAddress
from serveur.chain.shipper import Shipper
from serveur.clock import Clock, ScaledClock
from serveur.core.backup_desk import BackupDesk
from serveur.core.backups import BackupKind
from serveur.core.engine import Core, CoreConfig
from serveur.core.shelf import BackupShelf
from serveur.domain import WaypointKind, WaypointRecord, ZoneRecord
from serveur.errors import Conflict, ServeurError
from serveur.mqtt.calls import BrokerAddress, MqttCalls
from serveur.robots.names import OPTION_KEYS, RosNames
from serveur.security.sessions import SecurityConfig, Sessions
from serveur.server import Server
from serveur.stats.remote import StatsService
from serveur.store.base import Store
from serveur.store.factory import open_store, sqlite_file
from serveur.till.intake import IntakeServer
from serveur.till.tap import PrinterTap

__all__ = ["App", "RobotSpec", "parse_robot_spec"]

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class RobotSpec:
    name: str
    url: str
    home: str | None = None
    kinematics: str = "omni"
    #: ROS name options (serveur.robots.names): ns, move_base, cmd_vel, pose, ..., frame.
    link: Mapping[str, str] = field(default_factory=dict)
    #: Tables one trip may serve (a tray each); None: the site's default (``--trays``).
    trays: int | None = None


def parse_robot_spec(text: str) -> RobotSpec:
    """``NAME=URL[,home=WP][,kinematics=omni|diff][,trays=N][,ns=/r1][,OPTION=NAME...]`` as given
    to ``--robot``; the ROS name options are those of :class:`~serveur.robots.names.RosNames`."""
    name, sep, rest = text.partition("=")
    if not sep or not name or not rest:
        raise ValueError(f"--robot wants NAME=URL[,home=WAYPOINT], got {text!r}")
    url, *opts = rest.split(",")
    fields: dict[str, str] = {}
    link: dict[str, str] = {}
    for opt in opts:
        k, sep, v = opt.partition("=")
        if sep and k in ("home", "kinematics", "trays"):
            fields[k] = v
        elif sep and k in OPTION_KEYS:
            link[k] = v
        else:
            raise ValueError(
                f"unknown robot option {opt!r}"
                f" (home=, kinematics=, trays=, {'=, '.join(OPTION_KEYS)}=)"
            )
    RosNames.from_options(link)  # a bad name is refused here, not on the robot
    kinematics = fields.get("kinematics", "omni")
    if kinematics not in ("omni", "diff"):
        raise ValueError(f"kinematics must be omni or diff, not {kinematics!r}")
    trays = None
    if "trays" in fields:
        if not fields["trays"].isdigit() or not 1 <= int(fields["trays"]) <= 12:
            raise ValueError(f"trays must be a whole number from 1 to 12, not {fields['trays']!r}")
        trays = int(fields["trays"])
    return RobotSpec(name, url, fields.get("home"), kinematics, link, trays)


class App:
    """A running server. Use ``async with App(...) as app`` or ``start()``/``close()``.

    ``ssl`` makes the server's one port TLS-only (https + wss); ``robot_ssl`` is how links
    verify ``wss://`` robots (None: the system trust store). Both are contexts rather than
    file names so tests and embedders can build them however they like (serveur.security.tls).
    """

    def __init__(
        self,
        db: str | Path,
        *,
        host: str = "127.0.0.1",
        port: int = 8765,
        clock: Clock | None = None,
        map_path: str | Path | None = None,
        nav_map: Any = None,
        waypoints: Mapping[str, Any] | None = None,
        zones: Sequence[ZoneRecord] = (),
        robots: Sequence[RobotSpec] = (),
        config: CoreConfig | None = None,
        security: SecurityConfig | None = None,
        create_owner: bool = True,
        setup: bool = False,
        ssl: ssl_module.SSLContext | None = None,
        robot_ssl: ssl_module.SSLContext | None = None,
        plan_in_child: bool = True,
        backups: str | Path | None = None,
        mqtt: str | None = None,
        intake_port: int | None = None,
        chain: ChainAddress | None = None,
        chain_heartbeat: float = 30.0,
    ) -> None:
        self.clock = clock or ScaledClock(1.0)
        self.store: Store = open_store(str(db))
        self._db = str(db)
        self._map_path = map_path
        self._nav_map = nav_map
        self._waypoints = waypoints
        self._zones = zones
        self._robots = robots
        self._config = config
        self._host, self._port = host, port
        self._security = security
        self._create_owner = create_owner
        self._setup = setup
        self._ssl, self._robot_ssl = ssl, robot_ssl
        self._plan_in_child = plan_in_child
        #: The backups folder (None: none kept, nothing to restore from the console).
        self._backups = None if backups is None else Path(backups)
        self.shelf: BackupShelf | None = None
        self._restart_lock = asyncio.Lock()
        #: The site's MQTT broker for call buttons (None: none); checked here, used at start.
        self._mqtt = None if mqtt is None else BrokerAddress.parse(mqtt)
        self.mqtt_calls: MqttCalls | None = None
        #: The order-intake API's port (None: no API; 0: any free port, for tests).
        self._intake_port = intake_port
        self.intake: IntakeServer | None = None
        #: The chain's broker (None: this site is in no chain) and the outbox's shipper.
        self._chain = chain
        self._chain_heartbeat = chain_heartbeat
        self.shipper: Shipper | None = None
        self.tap: PrinterTap | None = None
        #: Set when a restore left no server running (see :meth:`restart_on`).
        self.broken = asyncio.Event()
        self.core: Core | None = None
        self.sessions: Sessions | None = None
        self.server: Server | None = None
        #: Set on the first start of an empty database: the new owner's password, to be
        #: shown once (by the CLI) and never again.
        self.first_owner_password: str | None = None
        #: With ``setup``, on a database with nobody in it: the code of the setup link (the
        #: owner's first page), instead of a generated owner password.
        self.setup_code: str | None = None

    async def start(self) -> App:
        """Open the store, start the core (robot links, dispatch) and listen.

        If any step fails (the port is taken, the database is unusable), what was started is
        closed again before the error propagates: a half-started server holds the database
        and worker threads, and its process would hang at exit instead of failing.
        """
        try:
            return await self._start()
        except BaseException:
            with contextlib.suppress(Exception):
                await self.close()
            raise

    async def _start(self) -> App:
        await self.store.open()
        now = self.clock.epoch()
        if self._waypoints:
            await import_waypoints(self.store, self._waypoints.values(), now=now)
        for zone in self._zones:  # a zones file given at start: its zones as drawn there
            await self.store.zones.put_zone(zone, replace=True, now=now, by="zones file")
        for spec in self._robots:
            await self._register(spec, now)
        self.core = Core(
            self.store,
            self.clock,
            config=self._config,
            nav_map=self._nav_map,
            map_path=None if self._map_path is None else str(self._map_path),
            robot_ssl=self._robot_ssl,
            plan_in_child=self._plan_in_child,
        )
        # The printer port: opened by the ticket desk at start, where the owner set it.
        self.tap = PrinterTap(
            self.core.tickets.take_job, host=self._host, on_change=self.core.tickets.tap_changed
        )
        self.core.tickets.tap = self.tap
        await self.core.start()
        self.sessions = Sessions(self.store, self.clock, self._security, hub=self.core.hub)
        if self._setup:
            self.setup_code = await self.sessions.prepare_setup()
        elif self._create_owner:
            self.first_owner_password = await self.sessions.ensure_owner()
        self.sessions.start()
        desk = None
        if self._backups is not None:
            self.shelf = BackupShelf(self._backups, self.store, self.clock)
            self.shelf.start()
            desk = BackupDesk(
                self.shelf,
                staging=self._staging(),
                restart=self.restart_on,
            )
        self.server = Server(
            self.core,
            self.sessions,
            host=self._host,
            port=self._port,
            ssl=self._ssl,
            stats=StatsService(self.store, self._db),
            backups=desk,
        )
        await self.server.start()
        self._port = self.server.port  # a restart listens where the screens knew it
        if self._mqtt is not None:
            self.mqtt_calls = MqttCalls(self._mqtt, self.core.calls.press, self.core.flush_events)
            self.mqtt_calls.start()
        if self._intake_port is not None:
            self.intake = IntakeServer(
                self.server.intake, self._host, self._intake_port, ssl_context=self._ssl
            )
            await self.intake.start()
            self._intake_port = self.intake.port  # a restart listens where integrations knew it
        if self._chain is not None:
            self.shipper = Shipper(
                self.store, self._chain, self.clock, heartbeat=self._chain_heartbeat
            )
            self.shipper.start()
            self.server.chain = self.shipper  # what the owner's `chain` verb reads
            self.core.publisher.on_events = self.shipper.wake  # ship as they are recorded
        return self

    def _staging(self) -> Path:
        """Where a backup waits for the restart that restores it: beside a SQLite file (the
        rename is then within one file system), else in the backups folder."""
        file = sqlite_file(self._db)
        if file is not None:
            return file.with_name(file.name + ".restoring")
        assert self._backups is not None
        return self._backups / "restoring.db"

    async def restart_on(self, staged: Path) -> None:
        """Stop, make the database the checked backup ``staged``, start again.

        Robots are halted and every client closed first, as at any shutdown: from then on
        nothing changes the database, and only then is the state about to be replaced copied
        (``before_restore``: a restore is undone like any other; a dish ordered while the owner
        confirmed is in it). If that copy cannot be made, the restore is abandoned and the
        server starts again as it was. The database is replaced whole or not at all (a file
        renamed, or one transaction); if that fails the server starts on what it had, and if
        the restored database does not start, the copy made just before is put back. If even
        that does not start, :attr:`broken` is set: ``serveur run`` exits non-zero and systemd
        starts it afresh, rather than a process that serves nothing.
        """
        async with self._restart_lock:
            try:
                await self._restart_on(staged)
            except Exception:
                log.exception("the server could not start again after a restore")
                self.broken.set()
            finally:
                await asyncio.to_thread(staged.unlink, missing_ok=True)

    async def _restart_on(self, staged: Path) -> None:
        assert self.shelf is not None
        shelf = self.shelf
        log.warning("restoring a backup: the server restarts on it")
        await self._stop_serving()
        try:
            before = await shelf.make(BackupKind.BEFORE_RESTORE)
        except ServeurError as exc:
            log.error("restore abandoned: the state before it could not be kept: %s", exc)
            await self._release()
            self.store = open_store(self._db)
            await self.start()
            return
        await self._release()
        self.store = open_store(self._db)
        try:
            await self.store.replace_with(staged)
        except ServeurError as exc:
            log.error("the backup was not restored, starting on the database as it was: %s", exc)
        try:
            await self.start()
        except Exception:
            log.exception("the restored database does not start: putting back %s", before.name)
            with contextlib.suppress(Exception):
                await self.close()
            await asyncio.to_thread(shutil.copyfile, shelf.path(before.name), staged)
            self.store = open_store(self._db)
            await self.store.replace_with(staged)
            await self.start()
        log.warning("restored: serving %s", self.url)

    async def issue_token(
        self,
        role: str = "staff",
        *,
        robot: str | None = None,
        table: str | None = None,
        scopes: Sequence[str] = (),
        label: str = "",
        ttl: float | None = None,
    ) -> str:
        """A new device/script token (tests, the demo and the replay tool use this)."""
        assert self.sessions is not None, "start the app first"
        token, _ = await self.sessions.create_token(
            role, robot=robot, table=table, scopes=scopes, label=label, ttl=ttl
        )
        return token

    async def _register(self, spec: RobotSpec, now: float) -> None:
        try:
            await self.store.robots.add_robot(
                spec.name,
                spec.url,
                home=spec.home,
                kinematics=spec.kinematics,
                link=spec.link,
                now=now,
            )
        except Conflict:
            await self.store.robots.update_robot(
                spec.name, url=spec.url, home=spec.home, link=spec.link
            )
        if spec.trays is not None:
            await self.store.robots.set_trays(spec.name, spec.trays, now=now)

    @property
    def url(self) -> str:
        assert self.server is not None
        return self.server.url

    async def close(self) -> None:
        """Shut down: robots stopped first (within half a second), then clients, then the rest."""
        await self._stop_serving()
        await self._release()

    async def _stop_serving(self) -> None:
        """Robots halted, every client closed: nothing changes the database from here on."""
        if self.core is not None:
            await self.core.halt_robots()
        if self.mqtt_calls is not None:
            await self.mqtt_calls.close()
            self.mqtt_calls = None
        if self.shipper is not None:
            await self.shipper.close()
            self.shipper = None
        if self.tap is not None:
            await self.tap.close()
            self.tap = None
        if self.intake is not None:
            await self.intake.close()
            self.intake = None
        if self.server is not None:
            await self.server.close()

    async def _release(self) -> None:
        if self.sessions is not None:
            await self.sessions.close()
        if self.shelf is not None:
            await self.shelf.close()
        if self.core is not None:
            await self.core.close()
        await self.store.close()

    async def __aenter__(self) -> App:
        return await self.start()

    async def __aexit__(self, *exc: object) -> None:
        await self.close()


async def import_waypoints(store: Store, waypoints: Iterable[Any], *, now: float) -> int:
    """Store navigation waypoints (e.g. a map's waypoints file); existing names are updated."""
    n = 0
    for w in waypoints:
        rec = WaypointRecord(name=w.name, x=w.x, y=w.y, yaw=w.yaw, kind=WaypointKind(w.kind))
        await store.waypoints.put_waypoint(rec, replace=True, now=now)
        n += 1
    return n
