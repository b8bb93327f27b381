"""Zones and leases on the live server: a robot drives a leg only once it holds every zone on it.

The rules are :class:`~serveur.core.leases.LeaseBook`'s (pure); :class:`Traffic` owns the book
and the zones and feeds it what happens:

* before each goal (:meth:`Traffic.lease_leg`, called by a robot controller's ``drive``), the
  zones the leg
  crosses — read off the planned path from the waypoint nearest the robot to its destination,
  widened by the robot's radius, plus the zones it stands in — are requested all at once. A
  robot that does not get them does not move: it stays where it is (at the pass, a table or its
  home: the legs start there, outside the aisles), its record says which zones it waits for,
  and its goal is sent when the grant comes (a ``lease`` report through its queue, so it is
  handled under its lock like any other);
* each pose (:meth:`Traffic.moved`) releases the zones the robot has left; the end of a leg releases
  the zones it is not standing in;
* a robot that goes Offline, is removed, stops or is taken by hand loses its place in the
  queue, and Offline or removed also its leases (it may be anywhere when it comes back);
* staff break a lease (``release``) stuck on a robot moved by hand;
* robots that wait for each other for ever (each standing in the other's zone) raise an alert
  naming them (see :meth:`LeaseBook.cycles`).

Without zones, or with ``CoreConfig.leases`` off, every leg goes at once, as before.
"""

from __future__ import annotations

import logging
from collections.abc import Callable
from typing import Any, Protocol

from serveur import protocol as P
from serveur.clock import Clock
from serveur.core.events import LeaseGranted, RobotEvent
from serveur.core.leases import Grant, LeaseBook, Zone, path_zones
from serveur.core.places import Places
from serveur.core.publisher import Publisher
from serveur.core.runtime import CoreConfig, Destination, Runtime
from serveur.domain import ZoneLease, ZoneRecord
from serveur.errors import NotFound
from serveur.status import RobotStatus
from serveur.store.base import Store

__all__ = ["Leg", "Traffic"]

log = logging.getLogger("serveur.core.engine")

S = RobotStatus
#: Statuses in which a robot drives legs; in any other its waiting request ends.
_MOVING = (S.DELIVERING, S.TRANSIT, S.MANUAL)


def _zone(z: ZoneRecord) -> Zone:
    return Zone(z.name, tuple((float(x), float(y)) for x, y in z.points), z.capacity)


class Leg(Protocol):
    """The robot a leg is for, as traffic needs it (a
    :class:`~serveur.core.robot.RobotController`)."""

    name: str
    rt: Runtime

    def publish(self) -> None: ...

    async def send_goal(self, dest: Destination) -> None: ...

    async def drive(self, dest: Destination) -> None: ...


class Traffic:
    """The live zones and their leases."""

    def __init__(
        self,
        store: Store,
        clock: Clock,
        config: CoreConfig,
        *,
        places: Places,
        publisher: Publisher,
        post: Callable[[str, RobotEvent], None],
    ) -> None:
        self.store = store
        self.clock = clock
        self.config = config
        self.places = places
        self.publisher = publisher
        #: Queue an event for a robot (a lease granted goes through the robot's queue).
        self._post = post
        self.leases = LeaseBook()
        self.zone_records: dict[str, ZoneRecord] = {}

    # -- zones ------------------------------------------------------------------------------

    async def load_zones(self) -> None:
        self.zone_records = {z.name: z for z in await self.store.zones.list_zones()}
        self.leases.set_zones(_zone(z) for z in self.zone_records.values())

    async def create_zone(self, msg: P.CreateZone, actor: str | None) -> dict[str, Any]:
        rec = ZoneRecord(
            name=msg.name,
            points=[(p[0], p[1]) for p in msg.points],
            capacity=msg.capacity,
            wait_at=msg.wait_at,
        )
        saved = await self.store.zones.put_zone(
            rec, replace=msg.replace, now=self.clock.epoch(), by=actor
        )
        self.zone_records[saved.name] = saved
        self.publisher.pub("zones", saved)
        self._granted(self.leases.set_zones(_zone(z) for z in self.zone_records.values()))
        return {"zone": saved}

    async def remove_zone(self, msg: P.SiteRemoveZone, actor: str | None) -> dict[str, Any]:
        gone = await self.store.zones.delete_zone(msg.zone, now=self.clock.epoch(), by=actor)
        self.zone_records.pop(gone.name, None)
        gone = gone.model_copy(update={"removed": True})
        self.publisher.pub("zones", gone)
        self._granted(self.leases.set_zones(_zone(z) for z in self.zone_records.values()))
        return {"zone": gone}

    async def release(self, msg: P.ReleaseMsg, actor: str | None) -> dict[str, Any]:
        if msg.zone not in self.leases.zones:
            raise NotFound(f"no zone named {msg.zone!r}", zone=msg.zone)
        broken, grants = self.leases.break_lease(msg.zone, msg.robot)
        if broken:
            log.warning("lease on %s broken by %s: %s", msg.zone, actor, ", ".join(broken))
            await self.store.events.add_event(
                "lease.broken",
                now=self.clock.epoch(),
                data={"zone": msg.zone, "robots": broken, "by": actor},
            )
        self._granted(grants)
        return {"broken": broken, "leases": [self._lease_row(msg.zone)]}

    def lease_rows(self) -> list[ZoneLease]:
        return [ZoneLease(**row) for row in self.leases.table()]  # type: ignore[arg-type]

    def _lease_row(self, zone: str) -> ZoneLease:
        return next(r for r in self.lease_rows() if r.zone == zone)

    # -- legs -------------------------------------------------------------------------------

    def _leases_on(self) -> bool:
        return self.config.leases and bool(self.leases.zones)

    def leg_zones(self, rt: Runtime, dest: Destination) -> list[str]:
        """The zones the robot's leg to ``dest`` crosses, and those it stands in."""
        goal = (dest.x, dest.y)
        if rt.pose is None:
            return path_zones([goal], self.leases.zones.values(), margin=self.config.robot_radius)
        here = (rt.pose[0], rt.pose[1])
        # The planned path between the waypoints nearest each end (a goal that is no waypoint,
        # Move here, included): what the robot's planner will drive, near enough.
        start = self.places.nearest(*here)
        end = dest.name if dest.name in self.places.waypoints else self.places.nearest(*goal)
        path = [here, goal]
        if start is not None and end is not None and start != end:
            path = [here, *self.places.path(start, end), goal]
        return path_zones(path, self.leases.zones.values(), margin=self.config.robot_radius)

    async def lease_leg(self, robot: Leg, dest: Destination) -> bool:
        """Ask for the leg's zones: True if the robot may go now, False if it waits."""
        if not self._leases_on():
            return True
        rt = robot.rt
        zones = self.leg_zones(rt, dest)
        grants = self.leases.request(rt.name, zones, self.clock.now())
        mine = any(g.robot == rt.name for g in grants)
        self._granted([g for g in grants if g.robot != rt.name])
        waiting = None if mine else list(self.leases.waiting(rt.name) or zones)
        if waiting != rt.waiting_for:
            rt.waiting_for = waiting
            rt.waiting_since = None if mine else self.clock.epoch()
            robot.publish()
        if not mine:
            log.info(
                "%s: waits for %s (held by or promised to %s)",
                rt.name,
                ", ".join(zones),
                ", ".join(self.leases.blockers(rt.name)) or "nobody",
            )
            spot = self._waiting_spot(rt)
            if spot is not None:
                await self._wait_outside(robot, dest, spot)
        self._publish_leases()
        return mine

    def _waiting_spot(self, rt: Runtime) -> Destination | None:
        """Where a refused robot should wait instead of where it stands: the waiting point of a
        zone it holds and stands in (else it would hold that zone while it waits for others,
        the one way robots can wait for each other for ever)."""
        if rt.pose is None:
            return None
        x, y = rt.pose[0], rt.pose[1]
        for name in self.leases.held(rt.name):
            zone, rec = self.leases.zones.get(name), self.zone_records.get(name)
            if zone is None or rec is None or rec.wait_at is None or not zone.contains(x, y):
                continue
            wp = self.places.waypoints.get(rec.wait_at)
            if wp is not None:
                return Destination("wait", wp.name, wp.x, wp.y, wp.yaw)
        return None

    async def _wait_outside(self, robot: Leg, dest: Destination, spot: Destination) -> None:
        """Leave the zone for its waiting point, holding nothing more; ask again from there."""
        rt = robot.rt
        self._granted(self.leases.withdraw(rt.name))
        log.info("%s: leaves its zone for %s to wait there", rt.name, spot.name)
        rt.resume_dest = dest
        rt.waiting_for = [spot.name]
        rt.dest = spot
        robot.publish()
        await robot.send_goal(spot)

    async def waited(self, robot: Leg, succeeded: bool) -> bool:
        """The goal to a waiting point ended: ask again for the leg it waited to drive.
        False if the robot did not get there (the caller reports the failure)."""
        rt = robot.rt
        resume, rt.resume_dest = rt.resume_dest, None
        rt.waiting_for = rt.waiting_since = None
        if not succeeded or resume is None or rt.state.status not in _MOVING:
            return succeeded
        await robot.drive(resume)
        return True

    async def lease_granted(self, robot: Leg) -> None:
        """A lease granted: the zones it waited for are its own now; drive the leg."""
        rt = robot.rt
        if rt.waiting_for is None:
            return
        waited = self.clock.epoch() - (rt.waiting_since or self.clock.epoch())
        rt.waiting_for = rt.waiting_since = None
        dest = rt.dest
        if dest is None or rt.state.status not in _MOVING or rt.goal_id is not None:
            self._granted(self.leases.expire(rt.name))
            robot.publish()
            return
        await self.store.events.add_event(
            "lease.waited",
            now=self.clock.epoch(),
            robot=rt.name,
            data={"zones": self.leases.held(rt.name), "waited_s": round(waited, 1)},
        )
        robot.publish()
        await robot.send_goal(dest)

    def moved(self, name: str, x: float, y: float) -> None:
        """A pose: zones left are released."""
        if self.leases.zones:
            grants = self.leases.moved(name, x, y)
            if grants:
                self._granted(grants)

    def leg_ended(self, rt: Runtime) -> None:
        if self.leases.zones:
            pose = rt.pose
            self._granted(self.leases.leg_over(rt.name, *(pose[:2] if pose else (None, None))))

    def lease_status(self, rt: Runtime, status: RobotStatus) -> None:
        """The robot's status changed: Offline ends its leases, a status without legs its
        waiting."""
        if not self.leases.zones:
            return
        if status is S.OFFLINE:
            grants = self.leases.expire(rt.name)
        elif status not in _MOVING:
            grants = self.leases.withdraw(rt.name)
        else:
            return
        if rt.waiting_for is not None:
            rt.waiting_for = rt.waiting_since = None
        self._granted(grants)

    def lease_forget(self, name: str) -> None:
        """A robot removed."""
        self._granted(self.leases.expire(name))

    def _granted(self, grants: list[Grant]) -> None:
        for g in grants:
            self._post(g.robot, LeaseGranted())
        self._publish_leases()

    def _publish_leases(self) -> None:
        for row in self.lease_rows():
            self.publisher.pub("leases", row)
