"""What a simulated robot publishes, at which rates: odometry, AMCL, laser, battery, status.

Split from :mod:`serveur.sim.robot`: the robot's publishing schedule (through its
:class:`~serveur.sim.outbox.Outbox`, each frame built only when a subscriber takes it now),
at whole numbers of :data:`~serveur.sim.state.TICK`: ``/odom``
20 Hz, ``/amcl_pose`` 10 Hz (or, in AMCL's "real" mode, latched and only after motion, see
:mod:`serveur.sim.robot`), move_base's feedback 10 Hz and status 5 Hz (a ROS 2 goal's
feedback every tick, to its sender alone), ``/scan`` 5 Hz (ray-cast on the map, other robots'
footprints in it when the floor is shared), ``/battery_state`` 1 Hz; noise on AMCL and scans.

Localisation, as AMCL shows it: ``/amcl_pose`` carries the filter's covariance, and the
particle cloud (ROS1 ``/particlecloud`` PoseArray, Nav2 ``/particle_cloud`` ParticleCloud,
:data:`CLOUD_PARTICLES` particles drawn around the pose with that spread) goes out with each
AMCL update. After an initial pose the spread is AMCL's initial covariance (0.5 m, 0.26 rad)
and shrinks as the robot moves (the filter converging); :meth:`Sensors.lose_localisation`
(a test's or the demo's fault) spreads it over metres, as a filter that lost track, until the
next initial pose. tf: ``odom`` -> ``base_footprint`` with every odometry message, ``map`` ->
``odom`` with every AMCL update (so the two compose to the AMCL pose), ``base_footprint`` ->
``base_link`` latched on ``/tf_static``.
"""

from __future__ import annotations

import asyncio
import math
import random
from collections.abc import Callable
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from serveur.maps.navigation import raycast
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.camera import CameraView
from serveur.sim.kinematics import wrap_angle
from serveur.sim.navigator import Navigator
from serveur.sim.outbox import Outbox
from serveur.sim.state import TICK, Goal, RobotState

__all__ = [
    "AMCL_MODES",
    "AMCL_TICKS",
    "AMCL_UPDATE_MIN_A",
    "AMCL_UPDATE_MIN_D",
    "CLOUD_PARTICLES",
    "CLOUD_TOPICS",
    "CONVERGED_SPREAD",
    "INITIAL_SPREAD",
    "NAV2_UPDATE_MIN_A",
    "NAV2_UPDATE_MIN_D",
    "SCAN_RAYS",
    "Sensors",
]

_ODOM_TICKS: Final = 1  # 20 Hz
AMCL_TICKS: Final = 2  # 10 Hz
_FEEDBACK_TICKS: Final = 2  # 10 Hz while a goal is active
_SCAN_TICKS: Final = 4  # 5 Hz
_STATUS_TICKS: Final = 4  # 5 Hz (actionlib's default status_frequency)
_BATTERY_TICKS: Final = 20  # 1 Hz
_CAMERA_TICKS: Final = 2  # 10 Hz of the robot's time...
#: ...but at most this many frames a wall second: a frame costs ~10-20 ms of CPU to render and
#: encode, and a simulation at 10x would otherwise render 100 a second for one viewer.
CAMERA_MAX_WALL_FPS: Final = 15.0
CAMERA_TOPIC: Final = "/camera/image/compressed"

#: Amperes a charger puts in (BatteryState's capacity, 20 Ah, over the 4.5 h of a full charge:
#: serveur.sim.robot.FULL_CHARGE).
CHARGE_CURRENT: Final = 20.0 / 4.5
SCAN_RAYS: Final = 360
SCAN_RANGE_MIN: Final = 0.12
SCAN_RANGE_MAX: Final = 8.0
SCAN_NOISE: Final = 0.01  # m, sigma
AMCL_NOISE_XY: Final = 0.01  # m, sigma
AMCL_NOISE_YAW: Final = 0.005  # rad, sigma
#: ``amcl`` parameter values: 10 Hz poses whatever happens, or the amcl node's behaviour.
AMCL_MODES: Final = ("continuous", "real")
AMCL_UPDATE_MIN_D: Final = 0.2  # m: amcl's update_min_d default
AMCL_UPDATE_MIN_A: Final = math.pi / 6.0  # rad (30 degrees): amcl's update_min_a default
NAV2_UPDATE_MIN_D: Final = 0.25  # m: Nav2 amcl's update_min_d default
NAV2_UPDATE_MIN_A: Final = 0.2  # rad: Nav2 amcl's update_min_a default

#: The spread (m, rad: standard deviations) of a converged filter, and AMCL's right after an
#: initial pose (its default initial covariance, 0.25 m² and 0.068 rad²).
CONVERGED_SPREAD: Final = (AMCL_NOISE_XY, AMCL_NOISE_YAW)
INITIAL_SPREAD: Final = (0.5, math.sqrt(0.06853891945200942))
#: Each AMCL update after the robot moved shrinks the spread by this factor (down to converged).
_CONVERGE: Final = 0.7
#: The particle cloud's topic by ROS version (amcl.cpp's ``particlecloud``; nav2_amcl's
#: ``particle_cloud``), and how many particles it holds (amcl's ``min_particles`` default).
CLOUD_TOPICS: Final = {1: "/particlecloud", 2: "/particle_cloud"}
CLOUD_PARTICLES: Final = 500
#: The robot's frames (tf): odometry's, its footprint's and its body's.
ODOM_FRAME: Final = "odom"
BASE_FRAME: Final = "base_footprint"
BODY_FRAME: Final = "base_link"


def _covariance(metres: float, radians: float) -> list[float]:
    cov = [0.0] * 36
    cov[0] = cov[7] = metres**2
    cov[35] = radians**2
    return cov


class Sensors:
    """What the robot publishes and when (see the module's docstring).

    The navigator's feedback and status go out here at their rates; what it publishes when a
    goal changes (status, results) it sends itself (:mod:`serveur.sim.navigator`).
    """

    def __init__(
        self,
        state: RobotState,
        outbox: Outbox,
        navigator: Navigator,
        *,
        amcl: str,
        rng: random.Random,
        np_rng: np.random.Generator,
    ) -> None:
        self.state = state
        self.outbox = outbox
        self.navigator = navigator
        self.amcl = amcl
        self._amcl_min = (
            (NAV2_UPDATE_MIN_D, NAV2_UPDATE_MIN_A)
            if state.ros == 2
            else (AMCL_UPDATE_MIN_D, AMCL_UPDATE_MIN_A)
        )
        self._rng = rng
        self._np_rng = np_rng
        # AMCL in "real" mode: the true pose the latched pose was taken at, a forced update
        self._amcl_at: tuple[float, float, float] | None = None
        self._amcl_force = True
        #: Builds ``/amcl_pose`` (a test swaps it, through ``SimRobot._build_amcl``, to make
        #: the localisation drift).
        self.amcl_builder: Callable[[int, float], dict[str, Any]] = self._build_amcl
        # laser
        self._scan_rel = -math.pi + (2.0 * math.pi / SCAN_RAYS) * np.arange(SCAN_RAYS)
        self._scan_cache: tuple[tuple[float, float, float], npt.NDArray[np.float64]] | None = None
        self._robots_scan: (
            tuple[
                tuple[float, float, float], tuple[tuple[float, float], ...], npt.NDArray[np.float64]
            ]
            | None
        ) = None

        # camera: rendered only while subscribed, in a worker thread, one frame at a time
        self._camera: CameraView | None = None
        self._camera_busy = False
        wall_ticks = state.clock.time_scale / (TICK * CAMERA_MAX_WALL_FPS)
        self._camera_ticks = max(_CAMERA_TICKS, math.ceil(wall_ticks))
        #: False: the camera stopped sending (a test's stalled camera); True again resumes.
        self.camera_on = True
        #: The localisation's spread (m, rad), and whether it converges as the robot moves
        #: (after an initial pose) or stays (lost: until the next initial pose).
        self.spread: tuple[float, float] = CONVERGED_SPREAD
        self._converging = False
        self._lost = False
        self._spread_at: tuple[float, float] | None = None
        self._cloud_topic = CLOUD_TOPICS[state.ros]
        static = {
            "transforms": [
                rb.transform_stamped(BASE_FRAME, BODY_FRAME, 0.0, 0.0, 0.0, stamp=state.epoch())
            ]
        }
        outbox.publish_latched("/tf_static", outbox.frame("/tf_static", static))

    def force_amcl(self) -> None:
        """AMCL publishes its pose at the next update whatever the motion (a node's start)."""
        self._amcl_force = True

    def relocalised(self) -> None:
        """The robot was put elsewhere: AMCL publishes the pose it was given, with its initial
        spread (converging as the robot moves), and the laser looks again."""
        self._scan_cache = None
        self._amcl_force = True
        self.spread = INITIAL_SPREAD
        self._converging = True
        self._lost = False
        self._spread_at = self.state.pose[:2]

    def lose_localisation(self, metres: float = 3.0, radians: float = 1.5) -> None:
        """AMCL loses track (a robot pushed by hand, a room rearranged): its particles spread
        over metres and stay so until an initial pose. Published at once (as if the robot had
        moved enough for an update)."""
        self.spread = (metres, radians)
        self._converging = False
        self._lost = True
        self._amcl_force = True

    def _converge(self) -> None:
        """An AMCL update: after an initial pose the filter tightens once the robot moved."""
        if not self._converging:
            return
        x, y = self.state.pose[:2]
        at = self._spread_at
        if at is not None and math.hypot(x - at[0], y - at[1]) < 0.05:
            return
        self._spread_at = (x, y)
        m, r = self.spread
        self.spread = (
            max(CONVERGED_SPREAD[0], m * _CONVERGE),
            max(CONVERGED_SPREAD[1], r * _CONVERGE),
        )
        self._converging = self.spread != CONVERGED_SPREAD

    def _nav2_feedback(self, g: Goal, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.state.pose
        f = self.navigator.follower
        if f is None:
            left = math.hypot(g.x - x, g.y - y)
        else:
            seg = min(f._seg, len(f.path) - 2)
            if seg < 0:
                left = math.hypot(g.x - x, g.y - y)
            else:
                nx, ny = f.path[seg + 1]
                left = math.hypot(nx - x, ny - y) + f._tail[seg]
        return ros2.nav2_feedback(
            x,
            y,
            yaw,
            stamp=stamp,
            navigation_time=self.state.t - g.started,
            distance_remaining=left,
            speed=self.state.motion.speed,
        )

    def publish_due(self, k: int) -> None:
        """Publish what falls due at tick ``k``, stamped with the last physics step's time."""
        stamp = self.state.tick_stamp()
        publish = self.outbox.publish
        active = self.navigator.active
        if k % _ODOM_TICKS == 0:
            publish("/odom", self._build_odom, stamp)
            publish("/tf", self._build_odom_tf, stamp)
        if k % AMCL_TICKS == 0:
            if self.amcl == "real":
                self._amcl_update(stamp)
            else:
                self._converge()
                publish("/amcl_pose", self.amcl_builder, stamp)
            publish("/tf", self._build_map_tf, stamp)
            publish(self._cloud_topic, self._build_cloud, stamp)
        if self.state.ros == 2:
            g = active
            if g is not None and g.owner is not None and g.owner.feedback:
                # One action_feedback per navigator feedback, unthrottled (20 Hz here).
                g.owner.send_feedback(self._nav2_feedback(g, stamp))
        elif k % _FEEDBACK_TICKS == 0 and active is not None:
            publish("/move_base/feedback", self._build_feedback, stamp)
        if k % _SCAN_TICKS == 0:
            publish("/scan", self._build_scan, stamp)
        if k % _STATUS_TICKS == 0 and self.state.ros == 1:
            self.navigator.publish_status(stamp)
        if k % _BATTERY_TICKS == 0:
            publish("/battery_state", self._build_battery, stamp)
        if k % self._camera_ticks == 0:
            self._camera_due(stamp)

    def _camera_due(self, stamp: float) -> None:
        """Render the view now (off the loop) if a subscriber takes a frame and none is being
        rendered; it is published, stamped with this tick's time, when done."""
        subs = self.outbox.subs.get(CAMERA_TOPIC)
        if not subs or self._camera_busy or not self.camera_on:
            return
        if not any(s.wants(self.state.t) for s in subs):
            return
        if self._camera is None:
            self._camera = CameraView(self.state.map)
        self._camera_busy = True
        x, y, yaw = self.state.pose
        fut = asyncio.get_running_loop().run_in_executor(None, self._camera.jpeg, x, y, yaw)
        fut.add_done_callback(lambda f: self._camera_done(f, stamp))

    def _camera_done(self, fut: asyncio.Future[bytes], stamp: float) -> None:
        self._camera_busy = False
        if fut.cancelled() or fut.exception() is not None:
            return
        jpeg = fut.result()
        self.outbox.publish(
            CAMERA_TOPIC, lambda seq, st: rb.compressed_image(jpeg, stamp=st, seq=seq), stamp
        )

    def _amcl_update(self, stamp: float) -> None:
        """AMCL in "real" mode: publish (latched) only when forced or after enough motion.

        amcl_node.cpp updates its filter when the motion since the last update exceeds
        ``update_min_d`` or ``update_min_a`` and publishes after the first update following
        an initial pose; the notes' model of it (shared/notes/rosbridge.md) is what is coded:
        more than 0.2 m (straight-line distance) or 30 degrees since the last published pose;
        for a ROS 2 robot Nav2's amcl defaults, 0.25 m or 0.2 rad (shared/notes/ros2.md).
        """
        x, y, yaw = self.state.pose
        at = self._amcl_at
        if (
            not self._amcl_force
            and at is not None
            and math.hypot(x - at[0], y - at[1]) <= self._amcl_min[0]
            and abs(wrap_angle(yaw - at[2])) <= self._amcl_min[1]
        ):
            return
        self._amcl_force = False
        self._amcl_at = (x, y, yaw)
        self._converge()
        out = self.outbox
        out.publish_latched(
            "/amcl_pose",
            out.frame("/amcl_pose", self.amcl_builder(out.next_seq("/amcl_pose"), stamp)),
        )

    def _build_odom(self, seq: int, stamp: float) -> dict[str, Any]:
        o = self.state.odom
        return rb.odometry(o.x, o.y, o.yaw, o.vx, o.vy, o.wz, stamp=stamp, seq=seq)

    def _build_amcl(self, seq: int, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.state.pose
        g = self._rng.gauss
        # A lost filter's estimate wanders with its spread (a fifth of it: the particles'
        # mean moves less than they do); otherwise AMCL's jitter (after an initial pose its
        # mean is the pose given).
        m, r = self.spread
        sd_xy, sd_yaw = AMCL_NOISE_XY, AMCL_NOISE_YAW
        if self._lost:
            sd_xy, sd_yaw = max(sd_xy, m / 5.0), max(sd_yaw, r / 5.0)
        return rb.pose_with_covariance_stamped(
            x + g(0.0, sd_xy),
            y + g(0.0, sd_xy),
            wrap_angle(yaw + g(0.0, sd_yaw)),
            stamp=stamp,
            seq=seq,
            covariance=_covariance(m, r),
        )

    def _build_cloud(self, seq: int, stamp: float) -> dict[str, Any]:
        """AMCL's particles: drawn around the true pose with the filter's spread."""
        x, y, yaw = self.state.pose
        m, r = self.spread
        n = CLOUD_PARTICLES
        xs = self._np_rng.normal(x, m, n)
        ys = self._np_rng.normal(y, m, n)
        yaws = self._np_rng.normal(yaw, r, n)
        poses = [
            rb.pose_msg(float(a), float(b), float(c)) for a, b, c in zip(xs, ys, yaws, strict=True)
        ]
        head = rb.header(seq, stamp, "map")
        if self.state.ros == 2:
            return {"header": head, "particles": [{"pose": p, "weight": 1.0 / n} for p in poses]}
        return {"header": head, "poses": poses}

    def _build_odom_tf(self, seq: int, stamp: float) -> dict[str, Any]:
        o = self.state.odom
        tf = rb.transform_stamped(ODOM_FRAME, BASE_FRAME, o.x, o.y, o.yaw, stamp=stamp, seq=seq)
        return {"transforms": [tf]}

    def _build_map_tf(self, seq: int, stamp: float) -> dict[str, Any]:
        """map -> odom: the transform that puts the odometry's pose on the map pose."""
        x, y, yaw = self.state.pose
        o = self.state.odom
        dyaw = yaw - o.yaw
        c, s = math.cos(dyaw), math.sin(dyaw)
        tx, ty = x - (c * o.x - s * o.y), y - (s * o.x + c * o.y)
        tf = rb.transform_stamped("map", ODOM_FRAME, tx, ty, wrap_angle(dyaw), stamp=stamp, seq=seq)
        return {"transforms": [tf]}

    def _build_feedback(self, seq: int, stamp: float) -> dict[str, Any]:
        g = self.navigator.active
        assert g is not None
        x, y, yaw = self.state.pose
        return rb.move_base_feedback(
            g.id, g.status, x, y, yaw, stamp=stamp, seq=seq, goal_stamp=g.stamp
        )

    def _build_scan(self, seq: int, stamp: float) -> dict[str, Any]:
        pose = self.state.pose
        cache = self._scan_cache
        if cache is None or cache[0] != pose:
            # Ray-cast only when the robot moved: at rest the room looks the same.
            x, y, yaw = pose
            clean = np.asarray(
                raycast(self.state.map, x, y, self._scan_rel + yaw, SCAN_RANGE_MAX),
                dtype=np.float64,
            )
            self._scan_cache = cache = (pose, clean)
        ranges = cache[1]
        if self.state.others:
            ranges = np.minimum(ranges, self._robot_ranges(*pose))
        ranges = ranges + self._np_rng.normal(0.0, SCAN_NOISE, SCAN_RAYS)
        ranges[ranges < SCAN_RANGE_MIN] = SCAN_RANGE_MIN
        ranges[ranges > SCAN_RANGE_MAX] = np.inf  # no return within range: +Inf (REP 117)
        return rb.laser_scan(
            ranges,
            stamp=stamp,
            seq=seq,
            angle_min=-math.pi,
            angle_increment=2.0 * math.pi / SCAN_RAYS,
            range_min=SCAN_RANGE_MIN,
            range_max=SCAN_RANGE_MAX,
            scan_time=TICK * _SCAN_TICKS,
            time_increment=TICK * _SCAN_TICKS / SCAN_RAYS,
        )

    def _robot_ranges(self, x: float, y: float, yaw: float) -> npt.NDArray[np.float64]:
        """Range along each scan ray to the nearest other robot's footprint (inf: none).

        Ray-disc intersection from the laser at the robot's centre, every robot in range at
        once; a robot whose disc holds the laser (overlapping robots) is not seen, as a laser
        does not see inside a body. Kept while neither this robot nor any other moved (a
        parked fleet's scans cost one comparison).
        """
        where = tuple((o.motion.x, o.motion.y) for o in self.state.others)
        cache = self._robots_scan
        if cache is not None and cache[0] == (x, y, yaw) and cache[1] == where:
            return cache[2]
        c = np.asarray(where, dtype=np.float64).reshape(-1, 2) - (x, y)
        r = np.fromiter((o.radius for o in self.state.others), np.float64, len(self.state.others))
        d2 = (c * c).sum(axis=1)
        near = (d2 > r * r) & (d2 <= (SCAN_RANGE_MAX + r) ** 2)
        out = np.full(SCAN_RAYS, np.inf)
        if near.any():
            c, d2, r = c[near], d2[near], r[near]
            ang = self._scan_rel + yaw
            b = c[:, :1] * np.cos(ang) + c[:, 1:] * np.sin(ang)  # (robots, rays)
            disc = b * b - (d2 - r * r)[:, None]
            t = np.where((disc >= 0.0) & (b > 0.0), b - np.sqrt(np.maximum(disc, 0.0)), np.inf)
            out = t.min(axis=0)
        self._robots_scan = ((x, y, yaw), where, out)
        return out

    def _build_battery(self, seq: int, stamp: float) -> dict[str, Any]:
        """sensor_msgs/BatteryState: CHARGING (1) with the charger's current on its contacts,
        FULL (4) there once full (no current), DISCHARGING (2) elsewhere (the current
        negative, as the message's convention is)."""
        m = self.state.motion
        pct = self.state.battery
        if self.state.charging:
            status, current = (
                (rb.BatteryStatus.FULL, 0.0)
                if pct >= 1.0
                else (rb.BatteryStatus.CHARGING, CHARGE_CURRENT)
            )
        else:
            status, current = rb.BatteryStatus.DISCHARGING, -(1.5 + 4.0 * m.speed)
        return rb.battery_state(
            pct,
            stamp=stamp,
            seq=seq,
            voltage=21.0 + 4.2 * pct,
            current=current,
            status=status,
            serial_number=self.state.name,
            # A ROS 2 driver leaves what it does not measure NaN (null on the wire).
            temperature=math.nan if self.state.ros == 2 else 30.0,
        )
