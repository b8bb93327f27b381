"""What only the MariaDB store has: URLs and secrets from the environment, migrations raced
by two servers, two servers racing for the same dishes and robots, a database restarted (or
killed) under load, least-privilege users, and backups to SQLite.

The behaviour shared with SQLite is tested by tests/store/test_store.py, parametrised over both.
"""

from __future__ import annotations

import asyncio
import contextlib
from pathlib import Path
from typing import Any

import pytest

from serveur.domain import OrderStatus, TaskStatus
from serveur.errors import Conflict, StoreError
from serveur.store.base import Store
from serveur.store.factory import open_store
from serveur.store.mariadb.db import MariaDBConfig, split_statements
from serveur.store.mariadb.store import MariaDBStore
from serveur.store.migrations import load_migrations
from serveur.store.sqlite.store import SQLiteStore
from tests.mariadb_server import PASSWORD, MariaDBServer, query
from tests.store.test_store import T0, TABLES, orders, seed

pytestmark = pytest.mark.timeout(60)


# -- URLs and the environment (no server needed) -------------------------------------------


def test_url_password_and_environment() -> None:
    env = {"SERVEUR_DB_PASSWORD": "from-env", "SERVEUR_DB": "mariadb://envuser:envpw@db:3307/x"}
    cfg = MariaDBConfig.from_url("mariadb://u:p%40ss@db.local:3307/serveur", env)
    assert (cfg.user, cfg.password, cfg.host, cfg.port, cfg.database) == (
        "u",
        "p@ss",
        "db.local",
        3307,
        "serveur",
    )
    # The URL's password wins; without one, the environment's is used.
    assert MariaDBConfig.from_url("mariadb://u@h/serveur", env).password == "from-env"
    assert MariaDBConfig.from_url("mariadb://u@h/serveur", {}).password == ""
    # The bare URL takes the whole URL from $SERVEUR_DB.
    whole = MariaDBConfig.from_url("mariadb://", env)
    assert (whole.user, whole.password, whole.port, whole.database) == (
        "envuser",
        "envpw",
        3307,
        "x",
    )
    with pytest.raises(StoreError, match="SERVEUR_DB"):
        MariaDBConfig.from_url("mariadb://", {})
    sock = MariaDBConfig.from_url(
        "mysql://u@localhost/s?socket=/run/mysqld/mysqld.sock&pool_size=3&retry_for=5", {}
    )
    assert (sock.unix_socket, sock.pool_size, sock.retry_for, sock.port) == (
        "/run/mysqld/mysqld.sock",
        3,
        5.0,
        3306,
    )
    for bad in (
        "mariadb://u:p@h",  # no database
        "mariadb://u:p@h/",
        "mariadb://:p@h/db",  # no user
        "mariadb://u:p@h/db;drop",
        "mariadb://u:p@h:notaport/db",
        "mariadb://u:p@h/db?pool_size=0",
        "mariadb://u:p@h/db?colour=blue",
    ):
        with pytest.raises(StoreError) as raised:
            MariaDBConfig.from_url(bad, {})
        assert ":p@" not in str(raised.value)  # never echo a password
    store = open_store("mariadb://u:secret@h/db")
    assert isinstance(store, MariaDBStore)
    assert "secret" not in repr(store) and "secret" not in repr(store.config)


def test_split_statements_respects_quotes_and_comments() -> None:
    script = """
    -- a comment; with a semicolon
    CREATE TABLE a (x TEXT DEFAULT ';', `we;ird` INT); # another; one
    /* block; comment */ INSERT INTO a VALUES ('it''s; fine', "x;y");
    """
    assert split_statements(script) == [
        "CREATE TABLE a (x TEXT DEFAULT ';', `we;ird` INT)",
        "INSERT INTO a VALUES ('it''s; fine', \"x;y\")",
    ]


# -- migrations ------------------------------------------------------------------------------


async def test_servers_starting_together_migrate_once(mariadb_url: str) -> None:
    stores = [open_store(mariadb_url) for _ in range(3)]
    await asyncio.gather(*(s.open() for s in stores))
    try:
        versions = query(mariadb_url, "SELECT version FROM schema_migrations")
        assert [r["version"] for r in versions] == [m.version for m in load_migrations("mariadb")]
        await seed(stores[0])
        assert len(await stores[2].robots.list_robots()) == 2
    finally:
        for s in stores:
            await s.close()


async def test_newer_schema_is_refused(mariadb_url: str, mariadb_server: MariaDBServer) -> None:
    async with open_store(mariadb_url):
        pass
    database = mariadb_url.rsplit("/", 1)[1].split("?")[0]
    mariadb_server.admin(f"INSERT INTO {database}.schema_migrations VALUES (999, 'future', 0)")
    with pytest.raises(StoreError, match="newer"):
        await open_store(mariadb_url).open()


async def test_migrated_database_runs_without_ddl_rights(
    mariadb_url: str, mariadb_server: MariaDBServer
) -> None:
    """After the migration, SELECT/INSERT/UPDATE/DELETE are enough (docs/mariadb.md)."""
    async with open_store(mariadb_url):
        pass
    database = mariadb_url.rsplit("/", 1)[1].split("?")[0]
    mariadb_server.admin(
        f"CREATE USER IF NOT EXISTS 'serveur_rt'@'127.0.0.1' IDENTIFIED BY 'rt';"
        f" GRANT SELECT, INSERT, UPDATE, DELETE ON {database}.* TO 'serveur_rt'@'127.0.0.1'"
    )
    url = mariadb_url.replace("serveur_test@", "serveur_rt:rt@")
    async with open_store(url) as s:
        await seed(s)
        (a,) = await orders(s, "T1")
        (task,) = await s.tasks.create_tasks([[("T1", [a])]], now=T0)
        await s.tasks.start_task(task.id, "r1", now=T0)
        await s.tasks.complete_stop(task.id, 0, now=T0)
        assert (await s.tasks.finish_task(task.id, now=T0)).status is TaskStatus.DONE
        assert await s.integrity_check() == "ok"
    with pytest.raises(StoreError, match="denied"):
        async with open_store(url.replace(":rt@", ":wrong@")):
            pass


# -- two servers, one database ---------------------------------------------------------------


async def test_two_servers_race_for_dishes_and_robots(mariadb_url: str) -> None:
    """Two stores (two servers' pools), each with many concurrent callers, race to put the
    same dishes on trips and the same robots on trips: no dish twice, no robot twice."""
    async with open_store(mariadb_url) as s1, open_store(mariadb_url) as s2:
        await seed(s1, robots=4)
        for _ in range(3):  # rounds: more interleavings
            ids = await orders(s1, *(TABLES * 3))
            by_table = {t: ids[i::4] for i, t in enumerate(TABLES)}
            attempts = [
                (s1 if i % 2 else s2, [[(t, by_table[t]) for t in tables]])
                for i, tables in enumerate(
                    [("T1", "T2"), ("T2", "T3"), ("T3",), ("T4", "T1"), ("T4",), ("T1",), ("T2",)]
                )
            ]
            made = await asyncio.gather(
                *(s.tasks.create_tasks(trips, now=T0) for s, trips in attempts),
                return_exceptions=True,
            )
            assert all(isinstance(r, list | Conflict) for r in made), made
            queued = await s1.tasks.list_tasks(status=TaskStatus.QUEUED)
            robots = [f"r{i}" for i in range(1, 5)]
            starts = await asyncio.gather(
                *(
                    (s1 if (t.id + i) % 2 else s2).tasks.start_task(t.id, r, now=T0)
                    for t in queued
                    for i, r in enumerate(robots)
                ),
                return_exceptions=True,
            )
            assert all(not isinstance(r, BaseException) or isinstance(r, Conflict) for r in starts)
            active = await s2.tasks.list_tasks(status=TaskStatus.ACTIVE)
            assert len({t.robot for t in active}) == len(active) <= len(robots)
            won = [r for r in starts if not isinstance(r, BaseException)]
            assert sorted(t.id for t in won) == sorted(t.id for t in active)
            for robot in await s1.robots.list_robots():
                mine = [t.id for t in active if t.robot == robot.name]
                assert mine == ([robot.current_task] if robot.current_task else [])
            # On the open trips (a cancelled trip's stops keep what they carried: history).
            live = await s1.tasks.list_tasks(status=(TaskStatus.QUEUED, TaskStatus.ACTIVE))
            claimed = [o for t in live for st in t.stops for o in st.orders]
            assert len(claimed) == len(set(claimed))
            assigned = await s2.orders.list_orders(status=OrderStatus.ASSIGNED)
            assert sorted(o.id for o in assigned) == sorted(claimed)
            for t in active:  # free the robots for the next round
                await s1.tasks.cancel_task(t.id, now=T0)
            for o in await s1.orders.list_orders(status=OrderStatus.PENDING):
                await s2.orders.cancel_order(o.id, now=T0)
        started = [e for e in await s1.events.list_events() if e.kind == "task.started"]
        assert len(started) == len({e.task_id for e in started})
        assert await s1.integrity_check() == "ok"


# -- the database goes away ----------------------------------------------------------------


async def test_database_restart_loses_and_duplicates_nothing(
    mariadb_url: str, mariadb_server: MariaDBServer
) -> None:
    """Keyed orders keep coming while the server is restarted cleanly, then killed: calls in
    flight wait and retry, resends of an unknown outcome are answered from their key, and in
    the end every key has exactly one order."""
    async with open_store(mariadb_url) as store:
        assert isinstance(store, MariaDBStore)
        await seed(store)
        sent: list[str] = []
        unknown: list[str] = []
        stop = asyncio.Event()
        reached = asyncio.Event()
        target = [0]

        async def waiter() -> None:
            n = 0
            while not stop.is_set():
                key = f"pos-{id(asyncio.current_task())}-{n}"
                n += 1
                try:
                    await store.orders.add_order("soup", "T1", ready_at=T0, key=key, now=T0)
                    sent.append(key)
                    if len(sent) >= target[0]:
                        reached.set()
                except StoreError as exc:
                    assert exc.details.get("outcome") == "unknown", exc
                    unknown.append(key)

        loads = [asyncio.create_task(waiter()) for _ in range(3)]
        try:
            for kill in (False, True):
                await asyncio.to_thread(mariadb_server.restart, kill=kill)
                target[0] = len(sent) + 10  # ten more orders placed after the restart
                reached.clear()
                await asyncio.wait_for(reached.wait(), 30)
        finally:
            stop.set()
            await asyncio.gather(*loads)
        for key in unknown:  # the client resends what it got no answer for
            await store.orders.add_order("soup", "T1", ready_at=T0, key=key, now=T0)
        placed = await store.orders.list_orders()
        keys = [o.key for o in placed]
        assert len(keys) == len(set(keys))
        assert sorted(keys) == sorted(sent + unknown)
        assert store.retries > 0
        assert await store.integrity_check() == "ok"


async def test_store_opened_while_database_starts(
    mariadb_url: str, mariadb_server: MariaDBServer
) -> None:
    """A server booting with its database (both started by systemd) waits for it."""
    mariadb_server.stop()
    opening = asyncio.ensure_future(open_store(mariadb_url).open())
    try:
        await asyncio.to_thread(mariadb_server.start)
        await asyncio.wait_for(asyncio.shield(opening), 30)
    finally:
        if mariadb_server.proc is None:
            mariadb_server.start()
        with contextlib.suppress(BaseException):
            await opening
    assert query(mariadb_url, "SELECT count(*) AS n FROM schema_migrations") == [
        {"n": len(load_migrations("mariadb"))}
    ]


# -- maintenance ---------------------------------------------------------------------------


async def test_backup_is_a_sqlite_copy(mariadb_url: str, tmp_path: Path) -> None:
    async with open_store(mariadb_url) as store:
        await seed(store)
        a, b = await orders(store, "T1", "T2")
        (task,) = await store.tasks.create_tasks(
            [[("T1", [a]), ("T2", [b])]], key="k", fingerprint="cart", now=T0
        )
        await store.tasks.start_task(task.id, "r1", now=T0)
        copy = tmp_path / "copy.db"
        copy.write_bytes(b"an older backup")
        await store.backup(copy)
        assert not copy.with_name("copy.db.tmp").exists()
        async with SQLiteStore(copy) as restored:
            assert await restored.integrity_check() == "ok"
            assert await restored.tasks.list_tasks() == await store.tasks.list_tasks()
            assert await restored.orders.list_orders() == await store.orders.list_orders()
            assert await restored.robots.list_robots() == await store.robots.list_robots()
            assert (
                await restored.waypoints.list_waypoints() == await store.waypoints.list_waypoints()
            )
            assert await restored.events.list_events() == await store.events.list_events()
            # Keys come along: a resend to the restored copy is still answered from its key.
            assert await restored.tasks.create_tasks([], key="k", fingerprint="cart", now=T0) == [
                await restored.tasks.get_task(task.id)
            ]


async def test_integrity_check_reports_problems(
    mariadb_url: str, mariadb_server: MariaDBServer
) -> None:
    store: Store
    async with open_store(mariadb_url) as store:
        await seed(store)
        database = mariadb_url.rsplit("/", 1)[1].split("?")[0]
        mariadb_server.admin(
            f"SET foreign_key_checks = 0;"
            f" UPDATE {database}.robot_info SET home = 'vanished' WHERE name = 'r1'"
        )
        report = await store.integrity_check()
        assert report != "ok" and "robot_info row r1 refers to a missing waypoints" in report


def test_password_stays_out_of_urls(mariadb_server: MariaDBServer) -> None:
    assert PASSWORD not in mariadb_server.url("serveur_t0")


async def test_busy_while_a_query_waits_on_the_server(mariadb_url: str) -> None:
    """A virtual-time loop must not jump while MariaDB (another process) answers: the store
    says it is busy from taking a connection to giving it back, and only then."""
    async with open_store(mariadb_url) as store:
        started = asyncio.Event()

        async def slow(tx: Any) -> Any:
            started.set()
            return await tx.one("SELECT SLEEP(0.2) AS s")

        assert not store.busy()
        query_task = asyncio.create_task(store.db.transact(slow, "read"))
        await asyncio.wait_for(started.wait(), 10)
        assert store.busy()
        assert (await asyncio.wait_for(query_task, 10)) == {"s": 0}
        assert not store.busy()


async def test_a_backup_holds_every_table(mariadb_url: str) -> None:
    """Every table the migrations make is in the backup's list (the calls and buttons of
    migration 011 were not, and a MariaDB site's backup lost them), and every foreign key is
    in the integrity check's."""
    from serveur.store.mariadb.backup import FOREIGN_KEYS, TABLES

    async with open_store(mariadb_url):
        pass
    made = {
        r["TABLE_NAME"]
        for r in query(
            mariadb_url,
            "SELECT TABLE_NAME FROM information_schema.TABLES"
            " WHERE TABLE_SCHEMA = DATABASE() AND TABLE_TYPE = 'BASE TABLE'",
        )
    }
    assert made - {"schema_migrations"} == set(TABLES)
    keys = query(
        mariadb_url,
        "SELECT TABLE_NAME, COLUMN_NAME, REFERENCED_TABLE_NAME FROM"
        " information_schema.KEY_COLUMN_USAGE WHERE TABLE_SCHEMA = DATABASE()"
        " AND REFERENCED_TABLE_NAME IS NOT NULL",
    )
    declared = {(t, c, parent) for t, _, c, parent, _ in FOREIGN_KEYS}
    assert {(k["TABLE_NAME"], k["COLUMN_NAME"], k["REFERENCED_TABLE_NAME"]) for k in keys} <= (
        declared
    )
