"""The live rows: robots and waypoints as every read sees them, the removed ones left out.

A robot or waypoint the owner removes keeps its row, marked ``removed_at`` (migration 006,
:mod:`serveur.store.robots`, :mod:`serveur.store.waypoints`): past trips and orders name it.
Every read of "the robots" or "the waypoints" must skip those rows, in every part of the
store, so the queries are written here once.
"""

from __future__ import annotations

from typing import Final

__all__ = ["ROBOT", "ROBOT_NAMED", "WAYPOINT", "WAYPOINT_NAMED"]

#: Every live robot's record (append ``AND ...`` or ``ORDER BY ...``).
ROBOT: Final = (
    "SELECT name, url, home, kinematics, link, mode, status, resume, current_task, battery,"
    " x, y, yaw, last_error, updated_at, status_since, trays, dock FROM robot_info"
    " WHERE removed_at IS NULL"
)
#: Every live waypoint (append ``AND ...`` or ``ORDER BY ...``).
WAYPOINT: Final = "SELECT name, x, y, yaw, kind FROM waypoints WHERE removed_at IS NULL"
#: One live robot or waypoint by name (portable ``?`` placeholder).
ROBOT_NAMED: Final = f"{ROBOT} AND name = ?"
WAYPOINT_NAMED: Final = f"{WAYPOINT} AND name = ?"
