"""What robots did to each other during a replay: conflicts, deadlocks, goals aborted, zone waits.

Issue 21: with robots that see each other in the simulator (``--robots-see-each-other``), two
robots meeting in an aisle one robot wide block each other; the server's zones and leases are
meant to prevent it. The replay measures it on the simulator's *true* poses (not the server's
view of them), with :class:`TrafficWatch` hooked after each physics step of the fleet:

* a **conflict** is an episode of two robots' centres closer than ``conflict_distance``
  (default ``2 x radius + 0.05`` m: their footprints touching, or within the 5 cm a local
  planner stops short of another robot). It starts when a pair enters the close state and ends
  when it leaves it (with 2 cm of hysteresis, so a robot rocking at the limit is one episode);
  where and when it started is kept;
* a **deadlock** is an episode of two or more robots that each have a goal (ACTIVE or PENDING
  in the robot's navigator) and have each moved less than ``progress`` (0.1 m) in the last
  ``deadlock_after`` s (20 s of sim time), chained within ``near`` (1.5 m) of each other. It is
  counted once, when such a group first forms (a group that grows keeps its episode), checked
  once a simulated second;
* a goal **aborted because of another robot** is one the simulated navigator ended ABORTED
  with "blocked by another robot" (:mod:`serveur.sim.robot`, after its patience); other aborts
  (stuck against a wall, no path, too slow) are counted apart. Terminal goals stay in the
  robot's status list 5 s, so the once-a-second check sees each of them.

Zone waits come from the server itself (``lease.waited`` events, :func:`zone_waits`), and their
places from the robots' records (``waiting_for``), which the service follows.

Pure except :meth:`TrafficWatch.attach`, which wraps the last robot's physics step (the fleet
steps every robot in turn in one pass, so after the last one every pose is of the same tick).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

__all__ = [
    "BLOCKED_BY_ROBOT",
    "TrafficWatch",
    "load_zones",
    "zone_waits",
]

#: How the simulated navigator words an abort caused by another robot (serveur.sim.robot).
BLOCKED_BY_ROBOT = "blocked by another robot"
_HYSTERESIS = 0.02  # m a pair must get beyond the threshold to end a conflict episode
_LIVE = ("ACTIVE", "PENDING")  # goal statuses that count as "has a goal"


def load_zones(path: str | Path) -> list[dict[str, Any]]:
    """A zones file's zones as ``{"name", "points", "capacity"}`` (``{"zones": [...]}`` or a
    bare list, the format of ``serveur run --zones``); the server checks each when the replay
    creates it. ValueError if the file is not such a document."""
    try:
        doc = json.loads(Path(path).read_text("utf-8"))
        items = doc["zones"] if isinstance(doc, dict) else doc
        out = [
            {
                "name": str(z["name"]),
                "points": [[float(p[0]), float(p[1])] for p in z["points"]],
                "capacity": int(z.get("capacity", 1)),
            }
            for z in items
        ]
    except (OSError, ValueError, KeyError, TypeError, IndexError) as exc:
        raise ValueError(f"{path}: not a zones file: {exc}") from None
    return out


@dataclass
class TrafficWatch:
    """Watches the fleet's true poses after every physics step (see the module's docstring).

    ``now()`` is the service's clock (seconds from opening), used to stamp episodes.
    """

    robots: Sequence[Any]
    now: Any
    conflict_distance: float = 0.45
    deadlock_after: float = 20.0
    progress: float = 0.1
    near: float = 1.5
    tick: float = 0.05
    conflicts: list[dict[str, Any]] = field(default_factory=list)
    deadlocks: list[dict[str, Any]] = field(default_factory=list)
    aborts: list[dict[str, Any]] = field(default_factory=list)
    closest: float = math.inf
    _close: dict[tuple[int, int], dict[str, Any]] = field(default_factory=dict)
    _steps: int = 0
    _anchor: dict[int, tuple[float, float, float]] = field(default_factory=dict)
    _stalled_group: set[int] = field(default_factory=set)
    _seen_goals: set[tuple[str, str]] = field(default_factory=set)
    _on: bool = False

    def attach(self) -> None:
        """Wrap the last robot's physics step: :meth:`after_step` runs once per fleet tick."""
        if not self.robots:
            return
        last = self.robots[-1]
        step = last._step

        def stepped(dt: float) -> None:
            step(dt)
            if self._on:
                self.after_step()

        last._step = stepped

    def start(self) -> None:
        """Count from now (the service opened)."""
        self._on = True

    def after_step(self) -> None:
        poses = [r.pose for r in self.robots]
        n = len(poses)
        lim = self.conflict_distance
        out = lim + _HYSTERESIS
        for i in range(n):
            xi, yi = poses[i][0], poses[i][1]
            for j in range(i + 1, n):
                d = math.hypot(poses[j][0] - xi, poses[j][1] - yi)
                if d < self.closest:
                    self.closest = d
                key = (i, j)
                episode = self._close.get(key)
                if episode is not None:
                    if d >= out:
                        del self._close[key]
                    elif d < episode["distance"]:
                        episode["distance"] = round(d, 3)
                elif d < lim:
                    episode = {
                        "t": round(self.now(), 1),
                        "robots": [self.robots[i].name, self.robots[j].name],
                        "x": round((xi + poses[j][0]) / 2, 2),
                        "y": round((yi + poses[j][1]) / 2, 2),
                        "distance": round(d, 3),
                    }
                    self._close[key] = episode
                    self.conflicts.append(episode)
        self._steps += 1
        if self._steps * self.tick >= 1.0 - 1e-9:
            self._steps = 0
            self._each_second(poses)

    def _each_second(self, poses: Sequence[tuple[float, float, float]]) -> None:
        t = float(self.now())
        stalled: list[int] = []
        for i, r in enumerate(self.robots):
            statuses = r.goal_statuses
            for gid, status, text in statuses:
                name = getattr(status, "name", str(status))
                if name == "ABORTED" and (r.name, gid) not in self._seen_goals:
                    self._seen_goals.add((r.name, gid))
                    self.aborts.append(
                        {
                            "t": round(t, 1),
                            "robot": r.name,
                            "by_robot": text.startswith(BLOCKED_BY_ROBOT),
                            "text": text,
                            "x": round(poses[i][0], 2),
                            "y": round(poses[i][1], 2),
                        }
                    )
            live = any(getattr(s, "name", str(s)) in _LIVE for _, s, _ in statuses)
            x, y = poses[i][0], poses[i][1]
            a = self._anchor.get(i)
            if not live:
                self._anchor.pop(i, None)
                continue
            if a is None or math.hypot(x - a[0], y - a[1]) >= self.progress:
                self._anchor[i] = (x, y, t)
            elif t - a[2] >= self.deadlock_after - 1e-9:
                stalled.append(i)
        # Groups of stalled robots chained within `near` of each other.
        groups: list[set[int]] = []
        for i in stalled:
            linked = [
                g
                for g in groups
                if any(
                    math.hypot(poses[i][0] - poses[j][0], poses[i][1] - poses[j][1]) <= self.near
                    for j in g
                )
            ]
            merged = {i}.union(*linked)
            groups = [g for g in groups if g not in linked] + [merged]
        now_in: set[int] = set()
        for g in groups:
            if len(g) < 2:
                continue
            now_in |= g
            if not g & self._stalled_group:  # a new group, not one already counted
                members = sorted(g)
                self.deadlocks.append(
                    {
                        "t": round(t, 1),
                        "robots": [self.robots[k].name for k in members],
                        "x": round(sum(poses[k][0] for k in members) / len(members), 2),
                        "y": round(sum(poses[k][1] for k in members) / len(members), 2),
                    }
                )
        self._stalled_group = now_in

    def result(self) -> dict[str, Any]:
        """What :class:`~serveur.replay.model.PolicyResult` keeps (``traffic``)."""
        by_robot = [a for a in self.aborts if a["by_robot"]]
        return {
            "conflict_distance": self.conflict_distance,
            "deadlock_after": self.deadlock_after,
            "conflicts": [dict(c) for c in self.conflicts],
            "deadlocks": list(self.deadlocks),
            "aborts": list(self.aborts),
            "aborted_by_robot": len(by_robot),
            "aborted_other": len(self.aborts) - len(by_robot),
            "closest": None if not math.isfinite(self.closest) else round(self.closest, 3),
        }


def zone_waits(events: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Waits for zones as the server recorded them (``lease.waited``: a robot got the zones
    it waited for; ``data``: ``zones``, ``waited_s``): count, total and per robot seconds."""
    per: dict[str, dict[str, float]] = {}
    count, total = 0, 0.0
    for e in events:
        if e["kind"] != "lease.waited":
            continue
        s = float((e.get("data") or {}).get("waited_s", 0.0))
        robot = e.get("robot") or "?"
        row = per.setdefault(robot, {"waits": 0, "seconds": 0.0})
        row["waits"] += 1
        row["seconds"] = round(row["seconds"] + s, 1)
        count += 1
        total += s
    return {"waits": count, "seconds": round(total, 1), "per_robot": dict(sorted(per.items()))}
