"""Delivery invariants read straight from a SQLite file, for the fault tests.

The fault tests (robot dropouts, server crashes) judge the server by what it stored, not by
what it said: a reply can be lost with the connection, the database is what the next server
starts from. :func:`check_deliveries` holds after *any* commit, even in the middle of a trip
step (each store mutation is one transaction); :func:`check_robots` holds once the server has
started and reconciled the robots' statuses with their trips (``Core.start``).

Plain :mod:`sqlite3` in one read transaction, so it sees one snapshot even while a server
writes (WAL) and needs nothing of the code under test.
"""

from __future__ import annotations

import json
import sqlite3
from collections import Counter
from collections.abc import Set as AbstractSet
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any


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
        if status in ("pending", "cancelled"):
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
            assert effective in ("Delivering", "Delivered", "Stopped", "Error"), (name, r)
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
