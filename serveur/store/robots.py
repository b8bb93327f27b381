"""The robots' rows: registering, editing, removing a robot, and what its link reports (status,
pose, trays). One part of :class:`~serveur.store.base.Store`, written once for every backend.

A removed robot keeps its row, marked ``removed_at`` (past trips and orders name it); every
read skips it (:mod:`serveur.store.live`), and registering the name again revives the row.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from typing import Any, Final

from serveur.domain import Robot, WaypointKind
from serveur.errors import Conflict, InvalidField, NotFound
from serveur.status import RobotMode, RobotStatus
from serveur.store import rows
from serveur.store.checks import check_finite, check_text, link_json, to_json
from serveur.store.live import ROBOT, ROBOT_NAMED
from serveur.store.sql import Db, Tx, one

__all__ = ["REVIVE_ROBOT", "Robots"]

#: A removed robot registered again: its row, reset to a new robot's state with the new fields.
#: Parameters: url, home, kinematics, link (JSON), updated_at, status_since, name.
REVIVE_ROBOT: Final = (
    "UPDATE robot_info SET url = ?, home = ?, kinematics = ?, link = ?, mode = 'off',"
    " status = 'Offline', resume = NULL, current_task = NULL, battery = NULL, x = NULL,"
    " y = NULL, yaw = NULL, last_error = NULL, trays = NULL, updated_at = ?, status_since = ?,"
    " removed_at = NULL WHERE name = ? AND removed_at IS NOT NULL"
)


class Robots:
    """Robot methods of the store (``store.robots``)."""

    def __init__(self, db: Db) -> None:
        self._db = db

    async def add_robot(
        self,
        name: str,
        url: str,
        *,
        home: str | None,
        kinematics: str = "omni",
        link: Mapping[str, str] | None = None,
        now: float,
    ) -> Robot:
        """Register a robot (Offline, mode off). A resend with the same fields returns it.

        ``link``: the robot's ROS name options (:class:`~serveur.robots.names.RosNames`,
        checked by the caller), kept as given.
        """
        dialect = self._db.dialect
        dialect.check_name(name, "name")
        check_text(url, "url")
        dialect.check_name(kinematics, "kinematics")

        async def work(tx: Tx) -> Robot:
            row = await one(tx, ROBOT_NAMED + tx.dialect.for_update, (name,))
            if row is not None:
                robot = Robot(**row)
                if (robot.url, robot.home, robot.kinematics, robot.link) == (
                    url,
                    home,
                    kinematics,
                    dict(link or {}),
                ):
                    return robot
                raise Conflict(
                    f"a robot named {name!r} exists with another url, home, kinematics or link",
                    robot=name,
                )
            if home is not None:
                await rows.get_waypoint(tx, home)
            revive = (url, home, kinematics, link_json(link), now, now, name)
            if not await tx.run(REVIVE_ROBOT, revive):
                await tx.run(
                    "INSERT INTO robot_info (name, url, home, kinematics, link, updated_at,"
                    " status_since) VALUES (?, ?, ?, ?, ?, ?, ?)",
                    (name, url, home, kinematics, link_json(link), now, now),
                )
            data: dict[str, Any] = {"url": url, "home": home, "kinematics": kinematics}
            if link:
                data["link"] = dict(link)
            await rows.add_event(tx, "robot.added", now, robot=name, data=data)
            return await rows.get_robot(tx, name)

        return await self._db.transact(work, "write")

    async def update_robot(
        self,
        name: str,
        *,
        url: str | None = None,
        home: str | None = None,
        link: Mapping[str, str] | None = None,
        now: float | None = None,
    ) -> Robot:
        """Change a robot's url, home and/or link options (``None`` keeps the current value).

        ``now`` (an addition to the agreed signature) stamps the event; without it the event
        gets the latest event's time, keeping the trail ordered (wall time would not match a
        simulated clock)."""
        if url is not None:
            check_text(url, "url")
        if home is not None:
            check_text(home, "home")

        async def work(tx: Tx) -> Robot:
            robot = await rows.get_robot(tx, name, lock=True)
            new_url = robot.url if url is None else url
            new_home = robot.home if home is None else home
            new_link = robot.link if link is None else dict(link)
            if (new_url, new_home, new_link) == (robot.url, robot.home, robot.link):
                return robot
            if new_home is not None and new_home != robot.home:
                await rows.get_waypoint(tx, new_home)
            stamp = now
            if stamp is None:
                latest = await one(tx, "SELECT coalesce(max(ts), 0) AS ts FROM events")
                stamp = float(latest["ts"]) if latest else 0.0
            await tx.run(
                "UPDATE robot_info SET url = ?, home = ?, link = ? WHERE name = ?",
                (new_url, new_home, link_json(new_link), name),
            )
            data: dict[str, Any] = {"url": new_url, "home": new_home}
            if new_link != robot.link:
                data["link"] = new_link
            await rows.add_event(tx, "robot.updated", float(stamp or 0.0), robot=name, data=data)
            return await rows.get_robot(tx, name)

        return await self._db.transact(work, "write")

    async def get_robot(self, name: str) -> Robot:
        return await self._db.transact(lambda tx: rows.get_robot(tx, name), "auto")

    async def list_robots(self) -> list[Robot]:
        """All robots, by name."""
        found = await self._db.transact(lambda tx: tx.all(f"{ROBOT} ORDER BY name"), "auto")
        return [Robot(**r) for r in found]

    async def save_robot_state(
        self,
        name: str,
        *,
        status: RobotStatus,
        mode: RobotMode,
        resume: RobotStatus | None,
        last_error: str | None,
        now: float,
        event: str = "robot.status",
        data: Mapping[str, Any] | None = None,
    ) -> Robot:
        """Persist a status change and its event together (one transaction)."""
        try:
            values = (
                RobotStatus(status).value,
                RobotMode(mode).value,
                None if resume is None else RobotStatus(resume).value,
            )
        except ValueError as exc:
            raise InvalidField(str(exc), field="status") from exc
        self._db.dialect.check_name(event, "event")
        payload: dict[str, Any] = {
            "status": values[0],
            "mode": values[1],
            "resume": values[2],
            "last_error": last_error,
        }
        payload.update(data or {})
        to_json(payload)  # refuse bad data before touching the database

        async def work(tx: Tx) -> Robot:
            changed = await tx.run(
                # status_since first: MariaDB assigns left to right, so it must still see
                # the old status (SQLite always does).
                "UPDATE robot_info SET"
                " status_since = CASE WHEN status = ? THEN status_since ELSE ? END,"
                " status = ?, mode = ?, resume = ?, last_error = ?,"
                " updated_at = ? WHERE name = ?",
                (values[0], now, *values, last_error, now, name),
            )
            if changed != 1:
                raise NotFound(f"no robot named {name!r}", robot=name)
            await rows.add_event(tx, event, now, robot=name, data=payload)
            return await rows.get_robot(tx, name)

        return await self._db.transact(work, "write")

    async def save_robot_pose(
        self, name: str, *, x: float, y: float, yaw: float, battery: float | None, now: float
    ) -> None:
        """Persist the last pose (no event: it is called often, throttled by the caller)."""
        pose = (check_finite(x, "x"), check_finite(y, "y"), check_finite(yaw, "yaw"))
        if battery is not None and not 0.0 <= check_finite(battery, "battery") <= 1.0:
            raise InvalidField("battery must be between 0 and 1", field="battery")
        # One absolute UPDATE: running it twice is harmless, so even a lost COMMIT may retry.
        changed = await self._db.transact(
            lambda tx: tx.run(
                "UPDATE robot_info SET x = ?, y = ?, yaw = ?, battery = ?, updated_at = ?"
                " WHERE name = ?",
                (*pose, battery, now, name),
            ),
            "auto",
        )
        if changed != 1:
            raise NotFound(f"no robot named {name!r}", robot=name)

    async def edit_robot(
        self, name: str, changes: Mapping[str, Any], *, now: float, by: str | None = None
    ) -> Robot:
        """Change a robot's ``url``, ``home``, ``kinematics``, ``link`` (a dict), ``trays``
        (None: the site's) and/or ``dock`` (a place of kind dock); fields not in ``changes``
        are kept. One event lists what changed; nothing changed is a no-op."""
        allowed = {"url", "home", "kinematics", "link", "trays", "dock"}
        if not changes or set(changes) - allowed:
            raise InvalidField(f"a robot edit changes some of {sorted(allowed)}", field="changes")

        async def work(tx: Tx) -> Robot:
            row = await one(tx, ROBOT_NAMED, (name,))
            if row is None:
                raise NotFound(f"no robot named {name!r}", robot=name)
            old = {**row, "link": json.loads(row["link"] or "{}")}
            new = {k: v for k, v in changes.items() if old[k] != v}
            if new.get("home") is not None:
                await rows.get_waypoint(tx, new["home"])
            if new.get("dock") is not None:
                dock = await rows.get_waypoint(tx, new["dock"])
                if dock.kind is not WaypointKind.DOCK:
                    raise InvalidField(
                        f"{dock.name} is not a dock (it is a {dock.kind.value})",
                        field="dock",
                        waypoint=dock.name,
                    )
            if new:
                sets = ", ".join(f"{k} = ?" for k in new)
                values = [
                    json.dumps(v, sort_keys=True) if k == "link" else v for k, v in new.items()
                ]
                await tx.run(
                    f"UPDATE robot_info SET {sets}, updated_at = ? WHERE name = ?",
                    (*values, now, name),
                )
                await rows.add_event(tx, "robot.updated", now, robot=name, data={**new, "by": by})
            return await rows.get_robot(tx, name)

        return await self._db.transact(work, "write")

    async def remove_robot(self, name: str, *, now: float, by: str | None = None) -> list[int]:
        """Remove a robot with no trip (Conflict otherwise); its screen tokens are revoked.
        Returns the revoked token ids."""

        async def work(tx: Tx) -> list[int]:
            row = await one(tx, ROBOT_NAMED, (name,))
            if row is None:
                raise NotFound(f"no robot named {name!r}", robot=name)
            if row["current_task"] is not None:
                raise Conflict(
                    f"robot {name} is on trip {row['current_task']}: cancel it first",
                    robot=name,
                    trip=row["current_task"],
                )
            await tx.run(
                "UPDATE robot_info SET removed_at = ?, status = 'Offline', mode = 'off',"
                " resume = NULL, updated_at = ? WHERE name = ?",
                (now, now, name),
            )
            revoked = await rows.revoke_where(
                tx, "role = 'robot-screen' AND robot = ?", (name,), now
            )
            data = {"by": by, "tokens": revoked}
            await rows.add_event(tx, "robot.removed", now, robot=name, data=data)
            return revoked

        return await self._db.transact(work, "write")

    async def set_trays(self, robot: str, trays: int | None, *, now: float) -> None:
        """How many tables one trip of ``robot`` may serve (None: the site's default)."""
        if trays is not None and (isinstance(trays, bool) or not 1 <= trays <= 12):
            raise InvalidField("trays must be a whole number from 1 to 12", field="trays")

        async def work(tx: Tx) -> None:
            if not await tx.run("UPDATE robot_info SET trays = ? WHERE name = ?", (trays, robot)):
                row = await one(tx, "SELECT trays FROM robot_info WHERE name = ?", (robot,))
                if row is None:
                    raise NotFound(f"no robot named {robot!r}", robot=robot)
            await rows.add_event(tx, "robot.trays", now, robot=robot, data={"trays": trays})

        await self._db.transact(work, "write")
