"""Zones and their leases: which robot may drive through which narrow part of the room (pure).

Two robots meeting head-on in a 70 cm aisle block each other: move_base and Nav2 replan,
wait, back off, and often deadlock (the simulator reproduces it, tests/sim/
test_sim_robots_see_each_other.py). The owner therefore draws *zones* — aisles, doorways, the
pass — each with a capacity (usually 1), and a robot may only drive a leg through a zone it
holds a lease on. This is the idea of Open-RMF's mutex groups, VDA 5050 3.0's release zones
and Pudu's traffic-control zones, without RMF's traffic negotiation (its users' top complaint:
delays and deadlocks).

The rules, as :class:`LeaseBook` applies them:

* **All at once.** Before a leg a robot asks for every zone on its path and the zones it
  stands in, and gets all or none: it never holds some while waiting for the rest (no
  hold-and-wait), so robots cannot deadlock on leases they drive under.
* **First come, first served.** Requests wait in arrival order; a request is granted only if
  every zone has room *and* no earlier waiting request needs one of its zones. A robot is never
  overtaken for ever (no starvation). Robots that share no zone never wait for each other.
* **Deterministic.** Zones are taken and listed in name order; equal inputs, equal grants.
* **Released on leaving.** A held zone is released once the robot's pose is outside it and it
  has either been inside since the grant (it drove through) or its leg is over.
* **Expiry.** A robot that goes Offline (or is stopped, removed, sent elsewhere) loses its
  leases and its place in the queue.
* **Staff break a lease** stuck on a robot that was pushed away by hand.

A robot standing still inside a zone at the start of a leg (a table's spot drawn inside an
aisle) holds that zone while it waits for the others: the one case of hold-and-wait. Two such
robots wanting each other's zone wait for ever; :meth:`LeaseBook.cycles` finds them so the
server can raise an alert. Drawing zones that leave the tables' and homes' spots outside
avoids it (docs/zones.md).

Geometry is plain floats: a zone is a simple polygon in map metres.
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field

__all__ = [
    "Grant",
    "LeaseBook",
    "Zone",
    "path_zones",
    "point_in_polygon",
    "segment_hits_polygon",
]

Point = tuple[float, float]


@dataclass(frozen=True, slots=True)
class Zone:
    """A part of the room leased to at most ``capacity`` robots at a time."""

    name: str
    points: tuple[Point, ...]
    capacity: int = 1

    def contains(self, x: float, y: float) -> bool:
        return point_in_polygon((x, y), self.points)


def point_in_polygon(p: Point, poly: Sequence[Point]) -> bool:
    """Even-odd rule; a point on an edge counts as inside."""
    x, y = p
    inside = False
    for (x1, y1), (x2, y2) in zip(poly, [*poly[1:], poly[0]], strict=True):
        if _on_segment(p, (x1, y1), (x2, y2)):
            return True
        if (y1 > y) != (y2 > y):
            cross = x1 + (y - y1) * (x2 - x1) / (y2 - y1)
            if x < cross:
                inside = not inside
    return inside


def _orient(a: Point, b: Point, c: Point) -> float:
    return (b[0] - a[0]) * (c[1] - a[1]) - (b[1] - a[1]) * (c[0] - a[0])


def _on_segment(p: Point, a: Point, b: Point, eps: float = 1e-9) -> bool:
    if abs(_orient(a, b, p)) > eps * max(1.0, math.dist(a, b)):
        return False
    return min(a[0], b[0]) - eps <= p[0] <= max(a[0], b[0]) + eps and (
        min(a[1], b[1]) - eps <= p[1] <= max(a[1], b[1]) + eps
    )


def _segments_cross(a: Point, b: Point, c: Point, d: Point) -> bool:
    o1, o2, o3, o4 = _orient(a, b, c), _orient(a, b, d), _orient(c, d, a), _orient(c, d, b)
    if ((o1 > 0) != (o2 > 0)) and ((o3 > 0) != (o4 > 0)) and 0 not in (o1, o2, o3, o4):
        return True
    return any(_on_segment(p, s, t) for p, s, t in ((c, a, b), (d, a, b), (a, c, d), (b, c, d)))


def segment_hits_polygon(a: Point, b: Point, poly: Sequence[Point]) -> bool:
    """Does the segment ``a`` to ``b`` touch the polygon (an end inside, or an edge crossed)?"""
    if point_in_polygon(a, poly) or point_in_polygon(b, poly):
        return True
    return any(_segments_cross(a, b, p, q) for p, q in zip(poly, [*poly[1:], poly[0]], strict=True))


def path_zones(path: Sequence[Point], zones: Iterable[Zone], *, margin: float = 0.0) -> list[str]:
    """Names (sorted) of the zones a path touches. ``margin`` (m): a robot's footprint reaches
    this far beyond its centre line, so a zone that close to the path counts too."""
    segments = list(itertools.pairwise(path)) or [(path[0], path[0])]
    hit: list[str] = []
    for z in zones:
        if any(_segment_polygon_distance(a, b, z.points) <= margin for a, b in segments):
            hit.append(z.name)
    return sorted(hit)


def _point_segment_distance(p: Point, a: Point, b: Point) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    if length2 == 0:
        return math.dist(p, a)
    t = max(0.0, min(1.0, ((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / length2))
    return math.dist(p, (a[0] + t * dx, a[1] + t * dy))


def _segment_polygon_distance(a: Point, b: Point, poly: Sequence[Point]) -> float:
    """0 if the segment touches the polygon, else the shortest distance between them (two
    segments that do not cross are closest at an end of one of them)."""
    if segment_hits_polygon(a, b, poly):
        return 0.0
    edges = list(zip(poly, [*poly[1:], poly[0]], strict=True))
    ends = (_point_segment_distance(e, p, q) for p, q in edges for e in (a, b))
    corners = (_point_segment_distance(v, a, b) for v in poly)
    return min(itertools.chain(ends, corners))


@dataclass(frozen=True, slots=True)
class Grant:
    """A waiting request granted: the robot may drive its leg now."""

    robot: str
    zones: tuple[str, ...]


@dataclass
class _Request:
    robot: str
    zones: tuple[str, ...]
    seq: int
    since: float


@dataclass
class _Holding:
    zones: set[str] = field(default_factory=set)
    entered: set[str] = field(default_factory=set)  # held zones the robot has been inside
    leg_over: bool = False


class LeaseBook:
    """The zones, who holds which, and who waits for what. Pure: times are given."""

    def __init__(self, zones: Iterable[Zone] = ()) -> None:
        self.zones: dict[str, Zone] = {z.name: z for z in zones}
        self._held: dict[str, _Holding] = {}
        self._queue: list[_Request] = []
        self._seq = itertools.count()

    # -- what is -----------------------------------------------------------------------------

    def holders(self, zone: str) -> list[str]:
        """Robots holding ``zone``, by name."""
        return sorted(r for r, h in self._held.items() if zone in h.zones)

    def held(self, robot: str) -> list[str]:
        h = self._held.get(robot)
        return sorted(h.zones) if h else []

    def waiting(self, robot: str) -> tuple[str, ...] | None:
        """The zones ``robot`` waits for (its whole request), or None if it does not wait."""
        for req in self._queue:
            if req.robot == robot:
                return req.zones
        return None

    def waiting_since(self, robot: str) -> float | None:
        for req in self._queue:
            if req.robot == robot:
                return req.since
        return None

    def blockers(self, robot: str) -> list[str]:
        """The robots ``robot`` waits behind: holders of its zones, and earlier requests."""
        zones = self.waiting(robot)
        if zones is None:
            return []
        out: set[str] = set()
        for z in zones:
            out.update(r for r in self.holders(z) if r != robot)
        for req in self._queue:
            if req.robot == robot:
                break
            if set(req.zones) & set(zones):
                out.add(req.robot)
        return sorted(out)

    def table(self) -> list[dict[str, object]]:
        """Every zone with its holders and waiting robots (the ``leases`` topic's view)."""
        rows = []
        for name in sorted(self.zones):
            rows.append(
                {
                    "zone": name,
                    "capacity": self.zones[name].capacity,
                    "holders": self.holders(name),
                    "waiting": [q.robot for q in self._queue if name in q.zones],
                }
            )
        return rows

    # -- changes -----------------------------------------------------------------------------

    def set_zones(self, zones: Iterable[Zone]) -> list[Grant]:
        """Zones drawn, edited or removed. Leases on a removed zone end; waiting requests
        forget it. A zone whose capacity shrank keeps its holders until they leave."""
        self.zones = {z.name: z for z in zones}
        for h in self._held.values():
            h.zones &= set(self.zones)
            h.entered &= h.zones
        for req in self._queue:
            req.zones = tuple(z for z in req.zones if z in self.zones)
        return self._grant()

    def request(self, robot: str, zones: Iterable[str], now: float) -> list[Grant]:
        """``robot`` starts a leg through ``zones`` (with those it stands in). The grants this
        makes: ``robot``'s own among them means go now (it holds them all); without it, it
        waits in the queue. Others may be granted too (zones this robot gave up). A new
        request replaces the robot's waiting one, and its leases from the last leg are given
        up except those it asks again (it cannot keep an old lease while waiting)."""
        wanted = tuple(sorted({z for z in zones if z in self.zones}))
        self._queue = [q for q in self._queue if q.robot != robot]
        h = self._held.setdefault(robot, _Holding())
        h.zones &= set(wanted)
        h.entered &= h.zones
        h.leg_over = False
        self._queue.append(_Request(robot, wanted, next(self._seq), now))
        return self._grant()

    def moved(self, robot: str, x: float, y: float) -> list[Grant]:
        """A pose: zones entered are noted, zones left are released (and what waited on them
        may be granted)."""
        h = self._held.get(robot)
        if h is None or not h.zones:
            return []
        freed = False
        for name in sorted(h.zones):
            inside = self.zones[name].contains(x, y)
            if inside:
                h.entered.add(name)
            elif name in h.entered or h.leg_over:
                h.zones.discard(name)
                h.entered.discard(name)
                freed = True
        return self._grant() if freed else []

    def leg_over(self, robot: str, x: float | None, y: float | None) -> list[Grant]:
        """The leg ended (arrived, failed, cancelled): zones the robot is not inside go now;
        the one it stands in goes when it leaves."""
        h = self._held.get(robot)
        if h is None:
            return []
        h.leg_over = True
        if x is None or y is None:
            return []
        return self.moved(robot, x, y) if h.zones else []

    def expire(self, robot: str) -> list[Grant]:
        """``robot`` is Offline, stopped, removed or sent elsewhere: its leases and its
        waiting request end."""
        self._queue = [q for q in self._queue if q.robot != robot]
        self._held.pop(robot, None)
        return self._grant()

    def withdraw(self, robot: str) -> list[Grant]:
        """``robot`` no longer waits (its leases, if any, stay)."""
        before = len(self._queue)
        self._queue = [q for q in self._queue if q.robot != robot]
        return self._grant() if len(self._queue) != before else []

    def break_lease(self, zone: str, robot: str | None = None) -> tuple[list[str], list[Grant]]:
        """Staff take ``zone`` back from ``robot`` (from every holder if None). Returns the
        robots whose lease was broken, and what that lets go."""
        broken = [r for r in self.holders(zone) if robot is None or r == robot]
        for r in broken:
            self._held[r].zones.discard(zone)
            self._held[r].entered.discard(zone)
        return broken, (self._grant() if broken else [])

    def cycles(self) -> list[list[str]]:
        """Groups of waiting robots that wait for each other (each holds what the next one
        needs): they will wait for ever unless someone moves one of them."""
        waits = {q.robot: set(self.blockers(q.robot)) for q in self._queue}
        found: list[list[str]] = []
        seen: set[str] = set()
        for start in sorted(waits):
            path: list[str] = []
            node: str | None = start
            while node is not None and node in waits and node not in path:
                path.append(node)
                nxt = sorted(waits[node] & set(waits))
                node = nxt[0] if nxt else None
            if node is not None and node in path:
                cycle = path[path.index(node) :]
                key = frozenset(cycle)
                if not key & seen:
                    seen |= key
                    found.append(sorted(cycle))
        return found

    # -- granting ----------------------------------------------------------------------------

    def _room(self, zone: str, robot: str) -> bool:
        holders = [r for r in self.holders(zone) if r != robot]
        return len(holders) < self.zones[zone].capacity

    def _grant(self) -> list[Grant]:
        """Grant waiting requests in arrival order: each gets all its zones if they have room
        and no earlier waiting request needs any of them."""
        granted: list[Grant] = []
        claimed: set[str] = set()  # zones an earlier request still waits for
        keep: list[_Request] = []
        for req in self._queue:
            h = self._held.setdefault(req.robot, _Holding())
            # A zone the robot holds already (it stands in it) is its own: a later claim on it
            # waits for this robot to drive out, so it must not hold this robot back.
            new = set(req.zones) - h.zones
            if not new & claimed and all(self._room(z, req.robot) for z in new):
                h.zones |= set(req.zones)
                granted.append(Grant(req.robot, req.zones))
            else:
                claimed |= new
                keep.append(req)
        self._queue = keep
        return granted
