"""Other robots on a simulated robot's floor: seen, waited for, planned around, given up on.

Split from :mod:`serveur.sim.robot` (the robot's part for sharing the floor): :class:`Floor`
reads the other robots from the shared state and acts on the navigator's path and goal (its
:class:`~serveur.sim.navigator.Wait` holds the wait under way).

Other robots are obstacles when the fleet says so (:meth:`SimRobot.share_floor`, the
fleet's ``robots_see_each_other``; on by default since issue 31). Then each robot's footprint,
a disc of the planner's robot radius, shows in the others' ``/scan`` (ray-disc intersection)
and stops them: a robot keeps :data:`ROBOT_CLEARANCE` from another's footprint, slowing down to
stop :data:`ROBOT_GAP` short of that in its way and waiting, as a local planner whose costmap
holds the other robot, inflated, does; after :data:`ROBOT_REPLAN_AFTER` s it plans
around the robots standing still (their discs marked on a copy of the map, as a costmap's
obstacle layer marks them) and takes the detour if one exists; after the patience
(:data:`ROBOT_PATIENCE`, 30 s of sim time: move_base aborts after ``controller_patience``, 15 s
by default in move_base.cpp, plus its default recoveries; Nav2's default navigate_to_pose tree
retries 6 times, with a progress checker allowing 10 s per 0.5 m, docs.nav2.org) its goal
ABORTs with "blocked by another robot (NAME) for N s": move_base ABORTED (4), Nav2 status 6
with error code 105 (FAILED_TO_MAKE_PROGRESS). What is not modelled: the recoveries' own motion
(in-place rotations, backing up), other robots' velocities (only where they are now), and any
rule about who gives way, so two robots meeting head-on in an aisle one robot wide deadlock
until both goals abort.
"""

from __future__ import annotations

import concurrent.futures
import itertools
import logging
import math
from collections.abc import Sequence
from typing import Final

import numpy as np

from serveur.errors import ServeurError
from serveur.maps.navigation import OccupancyMap, Planner
from serveur.robots.rosbridge import GoalStatus
from serveur.sim import ros2
from serveur.sim.kinematics import PathFollower
from serveur.sim.navigator import Navigator
from serveur.sim.state import Goal, RobotState

__all__ = [
    "ROBOT_CLEARANCE",
    "ROBOT_GAP",
    "ROBOT_PATIENCE",
    "ROBOT_PROGRESS",
    "ROBOT_REPLAN_AFTER",
    "ROBOT_REPLAN_EVERY",
    "ROBOT_REPLAN_TAKES",
    "Floor",
]

log = logging.getLogger("serveur.robot_sim")

#: Other robots as obstacles (opt-in, :meth:`SimRobot.share_floor`). A robot blocked by another
#: waits this long (s sim) before its goal ABORTs. move_base gives up after controller_patience
#: (15 s by default, move_base.cpp) then its default recoveries (two costmap clearings, two
#: in-place rotations); Nav2's default tree retries 6 times with Wait 5 s among its recoveries
#: and a progress checker allowing 10 s per 0.5 m. Some tens of seconds either way: 30 s.
ROBOT_PATIENCE: Final = 30.0
#: s sim blocked by a robot standing still before planning around it (a costmap marks it and
#: the planner routes around it), then at most every 5 s (move_base's planner_patience).
ROBOT_REPLAN_AFTER: Final = 2.0
ROBOT_REPLAN_EVERY: Final = 5.0
#: m a robot's footprint stops short of another's (a local planner's safety margin).
ROBOT_GAP: Final = 0.05
#: m between footprints under which another robot counts as in the way, also beside the path.
#: A real robot sees another as an obstacle in its costmap, inflated (costmap_2d / Nav2
#: inflation layer: inflation_radius 0.55 m, cost_scaling_factor 10 by default,
#: docs.nav2.org "Inflation Layer Parameters"): the cost 253·exp(-10·gap) reaches a third of
#: lethal (~93) at a 0.10 m gap, where the local planner's obstacle critic outweighs following
#: its path, so it slows, stops and replans rather than brushing past. Without it the simulated
#: robots passed and met each other footprint to footprint (centres 0.40 m apart: 103 such
#: encounters in a 1-hour replay of the demo room with 5 robots), which no real stack does.
ROBOT_CLEARANCE: Final = 0.10
_ROBOT_STOP: Final = 0.02  # m of room left under which a robot counts as blocked
#: m a blocked robot must get from where it stopped to count as progressing again (Nav2's
#: SimpleProgressChecker ``required_movement_radius`` default).
ROBOT_PROGRESS: Final = 0.5
_ROBOT_STILL: Final = 0.05  # m/s: a robot slower than this is standing still (planned around)
#: s sim between asking for a plan around robots and taking it: the planning runs in a worker
#: thread meanwhile (~40 ms on the demo room), and the robot, standing still, takes the detour
#: exactly this long after it asked whatever the load (a run stays deterministic).
ROBOT_REPLAN_TAKES: Final = 0.5
_DETOURS: concurrent.futures.ThreadPoolExecutor | None = None


def _detour_pool() -> concurrent.futures.ThreadPoolExecutor:
    global _DETOURS
    if _DETOURS is None:
        _DETOURS = concurrent.futures.ThreadPoolExecutor(2, thread_name_prefix="sim-detour")
    return _DETOURS


class Floor:
    """The robot among other robots (:meth:`share`; see the module's docstring)."""

    def __init__(self, state: RobotState, navigator: Navigator) -> None:
        self.state = state
        self.navigator = navigator
        self._patience = ROBOT_PATIENCE

    def share(self, others: Sequence[RobotState], patience: float = ROBOT_PATIENCE) -> None:
        """Make ``others`` solid for this robot: their footprints (discs of their
        :attr:`~serveur.sim.state.RobotState.radius`) show in its ``/scan`` and it never drives
        its own into theirs.

        Driving a goal, the robot slows down to stop :data:`ROBOT_GAP` short of a robot in its
        way and waits; after :data:`ROBOT_REPLAN_AFTER` s, if the robots in the way stand still,
        it plans around their footprints (again at most every :data:`ROBOT_REPLAN_EVERY` s)
        and follows the detour if there is one. Blocked ``patience`` s (sim) without getting
        :data:`ROBOT_PROGRESS` m from where it stopped, its goal ABORTs ("blocked by another
        robot"). Any other motion (teleop) into another robot is simply not taken. Nothing
        decides who gives way: two robots meeting head-on in an aisle one robot wide deadlock
        until both goals abort, as two move_base/Nav2 robots without a fleet manager would.
        """
        if not (math.isfinite(patience) and patience > 0):
            raise ValueError("patience must be a positive number of seconds")
        self.state.others = tuple(o for o in others if o is not self.state)
        self._patience = float(patience)
        self.navigator.wait.since = None

    # -- other robots (share_floor) ----------------------------------------------------------

    def _gap_ahead(self, dx: float, dy: float) -> tuple[float, RobotState | None]:
        """How far (m) this robot's footprint can go along the unit vector (dx, dy) before it
        comes within :data:`ROBOT_CLEARANCE` of another robot's, and which robot that is (inf,
        None: nothing in the way)."""
        m = self.state.motion
        best, who = math.inf, None
        for o in self.state.others:
            om = o.motion
            px, py = om.x - m.x, om.y - m.y
            s = px * dx + py * dy
            if s <= 0.0:
                continue  # beside or behind
            reach = self.state.radius + o.radius + ROBOT_CLEARANCE
            h2 = px * px + py * py - s * s
            if h2 >= reach * reach:
                continue  # passes clear of it
            gap = max(0.0, s - math.sqrt(reach * reach - h2))
            if gap < best:
                best, who = gap, o
        return best, who

    def mind_robots(self, g: Goal, cmd: tuple[float, float, float]) -> tuple[float, float, float]:
        """The local planner facing other robots: slow down to stop short of one in the way,
        wait, plan around robots standing still, and abort after the patience."""
        nav = self.navigator
        m = self.state.motion
        if nav.wait.detour is not None and self.state.t >= nav.wait.detour[0] - 1e-9:
            self._take_detour(g)
            cmd = nav.follower.command(m.x, m.y, m.yaw) if nav.follower else (0.0, 0.0, 0.0)
        vx, vy, wz = cmd
        speed = math.hypot(vx, vy)
        gap, who = math.inf, None
        if speed > 1e-9:
            c, s = math.cos(m.yaw), math.sin(m.yaw)
            gap, who = self._gap_ahead((vx * c - vy * s) / speed, (vx * s + vy * c) / speed)
        # Where the base is still going (it turns and slows with its acceleration limits, not
        # at once): that way must be clear too.
        moving = math.hypot(m.vx, m.vy)
        if moving > 1e-6:
            c, s = math.cos(m.yaw), math.sin(m.yaw)
            now = self._gap_ahead((m.vx * c - m.vy * s) / moving, (m.vx * s + m.vy * c) / moving)
            if now[0] < gap:
                gap, who = now
        room = gap - ROBOT_GAP
        if room > _ROBOT_STOP:
            if nav.wait.since is not None and (
                math.hypot(m.x - nav.wait.at[0], m.y - nav.wait.at[1]) >= ROBOT_PROGRESS
            ):
                nav.wait.since = None  # got away: a new block starts a new wait
            if gap < math.inf:
                lim = nav.limits
                v = min(math.sqrt(2.0 * 0.8 * lim.max_accel * room), 2.0 * room)
                if v < speed:
                    k = v / speed
                    return vx * k, vy * k, wz
            return cmd
        t = self.state.t
        if nav.wait.since is None:
            nav.wait.since, nav.wait.at = t, (m.x, m.y)
            # waiting for a robot is not slowness: the goal's deadline leaves room for it
            nav.goal_deadline = max(nav.goal_deadline, t + self._patience + 1.0)
        waited = t - nav.wait.since
        if waited >= self._patience:
            name = who.name if who is not None else "?"
            nav.finish(
                g,
                GoalStatus.ABORTED,
                f"blocked by another robot ({name}) for {waited:.0f} s",
                code=ros2.FAILED_TO_MAKE_PROGRESS,
            )
        elif (
            waited >= ROBOT_REPLAN_AFTER
            and t - nav.wait.replanned >= ROBOT_REPLAN_EVERY
            and nav.wait.detour is None
        ):
            nav.wait.replanned = t
            self._plan_around(g)
        return 0.0, 0.0, 0.0

    def _plan_around(self, g: Goal) -> None:
        """Ask for a plan to ``g`` with the footprints of the robots standing still marked as
        obstacles (a costmap's obstacle layer); :meth:`_take_detour` follows it if there is
        one, else the robot keeps waiting.

        The map and the robots are copied now and planned on in a worker thread (a fresh
        planner, one distance field: ~40 ms on the demo room), taken :data:`ROBOT_REPLAN_TAKES`
        s of sim time later, so neither the physics loop stalls nor a run's outcome depends on
        the machine's speed (a slow plan is waited for then).
        """
        nav = self.navigator
        still = [o for o in self.state.others if o.motion.speed < _ROBOT_STILL]
        if not still:
            return
        base = self.state.map
        grid = base.grid.copy()
        res, (ox, oy, _) = base.resolution, base.origin
        rows, cols = np.ogrid[0 : base.height, 0 : base.width]
        for o in still:
            om = o.motion
            cx, cy = (om.x - ox) / res - 0.5, (om.y - oy) / res - 0.5  # in cell-centre units
            r = (o.radius + ROBOT_CLEARANCE) / res  # its costmap footprint, inflated
            grid[(rows - cy) ** 2 + (cols - cx) ** 2 <= r * r] = 100
        m = self.state.motion
        start, goal = (m.x, m.y), (g.x, g.y)
        radius, clearance = self.state.planner.robot_radius, self.state.planner.clearance

        def work() -> list[tuple[float, float]]:
            planner = Planner(
                OccupancyMap(grid, res, base.origin), radius, clearance=clearance, cache_size=1
            )
            return planner.plan(start, goal)

        fut = _detour_pool().submit(work)
        fut.add_done_callback(lambda f: f.cancelled() or f.exception())
        nav.wait.detour = (self.state.t + ROBOT_REPLAN_TAKES, start, fut)

    def _take_detour(self, g: Goal) -> None:
        """Follow the plan :meth:`_plan_around` asked for (waiting for it if it is late), unless
        there is none or the robot moved since it asked."""
        nav = self.navigator
        due = nav.wait.detour
        nav.wait.detour = None
        assert due is not None
        _, (x0, y0), fut = due
        m = self.state.motion
        try:
            path = fut.result()
        except ServeurError as exc:
            log.debug("%s: no way around the robots in the way: %s", self.state.name, exc)
            return
        except Exception:
            log.exception("%s: planning around the robots in the way failed", self.state.name)
            return
        if math.hypot(m.x - x0, m.y - y0) > 0.05:
            return  # the way cleared meanwhile and the robot drove on
        nav.follower = PathFollower(path, g.yaw, nav.kinematics, nav.limits)
        length = sum(math.dist(a, b) for a, b in itertools.pairwise(path))
        nav.goal_deadline = max(
            nav.goal_deadline, self.state.t + 30.0 + 3.0 * length / nav.limits.max_speed
        )

    def into_robot(self, x0: float, y0: float, x1: float, y1: float) -> bool:
        """Whether moving from (x0, y0) to (x1, y1) drives this robot's footprint within
        :data:`ROBOT_GAP` of another robot's (robots already that close may still move apart):
        the base's safety stop, as Nav2's collision_monitor stops a robot whose stop polygon (the
        footprint and a few centimetres) holds an obstacle point, whatever its planner says."""
        for o in self.state.others:
            om = o.motion
            reach = self.state.radius + o.radius + ROBOT_GAP
            d1 = math.hypot(x1 - om.x, y1 - om.y)
            if d1 < reach and d1 < math.hypot(x0 - om.x, y0 - om.y):
                return True
        return False
