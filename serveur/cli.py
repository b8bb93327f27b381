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
import signal
import sys
import tempfile
from collections.abc import Sequence
from pathlib import Path

from serveur import __version__

__all__ = ["main"]

log = logging.getLogger("serveur")


async def _wait_for_signal() -> None:
    loop = asyncio.get_running_loop()
    stop = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError):
            loop.add_signal_handler(sig, stop.set)
    await stop.wait()


async def _run(ns: argparse.Namespace) -> int:
    from serveur.app import App, parse_robot_spec
    from serveur.clock import ScaledClock

    waypoints = None
    if ns.waypoints:
        from serveur.navigation import load_waypoints

        waypoints = load_waypoints(ns.waypoints)
    robots = [parse_robot_spec(s) for s in ns.robot]
    app = App(
        ns.db,
        host=ns.host,
        port=ns.port,
        clock=ScaledClock(ns.time_scale),
        map_path=ns.map,
        waypoints=waypoints,
        robots=robots,
    )
    await app.start()
    print(f"serveur {__version__} listening on {app.url} (database {ns.db})", flush=True)
    try:
        await _wait_for_signal()
    finally:
        await app.close()
    return 0


async def _demo(ns: argparse.Namespace) -> int:
    from serveur.app import App, RobotSpec
    from serveur.clock import ScaledClock
    from serveur.navigation import demo_map_path, load_demo
    from serveur.robot_sim import start_simulation

    clock = ScaledClock(ns.time_scale)
    nav_map, waypoints = load_demo()
    homes = sorted((w for w in waypoints.values() if w.kind == "home"), key=lambda w: w.name)
    if ns.robots > len(homes):
        print(
            f"the demo restaurant has {len(homes)} home spots; --robots {ns.robots} is too many",
            file=sys.stderr,
        )
        return 2
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
    db = ns.db or str(Path(tempfile.mkdtemp(prefix="serveur-demo-")) / "serveur.db")
    specs = [
        RobotSpec(r.name, url, homes[i].name, ns.kinematics)
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
    )
    try:
        await app.start()
        print(
            f"serveur demo: {ns.robots} simulated robots, time scale {ns.time_scale}x", flush=True
        )
        for spec in specs:
            print(f"  robot {spec.name}: {spec.url} (home {spec.home})")
        print(f"  clients connect to {app.url}")
        web = app.url.replace("ws://", "http://", 1).removesuffix("/ws")
        print(f"  staff console: {web}/")
        for spec in specs:
            print(f"  robot screen {spec.name}: {web}/robot/{spec.name}")
        tables = [w.name for w in waypoints.values() if w.kind == "table"]
        first = min(tables, key=lambda n: (len(n), n)) if tables else "T1"
        print(f"  table screen: {web}/table/{first} (any table's name)")
        print(f"  database: {db}")
        print("  Ctrl-C stops everything.", flush=True)
        await _wait_for_signal()
    finally:
        await app.close()
        await sim.close()
    return 0


def _schema(ns: argparse.Namespace) -> int:
    from serveur.protocol import schema

    print(json.dumps(schema(), indent=2))
    return 0


def _parser() -> argparse.ArgumentParser:
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
    run.add_argument("--map", help="ROS map YAML (default: adopt the map a robot publishes)")
    run.add_argument("--waypoints", help="waypoints JSON to import (tables, homes)")
    run.add_argument("--time-scale", type=float, default=1.0)
    run.set_defaults(func=_run, is_async=True)

    demo = sub.add_parser("demo", help="server + simulated robots + the demo restaurant")
    demo.add_argument("--host", default="127.0.0.1")
    demo.add_argument("--port", type=int, default=8765)
    demo.add_argument("--robots", type=int, default=2)
    demo.add_argument("--sim-port", type=int, default=9090)
    demo.add_argument("--time-scale", type=float, default=1.0)
    demo.add_argument("--kinematics", choices=["omni", "diff"], default="omni")
    demo.add_argument("--seed", type=int, default=0)
    demo.add_argument("--db", help="database file (default: a fresh temporary one)")
    demo.set_defaults(func=_demo, is_async=True)

    sim = sub.add_parser("sim", help="simulated robots speaking rosbridge v2")
    from serveur.robot_sim import add_sim_arguments, run_sim_from_args

    add_sim_arguments(sim)
    sim.set_defaults(func=run_sim_from_args, is_async=True)

    from serveur.orders import add_orders_parser

    add_orders_parser(sub)
    from serveur.replay import add_replay_parser

    add_replay_parser(sub)
    from serveur.maintenance import add_maintenance_parser

    add_maintenance_parser(sub)

    schema = sub.add_parser("schema", help="print the JSON Schema of every message")
    schema.set_defaults(func=_schema, is_async=False)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    ns = _parser().parse_args(argv)
    level = logging.WARNING - 10 * min(ns.verbose, 2) if ns.verbose else logging.INFO
    logging.basicConfig(level=level, format="%(asctime)s %(levelname)s %(name)s: %(message)s")
    if ns.is_async:
        try:
            return int(asyncio.run(ns.func(ns)))
        except KeyboardInterrupt:
            return 130
    return int(ns.func(ns))


if __name__ == "__main__":
    sys.exit(main())
