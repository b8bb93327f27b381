"""A fleet of simulated waiter robots, each speaking rosbridge v2 like a real ROS1 robot, or like
a ROS 2 robot with Nav2 behind rosbridge 2.x (``ros=2``; per robot in a mixed fleet).

Why a simulator that imitates the wire instead of a fake robot-link object: the server's robot
link, roslibpy and roslibjs must not be able to tell it from a robot running move_base, AMCL and
rosbridge_server, so every quirk those clients depend on is reproduced here (latched ``/map``,
``/move_base/status`` published even when idle, ``null`` for NaN, ``service_response`` always
carrying ``values``, binary frames only for ``cbor`` subscribers...). Tests and load runs then
exercise the same code paths as a restaurant.

Structure:

* :mod:`serveur.sim.robot` — one robot's ROS graph (:class:`~serveur.sim.robot.SimRobot`):
  kinematics (:mod:`serveur.sim.kinematics`), move_base's actionlib state machine, AMCL-like pose,
  odometry, laser, battery, and what it publishes.
* :mod:`serveur.sim.bridge` — one websocket server per robot (many clients each), with
  per-client, per-topic bounded queues so that a slow client only loses its own old messages
  and never blocks the robot or grows memory.
* :class:`Simulation` — the robots of a fleet, one physics loop stepping all of them at a fixed
  20 Hz of *simulated* time (so results do not depend on ``time_scale``), and the fault hooks.
  With ``robots_see_each_other`` (the default; ``serveur sim --robots-pass-through`` turns it
  off) the robots are obstacles to each other, in their scans and in motion, and can deadlock
  (:meth:`SimRobot.share_floor <serveur.sim.robot.SimRobot.share_floor>`).

All time goes through a :class:`~serveur.clock.Clock`: motion, publish rates, ``throttle_rate``,
the stale ``cmd_vel`` timeout and ROS stamps (``clock.epoch()``, plus the robots'
``clock_offset``: a robot's clock need not agree with the server's).

How far the robots follow the real ROS1 stack rather than an idealised one (actionlib's stamp
rules, move_base ignoring ``/cmd_vel``, AMCL's motion thresholds, rosbridge 0.11's ``status``,
CBOR and fragment quirks) is written in :mod:`serveur.sim.robot` and :mod:`serveur.sim.bridge`,
each rule with its source (actionlib / rosbridge_suite code, or shared/notes/rosbridge.md).
"""

from __future__ import annotations

import argparse
import asyncio
import contextlib
import hashlib
import logging
import math
import signal
import ssl as ssl_module
import sys
import threading
from collections import OrderedDict
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Final, TextIO

import numpy as np

from serveur.clock import Clock, ScaledClock
from serveur.errors import ServeurError
from serveur.maps.navigation import (
    OccupancyMap,
    Planner,
    Waypoint,
    demo_map_path,
    load_demo,
    load_map,
    load_waypoints,
)
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.bridge import Endpoint
from serveur.sim.kinematics import KINDS
from serveur.sim.robot import (
    AMCL_MODES,
    AMCL_TICKS,
    MAX_CATCH_UP,
    ROBOT_PATIENCE,
    TICK,
    SimRobot,
)
from serveur.sim.sensors import CAMERA_TOPIC
from serveur.sim.topics import Frame
from serveur.sim.video_server import VideoServer, rendered_camera

__all__ = [
    "AMCL_MODES",
    "TICK",
    "SimRobot",
    "Simulation",
    "add_sim_arguments",
    "parse_dock",
    "run_sim",
    "run_sim_from_args",
    "shared_planner",
    "start_simulation",
]

log = logging.getLogger("serveur.robot_sim")

# ---------------------------------------------------------------------------------------------
# The fleet
# ---------------------------------------------------------------------------------------------


class Simulation:
    """N robots, their endpoints and the physics loop. Use ``async with`` or start()/close()."""

    def __init__(
        self,
        robots: Sequence[SimRobot],
        endpoints: Sequence[Endpoint],
        clock: Clock,
        *,
        spread: bool = False,
        robots_see_each_other: bool = True,
        blocked_patience: float = ROBOT_PATIENCE,
        video: Sequence[VideoServer] = (),
    ) -> None:
        self.robots: list[SimRobot] = list(robots)
        self._endpoints = list(endpoints)
        #: Each robot's web_video_server, in robot order (none unless asked for).
        self.video: list[VideoServer] = list(video)
        self.clock = clock
        #: Step robot i i/N of the AMCL period after robot 0 (see :meth:`phases`).
        self.spread = spread
        #: Each robot's footprint is an obstacle to the others (:meth:`SimRobot.share_floor`).
        self.robots_see_each_other = robots_see_each_other
        if robots_see_each_other:
            for r in self.robots:
                r.share_floor(self.robots, blocked_patience)
        self._loop_task: asyncio.Task[None] | None = None

    def phases(self) -> list[tuple[int, float]]:
        """Per robot: (ticks its publishing lags robot 0's by, sim seconds its steps lag by).

        Lock-step (the default), every robot is stepped in the same pass and robots only
        alternate ticks (``SimRobot._ticks`` starts at the robot's index), so half the fleet's
        AMCL poses leave together. Real robots are independent machines whose 10 Hz timers are
        not phase-locked; with ``spread`` robot i's publishing is shifted by i/N of the AMCL
        period (whole ticks, then a fraction of a tick by which its physics steps run later),
        so N robots' poses arrive evenly spread. Physics and publish rates are unchanged.
        """
        n = len(self.robots)
        if not self.spread:
            return [(0, 0.0)] * n
        out = []
        for i in range(n):
            ticks, rest = divmod(i * AMCL_TICKS, n)
            out.append((ticks, rest * TICK / n))
        return out

    @property
    def urls(self) -> list[str]:
        """ws://host:port (wss:// with TLS) of each robot, in robot order."""
        return [e.url for e in self._endpoints]

    @property
    def video_urls(self) -> list[str]:
        """Each robot's camera stream, as web_video_server serves it
        (``http://host:port/stream?topic=/camera/image/compressed&type=ros_compressed``), in
        robot order; empty when the simulation serves no video (``video_port`` None)."""
        if not self.video:
            return []
        return [v.url(r.wire(CAMERA_TOPIC)) for r, v in zip(self.robots, self.video, strict=True)]

    async def start(self) -> None:
        """Open every endpoint and start the physics loop (idempotent)."""
        try:
            for e in self._endpoints:
                await e.start()
            for v in self.video:
                await v.start()
        except OSError:
            await self.close()
            raise
        if self._loop_task is None:
            self._loop_task = asyncio.ensure_future(self._run())

    async def close(self) -> None:
        """Stop the physics loop and close every endpoint (clients see close code 1001)."""
        task, self._loop_task = self._loop_task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task
        await asyncio.gather(*(e.stop() for e in self._endpoints), *(v.stop() for v in self.video))

    async def stop_endpoint(self, i: int) -> None:
        """Fault hook: close robot i's websocket server and its connections; the robot keeps
        its pose and goes on simulating (a rosbridge_server crash or a Wi-Fi drop)."""
        await self._endpoints[i].stop()

    async def start_endpoint(self, i: int) -> None:
        """Reopen robot i's websocket server on the same port."""
        await self._endpoints[i].start()

    async def restart_rosbridge(self, i: int) -> None:
        """Robot i's rosbridge is restarted (the old process killed, its connections closed,
        a new one started): heals :meth:`SimRobot.stop_bridge_ros_side`."""
        await self._endpoints[i].stop()
        self.robots[i].bridge_restarted()
        await self._endpoints[i].start()

    async def warm_plans(self, goals: Sequence[tuple[float, float]]) -> int:
        """Plan once to each goal now (in a worker thread); how many were reachable.

        A robot's first goal at a spot waits for that spot's distance field (40-80 ms of CPU
        on a restaurant map, which an accelerated replay turns into seconds of a robot
        standing still); after this every plan to these goals is a cached pointer walk.
        """
        robot = self.robots[0]
        start = robot.home[0], robot.home[1]

        def work() -> int:
            done = 0
            for goal in goals:
                with contextlib.suppress(ServeurError):
                    robot.navigator.plan_blocking(start, goal)
                    done += 1
            return done

        return await asyncio.get_running_loop().run_in_executor(None, work)

    async def __aenter__(self) -> Simulation:
        await self.start()
        return self

    async def __aexit__(self, *exc: object) -> None:
        await self.close()

    async def _run(self) -> None:
        """Step every robot at TICK of sim time; publish what falls due."""
        clock = self.clock
        t = clock.now()
        groups: dict[float, list[SimRobot]] = {}
        for r, (ticks, offset) in zip(self.robots, self.phases(), strict=True):
            r.state.t = t + offset  # stamps stay the sim time of the robot's own steps
            if self.spread:
                r._ticks = -ticks
            groups.setdefault(offset, []).append(r)
        passes = sorted(groups.items())
        while True:
            t += TICK
            delay = t - clock.now()
            if delay > 0:
                await clock.sleep(delay)
            steps = 1
            behind = clock.now() - t
            if behind >= TICK:  # overloaded: catch up with several steps in this pass
                steps += min(int(behind / TICK), MAX_CATCH_UP - 1)
                t += (steps - 1) * TICK
                slip = clock.now() - t
                if slip > TICK * MAX_CATCH_UP:  # hopelessly behind: let sim time slip
                    t += slip
                    for r in self.robots:
                        r.state.t += slip
            for offset, group in passes:
                if offset > 0.0 and (lag := t + offset - clock.now()) > 0:
                    await clock.sleep(lag)
                for r in group:
                    try:
                        r._advance(steps)
                    except Exception:  # one robot's bug must not stop the fleet
                        log.exception("%s: simulation step failed", r.name)


def _waypoints_beside(map_path: Path) -> dict[str, Waypoint]:
    if map_path.resolve() == demo_map_path().resolve():
        return load_demo()[1]
    stem = map_path.with_suffix("")
    for cand in (
        stem.with_name(stem.name + "_waypoints.json"),
        stem.with_name(stem.name + ".waypoints.json"),
        stem.with_suffix(".json"),
        map_path.with_name("waypoints.json"),
    ):
        if cand.is_file():
            return load_waypoints(cand)
    found = sorted(map_path.parent.glob("*waypoints*.json"))
    return load_waypoints(found[0]) if len(found) == 1 else {}


def _start_poses(
    n: int, grid: OccupancyMap, planner: Planner, waypoints: Mapping[str, Waypoint]
) -> list[tuple[float, float, float]]:
    """home1..homeN where they exist; the rest on distinct free spots (deterministic order)."""
    poses: list[tuple[float, float, float]] = []
    for i in range(n):
        wp = waypoints.get(f"home{i + 1}")
        if wp is not None:
            poses.append((wp.x, wp.y, wp.yaw))
    if len(poses) == n:
        return poses
    spacing = 0.5  # robots are 0.4 m wide
    ref = poses[0][:2] if poses else grid.cell_to_world(grid.height // 2, grid.width // 2)
    xs = np.arange(
        grid.origin[0] + spacing / 2, grid.origin[0] + grid.width * grid.resolution, spacing
    )
    ys = np.arange(
        grid.origin[1] + spacing / 2, grid.origin[1] + grid.height * grid.resolution, spacing
    )
    spots = [
        (float(x), float(y))
        for y in ys
        for x in xs
        if planner.is_traversable(float(x), float(y))
        and all(math.hypot(x - p[0], y - p[1]) >= spacing for p in poses)
    ]
    spots.sort(key=lambda s: (round(math.hypot(s[0] - ref[0], s[1] - ref[1]), 6), s))
    if len(spots) < n - len(poses):
        raise ServeurError(f"the map has room for {len(poses) + len(spots)} robots, not {n}")
    poses.extend((x, y, 0.0) for x, y in spots[: n - len(poses)])
    return poses


#: Planners kept for the next simulation of the same map in this process (see shared_planner).
_PLANNERS: OrderedDict[tuple[str, int], Planner] = OrderedDict()
_PLANNERS_KEPT: Final = 2
_PLANNERS_LOCK = threading.Lock()


def shared_planner(grid: OccupancyMap, *, cache_size: int) -> Planner:
    """The simulator's planner for ``grid``: the one an earlier simulation of the same map in
    this process made, if any, with its distance fields (one per goal, 40-80 ms of CPU each on
    a restaurant map). A planner only reads its map, and is thread-safe, so simulations can
    share one. A process that runs one simulation (``serveur sim``, a demo, a forecast's replay)
    gains nothing and loses nothing; the test suite and a bench start hundreds on the demo map.
    Keyed by the map's cells, resolution and origin (not its file name); the last two maps kept.
    """
    digest = hashlib.sha256(np.ascontiguousarray(grid.grid).tobytes())
    digest.update(repr((grid.resolution, grid.origin, grid.grid.shape)).encode())
    key = (digest.hexdigest(), cache_size)
    with _PLANNERS_LOCK:
        planner = _PLANNERS.get(key)
        if planner is None:
            planner = Planner(grid, robot_radius=0.2, cache_size=cache_size)
            _PLANNERS[key] = planner
        _PLANNERS.move_to_end(key)
        while len(_PLANNERS) > _PLANNERS_KEPT:
            _PLANNERS.popitem(last=False)
        return planner


async def start_simulation(
    n: int,
    *,
    port: int = 9090,
    host: str = "127.0.0.1",
    map_path: str | Path | None = None,
    kinematics: str = "omni",
    time_scale: float = 1.0,
    seed: int = 0,
    clock: Clock | None = None,
    names: Sequence[str] | None = None,
    ssl: ssl_module.SSLContext | None = None,
    spread: bool = False,
    clock_offset: float = 0.0,
    amcl: str = "continuous",
    namespaced: bool = False,
    ros: int | Sequence[int] = 1,
    release: str = "jazzy",
    twist_stamped: bool | None = None,
    humble_queue: bool | None = None,
    rosbridge_fix: bool = False,
    robots_see_each_other: bool = True,
    blocked_patience: float = ROBOT_PATIENCE,
    video_port: int | None = None,
    docks: Mapping[str, tuple[float, float, float] | str] | None = None,
    docking: bool | Sequence[bool] = False,
) -> Simulation:
    """Start ``n`` robots listening on ports ``port``..``port+n-1`` (0: free ports).

    Robot i is named ``names[i]`` or ``r{i+1}``, starts at waypoint ``home{i+1}`` and uses random
    seed ``seed + i``. ``clock`` overrides ``time_scale`` (tests pass a shared ScaledClock).
    ``ssl`` (a server context, see serveur.security.tls.server_context) serves every robot over TLS.
    ``spread`` spreads the robots' publish phases over the AMCL period (:meth:`Simulation.phases`).
    ``namespaced`` puts robot ``rN``'s topics under ``/rN`` (as on a shared ROS master).
    ``clock_offset`` (seconds) sets every robot's clock that far from ``clock``: all they stamp
    is ``clock.epoch() + clock_offset``. ``amcl`` is ``"continuous"`` (10 Hz poses) or
    ``"real"`` (latched, only after motion, like the amcl node): see :mod:`serveur.sim.robot`.

    ``ros`` is the dialect every robot speaks, 1 (rosbridge 0.11, move_base, amcl) or 2
    (rosbridge 2.x, Nav2's ``navigate_to_pose``: :mod:`serveur.sim.bridge`,
    :mod:`serveur.sim.ros2`), or one entry per robot for a mixed fleet (``[1, 2]``). For ROS 2
    robots: ``release`` (``humble``, ``jazzy``, ``kilted``) sets the NavigateToPose result's
    shape and the defaults of ``twist_stamped`` (``/cmd_vel`` is TwistStamped; Kilted) and
    ``humble_queue`` (rosbridge's ``send_action_goals_in_new_thread`` false, Humble's default: a
    goal holds its connection's later ops until it ends); None takes the release's default.
    ``rosbridge_fix``: rosbridge with its 2026 fix, which answers a rejected or unserved goal
    with ``action_result`` ``result: false`` (without it: no frame at all).

    ``robots_see_each_other``: every robot's footprint (a disc of the planner's robot radius,
    0.2 m) is an obstacle to the others, in their ``/scan`` and in motion: a robot stops short
    of another in its way, waits, plans around one standing still, and after
    ``blocked_patience`` s of sim time (default :data:`~serveur.sim.robot.ROBOT_PATIENCE`, 30 s,
    about what move_base's and Nav2's default patience and recoveries add up to) its goal
    ABORTs ("blocked by another robot"); see :meth:`SimRobot.share_floor`. Robots can then
    deadlock, e.g. meeting head-on in an aisle one robot wide. Off by default: the server has
    no zone leases yet (issue 21), and every multi-robot test and replay so far assumes robots
    pass through each other.

    ``video_port``: each robot also serves its camera over HTTP as ROS's web_video_server does
    (:mod:`serveur.sim.video_server`), robot i on ``video_port + i`` (0: free ports), rendered
    from its true pose; :attr:`Simulation.video_urls` are the streams' URLs. None (the
    default): no video server, the camera is only on rosbridge.

    ``docks``: a robot's charger (its dock), by robot name: a pose (x, y, yaw: how the robot
    stands on the contacts) or the name of a waypoint of the map; a robot not named docks at
    its home (where it starts), so it charges there as before. A robot charges only standing
    on a charger (any robot's): :mod:`serveur.sim.robot`. ``docking``: ROS 2 robots also run
    opennav_docking's docking server (``dock_robot``, ``undock_robot``:
    :mod:`serveur.sim.docking`); True for every ROS 2 robot, or one entry per robot.
    """
    if n < 1:
        raise ValueError("at least one robot")
    if kinematics not in KINDS:
        raise ValueError(f"kinematics must be one of {KINDS}, not {kinematics!r}")
    if amcl not in AMCL_MODES:
        raise ValueError(f"amcl must be one of {AMCL_MODES}, not {amcl!r}")
    if not math.isfinite(clock_offset):
        raise ValueError("clock_offset must be a finite number of seconds")
    if names is not None and len(names) < n:
        raise ValueError("fewer names than robots")
    dialects = [ros] * n if isinstance(ros, int) else list(ros)
    if len(dialects) != n or any(d not in (1, 2) for d in dialects):
        raise ValueError(f"ros must be 1, 2 or one of those per robot ({n}), not {ros!r}")
    if release not in ros2.RELEASES:
        raise ValueError(f"release must be one of {ros2.RELEASES}, not {release!r}")
    if isinstance(docking, bool):
        docked = [docking and d == 2 for d in dialects]
    else:
        docked = [bool(d) for d in docking]
        if len(docked) != n or any(d and r != 2 for d, r in zip(docked, dialects, strict=True)):
            raise ValueError(f"docking: one entry per robot ({n}), only on ROS 2 robots")
    clock = clock or ScaledClock(time_scale)
    if map_path is None:
        grid, waypoints = load_demo()
    else:
        grid = load_map(map_path)
        waypoints = _waypoints_beside(Path(map_path))
    # One distance field per goal, cached: robots drive to the same waypoints again and again,
    # so the cache holds every waypoint (the 30-table bench room has 37; with the default 32
    # the LRU thrashed and most goals cost a 40-80 ms field, i.e. a robot standing still for
    # seconds of simulated time at a replay's time scales). Capped by bytes in the Planner.
    planner = shared_planner(grid, cache_size=max(32, len(waypoints) + 16))
    plan_lock = threading.Lock()
    homes = _start_poses(n, grid, planner, waypoints)
    robot_names = [names[i] if names is not None else f"r{i + 1}" for i in range(n)]
    dock_poses = _dock_poses(docks or {}, robot_names, waypoints)
    # The latched /map, built once: every robot shares the one frame (namespaced robots each
    # get their own topic name on the same message).
    map_msg = rb.occupancy_grid(grid, stamp=clock.epoch() + clock_offset, seq=0)
    map_msgs = {1: map_msg, 2: ros2.to_ros2(map_msg)}
    map_frames = {d: Frame(rb.op_publish("/map", m)) for d, m in map_msgs.items()}
    robots: list[SimRobot] = []
    endpoints: list[Endpoint] = []
    for i in range(n):
        name = robot_names[i]
        namespace = f"/{name}" if namespaced else ""
        robot = SimRobot(
            name,
            index=i,
            grid=grid,
            planner=planner,
            home=homes[i],
            kinematics=kinematics,
            clock=clock,
            seed=seed + i,
            map_frame=Frame(rb.op_publish(f"{namespace}/map", map_msgs[dialects[i]]))
            if namespaced
            else map_frames[dialects[i]],
            plan_lock=plan_lock,
            clock_offset=clock_offset,
            amcl=amcl,
            namespace=namespace,
            ros=dialects[i],
            release=release,
            twist_stamped=twist_stamped,
            humble_queue=humble_queue,
            rosbridge_fix=rosbridge_fix,
            dock=dock_poses.get(name),
            docking=docked[i],
        )
        robots.append(robot)
        endpoints.append(Endpoint(robot, host, port + i if port else 0, ssl))
    # A charger is a charger whoever parks on it: every robot's dock is one for all.
    for r in robots:
        r.set_chargers([o.dock for o in robots])
    video: list[VideoServer] = []
    if video_port is not None:
        for i, r in enumerate(robots):
            video.append(_video_server(r, grid, host, video_port + i if video_port else 0, ssl))
    sim = Simulation(
        robots,
        endpoints,
        clock,
        spread=spread,
        robots_see_each_other=robots_see_each_other,
        blocked_patience=blocked_patience,
        video=video,
    )
    await sim.start()
    return sim


def _dock_poses(
    docks: Mapping[str, tuple[float, float, float] | str],
    names: Sequence[str],
    waypoints: Mapping[str, Waypoint],
) -> dict[str, tuple[float, float, float]]:
    """Each named robot's dock as a pose (a waypoint's name looked up); ValueError for a robot
    or a waypoint that does not exist, or a pose that is not three finite numbers."""
    out: dict[str, tuple[float, float, float]] = {}
    for name, spec in docks.items():
        if name not in names:
            raise ValueError(f"dock for robot {name!r}: no such robot ({', '.join(names)})")
        if isinstance(spec, str):
            wp = waypoints.get(spec)
            if wp is None:
                raise ValueError(f"dock for robot {name!r}: no waypoint {spec!r} on the map")
            out[name] = (wp.x, wp.y, wp.yaw)
            continue
        pose = tuple(float(v) for v in spec)
        if len(pose) != 3 or not all(math.isfinite(v) for v in pose):
            raise ValueError(f"dock for robot {name!r}: a pose is x, y, yaw (finite numbers)")
        out[name] = (pose[0], pose[1], pose[2])
    return out


def parse_dock(spec: str) -> tuple[str, tuple[float, float, float] | str]:
    """``serveur sim --dock``'s value: ``NAME=X,Y,YAW`` or ``NAME=WAYPOINT``."""
    name, sep, where = spec.partition("=")
    if not sep or not name.strip() or not where.strip():
        raise ValueError(f"--dock {spec!r}: NAME=X,Y,YAW or NAME=WAYPOINT")
    parts = where.split(",")
    if len(parts) == 1:
        return name.strip(), where.strip()
    try:
        x, y, yaw = (float(v) for v in parts)
    except ValueError:
        raise ValueError(f"--dock {spec!r}: X,Y,YAW are three numbers") from None
    return name.strip(), (x, y, yaw)


def _video_server(
    robot: SimRobot,
    grid: OccupancyMap,
    host: str,
    port: int,
    ssl: ssl_module.SSLContext | None,
) -> VideoServer:
    """Robot ``robot``'s web_video_server: its camera topic, rendered from its true pose and
    stamped with its clock, stalled with its rosbridge camera (``sensors.camera_on``)."""
    camera = rendered_camera(grid, lambda: robot.pose, robot.epoch, lambda: robot.sensors.camera_on)
    return VideoServer({robot.wire(CAMERA_TOPIC): camera}, host=host, port=port, ssl=ssl)


# ---------------------------------------------------------------------------------------------
# Command line (`serveur sim`)
# ---------------------------------------------------------------------------------------------


def add_sim_arguments(parser: argparse.ArgumentParser) -> None:
    """Options of ``serveur sim``."""
    parser.add_argument("--robots", type=int, default=1, help="number of robots (default 1)")
    parser.add_argument(
        "--port", type=int, default=9090, help="port of the first robot; robot i uses port+i"
    )
    parser.add_argument(
        "--host", default="127.0.0.1", help="address to listen on (default 127.0.0.1)"
    )
    parser.add_argument(
        "--map", default=None, help="map_server YAML (default: the demo restaurant)"
    )
    parser.add_argument(
        "--kinematics", choices=KINDS, default="omni", help="omni (default) or diff"
    )
    parser.add_argument("--time-scale", type=float, default=1.0, help="sim seconds per wall second")
    parser.add_argument("--seed", type=int, default=0, help="random seed (robot i uses seed+i)")
    parser.add_argument(
        "--names", default=None, help="comma-separated robot names (default r1, r2...)"
    )
    parser.add_argument(
        "--certfile", default=None, help="PEM certificate (chain): serve wss:// (needs --keyfile)"
    )
    parser.add_argument("--keyfile", default=None, help="PEM private key of --certfile")
    parser.add_argument(
        "--spread-phases",
        action="store_true",
        help="publish robot i's poses i/N of the AMCL period after robot 0's, as independent "
        "robots do (default: the robots are stepped in lock-step)",
    )
    parser.add_argument(
        "--clock-offset",
        type=float,
        default=0.0,
        metavar="SECONDS",
        help="the robots' clocks run this far ahead (negative: behind) of this machine's; "
        "every stamp they make is offset (default 0)",
    )
    parser.add_argument(
        "--namespaced",
        action="store_true",
        help="robot rN's topics under /rN (/r1/move_base/goal...), as robots sharing one ROS "
        "master are; register them with --robot rN=URL,ns=/rN",
    )
    parser.add_argument(
        "--ros",
        default="1",
        metavar="1|2|LIST",
        help="the robots' dialect: 1 (default; rosbridge 0.11, move_base) or 2 (rosbridge 2.x, "
        "Nav2 navigate_to_pose); a comma list gives one per robot (--ros 1,2)",
    )
    parser.add_argument(
        "--release",
        choices=ros2.RELEASES,
        default="jazzy",
        help="ROS 2 robots' release (default jazzy): the result's shape (humble: empty), and "
        "the defaults of --twist-stamped (kilted) and --humble-queue (humble)",
    )
    parser.add_argument(
        "--twist-stamped",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="ROS 2: /cmd_vel is geometry_msgs/msg/TwistStamped (default: the release's)",
    )
    parser.add_argument(
        "--humble-queue",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="ROS 2: rosbridge with send_action_goals_in_new_thread false: a goal holds its "
        "connection's later ops (cancel, cmd_vel) until it ends (default: the release's)",
    )
    parser.add_argument(
        "--rosbridge-fix",
        action="store_true",
        help="ROS 2: rosbridge with its 2026 fix: a rejected goal, or one to an action nobody "
        "serves, gets a failed action_result (default: no frame at all, as before the fix)",
    )
    parser.add_argument(
        "--robots-see-each-other",
        dest="robots_see_each_other",
        action="store_true",
        default=True,
        help="the default: each robot's footprint is an obstacle to the others (scans, motion): "
        "robots keep clear of each other, stop short, go around one standing still, abort a "
        "goal blocked too long, as real robots do",
    )
    parser.add_argument(
        "--robots-pass-through",
        dest="robots_see_each_other",
        action="store_false",
        help="robots do not see each other and drive through each other (ghosts: only for "
        "measuring something else)",
    )
    parser.add_argument(
        "--blocked-patience",
        type=float,
        default=ROBOT_PATIENCE,
        metavar="SECONDS",
        help="with --robots-see-each-other: sim seconds a robot blocked by another waits "
        f"before its goal aborts (default {ROBOT_PATIENCE:g}, like move_base's/Nav2's defaults)",
    )
    parser.add_argument(
        "--video-port",
        type=int,
        default=None,
        metavar="PORT",
        help="also serve each robot's camera over HTTP as ROS's web_video_server does "
        "(/stream?topic=/camera/image/compressed&type=ros_compressed): robot i on PORT+i, 0 for "
        "free ports (default: no video server)",
    )
    parser.add_argument(
        "--dock",
        action="append",
        default=[],
        metavar="NAME=X,Y,YAW|NAME=WAYPOINT",
        help="robot NAME's charger (its dock): a pose in the map frame (how the robot stands "
        "on the contacts) or a waypoint of the map; repeat for each robot. A robot charges only "
        "standing on a charger; without this one, its dock is its home (where it starts)",
    )
    parser.add_argument(
        "--docking",
        action="store_true",
        help="ROS 2 robots also run opennav_docking's docking server (dock_robot and "
        "undock_robot actions; nav2_msgs types, opennav_docking_msgs with --release humble): "
        "register them with docking=nav2 (docking=opennav on Humble)",
    )
    parser.add_argument(
        "--amcl",
        choices=AMCL_MODES,
        default="continuous",
        help="continuous (default): /amcl_pose at 10 Hz; real: like the amcl node, latched "
        "and only after 0.2 m or 30 degrees of motion",
    )


async def run_sim(
    n: int,
    *,
    port: int = 9090,
    host: str = "127.0.0.1",
    map_path: str | Path | None = None,
    kinematics: str = "omni",
    time_scale: float = 1.0,
    seed: int = 0,
    names: Sequence[str] | None = None,
    stop: asyncio.Event | None = None,
    out: TextIO | None = None,
    ssl: ssl_module.SSLContext | None = None,
    spread: bool = False,
    clock_offset: float = 0.0,
    amcl: str = "continuous",
    namespaced: bool = False,
    ros: int | Sequence[int] = 1,
    release: str = "jazzy",
    twist_stamped: bool | None = None,
    humble_queue: bool | None = None,
    rosbridge_fix: bool = False,
    robots_see_each_other: bool = True,
    blocked_patience: float = ROBOT_PATIENCE,
    video_port: int | None = None,
    docks: Mapping[str, tuple[float, float, float] | str] | None = None,
    docking: bool = False,
) -> int:
    """Run a simulation until ``stop`` is set or SIGINT/SIGTERM; print the URLs first (each
    robot's rosbridge, then, with ``video_port``, each robot's camera stream).

    Returns a process exit code: 0 after a clean stop, 1 when it could not start.
    """
    out = out or sys.stdout
    stop = stop or asyncio.Event()
    loop = asyncio.get_running_loop()
    installed: list[signal.Signals] = []
    for sig in (signal.SIGINT, signal.SIGTERM):
        with contextlib.suppress(NotImplementedError, RuntimeError, ValueError):
            loop.add_signal_handler(sig, stop.set)
            installed.append(sig)
    try:
        try:
            sim = await start_simulation(
                n,
                port=port,
                host=host,
                map_path=map_path,
                kinematics=kinematics,
                time_scale=time_scale,
                seed=seed,
                names=names,
                ssl=ssl,
                spread=spread,
                clock_offset=clock_offset,
                amcl=amcl,
                namespaced=namespaced,
                ros=ros,
                release=release,
                twist_stamped=twist_stamped,
                humble_queue=humble_queue,
                rosbridge_fix=rosbridge_fix,
                robots_see_each_other=robots_see_each_other,
                blocked_patience=blocked_patience,
                video_port=video_port,
                docks=docks,
                docking=docking,
            )
        except (OSError, ServeurError, ValueError) as exc:
            print(f"serveur sim: cannot start: {exc}", file=sys.stderr, flush=True)
            return 1
        try:
            for url in [*sim.urls, *sim.video_urls]:
                print(url, file=out)
            out.flush()
            await stop.wait()
        finally:
            await sim.close()
        return 0
    finally:
        for sig in installed:
            loop.remove_signal_handler(sig)


async def run_sim_from_args(ns: argparse.Namespace) -> int:
    """``serveur sim`` entry point: the options of :func:`add_sim_arguments` -> :func:`run_sim`."""
    names = [s.strip() for s in ns.names.split(",")] if getattr(ns, "names", None) else None
    ctx = None
    certfile, keyfile = getattr(ns, "certfile", None), getattr(ns, "keyfile", None)
    if certfile or keyfile:
        from serveur.security.tls import server_context

        if not (certfile and keyfile):
            print("serveur sim: --certfile and --keyfile go together", file=sys.stderr)
            return 2
        try:
            ctx = server_context(certfile, keyfile)
        except ServeurError as exc:
            print(f"serveur sim: cannot start: {exc}", file=sys.stderr, flush=True)
            return 1
    ros: int | list[int]
    try:
        parts = [int(p) for p in str(getattr(ns, "ros", "1")).split(",")]
    except ValueError:
        print("serveur sim: --ros takes 1, 2 or a comma list of them", file=sys.stderr)
        return 2
    if len(parts) == 1:
        ros = parts[0]
    elif len(parts) == ns.robots:
        ros = parts
    else:
        print(f"serveur sim: --ros lists {len(parts)} robots, not {ns.robots}", file=sys.stderr)
        return 2
    try:
        docks = dict(parse_dock(spec) for spec in getattr(ns, "dock", None) or [])
    except ValueError as exc:
        print(f"serveur sim: {exc}", file=sys.stderr)
        return 2
    return await run_sim(
        ns.robots,
        port=ns.port,
        host=ns.host,
        map_path=ns.map,
        kinematics=ns.kinematics,
        time_scale=ns.time_scale,
        seed=ns.seed,
        names=names,
        ssl=ctx,
        spread=ns.spread_phases,
        clock_offset=getattr(ns, "clock_offset", 0.0),
        amcl=getattr(ns, "amcl", "continuous"),
        namespaced=getattr(ns, "namespaced", False),
        ros=ros,
        release=getattr(ns, "release", "jazzy"),
        twist_stamped=getattr(ns, "twist_stamped", None),
        humble_queue=getattr(ns, "humble_queue", None),
        rosbridge_fix=getattr(ns, "rosbridge_fix", False),
        robots_see_each_other=getattr(ns, "robots_see_each_other", True),
        blocked_patience=getattr(ns, "blocked_patience", ROBOT_PATIENCE),
        video_port=getattr(ns, "video_port", None),
        docks=docks,
        docking=getattr(ns, "docking", False),
    )
