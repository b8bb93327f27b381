"""The store against real database files: every method, its refusals, and its races.

Backend-neutral on purpose: tests get a :class:`Backend` (a way to open another
:class:`~serveur.store.base.Store` on the same database, and to read it with raw SQL) and an opened
``store``. A MariaDB backend joins by adding a parameter to :func:`backend`; the few tests
that are about SQLite files skip themselves elsewhere.
"""

from __future__ import annotations

import asyncio
import contextlib
import sqlite3
from collections.abc import AsyncIterator, Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import pytest

from serveur.domain import (
    OrderStatus,
    StopStatus,
    TaskStatus,
    WaypointKind,
    WaypointRecord,
)
from serveur.errors import Conflict, InvalidField, NotFound, Stale, StoreError
from serveur.status import RobotMode, RobotStatus
from serveur.store.base import NewDish, Store
from serveur.store.factory import open_store
from serveur.store.migrations import load_migrations
from serveur.store.sqlite.store import SQLiteStore, split_sql
from tests.mariadb_server import query

pytestmark = pytest.mark.timeout(30)

T0 = 1_700_000_000.0
TABLES = ("T1", "T2", "T3", "T4")


@dataclass
class Backend:
    """One database under test: ``new()`` gives an unopened Store on it, ``rows()`` reads it."""

    kind: str
    new: Callable[[], Store]
    rows: Callable[[str], list[dict[str, Any]]]
    path: Path | None = None


def _sqlite_rows(path: Path) -> Callable[[str], list[dict[str, Any]]]:
    def rows(sql: str) -> list[dict[str, Any]]:
        with contextlib.closing(sqlite3.connect(path)) as conn:
            conn.row_factory = sqlite3.Row
            return [dict(r) for r in conn.execute(sql)]

    return rows


@pytest.fixture(params=["sqlite", "mariadb"])
def backend(request: pytest.FixtureRequest, tmp_path: Path) -> Backend:
    if request.param == "sqlite":
        path = tmp_path / "serveur.db"
        return Backend("sqlite", lambda: SQLiteStore(path), _sqlite_rows(path), path)
    if request.param == "mariadb":  # a fresh database on the session's private server
        url: str = request.getfixturevalue("mariadb_url")
        return Backend("mariadb", lambda: open_store(url), lambda sql: query(url, sql))
    raise AssertionError(request.param)  # pragma: no cover


@pytest.fixture
async def store(backend: Backend) -> AsyncIterator[Store]:
    async with backend.new() as s:
        yield s


def sqlite_only(backend: Backend) -> Path:
    if backend.kind != "sqlite" or backend.path is None:
        pytest.skip("about SQLite files")
    return backend.path


async def seed(store: Store, robots: int = 2) -> None:
    """Four tables, a home per robot, robots r1..rN (Offline)."""
    for i, name in enumerate(TABLES):
        wp = WaypointRecord(name=name, x=float(i), y=1.0, kind=WaypointKind.TABLE)
        await store.waypoints.put_waypoint(wp, now=T0)
    for i in range(1, robots + 1):
        await store.waypoints.put_waypoint(
            WaypointRecord(name=f"home{i}", x=-float(i), y=0.0, kind=WaypointKind.HOME), now=T0
        )
        await store.robots.add_robot(f"r{i}", f"ws://r{i}:9090", home=f"home{i}", now=T0)


async def orders(store: Store, *tables: str) -> list[int]:
    """One order per table given, ready in that order; their ids."""
    ids = []
    for i, table in enumerate(tables):
        order = await store.orders.add_order(f"dish{i}", table, ready_at=T0 + i, now=T0 + i)
        ids.append(order.id)
    return ids


async def event_kinds(store: Store) -> list[str]:
    return [e.kind for e in await store.events.list_events()]


# -- opening, migrations, URLs -----------------------------------------------------------


def test_open_store_urls(tmp_path: Path) -> None:
    abs_store = open_store(f"sqlite://{tmp_path}/a.db")
    assert isinstance(abs_store, SQLiteStore) and abs_store.path == f"{tmp_path}/a.db"
    rel = open_store("sqlite:data/b.db")
    assert isinstance(rel, SQLiteStore) and rel.path == "data/b.db"
    bare = open_store(str(tmp_path / "c.db"))
    assert isinstance(bare, SQLiteStore) and bare.path == str(tmp_path / "c.db")
    for url in ("mariadb://u:p@host", "postgres://host/db", "sqlite://host/x.db", "sqlite:"):
        with pytest.raises(StoreError):
            open_store(url)
    assert type(open_store("mariadb://u:p@host/db")).__name__ == "MariaDBStore"


def test_migration_files() -> None:
    history = load_migrations("sqlite")
    assert [m.version for m in history] == sorted({m.version for m in history})
    assert history[0].version == 1 and history[0].name == "init"
    with pytest.raises(StoreError):
        load_migrations("oracle")


def test_split_sql_respects_strings_comments_and_triggers() -> None:
    script = """
    -- a comment; with a semicolon
    CREATE TABLE a (x TEXT DEFAULT ';');
    /* block; comment */
    CREATE TRIGGER t AFTER INSERT ON a BEGIN
        INSERT INTO a VALUES ('x;y');
        SELECT 1;
    END;
    """
    statements = split_sql(script)
    assert len(statements) == 2
    assert statements[1].startswith("/* block") and statements[1].endswith("END;")
    with pytest.raises(StoreError):
        split_sql("CREATE TRIGGER t AFTER INSERT ON a BEGIN SELECT 1;")


async def test_pragmas_and_reopen_applies_nothing_twice(backend: Backend) -> None:
    sqlite_only(backend)
    async with backend.new() as s:
        await seed(s)
        db = s._db  # type: ignore[attr-defined]
        assert (await db.execute_fetchall("PRAGMA journal_mode"))[0][0] == "wal"
        assert (await db.execute_fetchall("PRAGMA synchronous"))[0][0] == 1  # NORMAL
        assert (await db.execute_fetchall("PRAGMA foreign_keys"))[0][0] == 1
        assert (await db.execute_fetchall("PRAGMA busy_timeout"))[0][0] > 0
    first = backend.rows("SELECT * FROM schema_migrations ORDER BY version")
    assert [r["version"] for r in first] == [m.version for m in load_migrations("sqlite")]
    async with backend.new() as s:
        assert len(await s.robots.list_robots()) == 2
    assert backend.rows("SELECT * FROM schema_migrations ORDER BY version") == first


async def test_newer_schema_is_refused(backend: Backend) -> None:
    path = sqlite_only(backend)
    async with backend.new():
        pass
    with contextlib.closing(sqlite3.connect(path)) as conn, conn:
        conn.execute("INSERT INTO schema_migrations VALUES (999, 'future', 0)")
    with pytest.raises(StoreError, match="newer"):
        await backend.new().open()


async def test_open_twice_close_twice_and_closed_store(backend: Backend) -> None:
    s = backend.new()
    await s.open()
    await s.open()
    await s.close()
    await s.close()
    with pytest.raises(StoreError, match="not open"):
        await s.robots.list_robots()


async def test_unopenable_path(tmp_path: Path) -> None:
    with pytest.raises(StoreError):
        await SQLiteStore(tmp_path / "missing" / "dir" / "x.db").open()


# -- robots --------------------------------------------------------------------------------


async def test_add_robot_defaults_and_safe_resend(store: Store) -> None:
    await seed(store, robots=0)
    await store.waypoints.put_waypoint(WaypointRecord(name="home1", x=0, y=0), now=T0)
    robot = await store.robots.add_robot("r1", "ws://r1:9090", home="home1", now=T0 + 1)
    assert (robot.status, robot.mode, robot.current_task) == (
        RobotStatus.OFFLINE,
        RobotMode.OFF,
        None,
    )
    assert robot.updated_at == T0 + 1 and robot.kinematics == "omni"
    assert await store.robots.add_robot("r1", "ws://r1:9090", home="home1", now=T0 + 2) == robot
    with pytest.raises(Conflict):
        await store.robots.add_robot("r1", "ws://other:9090", home="home1", now=T0)
    with pytest.raises(Conflict):
        await store.robots.add_robot("r1", "ws://r1:9090", home="home1", kinematics="diff", now=T0)
    with pytest.raises(NotFound):
        await store.robots.add_robot("r2", "ws://r2:9090", home="nowhere", now=T0)
    with pytest.raises(InvalidField):
        await store.robots.add_robot("", "ws://r2:9090", home=None, now=T0)
    homeless = await store.robots.add_robot("r0", "ws://r0:9090", home=None, now=T0)
    assert homeless.home is None
    assert [r.name for r in await store.robots.list_robots()] == ["r0", "r1"]
    assert (await event_kinds(store)).count("robot.added") == 2


async def test_get_and_update_robot(store: Store) -> None:
    await seed(store)
    with pytest.raises(NotFound):
        await store.robots.get_robot("ghost")
    with pytest.raises(NotFound):
        await store.robots.update_robot("ghost", url="ws://x")
    with pytest.raises(NotFound):
        await store.robots.update_robot("r1", home="nowhere")
    before = await event_kinds(store)
    assert await store.robots.update_robot("r1") == await store.robots.get_robot("r1")
    assert await event_kinds(store) == before  # no change, no event
    updated = await store.robots.update_robot("r1", url="ws://new:9090", home="home2")
    assert (updated.url, updated.home) == ("ws://new:9090", "home2")
    assert await store.robots.get_robot("r1") == updated
    last = (await store.events.list_events())[-1]
    assert last.kind == "robot.updated" and last.robot == "r1"
    assert last.data == {"url": "ws://new:9090", "home": "home2"}


async def test_save_robot_state_writes_its_event(store: Store) -> None:
    await seed(store)
    robot = await store.robots.save_robot_state(
        "r1",
        status=RobotStatus.STOPPED,
        mode=RobotMode.AUTO,
        resume=RobotStatus.DELIVERING,
        last_error=None,
        now=T0 + 5,
        data={"by": "staff"},
    )
    assert (robot.status, robot.mode, robot.resume) == (
        RobotStatus.STOPPED,
        RobotMode.AUTO,
        RobotStatus.DELIVERING,
    )
    assert robot.updated_at == T0 + 5
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.robot, event.ts) == ("robot.status", "r1", T0 + 5)
    assert event.data == {
        "status": "Stopped",
        "mode": "auto",
        "resume": "Delivering",
        "last_error": None,
        "by": "staff",
    }
    robot = await store.robots.save_robot_state(
        "r1",
        status=RobotStatus.ERROR,
        mode=RobotMode.AUTO,
        resume=None,
        last_error="goal aborted",
        now=T0 + 6,
        event="robot.error",
    )
    assert robot.last_error == "goal aborted"
    assert (await store.events.list_events())[-1].kind == "robot.error"
    with pytest.raises(NotFound):
        await store.robots.save_robot_state(
            "ghost",
            status=RobotStatus.READY,
            mode=RobotMode.OFF,
            resume=None,
            last_error=None,
            now=T0,
        )


async def test_status_since_moves_only_when_the_status_changes(store: Store) -> None:
    await seed(store)
    assert (await store.robots.get_robot("r1")).status_since == T0  # added Offline at T0

    async def save(status: RobotStatus, now: float) -> float:
        robot = await store.robots.save_robot_state(
            "r1", status=status, mode=RobotMode.AUTO, resume=None, last_error=None, now=now
        )
        return robot.status_since

    assert await save(RobotStatus.AWAITING, T0 + 5) == T0 + 5
    assert await save(RobotStatus.AWAITING, T0 + 9) == T0 + 5  # same status: still since T0+5
    await store.robots.save_robot_pose("r1", x=1.0, y=2.0, yaw=0.0, battery=None, now=T0 + 10)
    assert (await store.robots.get_robot("r1")).status_since == T0 + 5  # poses do not move it
    assert await save(RobotStatus.OFFLINE, T0 + 12) == T0 + 12


async def test_save_robot_pose(store: Store) -> None:
    await seed(store)
    before = await event_kinds(store)
    await store.robots.save_robot_pose("r1", x=1.5, y=-2.0, yaw=0.5, battery=0.8, now=T0 + 3)
    robot = await store.robots.get_robot("r1")
    assert (robot.x, robot.y, robot.yaw, robot.battery, robot.updated_at) == (
        1.5,
        -2.0,
        0.5,
        0.8,
        T0 + 3,
    )
    assert await event_kinds(store) == before  # poses make no events
    for bad in ({"battery": 87.0}, {"x": float("nan")}, {"yaw": float("inf")}):
        pose: dict[str, Any] = {"x": 0.0, "y": 0.0, "yaw": 0.0, "battery": None} | bad
        with pytest.raises(InvalidField):
            await store.robots.save_robot_pose("r1", **pose, now=T0)
    with pytest.raises(NotFound):
        await store.robots.save_robot_pose("ghost", x=0, y=0, yaw=0, battery=None, now=T0)


# -- waypoints -----------------------------------------------------------------------------


async def test_waypoints(store: Store) -> None:
    wp = WaypointRecord(name="T9", x=1.0, y=2.0, yaw=0.3, kind=WaypointKind.TABLE)
    assert await store.waypoints.put_waypoint(wp, now=T0) == wp
    assert await store.waypoints.put_waypoint(wp, now=T0 + 1) == wp  # identical resend
    assert (await event_kinds(store)).count("waypoint.saved") == 1
    moved = wp.model_copy(update={"x": 5.0})
    with pytest.raises(Conflict):
        await store.waypoints.put_waypoint(moved, now=T0)
    assert await store.waypoints.put_waypoint(moved, replace=True, now=T0 + 2) == moved
    assert await store.waypoints.get_waypoint("T9") == moved
    with pytest.raises(NotFound):
        await store.waypoints.get_waypoint("nowhere")
    with pytest.raises(InvalidField):
        await store.waypoints.put_waypoint(WaypointRecord(name="bad", x=float("nan"), y=0), now=T0)
    await store.waypoints.put_waypoint(WaypointRecord(name="A", x=0, y=0), now=T0)
    assert [w.name for w in await store.waypoints.list_waypoints()] == ["A", "T9"]


async def test_delete_waypoint(store: Store) -> None:
    await seed(store)
    await orders(store, "T1")
    with pytest.raises(NotFound):
        await store.waypoints.delete_waypoint("nowhere", now=T0)
    with pytest.raises(Conflict) as by_order:
        await store.waypoints.delete_waypoint("T1", now=T0)
    assert by_order.value.details["orders"] == 1
    with pytest.raises(Conflict) as by_robot:
        await store.waypoints.delete_waypoint("home1", now=T0)
    assert by_robot.value.details["robots"] == ["r1"]
    await store.waypoints.delete_waypoint("T2", now=T0 + 1)
    with pytest.raises(NotFound):
        await store.waypoints.get_waypoint("T2")
    assert (await store.events.list_events())[-1].data == {"name": "T2"}


# -- orders --------------------------------------------------------------------------------


async def test_add_and_get_order(store: Store) -> None:
    await seed(store)
    order = await store.orders.add_order("laksa", "T1", ready_at=T0 + 1, now=T0 + 2)
    assert (order.dish, order.table, order.status, order.task_id, order.ready_at) == (
        "laksa",
        "T1",
        OrderStatus.PENDING,
        None,
        T0 + 1,
    )
    assert await store.orders.get_order(order.id) == order
    with pytest.raises(NotFound):
        await store.orders.get_order(999)
    with pytest.raises(NotFound):
        await store.orders.add_order("laksa", "T99", ready_at=T0, now=T0)
    with pytest.raises(InvalidField):
        await store.orders.add_order(" ", "T1", ready_at=T0, now=T0)
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.order_id) == ("order.created", order.id)


async def test_order_idempotency_key(store: Store) -> None:
    await seed(store)
    first = await store.orders.add_order("laksa", "T1", ready_at=T0, key="k1", now=T0)
    assert first.key == "k1"
    again = await store.orders.add_order("laksa", "T1", ready_at=T0 + 9, key="k1", now=T0 + 9)
    assert again == first
    assert len(await store.orders.list_orders()) == 1
    with pytest.raises(Conflict):
        await store.orders.add_order("satay", "T1", ready_at=T0, key="k1", now=T0)
    with pytest.raises(Conflict):
        await store.orders.add_order("laksa", "T2", ready_at=T0, key="k1", now=T0)
    # A resend after the dish moved on returns it as it is now, unchanged.
    await store.tasks.create_tasks([[("T1", [first.id])]], now=T0)
    resent = await store.orders.add_order("laksa", "T1", ready_at=T0, key="k1", now=T0 + 10)
    assert resent.status is OrderStatus.ASSIGNED
    # Keys are one namespace: a trip key cannot be reused for an order.
    (o2,) = await orders(store, "T2")
    await store.tasks.create_tasks([[("T2", [o2])]], key="trip", now=T0)
    with pytest.raises(Conflict):
        await store.orders.add_order("laksa", "T1", ready_at=T0, key="trip", now=T0)


async def test_list_orders_filters(store: Store) -> None:
    await seed(store)
    a, b, c, d = await orders(store, "T1", "T1", "T2", "T3")
    (task,) = await store.tasks.create_tasks([[("T1", [a])]], now=T0)
    await store.orders.cancel_order(d, now=T0)
    assert [o.id for o in await store.orders.list_orders()] == [a, b, c, d]
    assert [o.id for o in await store.orders.list_orders(status=OrderStatus.PENDING)] == [b, c]
    both = await store.orders.list_orders(status=[OrderStatus.ASSIGNED, OrderStatus.VOIDED])
    assert [o.id for o in both] == [a, d]
    assert await store.orders.list_orders(status=[]) == []
    assert [o.id for o in await store.orders.list_orders(table="T1")] == [a, b]
    assert [o.id for o in await store.orders.list_orders(task_id=task.id)] == [a]
    pending_t1 = await store.orders.list_orders(status=OrderStatus.PENDING, table="T1")
    assert [o.id for o in pending_t1] == [b]


async def test_cancel_order(store: Store) -> None:
    await seed(store)
    a, b = await orders(store, "T1", "T2")
    cancelled = await store.orders.cancel_order(a, now=T0 + 1)
    assert cancelled.status is OrderStatus.VOIDED
    with pytest.raises(Conflict):
        await store.orders.cancel_order(a, now=T0)
    await store.tasks.create_tasks([[("T2", [b])]], now=T0)
    with pytest.raises(Conflict):
        await store.orders.cancel_order(b, now=T0)
    with pytest.raises(NotFound):
        await store.orders.cancel_order(999, now=T0)
    assert (await store.events.list_events())[-1].kind == "task.created"


# -- creating trips ------------------------------------------------------------------------


async def test_create_tasks(store: Store) -> None:
    await seed(store)
    a, b, c, d = await orders(store, "T1", "T1", "T2", "T3")
    t1, t2 = await store.tasks.create_tasks(
        [[("T2", [c]), ("T1", [b, a])], [("T3", [d])]], now=T0 + 5
    )
    assert (t1.status, t1.robot, t1.current_stop, t1.created_at) == (
        TaskStatus.QUEUED,
        None,
        0,
        T0 + 5,
    )
    assert [(s.seq, s.table, s.orders, s.status) for s in t1.stops] == [
        (0, "T2", [c], StopStatus.PENDING),
        (1, "T1", [a, b], StopStatus.PENDING),
    ]
    assert [s.orders for s in t2.stops] == [[d]]
    assert await store.tasks.get_task(t1.id) == t1
    for oid, tid in ((a, t1.id), (b, t1.id), (c, t1.id), (d, t2.id)):
        order = await store.orders.get_order(oid)
        assert (order.status, order.task_id, order.dispatched_at) == (
            OrderStatus.ASSIGNED,
            tid,
            None,
        )
    created = [e for e in await store.events.list_events() if e.kind == "task.created"]
    assert [e.task_id for e in created] == [t1.id, t2.id]
    assert created[0].data == {
        "stops": [{"table": "T2", "orders": [c]}, {"table": "T1", "orders": [b, a]}]
    }
    with pytest.raises(NotFound):
        await store.tasks.get_task(999)


@pytest.mark.parametrize(
    ("trips", "error"),
    [
        ("unknown order", NotFound),
        ("not pending", Conflict),
        ("twice in one trip", InvalidField),
        ("twice across trips", InvalidField),
        ("wrong table", InvalidField),
        ("table twice in a trip", InvalidField),
        ("no trips", InvalidField),
        ("empty trip", InvalidField),
        ("stop without orders", InvalidField),
    ],
)
async def test_create_tasks_is_all_or_nothing(
    store: Store, trips: str, error: type[Exception]
) -> None:
    await seed(store)
    a, b, c, taken = await orders(store, "T1", "T1", "T2", "T3")
    await store.tasks.create_tasks([[("T3", [taken])]], now=T0)
    events_before = await store.events.list_events()
    good = [("T1", [a, b]), ("T2", [c])]
    cases: dict[str, Any] = {
        "unknown order": [good, [("T3", [999])]],
        "not pending": [good, [("T3", [taken])]],
        "twice in one trip": [[("T1", [a, a]), ("T2", [c])]],
        "twice across trips": [good, [("T1", [b])]],
        "wrong table": [[("T1", [a, b, c])]],
        "table twice in a trip": [[("T1", [a]), ("T2", [c]), ("T1", [b])]],
        "no trips": [],
        "empty trip": [good, []],
        "stop without orders": [[("T1", [a, b]), ("T2", [])]],
    }
    with pytest.raises(error) as raised:
        await store.tasks.create_tasks(cases[trips], now=T0 + 1)
    if trips == "not pending":
        assert raised.value.details["orders"] == [taken]  # type: ignore[attr-defined]
    assert len(await store.tasks.list_tasks()) == 1
    pending = await store.orders.list_orders(status=OrderStatus.PENDING)
    assert [o.id for o in pending] == [a, b, c]
    assert await store.events.list_events() == events_before


async def test_create_tasks_idempotency_key(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T2", "T3")
    first = await store.tasks.create_tasks(
        [[("T1", [a])], [("T2", [b])]], key="cart-1", fingerprint="f1", now=T0
    )
    await store.tasks.start_task(first[0].id, "r1", now=T0 + 1)
    # The resend finds the dishes assigned, so the scheduler's new split is ignored.
    again = await store.tasks.create_tasks([], key="cart-1", fingerprint="f1", now=T0 + 2)
    assert [t.id for t in again] == [t.id for t in first]
    assert again[0].status is TaskStatus.ACTIVE  # current state, not the first reply
    assert len(await store.tasks.list_tasks()) == 2
    with pytest.raises(Conflict):
        await store.tasks.create_tasks([[("T3", [c])]], key="cart-1", fingerprint="f2", now=T0)
    # Without a fingerprint the trips themselves are the fingerprint.
    (t3,) = await store.tasks.create_tasks([[("T3", [c])]], key="cart-2", now=T0)
    assert await store.tasks.create_tasks([[("T3", [c])]], key="cart-2", now=T0) == [t3]
    with pytest.raises(Conflict):
        await store.tasks.create_tasks([[("T3", [c, a])]], key="cart-2", now=T0)
    # An order key cannot name a trip.
    await store.orders.add_order("x", "T4", ready_at=T0, key="order-key", now=T0)
    with pytest.raises(Conflict):
        await store.tasks.create_tasks([[("T3", [c])]], key="order-key", now=T0)
    assert len(await store.tasks.list_tasks()) == 3


async def _robot_status(store: Store, name: str, status: RobotStatus) -> None:
    await store.robots.save_robot_state(
        name, status=status, mode=RobotMode.AUTO, resume=None, last_error=None, now=T0
    )


async def test_add_to_task_puts_dishes_on_a_trip_still_at_the_pass(store: Store) -> None:
    """A plate out while its table's robot is being loaded goes on that robot, at its stop;
    once the robot has left, the trip is refused as stale and nothing changes."""
    await seed(store)
    a, b, c, d, e, f = await orders(store, "T1", "T2", "T1", "T2", "T1", "T3")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b])]], now=T0)
    # Queued: it joins.
    queued = await store.tasks.add_to_task(task.id, [c], fingerprint="q", now=T0 + 1)
    assert [(s.table, s.orders) for s in queued.stops] == [("T1", [a, c]), ("T2", [b])]
    assert (await store.orders.get_order(c)).dispatched_at is None
    # Taken by r1, Loading: it joins, dispatched now, with an event.
    await store.tasks.start_task(task.id, "r1", now=T0 + 2)
    await _robot_status(store, "r1", RobotStatus.LOADING)
    got = await store.tasks.add_to_task(task.id, [d], key="join-1", fingerprint="j", now=T0 + 3)
    assert [(s.table, s.orders) for s in got.stops] == [("T1", [a, c]), ("T2", [b, d])]
    order = await store.orders.get_order(d)
    assert (order.status, order.task_id, order.dispatched_at) == (
        OrderStatus.ASSIGNED,
        task.id,
        T0 + 3,
    )
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.robot, event.task_id, event.data) == (
        "task.dishes_added",
        "r1",
        task.id,
        {"orders": [d]},
    )
    # Refused, changing nothing: a table the trip does not serve, a dish not pending, an
    # unknown dish.
    before = await store.events.list_events()
    with pytest.raises(InvalidField) as raised:
        await store.tasks.add_to_task(task.id, [e, f], fingerprint="x", now=T0 + 4)
    assert raised.value.details == {"field": "orders", "orders": [f], "tables": ["T1", "T2"]}
    with pytest.raises(Conflict):
        await store.tasks.add_to_task(task.id, [a], fingerprint="x", now=T0 + 4)
    with pytest.raises(NotFound):
        await store.tasks.add_to_task(task.id, [999], fingerprint="x", now=T0 + 4)
    with pytest.raises(NotFound):
        await store.tasks.add_to_task(999, [e], fingerprint="x", now=T0 + 4)
    # Go: it has left, the dish stays pending for a cart of its own.
    await _robot_status(store, "r1", RobotStatus.DELIVERING)
    before = await store.events.list_events()
    with pytest.raises(Stale) as left:
        await store.tasks.add_to_task(task.id, [e], fingerprint="x", now=T0 + 5)
    assert left.value.details == {"task": task.id, "robot": "r1", "status": "Delivering"}
    assert (await store.orders.get_order(e)).status is OrderStatus.PENDING
    assert await store.events.list_events() == before
    # The tablet that lost the reply resends: the trip as it is now, not a refusal.
    again = await store.tasks.add_to_task(task.id, [d], key="join-1", fingerprint="j", now=T0 + 6)
    assert again.id == task.id and [s.orders for s in again.stops][1] == [b, d]


async def test_list_tasks_filters(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T2", "T3")
    t1, t2, t3 = await store.tasks.create_tasks(
        [[("T1", [a])], [("T2", [b])], [("T3", [c])]], now=T0
    )
    await store.tasks.start_task(t2.id, "r1", now=T0)
    await store.tasks.start_task(t3.id, "r2", now=T0)
    await store.tasks.cancel_task(t3.id, now=T0)
    assert [t.id for t in await store.tasks.list_tasks()] == [t1.id, t2.id, t3.id]
    assert [t.id for t in await store.tasks.list_tasks(status=TaskStatus.QUEUED)] == [t1.id]
    active_or_cancelled = await store.tasks.list_tasks(
        status=[TaskStatus.ACTIVE, TaskStatus.CANCELLED]
    )
    assert [t.id for t in active_or_cancelled] == [t2.id, t3.id]
    assert [t.id for t in await store.tasks.list_tasks(robot="r2")] == [t3.id]
    assert await store.tasks.list_tasks(robot="r2", status=TaskStatus.ACTIVE) == []
    listed = {t.id: t for t in await store.tasks.list_tasks()}
    for t in (t1, t2, t3):
        assert listed[t.id] == await store.tasks.get_task(t.id)


# -- running trips -------------------------------------------------------------------------


async def test_start_task(store: Store) -> None:
    await seed(store)
    a, b = await orders(store, "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b])]], now=T0)
    started = await store.tasks.start_task(task.id, "r1", now=T0 + 10)
    assert (started.status, started.robot, started.started_at) == (
        TaskStatus.ACTIVE,
        "r1",
        T0 + 10,
    )
    assert (await store.robots.get_robot("r1")).current_task == task.id
    assert {o.dispatched_at for o in await store.orders.list_orders(task_id=task.id)} == {T0 + 10}
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.robot, event.task_id) == ("task.started", "r1", task.id)
    assert event.data == {"robot": "r1", "stops": ["T1", "T2"]}
    with pytest.raises(Conflict):  # no longer queued
        await store.tasks.start_task(task.id, "r2", now=T0)
    (c,) = await orders(store, "T3")
    (other,) = await store.tasks.create_tasks([[("T3", [c])]], now=T0)
    with pytest.raises(Conflict):  # r1 is busy
        await store.tasks.start_task(other.id, "r1", now=T0)
    with pytest.raises(NotFound):
        await store.tasks.start_task(999, "r2", now=T0)
    with pytest.raises(NotFound):
        await store.tasks.start_task(other.id, "ghost", now=T0)


async def test_start_task_reorders_stops(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T2", "T3")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b]), ("T3", [c])]], now=T0)
    for bad in (["T1", "T2"], ["T1", "T2", "T2"], ["T1", "T2", "T4"]):
        with pytest.raises(InvalidField):
            await store.tasks.start_task(task.id, "r1", stop_order=bad, now=T0)
    assert await store.tasks.get_task(task.id) == task  # refused: nothing changed
    started = await store.tasks.start_task(task.id, "r1", stop_order=["T3", "T1", "T2"], now=T0)
    assert [(s.seq, s.table, s.orders) for s in started.stops] == [
        (0, "T3", [c]),
        (1, "T1", [a]),
        (2, "T2", [b]),
    ]


async def test_start_task_races(store: Store) -> None:
    await seed(store, robots=6)
    ids = await orders(store, "T1", "T2")
    t1, t2 = await store.tasks.create_tasks([[("T1", [ids[0]])], [("T2", [ids[1]])]], now=T0)
    # Six robots grab the same trip at once: exactly one gets it.
    results = await asyncio.gather(
        *(store.tasks.start_task(t1.id, f"r{i}", now=T0) for i in range(1, 7)),
        return_exceptions=True,
    )
    winners = [r for r in results if not isinstance(r, BaseException)]
    assert len(winners) == 1
    assert all(isinstance(r, Conflict) for r in results if isinstance(r, BaseException))
    busy = [r for r in await store.robots.list_robots() if r.current_task is not None]
    assert [(r.name, r.current_task) for r in busy] == [(winners[0].robot, t1.id)]
    # One idle robot offered two trips at once: it takes exactly one.
    (c,) = await orders(store, "T3")
    (t3,) = await store.tasks.create_tasks([[("T3", [c])]], now=T0)
    idle = next(r.name for r in await store.robots.list_robots() if r.current_task is None)
    pair = await asyncio.gather(
        store.tasks.start_task(t2.id, idle, now=T0),
        store.tasks.start_task(t3.id, idle, now=T0),
        return_exceptions=True,
    )
    assert sorted(type(r).__name__ for r in pair) == ["Conflict", "Task"]
    assert len(await store.tasks.list_tasks(robot=idle, status=TaskStatus.ACTIVE)) == 1


async def test_arrive_stop(store: Store) -> None:
    await seed(store)
    a, b = await orders(store, "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b])]], now=T0)
    with pytest.raises(Conflict):  # queued: no robot is travelling
        await store.tasks.arrive_stop(task.id, 0, now=T0)
    await store.tasks.start_task(task.id, "r1", now=T0)
    arrived = await store.tasks.arrive_stop(task.id, 0, now=T0 + 20)
    assert (arrived.stops[0].status, arrived.stops[0].arrived_at) == (StopStatus.ARRIVED, T0 + 20)
    n_events = len(await store.events.list_events())
    assert await store.tasks.arrive_stop(task.id, 0, now=T0 + 30) == arrived  # repeat: unchanged
    assert len(await store.events.list_events()) == n_events
    with pytest.raises(Conflict):  # not the current stop
        await store.tasks.arrive_stop(task.id, 1, now=T0)
    with pytest.raises(NotFound):
        await store.tasks.arrive_stop(task.id, 2, now=T0)
    with pytest.raises(NotFound):
        await store.tasks.arrive_stop(999, 0, now=T0)
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.task_id, event.data) == (
        "stop.arrived",
        task.id,
        {"seq": 0, "table": "T1"},
    )


async def test_complete_stop_delivers_its_orders_once(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a, b]), ("T2", [c])]], now=T0)
    with pytest.raises(Conflict):
        await store.tasks.complete_stop(task.id, 0, now=T0)  # queued
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.arrive_stop(task.id, 0, now=T0 + 1)
    with pytest.raises(Conflict):
        await store.tasks.complete_stop(task.id, 1, now=T0)  # not current
    # Two "food collected" presses race: exactly one wins.
    results = await asyncio.gather(
        store.tasks.complete_stop(task.id, 0, now=T0 + 2),
        store.tasks.complete_stop(task.id, 0, now=T0 + 2),
        return_exceptions=True,
    )
    assert sorted(type(r).__name__ for r in results) == ["Conflict", "Task"]
    task = await store.tasks.get_task(task.id)
    assert task.current_stop == 1 and task.stops[0].status is StopStatus.DONE
    assert task.stops[0].done_at == T0 + 2
    delivered = await store.orders.list_orders(status=OrderStatus.DELIVERED)
    assert [(o.id, o.delivered_at) for o in delivered] == [(a, T0 + 2), (b, T0 + 2)]
    assert (await store.orders.get_order(c)).status is OrderStatus.ASSIGNED
    # A stop may be completed without an "arrived" report (staff pressed first).
    task = await store.tasks.complete_stop(task.id, 1, now=T0 + 3)
    assert task.current_stop == 2 and task.stops[1].arrived_at is None
    assert [e.kind for e in await store.events.list_events()].count("stop.done") == 2


async def test_finish_task(store: Store) -> None:
    await seed(store)
    a, b = await orders(store, "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b])]], now=T0)
    with pytest.raises(Conflict):
        await store.tasks.finish_task(task.id, now=T0)  # queued
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.complete_stop(task.id, 0, now=T0 + 1)
    with pytest.raises(Conflict):
        await store.tasks.finish_task(task.id, now=T0)  # a stop left
    await store.tasks.complete_stop(task.id, 1, now=T0 + 2)
    done = await store.tasks.finish_task(task.id, now=T0 + 3)
    assert (done.status, done.finished_at, done.robot) == (TaskStatus.DONE, T0 + 3, "r1")
    assert (await store.robots.get_robot("r1")).current_task is None
    with pytest.raises(Conflict):
        await store.tasks.finish_task(task.id, now=T0)
    with pytest.raises(NotFound):
        await store.tasks.finish_task(999, now=T0)
    assert (await store.events.list_events())[-1].kind == "task.finished"


async def test_cancel_task_returns_exactly_the_undelivered_orders(store: Store) -> None:
    await seed(store)
    a, b, c, d = await orders(store, "T1", "T2", "T2", "T3")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b, c]), ("T3", [d])]], now=T0)
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.complete_stop(task.id, 0, now=T0 + 1)
    await store.tasks.arrive_stop(task.id, 1, now=T0 + 2)
    cancelled = await store.tasks.cancel_task(task.id, now=T0 + 3, reason="robot stuck")
    assert (cancelled.status, cancelled.finished_at) == (TaskStatus.CANCELLED, T0 + 3)
    assert [s.status for s in cancelled.stops] == [
        StopStatus.DONE,
        StopStatus.SKIPPED,
        StopStatus.SKIPPED,
    ]
    assert cancelled.stops[0].orders == [a]
    assert (await store.orders.get_order(a)).status is OrderStatus.DELIVERED
    back = await store.orders.list_orders(status=OrderStatus.PENDING)
    assert [(o.id, o.task_id, o.dispatched_at) for o in back] == [
        (b, None, None),
        (c, None, None),
        (d, None, None),
    ]
    assert (await store.robots.get_robot("r1")).current_task is None
    event = (await store.events.list_events())[-1]
    assert event.kind == "task.cancelled"
    assert event.data == {"reason": "robot stuck", "orders_returned": [b, c, d]}
    with pytest.raises(Conflict):
        await store.tasks.cancel_task(task.id, now=T0)
    # The stops not served keep what they carried: the trip's history says it.
    assert [s.orders for s in cancelled.stops] == [[a], [b, c], [d]]
    # The returned dishes can go out again, and the robot can take them.
    (again,) = await store.tasks.create_tasks([[("T2", [b, c]), ("T3", [d])]], now=T0 + 4)
    assert (await store.tasks.start_task(again.id, "r1", now=T0 + 5)).robot == "r1"
    assert [s.orders for s in (await store.tasks.get_task(task.id)).stops] == [[a], [b, c], [d]]
    assert [s.orders for s in (await store.tasks.get_task(again.id)).stops] == [[b, c], [d]]


async def test_a_skipped_stop_keeps_the_dishes_it_carried(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a, b]), ("T2", [c])]], now=T0)
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.arrive_stop(task.id, 0, now=T0 + 1)
    skipped = await store.tasks.skip_stop(task.id, 0, now=T0 + 2, reason="timeout")
    assert skipped.stops[0].status is StopStatus.SKIPPED and skipped.stops[0].orders == [a, b]
    assert {(o.status, o.task_id) for o in await store.orders.list_orders(table="T1")} == {
        (OrderStatus.RETURNED, None)
    }
    assert [s.orders for s in (await store.tasks.list_tasks(robot="r1"))[0].stops] == [[a, b], [c]]


async def test_cancel_queued_task(store: Store) -> None:
    await seed(store)
    (a,) = await orders(store, "T1")
    (task,) = await store.tasks.create_tasks([[("T1", [a])]], now=T0)
    cancelled = await store.tasks.cancel_task(task.id, now=T0 + 1)
    assert cancelled.robot is None and cancelled.stops[0].status is StopStatus.SKIPPED
    assert (await store.orders.get_order(a)).status is OrderStatus.PENDING
    with pytest.raises(NotFound):
        await store.tasks.cancel_task(999, now=T0)


async def test_requeue_task(store: Store) -> None:
    await seed(store)
    a, b, c = await orders(store, "T1", "T2", "T3")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b]), ("T3", [c])]], now=T0)
    with pytest.raises(Conflict):
        await store.tasks.requeue_task(task.id, now=T0)  # queued
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.complete_stop(task.id, 0, now=T0 + 1)
    await store.tasks.arrive_stop(task.id, 1, now=T0 + 2)
    requeued = await store.tasks.requeue_task(task.id, now=T0 + 60, reason="r1 gone")
    assert (requeued.status, requeued.robot, requeued.started_at) == (TaskStatus.QUEUED, None, None)
    assert requeued.current_stop == 1
    assert [(s.status, s.arrived_at) for s in requeued.stops] == [
        (StopStatus.DONE, None),
        (StopStatus.PENDING, None),
        (StopStatus.PENDING, None),
    ]
    assert (await store.robots.get_robot("r1")).current_task is None
    still = await store.orders.list_orders(task_id=task.id)
    assert [(o.status, o.dispatched_at) for o in still] == [
        (OrderStatus.DELIVERED, T0),
        (OrderStatus.ASSIGNED, None),
        (OrderStatus.ASSIGNED, None),
    ]
    event = (await store.events.list_events())[-1]
    assert (event.kind, event.robot, event.data) == (
        "task.requeued",
        "r1",
        {"reason": "r1 gone", "robot": "r1"},
    )
    # Another robot takes the rest; a full tour may be given, done stops keep their place.
    restarted = await store.tasks.start_task(
        task.id, "r2", stop_order=["T3", "T1", "T2"], now=T0 + 61
    )
    assert [(s.table, s.status) for s in restarted.stops] == [
        ("T1", StopStatus.DONE),
        ("T3", StopStatus.PENDING),
        ("T2", StopStatus.PENDING),
    ]
    assert restarted.current_stop == 1 and restarted.robot == "r2"
    await store.tasks.complete_stop(task.id, 1, now=T0 + 62)
    assert (await store.orders.get_order(c)).status is OrderStatus.DELIVERED
    await store.tasks.complete_stop(task.id, 2, now=T0 + 63)
    with pytest.raises(Conflict):  # everything delivered: finish, not requeue
        await store.tasks.requeue_task(task.id, now=T0)
    assert (await store.tasks.finish_task(task.id, now=T0 + 64)).status is TaskStatus.DONE


async def test_cart(store: Store) -> None:
    await seed(store)
    late = await store.orders.add_order("late", "T1", ready_at=T0 + 50, now=T0)
    early = await store.orders.add_order("early", "T1", ready_at=T0 + 10, now=T0)
    waiting = await store.orders.add_order(
        "waiting", "T1", ready_at=T0, now=T0
    )  # not on a trip yet
    other = await store.orders.add_order("other", "T2", ready_at=T0, now=T0)
    (task,) = await store.tasks.create_tasks(
        [[("T1", [late.id, early.id]), ("T2", [other.id])]], now=T0
    )
    assert [o.id for o in await store.orders.cart("T1")] == [early.id, late.id]
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.complete_stop(task.id, 0, now=T0 + 60)
    cart = await store.orders.cart("T1")
    assert [(o.id, o.status) for o in cart] == [
        (early.id, OrderStatus.DELIVERED),
        (late.id, OrderStatus.DELIVERED),
    ]
    assert waiting.id not in [o.id for o in cart]
    assert await store.orders.cart("T3") == []
    with pytest.raises(NotFound):
        await store.orders.cart("T99")


# -- events --------------------------------------------------------------------------------


async def test_events(store: Store) -> None:
    e1 = await store.events.add_event("robot.link", robot="r1", data={"up": True, "n": 1.5}, now=T0)
    e2 = await store.events.add_event("note", task_id=3, order_id=4, now=T0 + 1)
    assert (e1.kind, e1.robot, e1.ts, e1.data) == ("robot.link", "r1", T0, {"up": True, "n": 1.5})
    assert (e2.task_id, e2.order_id, e2.data) == (3, 4, {})
    assert await store.events.list_events() == [e1, e2]
    assert await store.events.list_events(since_id=e1.id) == [e2]
    assert await store.events.list_events(limit=1) == [e1]
    with pytest.raises(InvalidField):
        await store.events.list_events(limit=0)
    with pytest.raises(InvalidField):
        await store.events.add_event("bad", data={"x": object()}, now=T0)
    with pytest.raises(InvalidField):
        await store.events.add_event("bad", data={"x": float("nan")}, now=T0)
    with pytest.raises(InvalidField):
        await store.events.add_event("", now=T0)
    assert len(await store.events.list_events()) == 2


async def test_every_mutation_of_a_service_is_recorded(store: Store) -> None:
    await seed(store, robots=1)
    (a,) = await orders(store, "T1")
    (task,) = await store.tasks.create_tasks([[("T1", [a])]], now=T0)
    await store.tasks.start_task(task.id, "r1", now=T0)
    await store.tasks.arrive_stop(task.id, 0, now=T0)
    await store.tasks.complete_stop(task.id, 0, now=T0)
    await store.tasks.finish_task(task.id, now=T0)
    assert await event_kinds(store) == [
        *["waypoint.saved"] * 5,
        "robot.added",
        "order.created",
        "task.created",
        "task.started",
        "stop.arrived",
        "stop.done",
        "task.finished",
    ]


async def next_turn() -> None:
    """Let the event loop run once (a yield, not a wait)."""
    loop = asyncio.get_running_loop()
    turned = loop.create_future()
    loop.call_soon(turned.set_result, None)
    await turned


async def test_cancelled_callers_leave_no_half_transaction(store: Store) -> None:
    """A caller cancelled at any point (client gone, server shutting down) changes all or
    nothing, and the next caller finds no transaction left open."""
    await seed(store)
    for turns in range(0, 400, 10):  # from before BEGIN to after COMMIT
        (oid,) = await orders(store, "T1")
        call = asyncio.ensure_future(store.tasks.create_tasks([[("T1", [oid])]], now=T0))
        for _ in range(turns):
            await next_turn()
        call.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await call
        order = await store.orders.get_order(oid)
        if order.status is OrderStatus.ASSIGNED:
            assert order.task_id is not None
            assert (await store.tasks.get_task(order.task_id)).stops[0].orders == [oid]
        else:
            assert (order.status, order.task_id) == (OrderStatus.PENDING, None)
    for task in await store.tasks.list_tasks():
        assert task.stops and all(stop.orders for stop in task.stops)
    created = [e.task_id for e in await store.events.list_events() if e.kind == "task.created"]
    assert created == [t.id for t in await store.tasks.list_tasks()]
    assert await store.integrity_check() == "ok"


# -- views, persistence, maintenance -------------------------------------------------------


async def test_views(store: Store, backend: Backend) -> None:
    await seed(store)
    a, b, c, d = await orders(store, "T1", "T2", "T2", "T3")
    (t1,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b, c])]], now=T0)
    await store.tasks.start_task(t1.id, "r1", now=T0)
    await store.tasks.complete_stop(t1.id, 0, now=T0)
    view = {r["id"]: r for r in backend.rows("SELECT * FROM orders_view")}
    assert view[a] == {
        "id": a,
        "ordername": "dish0",
        "robot_name": "r1",
        "res_table": "T1",
        "order_status": "delivered",
        "task_status": "active",
        "task_id": t1.id,
    }
    assert (view[b]["order_status"], view[b]["task_id"]) == ("assigned", t1.id)
    assert view[d]["task_id"] is None and view[d]["robot_name"] is None
    robots = {r["robot_name"]: r for r in backend.rows("SELECT * FROM robot_info_view")}
    assert robots["r1"] == {
        "robot_name": "r1",
        "url": "ws://r1:9090",
        "status": "Offline",
        "mode": "off",
        "home": "home1",
        "destination": "T2",
        "number_of_orders": 3,
    }
    assert (robots["r2"]["destination"], robots["r2"]["number_of_orders"]) == (None, 0)
    await store.tasks.complete_stop(t1.id, 1, now=T0)
    robots = {r["robot_name"]: r for r in backend.rows("SELECT * FROM robot_info_view")}
    assert robots["r1"]["destination"] is None  # every stop served: heading home


async def test_reopen_keeps_everything(backend: Backend) -> None:
    async with backend.new() as s:
        await seed(s)
        a, b = await orders(s, "T1", "T2")
        trips = [[("T1", [a]), ("T2", [b])]]
        (task,) = await s.tasks.create_tasks(trips, key="k", fingerprint="cart", now=T0)
        await s.tasks.start_task(task.id, "r1", now=T0)
        await s.tasks.complete_stop(task.id, 0, now=T0)
        before = (
            await s.robots.list_robots(),
            await s.waypoints.list_waypoints(),
            await s.orders.list_orders(),
            await s.tasks.list_tasks(),
            await s.events.list_events(),
        )
    async with backend.new() as s:
        after = (
            await s.robots.list_robots(),
            await s.waypoints.list_waypoints(),
            await s.orders.list_orders(),
            await s.tasks.list_tasks(),
            await s.events.list_events(),
        )
        assert after == before
        again = await s.tasks.create_tasks([], key="k", fingerprint="cart", now=T0)
        assert again == before[3]  # keys survive too


async def test_backup_and_integrity(store: Store, backend: Backend, tmp_path: Path) -> None:
    path = sqlite_only(backend)
    await seed(store)
    a, b = await orders(store, "T1", "T2")
    (task,) = await store.tasks.create_tasks([[("T1", [a]), ("T2", [b])]], now=T0)
    await store.tasks.start_task(task.id, "r1", now=T0)
    assert await store.integrity_check() == "ok"
    copy = tmp_path / "backups" / "copy.db"
    copy.parent.mkdir()
    copy.write_bytes(b"an older backup")
    await store.backup(copy)
    assert not copy.with_name("copy.db.tmp").exists()
    with pytest.raises(InvalidField):
        await store.backup(path)
    async with SQLiteStore(copy) as restored:
        assert await restored.integrity_check() == "ok"
        assert await restored.tasks.list_tasks() == await store.tasks.list_tasks()
        assert await restored.orders.list_orders() == await store.orders.list_orders()
        assert await restored.robots.list_robots() == await store.robots.list_robots()
        assert await restored.events.list_events() == await store.events.list_events()


async def test_integrity_check_reports_problems(store: Store, backend: Backend) -> None:
    path = sqlite_only(backend)
    await seed(store)
    with contextlib.closing(sqlite3.connect(path)) as conn, conn:  # foreign_keys off here
        conn.execute("UPDATE robot_info SET home = 'vanished' WHERE name = 'r1'")
    report = await store.integrity_check()
    assert report != "ok" and "robot_info" in report


async def test_two_stores_on_one_file_assign_each_order_once(backend: Backend) -> None:
    """Two server processes (two connections) race to put the same dishes on trips."""
    async with backend.new() as s1, backend.new() as s2:
        await seed(s1)
        ids = await orders(s1, *(TABLES * 3))  # 12 dishes, 3 per table
        by_table = {
            t: [i for i, tt in zip(ids, TABLES * 3, strict=True) if tt == t] for t in TABLES
        }

        def trip(*tables: str) -> list[tuple[str, list[int]]]:
            return [(t, by_table[t]) for t in tables]

        attempts = [
            (s1, [trip("T1", "T2")]),
            (s2, [trip("T2", "T3")]),
            (s1, [trip("T3"), trip("T4")]),
            (s2, [trip("T4", "T1")]),
            (s1, [trip("T1")]),
            (s2, [trip("T2")]),
            (s1, [trip("T3", "T4")]),
            (s2, [trip("T4")]),
        ]
        results = await asyncio.gather(
            *(s.tasks.create_tasks(trips, now=T0) for s, trips in attempts), return_exceptions=True
        )
        assert all(isinstance(r, list | Conflict) for r in results), results
        claimed = [
            oid
            for r in results
            if isinstance(r, list)
            for task in r
            for stop in task.stops
            for oid in stop.orders
        ]
        assert len(claimed) == len(set(claimed))  # no dish on two trips
        for s in (s1, s2):
            assigned = await s.orders.list_orders(status=OrderStatus.ASSIGNED)
            assert sorted(o.id for o in assigned) == sorted(claimed)
            tasks = {t.id: t for t in await s.tasks.list_tasks()}
            for order in assigned:
                assert order.task_id is not None
                assert order.id in [o for st in tasks[order.task_id].stops for o in st.orders]
        assert len(claimed) > 0


async def test_set_role_keeps_an_owner_and_ends_the_changed_users_sessions(store: Store) -> None:
    # Portable SQL (store/accounts.py): run on both backends.
    from serveur.errors import Conflict

    await store.accounts.add_user("ana", "owner", "h1", now=T0)
    await store.accounts.add_user("bo", "staff", "h2", now=T0)
    user, ended = await store.accounts.set_role("bo", "owner", now=T0 + 1)
    assert (user.name, user.role) == ("bo", "owner")
    _, ended = await store.accounts.set_role("bo", "owner", now=T0 + 2)
    assert ended == []  # unchanged: no session ends
    await store.accounts.set_role("ana", "staff", now=T0 + 3)
    with pytest.raises(Conflict):
        await store.accounts.set_role("bo", "staff", now=T0 + 4)  # the last owner
    assert {u.name: u.role for u in await store.accounts.list_users()} == {
        "ana": "staff",
        "bo": "owner",
    }


async def test_the_site_map_is_one_row_replaced_whole(store: Store) -> None:
    from serveur.store.base import StoredMap

    assert await store.site_map.get() is None
    first = StoredMap(0.05, (-1.0, -2.0), 3, 2, bytes([0, 100, 0, 0xFF, 0, 0]), "robot files")
    await store.site_map.put(first, now=10.0, by="user:ana")
    assert await store.site_map.get() == first
    second = StoredMap(0.1, (0.0, 0.0), 2, 2, bytes([0, 0, 100, 100]), "floor plan")
    await store.site_map.put(second, now=11.0)
    assert await store.site_map.get() == second
    bad = StoredMap(0.1, (0.0, 0.0), 2, 2, bytes([0, 0, 100]), "short")  # 3 cells for 2x2
    with pytest.raises(Conflict):
        await store.site_map.put(bad, now=12.0)
    assert await store.site_map.get() == second  # a refused map changed nothing


async def test_the_floor_plan_under_the_map_is_one_row_cleared_with_a_new_map(
    store: Store,
) -> None:
    from serveur.store.base import StoredBackdrop

    assert await store.site_backdrop.get() is None
    assert await store.site_backdrop.clear() is False
    png = b"\x89PNG\r\n\x1a\n" + bytes(range(256)) * 40  # bytes kept as given
    b = StoredBackdrop(png, "image/png", "ab" * 16, 0.027, 0.5, 1.0, -2.0, 0.03, 3)
    await store.site_backdrop.put(b, now=10.0, by="user:ana")
    assert await store.site_backdrop.get() == b
    bad = StoredBackdrop(png, "image/gif", "cd" * 16, 0.027, 0.5, 1.0, -2.0, 0.03, 3)
    with pytest.raises(Conflict):
        await store.site_backdrop.put(bad, now=11.0)
    assert await store.site_backdrop.get() == b
    assert await store.site_backdrop.clear() is True
    assert await store.site_backdrop.get() is None


async def test_a_ticket_orders_once_even_when_two_stores_race_and_a_void_withdraws(
    backend: Backend,
) -> None:
    """The till's ticket (issue 33): two servers reading the same ticket at once (or a reprint
    arriving while the first is stored) make its orders once; the database's unique
    ``first_key`` says so. A void ticket withdraws dishes no robot took yet, the newest first."""
    async with backend.new() as s1, backend.new() as s2:
        await seed(s1)
        dishes = [NewDish("Laksa", 3, "no chilli"), NewDish("Satay", 1)]
        jobs = [
            await s.tickets.add_job("printer 10.0.0.9", b"raw", ["Table 1\n3 x Laksa"], now=T0)
            for s in (s1, s2, s1)
        ]
        results = await asyncio.gather(
            *(
                s.tickets.order(j[0].id, "till-k1", "T1", {"r": 1}, dishes, now=T0 + 1)
                for s, j in zip((s1, s2, s1), jobs, strict=True)
            ),
            return_exceptions=True,
        )
        assert all(isinstance(r, tuple) for r in results), results
        made = [orders for _, orders in results if orders]  # type: ignore[misc]
        assert len(made) == 1 and [(o.dish, o.quantity) for o in made[0]] == [
            ("Laksa", 3),
            ("Satay", 1),
        ]
        statuses = sorted(t.status.value for t, _ in results)  # type: ignore[misc]
        assert statuses == ["ordered", "reprint", "reprint"]
        first = next(t for t, o in results if o)  # type: ignore[misc]
        assert all(t.of_ticket == first.id for t, _ in results if t.status.value == "reprint")  # type: ignore[misc]
        assert len(await s2.orders.list_orders()) == 2

        void = (await s2.tickets.add_job("printer", b"v", ["VOID"], now=T0 + 2))[0]
        done, changed, voided = await s2.tickets.void(
            void.id, "till-void", "T1", {}, [NewDish("Laksa", 1), NewDish("Cendol", 2)], now=T0 + 3
        )
        assert done.status.value == "void" and voided.missing == (("Cendol", 2),)
        assert [(o.dish, o.quantity, o.status) for o in changed] == [
            ("Laksa", 2, OrderStatus.ORDERED)
        ]
        assert "Cendol" in (done.problem or "")
        # The void printed again: nothing more withdrawn.
        again = (await s1.tickets.add_job("printer", b"v", ["VOID"], now=T0 + 4))[0]
        done2, changed2, _ = await s1.tickets.void(
            again.id, "till-void", "T1", {}, [NewDish("Laksa", 1)], now=T0 + 5
        )
        assert done2.status.value == "reprint" and changed2 == []
        assert (await s1.orders.get_order(made[0][0].id)).quantity == 2
