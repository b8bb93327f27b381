"""The ``serveur`` command: run, demo, sim, schema.

``serveur demo`` is the whole restaurant in one command: simulated robots, the demo dining
room (its tables as waypoints, robots registered with their homes) and the server, sharing one
simulated clock so ``--time-scale`` speeds up the robots and the server's timers alike.
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import json
import logging
import os
import shutil
import signal
import ssl
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any

from serveur import __version__
from serveur.errors import ServeurError

if TYPE_CHECKING:
    from serveur.core.runtime import CoreConfig
    from serveur.security.sessions import SecurityConfig

__all__ = ["main"]

log = logging.getLogger("serveur")


def _on_signal() -> asyncio.Event:
    """An event set by SIGINT or SIGTERM, with the handlers installed now: before the ready
    line is printed, so a supervisor that signals as soon as it reads it stops us cleanly."""
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError):
            loop.add_signal_handler(sig, stop.set)
    return stop


def _security(ns: argparse.Namespace) -> SecurityConfig:
    from serveur.security.sessions import SecurityConfig

    return SecurityConfig(
        allowed_origins=tuple(ns.allow_origin),
        max_per_address=ns.max_connections_per_address,
        rate=ns.rate_limit,
        burst=max(ns.rate_limit * 4, 20.0),
    )


def _add_service_arguments(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("dinner service")
    g.add_argument(
        "--auto-depart",
        action="store_true",
        help="trips leave as soon as a robot takes them (default: the robot waits at the pass,"
        " Loading, until staff press Go)",
    )
    g.add_argument(
        "--table-timeout",
        type=float,
        default=180.0,
        metavar="S",
        help='a robot waiting this long at a table without "food collected" goes on, the'
        " dishes returned to the pass (0: wait for ever; default 180)",
    )
    g.add_argument(
        "--trays",
        type=int,
        default=4,
        metavar="N",
        help="tables one trip serves, one tray each, unless a robot says otherwise (default 4)",
    )


def _service_config(ns: argparse.Namespace) -> CoreConfig:
    from serveur.core.runtime import CoreConfig

    return CoreConfig(
        auto_depart=ns.auto_depart,
        table_timeout=ns.table_timeout or None,
        capacity=ns.trays,
    )


def _add_security_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--allow-origin",
        action="append",
        default=[],
        metavar="ORIGIN",
        help="another web origin allowed to open the websocket (e.g. https://pos.local); "
        "the server's own pages are always allowed",
    )
    p.add_argument("--max-connections-per-address", type=int, default=64)
    p.add_argument(
        "--rate-limit", type=float, default=50.0, help="requests per second per connection"
    )


def _tls(ns: argparse.Namespace) -> tuple[ssl.SSLContext | None, ssl.SSLContext | None]:
    """The server's and the robot links' TLS contexts from ``--certfile/--keyfile`` and
    ``--robot-cafile`` (None: serve in the clear / the system trust store)."""
    from serveur.security.tls import client_context, server_context

    server = server_context(ns.certfile, ns.keyfile) if ns.certfile else None
    robots = client_context(ns.robot_cafile) if ns.robot_cafile else None
    return server, robots


async def _backup_into(db: str, folder: str) -> int:
    """``serveur backup --into FOLDER``: a backup made as the console's "Back up now" makes
    it (named, checked, noted beside it, the oldest of its kind pruned), so the console lists
    it with the server's own."""
    from serveur.clock import ScaledClock
    from serveur.core.backups import BackupKind
    from serveur.core.shelf import BackupShelf
    from serveur.store.factory import open_store

    async with open_store(db) as store:
        entry = await BackupShelf(folder, store, ScaledClock()).make(BackupKind.NOW)
    if entry.check != "ok":
        print(f"backup {folder}/{entry.name} is damaged:\n{entry.check}", file=sys.stderr)
        return 1
    print(f"backup of {db} written to {folder}/{entry.name} (integrity check: ok)")
    return 0


def _backups_folder(given: str | None, db: str) -> Path | None:
    """``--backups``, or the ``backups`` folder beside a SQLite file (a MariaDB server's
    backups need a folder named: its database is on another box)."""
    if given == "off":
        return None
    if given:
        return Path(given)
    from serveur.store.factory import sqlite_file

    file = sqlite_file(db)
    return None if file is None else file.resolve().parent / "backups"


async def _run(ns: argparse.Namespace) -> int:
    from serveur.app import App, parse_robot_spec
    from serveur.clock import ScaledClock
    from serveur.errors import ServeurError

    try:
        tls, robot_tls = _tls(ns)
    except ServeurError as exc:
        print(f"serveur run: cannot start: {exc}", file=sys.stderr)
        return 1

    waypoints = None
    if ns.waypoints:
        from serveur.maps.mapio import load_waypoints

        waypoints = load_waypoints(ns.waypoints)
    zones = []
    if ns.zones:
        from serveur.store.zones import load_zones_file

        try:
            zones = load_zones_file(ns.zones)
        except ServeurError as exc:
            print(f"serveur run: cannot start: {exc}", file=sys.stderr)
            return 1
    robots = [parse_robot_spec(s) for s in ns.robot]
    if ns.mqtt:
        from serveur.mqtt.calls import BrokerAddress

        try:
            BrokerAddress.parse(ns.mqtt)
        except ValueError as exc:
            print(f"serveur run: cannot start: --mqtt: {exc}", file=sys.stderr)
            return 2
    chain = None
    if ns.chain:
        from serveur.chain.address import ChainAddress
        from serveur.chain.wire import check_site

        try:
            chain = ChainAddress.parse(ns.chain, ca=ns.chain_ca)
            check_site(chain.user)
        except (ValueError, ServeurError) as exc:
            print(f"serveur run: cannot start: --chain: {exc}", file=sys.stderr)
            return 2
    app = App(
        ns.db,
        host=ns.host,
        port=ns.port,
        clock=ScaledClock(ns.time_scale),
        map_path=ns.map,
        waypoints=waypoints,
        zones=zones,
        robots=robots,
        security=_security(ns),
        ssl=tls,
        robot_ssl=robot_tls,
        config=_service_config(ns),
        setup=True,
        backups=_backups_folder(ns.backups, ns.db),
        mqtt=ns.mqtt,
        intake_port=ns.intake_port,
        chain=chain,
        chain_heartbeat=ns.chain_heartbeat,
    )
    try:
        await app.start()
    except OSError as exc:
        # The port taken, an address not on this host: one line, a non-zero exit, no hang.
        print(
            f"serveur run: cannot listen on {ns.host}:{ns.port}: {exc.strerror or exc}",
            file=sys.stderr,
        )
        return 1
    from serveur.maps.memory import freeze_heap

    freeze_heap()  # start-up objects out of the collector's way: no 70 ms full collections
    stop = _on_signal()
    print(f"serveur {__version__} listening on {app.url} (database {ns.db})", flush=True)
    web = app.url.replace("ws", "http", 1).removesuffix("/ws")
    if app.setup_code is not None:
        # Nobody has set this restaurant up: one link (and its QR code) for the owner's tablet.
        from serveur.security.first_run import print_setup_link, setup_url

        assert app.server is not None
        url = setup_url(ns.host, app.server.port, app.setup_code, tls=tls is not None)
        print_setup_link(url, sys.stdout)
    if app.first_owner_password is not None:
        # Shown this once, on the terminal of whoever started an empty database.
        print(
            f"First start: created the owner account.\n"
            f"  log in at {web}/ as user 'owner', password {app.first_owner_password}\n"
            f"  then change it: serveur user passwd owner --db {ns.db}\n"
            f"  staff accounts: serveur user add NAME --db {ns.db}",
            flush=True,
        )
    try:
        # A restore that left no server running ends the process: systemd starts it afresh.
        stopped, broken = (
            asyncio.ensure_future(stop.wait()),
            asyncio.ensure_future(app.broken.wait()),
        )
        await asyncio.wait([stopped, broken], return_when=asyncio.FIRST_COMPLETED)
        for waiter in (stopped, broken):
            waiter.cancel()
    finally:
        await app.close()
    return 1 if app.broken.is_set() else 0


async def _demo(ns: argparse.Namespace) -> int:
    from serveur.app import App, RobotSpec
    from serveur.clock import ScaledClock
    from serveur.errors import ServeurError
    from serveur.maps.navigation import demo_map_path, load_demo
    from serveur.robot_sim import start_simulation

    try:
        tls, robot_tls = _tls(ns)
    except ServeurError as exc:
        print(f"serveur demo: cannot start: {exc}", file=sys.stderr)
        return 1
    clock = ScaledClock(ns.time_scale)
    nav_map, waypoints = load_demo()
    homes = sorted((w for w in waypoints.values() if w.kind == "home"), key=lambda w: w.name)
    # The demo room's dish return (bussing robots are emptied there) beside the kitchen, and
    # a charger at each robot's home spot: the simulator charges a robot standing on it.
    waypoints = {**waypoints, **_demo_places(homes[: ns.robots])}
    if ns.robots > len(homes):
        print(
            f"the demo restaurant has {len(homes)} home spots; --robots {ns.robots} is too many",
            file=sys.stderr,
        )
        return 2
    try:
        sim = await start_simulation(
            ns.robots,
            port=ns.sim_port,
            host=ns.host,
            map_path=demo_map_path(),
            kinematics=ns.kinematics,
            time_scale=ns.time_scale,
            clock=clock,
            seed=ns.seed,
        )
    except OSError as exc:
        last = ns.sim_port + ns.robots - 1
        print(
            f"serveur demo: cannot start the simulated robots on {ns.host}:{ns.sim_port}-{last}"
            f" ({exc.strerror or exc}); is another demo running? Give --sim-port PORT, or"
            " --sim-port 0 for free ports",
            file=sys.stderr,
        )
        return 1
    # A fresh temporary database unless --db: removed again when the demo stops.
    tmpdir = None if ns.db else Path(tempfile.mkdtemp(prefix="serveur-demo-"))
    db = ns.db or str(Path(str(tmpdir)) / "serveur.db")
    # The simulated robots' cameras (serveur.sim.camera), watched beside the joystick.
    camera = {"camera": "camera/image/compressed"}
    specs = [
        RobotSpec(r.name, url, homes[i].name, ns.kinematics, dict(camera))
        for i, (r, url) in enumerate(zip(sim.robots, sim.urls, strict=True))
    ]
    app = App(
        db,
        host=ns.host,
        port=ns.port,
        clock=clock,
        nav_map=nav_map,
        waypoints=waypoints,
        robots=specs,
        security=_security(ns),
        config=_service_config(ns),
        create_owner=False,
        ssl=tls,
        robot_ssl=robot_tls,
    )
    try:
        try:
            await app.start()
        except OSError as exc:
            print(
                f"serveur demo: cannot listen on {ns.host}:{ns.port} ({exc.strerror or exc});"
                " is another demo running? Give --port PORT",
                file=sys.stderr,
            )
            return 1
        creds = await _demo_accounts(app, specs, waypoints)
        await _demo_docks(app, specs)
        stop = _on_signal()
        print(
            f"serveur demo: {ns.robots} simulated robots, time scale {ns.time_scale}x", flush=True
        )
        for spec in specs:
            print(f"  robot {spec.name}: {spec.url} (home {spec.home})")
        print(f"  clients connect to {app.url}")
        web = app.url.replace("ws", "http", 1).removesuffix("/ws")  # wss:// -> https://
        print(f"  staff console: {web}/")
        print(f"    log in as staff / {creds['staff']}  (owner: owner / {creds['owner']})")
        for spec in specs:
            print(f"  robot screen {spec.name}: {web}/robot/{spec.name}#token={creds[spec.name]}")
        first = creds["table"]
        print(f"  table screen: {web}/table/{first}#token={creds['table-token']}")
        print(f"  call button of {first} (a Wi-Fi button's request): GET {web}{creds['button']}")
        print("  (demo credentials: fresh and random on every start)")
        kept = "removed when the demo stops; --db PATH keeps one" if tmpdir else "kept"
        print(f"  database: {db} ({kept})")
        print("  Ctrl-C stops everything.", flush=True)
        await stop.wait()
    finally:
        await app.close()
        await sim.close()
        if tmpdir is not None:
            shutil.rmtree(tmpdir, ignore_errors=True)
    return 0


def _demo_places(homes: Sequence[Any]) -> dict[str, Any]:
    from serveur.maps.mapio import Waypoint

    places = {"dish return": Waypoint("dish return", 9.0, 10.8, 1.570796, "dish_return")}
    for i, home in enumerate(homes):
        name = f"dock{i + 1}"
        places[name] = Waypoint(name, home.x, home.y, home.yaw, "dock")
    return places


async def _demo_docks(app: Any, specs: Sequence[Any]) -> None:
    """Each demo robot's dock is the charger at its home spot."""
    from serveur import protocol as P

    for i, spec in enumerate(specs):
        edit = {"clientmsg": "site", "action": "edit_robot", "robot": spec.name}
        edit["dock"] = f"dock{i + 1}"
        await app.core.site.site(P.SiteEditRobot.model_validate(edit), "demo")


async def _demo_accounts(app: Any, specs: Sequence[Any], waypoints: Any) -> dict[str, str]:
    """Demo logins: an owner and a staff user with random passwords, a token per robot
    screen and one for the first table's screen."""
    from serveur.domain import CallKind
    from serveur.security import auth

    assert app.sessions is not None
    creds: dict[str, str] = {}
    existing = {u.name: u.role for u in await app.store.accounts.list_users()}
    for name, role in (("owner", "owner"), ("staff", "staff")):
        password = auth.new_password()
        pw_hash = await asyncio.to_thread(auth.hash_password, password)
        if name in existing:
            # A demo started again on its database (--db): the same accounts, new passwords.
            await app.store.accounts.set_password(name, pw_hash, now=app.clock.epoch())
        else:
            await app.store.accounts.add_user(name, role, pw_hash, now=app.clock.epoch())
        creds[name] = password
    for spec in specs:
        creds[spec.name] = await app.issue_token("robot-screen", robot=spec.name, label="demo")
    tables = [w.name for w in waypoints.values() if w.kind == "table"]
    first = min(tables, key=lambda n: (len(n), n)) if tables else "T1"
    creds["table"] = first
    creds["table-token"] = await app.issue_token("table-screen", table=first, label="demo")
    # A Wi-Fi call button for that table (named by the start time: a demo started again on
    # its database gets a new one; button names are never reused).
    made = await app.core.calls.add_button(
        f"{first} demo button {int(app.clock.epoch())}", first, CallKind.WAITER
    )
    creds["button"] = made["path"]
    return creds


def _schema(ns: argparse.Namespace) -> int:
    from serveur.protocol import schema

    print(json.dumps(schema(), indent=2))
    return 0


def _add_tls_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument(
        "--certfile",
        help="PEM certificate (chain, leaf first): serve https and wss only (needs --keyfile)",
    )
    p.add_argument("--keyfile", help="PEM private key of --certfile (unencrypted)")
    p.add_argument(
        "--robot-cafile",
        help="PEM CA bundle that verifies wss:// robot URLs (default: the system trust store)",
    )


_SIM_HELP = "simulated robots speaking rosbridge v2 (ROS1 move_base, or ROS 2 Nav2: --ros 2)"
_REPLAY_HELP = "replay an order log through the server and simulated robots"


def _parser(argv: Sequence[str] | None = None) -> argparse.ArgumentParser:
    p = argparse.ArgumentParser(
        prog="serveur", description="Fleet server for restaurant waiter robots"
    )
    p.add_argument("--version", action="version", version=f"serveur {__version__}")
    p.add_argument("-v", "--verbose", action="count", default=0)
    sub = p.add_subparsers(dest="command", required=True)

    run = sub.add_parser("run", help="run the server")
    run.add_argument("--host", default="127.0.0.1")
    run.add_argument("--port", type=int, default=8765)
    run.add_argument(
        "--db",
        default=os.environ.get("SERVEUR_DB", "./serveur.db"),
        help="SQLite file, sqlite:///path or mariadb://user@host:port/db "
        "(default: $SERVEUR_DB, else ./serveur.db; see docs/mariadb.md)",
    )
    run.add_argument(
        "--robot",
        action="append",
        default=[],
        metavar="NAME=URL[,home=WP]",
        help="register a robot (repeatable)",
    )
    run.add_argument(
        "--backups",
        default=os.environ.get("SERVEUR_BACKUPS"),
        help="folder of the nightly backups and the console's (default: $SERVEUR_BACKUPS,"
        " else 'backups' beside a SQLite database; 'off': none)",
    )
    run.add_argument(
        "--mqtt",
        default=os.environ.get("SERVEUR_MQTT"),
        metavar="mqtt://[USER:PASSWORD@]HOST[:PORT][/PREFIX]",
        help="the restaurant's MQTT broker: call buttons publish presses on PREFIX/call"
        " (default: $SERVEUR_MQTT; none)",
    )
    run.add_argument(
        "--chain",
        default=os.environ.get("SERVEUR_CHAIN"),
        metavar="mqtts://SITE[:PASSWORD]@HOST[:PORT]",
        help="the chain's broker: every event also goes, numbered, to the chain's centre"
        " (serveur hq; docs/chain.md). SITE is this restaurant's name there; no password:"
        " $SERVEUR_CHAIN_PASSWORD (default: $SERVEUR_CHAIN; none)",
    )
    run.add_argument(
        "--chain-ca",
        default=os.environ.get("SERVEUR_CHAIN_CA"),
        metavar="FILE",
        help="the chain's CA certificate (PEM) for the broker's TLS (default: the system's)",
    )
    # Seconds between the site's heartbeats to the centre (tests shorten it).
    run.add_argument("--chain-heartbeat", type=float, default=30.0, help=argparse.SUPPRESS)
    run.add_argument(
        "--intake-port",
        type=int,
        default=int(os.environ["SERVEUR_INTAKE_PORT"])
        if os.environ.get("SERVEUR_INTAKE_PORT")
        else None,
        metavar="PORT",
        help="the order-intake API (POST /api/orders, docs/till.md) on this port"
        " (default: $SERVEUR_INTAKE_PORT; none)",
    )
    run.add_argument("--map", help="ROS map YAML (default: adopt the map a robot publishes)")
    run.add_argument("--waypoints", help="waypoints JSON to import (tables, homes)")
    run.add_argument(
        "--zones",
        help="zones JSON to import (aisles, doorways robots take turns through; docs/zones.md)",
    )
    run.add_argument("--time-scale", type=float, default=1.0)
    _add_security_arguments(run)
    _add_service_arguments(run)
    _add_tls_arguments(run)
    run.set_defaults(func=_run, is_async=True)

    demo = sub.add_parser("demo", help="server + simulated robots + the demo restaurant")
    demo.add_argument("--host", default="127.0.0.1")
    demo.add_argument("--port", type=int, default=8765)
    demo.add_argument("--robots", type=int, default=2)
    demo.add_argument(
        "--sim-port",
        type=int,
        default=9090,
        help="the simulated robots' rosbridge ports start here (9090, 9091, ...; 0: free ports)",
    )
    demo.add_argument("--time-scale", type=float, default=1.0)
    demo.add_argument("--kinematics", choices=["omni", "diff"], default="omni")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument(
        "--db",
        help="database file, kept (default: a fresh temporary one, removed when the demo stops);"
        " on an existing one the demo accounts get new passwords",
    )
    _add_security_arguments(demo)
    _add_service_arguments(demo)
    # The demo's own simulated robots stay on plain ws:// (loopback, same process);
    # --robot-cafile is for wss:// robots added from the console.
    _add_tls_arguments(demo)
    demo.set_defaults(func=_demo, is_async=True)

    # The simulator and the replay import numpy, Pillow and the whole simulator: their options
    # are registered only when the command line names them, so that `serveur run` on a Pi never
    # loads those (~20 MB of RSS, docs/performance.md). Otherwise a stub keeps them in --help.
    wanted = set(sys.argv[1:] if argv is None else argv)
    if "sim" in wanted:
        from serveur.robot_sim import add_sim_arguments, run_sim_from_args

        sim = sub.add_parser("sim", help=_SIM_HELP)
        add_sim_arguments(sim)
        sim.set_defaults(func=run_sim_from_args, is_async=True)
    else:
        sub.add_parser("sim", help=_SIM_HELP)

    from serveur.replay.orders import add_orders_parser

    add_orders_parser(sub)
    if "replay" in wanted:
        from serveur.replay.cli import add_replay_parser

        add_replay_parser(sub)
    else:
        sub.add_parser("replay", help=_REPLAY_HELP)
    from serveur.security.accounts_cli import add_accounts_parsers

    add_accounts_parsers(sub)
    from serveur.store.maintenance import add_maintenance_parser

    add_maintenance_parser(sub)
    sub.choices["backup"].set_defaults(backup_into=_backup_into)
    from serveur.stats.cli import add_stats_parser

    add_stats_parser(sub)
    from serveur.hq.cli import add_hq_parser

    add_hq_parser(sub)

    schema = sub.add_parser("schema", help="print the JSON Schema of every message")
    schema.set_defaults(func=_schema, is_async=False)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    parser = _parser(argv)
    ns = parser.parse_args(argv)
    if bool(getattr(ns, "certfile", None)) != bool(getattr(ns, "keyfile", None)):
        # Half a TLS configuration must not silently serve in the clear.
        parser.error(f"{ns.command}: --certfile and --keyfile go together: give both or neither")
    level = logging.WARNING - 10 * min(ns.verbose, 2) if ns.verbose else logging.INFO
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    from serveur.security.sessions import RedactSecrets

    for handler in logging.getLogger().handlers:  # every record, from any logger, is scrubbed
        handler.addFilter(RedactSecrets())
    try:
        if ns.is_async:
            return int(asyncio.run(ns.func(ns)))
        return int(ns.func(ns))
    except KeyboardInterrupt:
        return 130
    except ServeurError as exc:  # a refused input or an unusable database: one clear line
        print(f"serveur: {exc.message}", file=sys.stderr)
        return 1


if __name__ == "__main__":
    sys.exit(main())
