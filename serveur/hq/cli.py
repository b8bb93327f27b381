"""``serveur hq run`` (the centre: consumer and dashboard) and ``serveur hq user add``.

The centre's database is its own (``--db``, MariaDB for a chain: ``mariadb://...``; a SQLite
file works for a trial), never a site's. Its accounts are its own too: a site's owner does
not log in here, and an hq account opens nothing on a site.
"""

from __future__ import annotations

import argparse
import asyncio
import getpass
import logging
import os
import signal
import sys
import time
from typing import Any

from serveur.errors import ServeurError

__all__ = ["add_hq_parser"]

log = logging.getLogger(__name__)


async def _run(ns: argparse.Namespace) -> int:
    from serveur.chain.address import ChainAddress
    from serveur.hq.consumer import Consumer
    from serveur.hq.dashboard import Dashboard
    from serveur.hq.store import HqStore, open_hq_db
    from serveur.till.intake import IntakeServer

    try:
        address = ChainAddress.parse(ns.broker, ca=ns.ca)
    except ValueError as exc:
        print(f"serveur hq: --broker: {exc}", file=sys.stderr)
        return 2
    store = HqStore(open_hq_db(ns.db))
    try:
        await store.db.open()
    except ServeurError as exc:
        print(f"serveur hq: cannot open {ns.db}: {exc}", file=sys.stderr)
        return 1
    consumer = Consumer(store, address, time.time, down_after=ns.down_after, tick=ns.tick)
    dashboard = Dashboard(store, time.time)
    web = IntakeServer(dashboard.handle, ns.host, ns.port)
    try:
        await web.start()
    except OSError as exc:
        print(f"serveur hq: cannot listen on {ns.host}:{ns.port}: {exc}", file=sys.stderr)
        await store.db.close()
        return 1
    await consumer.start()
    print(
        f"serveur hq listening on http://{ns.host}:{web.port}/ (broker {address.describe()})",
        flush=True,
    )
    stop = asyncio.Event()
    loop = asyncio.get_running_loop()
    for sig in (signal.SIGINT, signal.SIGTERM):
        loop.add_signal_handler(sig, stop.set)
    try:
        await stop.wait()
    finally:
        await web.close()
        await consumer.close()
        await store.db.close()
    return 0


async def _user_add(ns: argparse.Namespace) -> int:
    from serveur.hq.store import HqStore, open_hq_db
    from serveur.security.auth import hash_password

    password = os.environ.get("SERVEUR_HQ_PASSWORD") or getpass.getpass(f"password for {ns.name}: ")
    if len(password) < 8:
        print("serveur hq: a password is at least 8 characters", file=sys.stderr)
        return 2
    try:
        async with HqStore(open_hq_db(ns.db)) as store:
            await store.add_user(
                ns.name, await asyncio.to_thread(hash_password, password), time.time()
            )
    except ServeurError as exc:
        print(f"serveur hq: {exc}", file=sys.stderr)
        return 1
    print(f"account {ns.name} added: it reads the chain's dashboard")
    return 0


def _cmd(ns: argparse.Namespace) -> int:
    runner: Any = _run if ns.hq_command == "run" else _user_add
    return int(asyncio.run(runner(ns)))


def add_hq_parser(sub: argparse._SubParsersAction[argparse.ArgumentParser]) -> None:
    """Register ``serveur hq`` (called once from :mod:`serveur.cli`)."""
    p = sub.add_parser(
        "hq",
        help="the chain's centre: every site's events, a read-only dashboard (docs/chain.md)",
    )
    hq = p.add_subparsers(dest="hq_command", required=True)
    db_help = (
        "the centre's database: mariadb://USER@HOST/DB or a SQLite file (default: $SERVEUR_HQ_DB)"
    )
    run = hq.add_parser("run", help="consume the sites' streams and serve the dashboard")
    run.add_argument("--db", default=os.environ.get("SERVEUR_HQ_DB", "./hq.db"), help=db_help)
    run.add_argument(
        "--broker",
        default=os.environ.get("SERVEUR_HQ_BROKER"),
        required=not os.environ.get("SERVEUR_HQ_BROKER"),
        metavar="mqtts://hq[:PASSWORD]@HOST[:PORT]",
        help="the chain's broker, as user hq (no password: $SERVEUR_CHAIN_PASSWORD)",
    )
    run.add_argument(
        "--ca",
        default=os.environ.get("SERVEUR_CHAIN_CA"),
        metavar="FILE",
        help="the chain's CA certificate (PEM)",
    )
    run.add_argument("--host", default="127.0.0.1")
    run.add_argument("--port", type=int, default=8780)
    run.add_argument(
        "--down-after",
        type=float,
        default=300.0,
        metavar="S",
        help="a site silent this long is shown down (default 300 s)",
    )
    run.add_argument("--tick", type=float, default=1.0, help=argparse.SUPPRESS)
    user = hq.add_parser("user", help="the centre's own accounts")
    users = user.add_subparsers(dest="user_command", required=True)
    add = users.add_parser(
        "add", help="add a dashboard account (password: $SERVEUR_HQ_PASSWORD or asked)"
    )
    add.add_argument("name")
    add.add_argument("--db", default=os.environ.get("SERVEUR_HQ_DB", "./hq.db"), help=db_help)
    p.set_defaults(func=_cmd, is_async=False)
