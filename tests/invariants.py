"""Database invariants read straight from a SQLite file: the fault tests' and the fuzzer's.

The fault tests (robot dropouts, server crashes) judge the server by what it stored, not by
what it said: a reply can be lost with the connection, the database is what the next server
starts from. :func:`check_deliveries` holds after *any* commit, even in the middle of a trip
step (each store mutation is one transaction); :func:`check_robots` holds once the server has
started and reconciled the robots' statuses with their trips (``Core.start``).

Plain :mod:`sqlite3` in one read transaction, so it sees one snapshot even while a server
writes (WAL) and needs nothing of the code under test.

:func:`check_invariants` (the second half, written for the protocol fuzzer) opens the
SQLite file read-only (a second connection: the server may keep running) and asserts the
lifecycle rules of ``docs/protocol.md`` ("Orders and tasks", "Robot status", "When a robot's
link drops") and ``serveur/status.py``; any test that wants to know the state survived (a
crash, a restart) can call it too.

Each rule is one SQL query returning the rows that break it, so a check costs a few scans
even on a database with hundreds of thousands of orders.

Two levels:

* every committed transaction keeps the *always* rules: each order is in exactly one state,
  on exactly one trip while ``assigned`` or ``delivered`` and on none otherwise, each active
  trip has exactly one robot and each robot at most one trip, finished trips hold no
  undelivered dish, modes and statuses agree...;
* between transactions of one instruction (e.g. ``next`` at the last table: the trip is
  finished, then the robot becomes Transit) a robot's status may lag behind its trip. With
  ``settled=True`` (the default) the robot-versus-trip rules are checked too; call it when no
  robot is inside an instruction (the fuzz harness holds every robot's lock), or after a clean
  shutdown. After a crash, pass ``settled=False``.
"""

from __future__ import annotations

import json
import sqlite3
from collections import Counter
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from serveur.domain import OrderStatus, StopStatus, TaskStatus
from serveur.status import RobotStatus

__all__ = [
    "InvariantViolation",
    "Snapshot",
    "check_deliveries",
    "check_invariants",
    "check_robots",
    "integrity",
    "read",
    "violations",
]


@dataclass
class Snapshot:
    orders: dict[int, dict[str, Any]]
    tasks: dict[int, dict[str, Any]]
    stops: dict[tuple[int, str], dict[str, Any]]
    robots: dict[str, dict[str, Any]]
    #: order id -> how many ``stop.done`` events delivered it (must never exceed 1).
    deliveries: Counter[int] = field(default_factory=Counter)

    def delivered(self) -> set[int]:
        return {i for i, o in self.orders.items() if o["status"] == "delivered"}


def read(db: str | Path) -> Snapshot:
    con = sqlite3.connect(db, timeout=30)
    con.row_factory = sqlite3.Row
    try:
        con.execute("BEGIN")
        orders = {r["id"]: dict(r) for r in con.execute("SELECT * FROM orders")}
        tasks = {r["id"]: dict(r) for r in con.execute("SELECT * FROM task")}
        stops = {
            (r["task_id"], r["waypoint"]): dict(r) for r in con.execute("SELECT * FROM task_stop")
        }
        robots = {r["name"]: dict(r) for r in con.execute("SELECT * FROM robot_info")}
        deliveries: Counter[int] = Counter()
        for (data,) in con.execute("SELECT data FROM events WHERE kind = 'stop.done'"):
            deliveries.update(json.loads(data)["orders"])
        con.execute("COMMIT")
    finally:
        con.close()
    return Snapshot(orders, tasks, stops, robots, deliveries)


def check_deliveries(snap: Snapshot, delivered_before: AbstractSet[int] = frozenset()) -> None:
    """Every order in exactly one consistent state; no delivery lost, repeated or undone."""
    for oid, o in snap.orders.items():
        status, task_id = o["status"], o["task_num"]
        if status in ("ordered", "cooking", "pending", "returned", "voided"):
            assert task_id is None, o
            assert snap.deliveries[oid] == 0, (o, "delivered but not delivered")
            continue
        task = snap.tasks[task_id]
        stop = snap.stops[(task_id, o["res_table"])]
        if status == "assigned":
            assert task["status"] in ("queued", "active"), (o, task)
            assert stop["status"] in ("pending", "arrived"), (o, stop)
            assert snap.deliveries[oid] == 0, (o, "assigned after a delivery")
        else:
            assert status == "delivered", o
            assert stop["status"] == "done" and o["delivered_at"] is not None, (o, stop)
            assert snap.deliveries[oid] == 1, (o, snap.deliveries[oid])
    assert all(n <= 1 for n in snap.deliveries.values()), snap.deliveries
    assert delivered_before <= snap.delivered(), delivered_before - snap.delivered()
    # One robot per active trip, and the robot knows it; no robot holds a finished trip.
    holders = Counter(r["current_task"] for r in snap.robots.values() if r["current_task"])
    for tid, t in snap.tasks.items():
        if t["status"] == "active":
            assert holders[tid] == 1, (t, holders)
            assert snap.robots[t["robot_name"]]["current_task"] == tid, t
        else:
            assert holders[tid] == 0, (t, holders)
        if t["status"] == "queued":
            assert t["robot_name"] is None, t


def check_robots(snap: Snapshot) -> None:
    """Each robot's status (or the status it resumes when Offline) agrees with its trip."""
    for name, r in snap.robots.items():
        effective = r["resume"] if r["status"] == "Offline" else r["status"]
        task_id = r["current_task"]
        if effective in ("Delivering", "Delivered"):
            assert task_id is not None, (name, r)
        if task_id is not None:
            assert effective in ("Loading", "Delivering", "Delivered", "Stopped", "Error"), (
                name,
                r,
            )
            task = snap.tasks[task_id]
            assert task["status"] == "active" and task["robot_name"] == name, (r, task)
            if effective == "Delivered":
                current = [s for s in snap.stops.values() if s["task_id"] == task_id]
                current.sort(key=lambda s: s["seq"])
                assert current[task["current_stop"]]["status"] == "arrived", (r, current)


def integrity(db: str | Path) -> str:
    """SQLite's own verdict on the file: ``"ok"`` or the problems, one per line."""
    con = sqlite3.connect(db, timeout=30)
    try:
        rows = [r[0] for r in con.execute("PRAGMA integrity_check")]
        rows += [f"foreign key: {r}" for r in con.execute("PRAGMA foreign_key_check")]
    finally:
        con.close()
    return "\n".join(rows)


# --------------------------------------------------------------------------- the fuzzer's checks

# The stored values must be the enums' values (the store writes nothing else).
ORDER_STATUSES = tuple(v.value for v in OrderStatus)
TASK_STATUSES = tuple(v.value for v in TaskStatus)
STOP_STATUSES = tuple(v.value for v in StopStatus)
ROBOT_STATUSES = tuple(v.value for v in RobotStatus)
#: Which statuses each mode allows (status.py: auto/manual/ready set the mode with the status).
MODE_STATUSES = {
    "off": ("Ready", "Offline"),
    "manual": ("Manual", "Offline"),
    "auto": (
        "Awaiting",
        "Loading",
        "Delivering",
        "Delivered",
        "Stopped",
        "Transit",
        "Error",
        "Offline",
    ),
}
#: A robot carrying a trip is moving to a table, at one, halted, failed or offline.
WITH_TRIP = ("Loading", "Delivering", "Delivered", "Stopped", "Error", "Offline")
#: Offline robots remember the move to resume; never Ready/Awaiting/Manual (re-derived by mode).
OFFLINE_RESUME = ("Loading", "Delivering", "Delivered", "Stopped", "Transit", "Error")


class InvariantViolation(AssertionError):
    """The database breaks at least one invariant; the message lists them (at most 20 each)."""


def _q(values: tuple[str, ...]) -> str:
    return "(" + ", ".join(f"'{v}'" for v in values) + ")"


_MODE_SQL = " OR ".join(
    f"(mode = '{mode}' AND status NOT IN {_q(statuses)})"
    for mode, statuses in MODE_STATUSES.items()
)

#: (name, SQL returning one row per violation) — hold after every committed transaction.
ALWAYS: tuple[tuple[str, str], ...] = (
    # -- orders
    (
        "order status is a known one (ordered ... voided)",
        f"SELECT id, status FROM orders WHERE status IS NULL OR status NOT IN {_q(ORDER_STATUSES)}",
    ),
    (
        "an order is on a trip exactly while assigned or delivered",
        "SELECT id, status, task_num FROM orders"
        " WHERE (task_num IS NOT NULL) <> (status IN ('assigned', 'delivered'))",
    ),
    (
        "an order's trip exists",
        "SELECT o.id, o.task_num FROM orders o LEFT JOIN task t ON t.id = o.task_num"
        " WHERE o.task_num IS NOT NULL AND t.id IS NULL",
    ),
    (
        "an order on a trip is at exactly one of its stops (its table's)",
        "SELECT o.id, o.task_num, o.res_table,"
        " (SELECT count(*) FROM task_stop s WHERE s.task_id = o.task_num"
        "   AND s.waypoint = o.res_table) AS n"
        " FROM orders o WHERE o.task_num IS NOT NULL AND n <> 1",
    ),
    (
        "an assigned order is on a queued or active trip, at a stop not yet served",
        "SELECT o.id, t.id, t.status, s.status FROM orders o"
        " JOIN task t ON t.id = o.task_num"
        " JOIN task_stop s ON s.task_id = t.id AND s.waypoint = o.res_table"
        " WHERE o.status = 'assigned'"
        "   AND (t.status NOT IN ('queued', 'active') OR s.status NOT IN ('pending', 'arrived'))",
    ),
    (
        "a delivered order was delivered at a done stop",
        "SELECT o.id, o.task_num, s.status, o.delivered_at FROM orders o"
        " JOIN task_stop s ON s.task_id = o.task_num AND s.waypoint = o.res_table"
        " WHERE o.status = 'delivered' AND (s.status <> 'done' OR o.delivered_at IS NULL)",
    ),
    (
        "a pending or cancelled order has no dispatch or delivery time (nor an ordered, cooking"
        " or voided one)",
        "SELECT id, status, dispatched_at, delivered_at FROM orders"
        " WHERE status IN ('ordered', 'cooking', 'pending', 'voided')"
        "   AND (dispatched_at IS NOT NULL OR delivered_at IS NOT NULL)",
    ),
    (
        "a returned order has a return time and was never delivered",
        "SELECT id, returned_at, delivered_at FROM orders WHERE status = 'returned'"
        " AND (returned_at IS NULL OR delivered_at IS NOT NULL)",
    ),
    (
        "a dish from the pass on has been ready",
        "SELECT id, status FROM orders"
        " WHERE status NOT IN ('ordered', 'cooking', 'voided') AND ready_at IS NULL",
    ),
    (
        "an assigned order is dispatched exactly while its trip is active",
        "SELECT o.id, t.status, o.dispatched_at FROM orders o JOIN task t ON t.id = o.task_num"
        " WHERE o.status = 'assigned'"
        "   AND ((t.status = 'active') <> (o.dispatched_at IS NOT NULL)"
        "        OR o.delivered_at IS NOT NULL)",
    ),
    # -- tasks and stops
    (
        "task status is one of queued/active/done/cancelled",
        f"SELECT id, status FROM task WHERE status IS NULL OR status NOT IN {_q(TASK_STATUSES)}",
    ),
    (
        "a stop's status is one of pending/arrived/done/skipped",
        "SELECT task_id, seq, status FROM task_stop"
        f" WHERE status IS NULL OR status NOT IN {_q(STOP_STATUSES)}",
    ),
    (
        "a trip has stops numbered 0..n-1",
        "SELECT t.id, count(s.seq), min(s.seq), max(s.seq) FROM task t"
        " LEFT JOIN task_stop s ON s.task_id = t.id GROUP BY t.id"
        " HAVING count(s.seq) = 0 OR min(s.seq) <> 0 OR max(s.seq) <> count(s.seq) - 1",
    ),
    (
        "a queued trip has no robot, has not started, and every stop is pending",
        "SELECT t.id, t.robot_name, t.started_at, t.finished_at, t.current_stop FROM task t"
        " WHERE t.status = 'queued' AND (t.robot_name IS NOT NULL OR t.started_at IS NOT NULL"
        "   OR t.finished_at IS NOT NULL OR t.current_stop <> 0 OR EXISTS"
        "   (SELECT 1 FROM task_stop s WHERE s.task_id = t.id AND s.status <> 'pending'))",
    ),
    (
        "an active trip has a robot, has started and is not finished",
        "SELECT id, robot_name, started_at, finished_at FROM task WHERE status = 'active'"
        " AND (robot_name IS NULL OR started_at IS NULL OR finished_at IS NOT NULL)",
    ),
    (
        "an active trip's stops before current_stop are done, those after it pending",
        "SELECT t.id, t.current_stop, s.seq, s.status FROM task t"
        " JOIN task_stop s ON s.task_id = t.id WHERE t.status = 'active' AND ("
        "   (s.seq < t.current_stop AND s.status NOT IN ('done', 'skipped'))"
        "   OR (s.seq = t.current_stop AND s.status NOT IN ('pending', 'arrived'))"
        "   OR (s.seq > t.current_stop AND s.status <> 'pending'))",
    ),
    (
        "a stop not yet served on a queued or active trip has a dish to serve",
        "SELECT t.id, s.seq, s.waypoint FROM task t JOIN task_stop s ON s.task_id = t.id"
        " WHERE t.status IN ('queued', 'active') AND s.status IN ('pending', 'arrived')"
        " AND NOT EXISTS (SELECT 1 FROM orders o WHERE o.task_num = t.id"
        "   AND o.res_table = s.waypoint AND o.status = 'assigned')",
    ),
    (
        "a done stop's dishes are all delivered and it has a done time",
        "SELECT s.task_id, s.seq, s.done_at FROM task_stop s WHERE s.status = 'done'"
        " AND (s.done_at IS NULL OR EXISTS (SELECT 1 FROM orders o WHERE o.task_num = s.task_id"
        "   AND o.res_table = s.waypoint AND o.status <> 'delivered'))",
    ),
    (
        "an arrived stop has an arrival time",
        "SELECT task_id, seq FROM task_stop WHERE status = 'arrived' AND arrived_at IS NULL",
    ),
    (
        "a done trip has every stop done (or skipped) and a finish time",
        "SELECT t.id, t.finished_at FROM task t WHERE t.status = 'done' AND (t.finished_at IS NULL"
        " OR EXISTS (SELECT 1 FROM task_stop s WHERE s.task_id = t.id"
        "            AND s.status NOT IN ('done', 'skipped')))",
    ),
    (
        "a cancelled trip has a finish time, no stop left to serve and no assigned dish",
        "SELECT t.id, t.finished_at FROM task t WHERE t.status = 'cancelled'"
        " AND (t.finished_at IS NULL"
        "   OR EXISTS (SELECT 1 FROM task_stop s WHERE s.task_id = t.id"
        "              AND s.status NOT IN ('done', 'skipped'))"
        "   OR EXISTS (SELECT 1 FROM orders o WHERE o.task_num = t.id AND o.status = 'assigned'))",
    ),
    (
        "a robot has at most one active trip",
        "SELECT robot_name, count(*) FROM task WHERE status = 'active'"
        " GROUP BY robot_name HAVING count(*) > 1",
    ),
    # -- robots
    (
        "robot status and mode are known values",
        f"SELECT name, status, mode FROM robot_info WHERE status NOT IN {_q(ROBOT_STATUSES)}"
        f" OR mode NOT IN {_q(tuple(MODE_STATUSES))}",
    ),
    (
        "a robot's status agrees with its mode",
        f"SELECT name, mode, status FROM robot_info WHERE {_MODE_SQL}",
    ),
    (
        "resume is set only by Stopped, Error (Delivering/Transit) and Offline",
        "SELECT name, status, resume FROM robot_info WHERE resume IS NOT NULL AND NOT ("
        "  (status IN ('Stopped', 'Error') AND resume IN ('Delivering', 'Transit'))"
        f"  OR (status = 'Offline' AND resume IN {_q(OFFLINE_RESUME)}))",
    ),
    (
        "a robot's current trip is active and is that robot's",
        "SELECT r.name, r.current_task, t.status, t.robot_name FROM robot_info r"
        " LEFT JOIN task t ON t.id = r.current_task WHERE r.current_task IS NOT NULL"
        " AND (t.id IS NULL OR t.status <> 'active' OR t.robot_name IS NOT r.name)",
    ),
    (
        "an active trip is its robot's current trip",
        "SELECT t.id, t.robot_name, r.current_task FROM task t"
        " LEFT JOIN robot_info r ON r.name = t.robot_name"
        " WHERE t.status = 'active' AND (r.name IS NULL OR r.current_task IS NOT t.id)",
    ),
    (
        "a robot without a trip is never Delivering",
        "SELECT name, status FROM robot_info WHERE current_task IS NULL AND status = 'Delivering'",
    ),
)

#: Rules that hold once no instruction is half-way (see the module docstring).
SETTLED: tuple[tuple[str, str], ...] = (
    (
        "a robot with a trip is Delivering, Delivered, Stopped, Error or Offline",
        f"SELECT name, status FROM robot_info WHERE current_task IS NOT NULL"
        f" AND status NOT IN {_q(WITH_TRIP)}",
    ),
    (
        "a robot without a trip is not Delivering or Delivered, nor resumes to them",
        "SELECT name, status, resume FROM robot_info WHERE current_task IS NULL"
        " AND (status IN ('Delivering', 'Delivered') OR resume IN ('Delivering', 'Delivered'))",
    ),
    (
        "an Offline robot with a trip remembers the move it was making",
        "SELECT name, resume FROM robot_info WHERE current_task IS NOT NULL"
        " AND status = 'Offline' AND (resume IS NULL OR resume = 'Transit')",
    ),
    (
        "an active trip still has a stop to serve",
        "SELECT t.id, t.current_stop FROM task t WHERE t.status = 'active'"
        " AND t.current_stop >= (SELECT count(*) FROM task_stop s WHERE s.task_id = t.id)",
    ),
    (
        "a Delivered robot is at its current stop (arrived), a Delivering one on its way",
        "SELECT r.name, r.status, r.resume, s.seq, s.status FROM robot_info r"
        " JOIN task t ON t.id = r.current_task"
        " JOIN task_stop s ON s.task_id = t.id AND s.seq = t.current_stop"
        " WHERE ((r.status = 'Delivered' OR (r.status = 'Offline' AND r.resume = 'Delivered'))"
        "        AND s.status <> 'arrived')"
        "    OR ((r.status IN ('Delivering', 'Stopped')"
        "         OR (r.status = 'Offline' AND r.resume IN ('Delivering', 'Stopped')))"
        "        AND s.status <> 'pending')",
    ),
)


def _connect(db_path: str | Path) -> sqlite3.Connection:
    uri = Path(db_path).resolve().as_uri() + "?mode=ro"
    return sqlite3.connect(uri, uri=True, timeout=30.0, isolation_level=None)


def violations(db_path: str | Path, *, settled: bool = True, limit: int = 20) -> list[str]:
    """Every broken invariant as ``"rule: row, row, ..."`` (empty when the database is sound).

    Reads one consistent snapshot (one read transaction) of the file.
    """
    db = _connect(db_path)
    try:
        db.execute("BEGIN")  # one snapshot for every query
        out: list[str] = []
        quick = db.execute("PRAGMA quick_check").fetchall()
        if [tuple(r) for r in quick] != [("ok",)]:
            out.append(f"PRAGMA quick_check: {quick[:limit]}")
        fks = db.execute("PRAGMA foreign_key_check").fetchmany(limit)
        if fks:
            out.append(f"foreign keys point at missing rows: {fks}")
        for name, sql in ALWAYS + (SETTLED if settled else ()):
            rows = db.execute(f"{sql} LIMIT {limit}").fetchall()
            if rows:
                out.append(f"{name}: {[tuple(r) for r in rows]}")
        db.execute("COMMIT")
        return out
    finally:
        db.close()


def check_invariants(db_path: str | Path, *, settled: bool = True) -> None:
    """Raise :class:`InvariantViolation` listing every invariant the database breaks.

    ``db_path`` is the server's SQLite file; it is opened read-only. ``settled=False`` skips
    the rules that may lag between the transactions of one instruction (use it after a crash).
    """
    found = violations(db_path, settled=settled)
    if found:
        raise InvariantViolation(
            f"{len(found)} invariant(s) broken in {db_path}:\n  " + "\n  ".join(found)
        )
