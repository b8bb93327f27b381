"""The owner's changes to the site, carried out on the live server: robots edited or removed,
waypoints renamed or removed, the site's settings.

:class:`Site` does them for the core: each change is stored first (:mod:`serveur.store.site`,
which re-checks what depends on its target in the same transaction), then applied to the
running server — a robot's link restarted or closed, the places' waypoints, the dispatcher's
tables, the screens' topics — and published, so every console sees it at once. A change the
store refuses leaves the running server untouched.

Settings the owner saves win over the command line's values from then on, across restarts;
settings never saved keep the command line's (``serveur serve --table-timeout`` is the
factory default, the console the restaurant's choice).
"""

from __future__ import annotations

import logging
from collections.abc import Awaitable, Callable
from pathlib import Path
from typing import Any, Protocol

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.robot import RobotController
from serveur.core.runtime import CoreConfig
from serveur.core.service import Service
from serveur.core.traffic import Traffic
from serveur.domain import Robot, WaypointRecord
from serveur.errors import Conflict, InvalidField
from serveur.robots.names import RosNames
from serveur.status import Event, RobotStatus, apply
from serveur.store.base import Store

__all__ = ["SITE_ACTIONS", "TARGET_WAIT", "Fleet", "Site"]

log = logging.getLogger("serveur.core.engine")

#: The target wait of a site whose owner has not set one (s): ten minutes from the pass to
#: the table for 95 % of dishes, a common aim for a busy restaurant's hot food.
TARGET_WAIT = 600.0
#: A robot's fields whose change means connecting to it anew.
_RELINK = ("url", "kinematics", "link")
#: The settings of the modes besides delivering, kept on the core's config (seconds or battery
#: fractions; serveur.core.runtime.CoreConfig says what each does).
MODE_SETTINGS = (
    "call_escalate",
    "bussing_wait",
    "bussing_max_delay",
    "charge_below",
    "charge_until",
    "cruise_pause",
    "cruise_resume",
)


class Fleet(Protocol):
    """The robots' registry, as the owner's changes need it (the core)."""

    def controller(self, name: str) -> RobotController:
        """The robot's controller; NotFound if there is none."""
        ...

    def has_robot(self, name: str) -> bool: ...

    def add_robot(self, robot: Robot) -> RobotController:
        """A controller for a newly registered robot, its link started."""
        ...

    async def remove_robot(self, ctl: RobotController) -> None:
        """The robot's controller stopped (link closed, events ended) and forgotten."""
        ...


class Site:
    """The ``site`` verb's changes (all but the audit search) and the site's settings."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: CoreConfig,
        *,
        fleet: Fleet,
        records: dict[str, Robot],
        places: Places,
        publisher: Publisher,
        service: Service,
        traffic: Traffic,
        kick: Callable[[], None],
        calls_moved: Callable[[], Awaitable[None]] | None = None,
    ) -> None:
        self.store = store
        self.clock = clock
        self.config = config
        self.fleet = fleet
        self._robots = records
        self.places = places
        self.publisher = publisher
        self.service = service
        self.traffic = traffic
        self._kick = kick
        #: The call desk re-reads its open calls when a table is renamed or removed.
        self._calls_moved = calls_moved
        #: The pages' languages: those offered, and the one a device without a choice gets.
        self.languages = list(config.languages)
        self.language = config.language
        #: Staff may watch the robots' cameras (the owner can switch them off for the site).
        self.cameras = True
        #: The restaurant's name, and its address as its tablets reach it (setup links).
        self.name = ""
        self.public_url: str | None = None
        #: The wait the owner aims at (s): 95 % of dishes at their table within it. Nothing in
        #: the service acts on it; the forecast judges each fleet size against it.
        self.target_wait = TARGET_WAIT

    async def site(self, msg: Any, actor: str | None) -> dict[str, Any]:
        """The ``site`` verb's actions the core carries out (the audit search is the
        server's), found through :data:`SITE_ACTIONS`."""
        handler = SITE_ACTIONS.get(type(msg))
        if handler is None:
            raise InvalidField(f"site {msg.action!r} is not the core's")
        return await handler(self, msg, actor)

    # -- settings ---------------------------------------------------------------------------

    def settings(self) -> dict[str, Any]:
        """The settings as they apply now (the ``settings`` topic's record)."""
        return {
            "table_timeout": self.config.table_timeout,
            "trays": self.config.capacity,
            "auto_depart": self.config.auto_depart,
            "languages": list(self.languages),
            "language": self.language,
            "cameras": self.cameras,
            "name": self.name,
            "public_url": self.public_url,
            "target_wait": self.target_wait,
            **{k: getattr(self.config, k) for k in MODE_SETTINGS},
        }

    async def load_settings(self) -> None:
        """Apply the settings the owner saved (at start; unknown names are ignored)."""
        self._apply_settings(await self.store.service.get_settings())

    def _apply_settings(self, values: dict[str, Any]) -> None:
        if "table_timeout" in values:
            self.config.table_timeout = values["table_timeout"]
        if "trays" in values:
            self.config.capacity = int(values["trays"])
        if "auto_depart" in values:
            self.config.auto_depart = bool(values["auto_depart"])
        if "cameras" in values:
            self.cameras = bool(values["cameras"])
        if "name" in values:
            self.name = str(values["name"] or "")
        if "public_url" in values:
            self.public_url = values["public_url"] or None
        if "target_wait" in values:
            self.target_wait = float(values["target_wait"])
        for k in MODE_SETTINGS:
            if k in values and values[k] is not None:
                setattr(self.config, k, float(values[k]))
        if "languages" in values:
            self.languages = [x for x in values["languages"] if x in P.LANGUAGES] or ["en"]
        if "language" in values and values["language"] in self.languages:
            self.language = values["language"]
        elif self.language not in self.languages:
            self.language = self.languages[0]

    async def set_settings(self, msg: P.SiteSetSettings, actor: str | None) -> dict[str, Any]:
        changes = msg.changes()
        langs = changes.get("languages", self.languages)
        lang = changes.get("language", self.language if self.language in langs else langs[0])
        if lang not in langs:
            raise InvalidField(f"{lang} is not among the languages offered", field="language")
        changes["language"] = lang
        below = changes.get("charge_below", self.config.charge_below)
        until = changes.get("charge_until", self.config.charge_until)
        if until <= below:
            raise InvalidField(
                f"a robot would charge below {below:g} and stop at {until:g}: charge_until"
                " must be above charge_below",
                field="charge_until",
            )
        await self.store.service.put_settings(changes, now=self.clock.epoch(), by=actor)
        self._apply_settings(changes)
        self.publisher.pub("settings", self.settings())
        self._kick()  # more trays, no table timeout...: what is queued may go now
        return {"settings": self.settings()}

    # -- robots -----------------------------------------------------------------------------

    async def register_robot(self, msg: P.CreateRobot) -> dict[str, Any]:
        """``create robot``: store it (a resend with the same fields returns it) and connect."""
        if msg.home is not None:
            self.places.waypoint(msg.home)
        link = dict(msg.link or {})
        try:
            RosNames.from_options(link)
        except ValueError as exc:
            raise InvalidField(str(exc), field="link") from None
        robot = await self.store.robots.add_robot(
            msg.name,
            msg.url,
            home=msg.home,
            kinematics=msg.kinematics,
            link=link,
            now=self.clock.epoch(),
        )
        if msg.trays is not None and msg.trays != robot.trays:
            await self.store.robots.set_trays(robot.name, msg.trays, now=self.clock.epoch())
            robot = await self.store.robots.get_robot(robot.name)
            if robot.name in self._robots:
                self._robots[robot.name] = robot
        if self.fleet.has_robot(robot.name):
            ctl = self.fleet.controller(robot.name)
        else:
            ctl = self.fleet.add_robot(robot)
        ctl.publish()
        return {"robot": ctl.view()}

    async def edit_robot(self, msg: P.SiteEditRobot, actor: str | None) -> dict[str, Any]:
        ctl = self.fleet.controller(msg.robot)
        rt = ctl.rt
        changes = msg.changes()
        if "link" in changes:
            try:
                RosNames.from_options(changes["link"])
            except ValueError as exc:
                raise InvalidField(str(exc), field="link") from None
        if changes.get("home") is not None:
            self.places.waypoint(changes["home"])
        async with rt.lock:
            old = self._robots[rt.name]
            relink = any(k in changes and changes[k] != getattr(old, k) for k in _RELINK)
            if relink and old.current_task is not None:
                raise Conflict(
                    f"robot {rt.name} is on trip {old.current_task}: change its address, drive"
                    " or ROS options when it is back",
                    robot=rt.name,
                    trip=old.current_task,
                )
            robot = await self.store.robots.edit_robot(
                rt.name, changes, now=self.clock.epoch(), by=actor
            )
            # Keep the live status fields: the core's record is the one the links update.
            self._robots[rt.name] = old.model_copy(
                update={k: getattr(robot, k) for k in (*_RELINK, "home", "trays", "dock")}
            )
            if relink and rt.link is not None:
                log.info("%s: reconnecting to %s (edited by %s)", rt.name, robot.url, actor)
                await rt.link.close()
                rt.link_error = None
                if rt.state.status is not RobotStatus.OFFLINE:
                    # The old link is closed now: the reply says Offline, as the robot is
                    # until the new address answers (it then resumes what it was doing),
                    # instead of the status of a link that no longer exists.
                    edited = sorted(k for k in _RELINK if k in changes)
                    await ctl.save_state(
                        apply(rt.state, Event.LINK_DOWN),
                        error=f"reconnecting: {', '.join(edited)} edited",
                        data={"event": Event.LINK_DOWN.value},
                    )
                ctl.start_link()
        ctl.publish()
        self._kick()
        return {"robot": ctl.view()}

    async def remove_robot(self, msg: P.SiteRemoveRobot, actor: str | None) -> dict[str, Any]:
        ctl = self.fleet.controller(msg.robot)
        rt = ctl.rt
        async with rt.lock:
            revoked = await self.store.robots.remove_robot(
                rt.name, now=self.clock.epoch(), by=actor
            )
            robot = ctl.view()
        await self.fleet.remove_robot(ctl)
        self.publisher.pub("robots", robot.model_copy(update={"removed": True}))
        log.info("%s: removed by %s", rt.name, actor)
        return {"robot": robot.model_copy(update={"removed": True}), "revoked": revoked}

    # -- waypoints --------------------------------------------------------------------------

    async def dependents(self, msg: P.SiteDependents) -> dict[str, Any]:
        wp = self.places.waypoint(msg.waypoint)
        deps = await self.store.waypoints.waypoint_dependents(wp.name)
        return {"waypoint": wp, "dependents": deps.as_dict()}

    async def rename_waypoint(self, msg: P.SiteRenameWaypoint, actor: str | None) -> dict[str, Any]:
        old = self.places.waypoint(msg.waypoint)
        wp, deps = await self.store.waypoints.rename_waypoint(
            old.name, msg.name, now=self.clock.epoch(), by=actor
        )
        self._waypoint_gone(old)
        self.places.put(wp)
        self.publisher.pub("waypoints", wp)
        for robot in deps.homes:
            if self.fleet.has_robot(robot):
                ctl = self.fleet.controller(robot)
                ctl.record = ctl.record.model_copy(update={"home": wp.name})
                ctl.publish()
        for robot in deps.docks:
            if self.fleet.has_robot(robot):
                ctl = self.fleet.controller(robot)
                ctl.record = ctl.record.model_copy(update={"dock": wp.name})
                ctl.publish()
        if self._calls_moved is not None:
            await self._calls_moved()
        block = self.service.blocks.pop(old.name, None)
        if block is not None:
            self.publisher.pub("blocks", block.model_copy(update={"reason": ""}))
            moved = block.model_copy(update={"table": wp.name})
            self.service.blocks[wp.name] = moved
            self.publisher.pub("blocks", moved)
        await self.publisher.pub_orders(deps.orders)
        return {"waypoint": wp, "renamed": old.name, "dependents": deps.as_dict()}

    async def remove_waypoint(self, msg: P.SiteRemoveWaypoint, actor: str | None) -> dict[str, Any]:
        wp = self.places.waypoint(msg.waypoint)
        deps = await self.store.waypoints.remove_waypoint(wp.name, now=self.clock.epoch(), by=actor)
        self._waypoint_gone(wp)
        block = self.service.blocks.pop(wp.name, None)
        if block is not None:
            self.publisher.pub("blocks", block.model_copy(update={"reason": ""}))
        if self._calls_moved is not None:
            await self._calls_moved()
        return {"waypoint": wp.model_copy(update={"removed": True}), "revoked": deps.tokens}

    # -- the site as files (a replay of it) ---------------------------------------------

    def write_site(self, folder: Path) -> tuple[Path, float | None, int]:
        """The site's map and waypoints as ``serveur replay --map`` reads them, written into
        ``folder``; returns the map YAML's path, the table timeout and the trays."""
        from serveur.maps.mapio import Waypoint, save_map_cells, save_waypoints

        m = self.places.map
        if m is None:
            raise Conflict("the server has no map yet: a replay needs the restaurant's map")
        yaml_path = folder / "site.yaml"
        save_map_cells(m.data, m.width, m.height, m.resolution, m.origin, yaml_path)
        wps = {
            w.name: Waypoint(w.name, w.x, w.y, w.yaw, w.kind.value)
            for w in self.places.waypoints.values()
        }
        save_waypoints(wps, folder / "site_waypoints.json")
        return yaml_path, self.config.table_timeout, self.config.capacity

    def _waypoint_gone(self, wp: WaypointRecord) -> None:
        self.places.remove(wp.name)
        self.publisher.pub("waypoints", wp.model_copy(update={"removed": True}))

    async def _settings(self, msg: P.SiteSettings, actor: str | None) -> dict[str, Any]:
        return {"settings": self.settings()}

    async def _remove_zone(self, msg: P.SiteRemoveZone, actor: str | None) -> dict[str, Any]:
        return await self.traffic.remove_zone(msg, actor)

    async def _dependents(self, msg: P.SiteDependents, actor: str | None) -> dict[str, Any]:
        return await self.dependents(msg)


#: ``site`` action message -> what it does.
SITE_ACTIONS: dict[type, Callable[[Site, Any, str | None], Awaitable[dict[str, Any]]]] = {
    P.SiteEditRobot: Site.edit_robot,
    P.SiteRemoveRobot: Site.remove_robot,
    P.SiteDependents: Site._dependents,
    P.SiteRenameWaypoint: Site.rename_waypoint,
    P.SiteRemoveWaypoint: Site.remove_waypoint,
    P.SiteSetSettings: Site.set_settings,
    P.SiteSettings: Site._settings,
    P.SiteRemoveZone: Site._remove_zone,
}
