"""What a simulated robot publishes, at which rates: odometry, AMCL, laser, battery, status.

Split from :mod:`serveur.sim.robot`: the robot's subscriptions (a client's, kept per topic, a
latched topic's last message offered to a new one) and its publishing, each frame built only
when a subscriber takes it now, at whole numbers of :data:`~serveur.sim.base.TICK`: ``/odom``
20 Hz, ``/amcl_pose`` 10 Hz (or, in AMCL's "real" mode, latched and only after motion, see
:mod:`serveur.sim.robot`), move_base's feedback 10 Hz and status 5 Hz (a ROS 2 goal's
feedback every tick, to its sender alone), ``/scan`` 5 Hz (ray-cast on the map, other robots'
footprints in it when the floor is shared), ``/battery_state`` 1 Hz; noise on AMCL and scans.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from typing import Any, Final

import numpy as np
import numpy.typing as npt

from serveur.maps.navigation import raycast
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.base import TICK, Goal, RobotBase
from serveur.sim.kinematics import wrap_angle
from serveur.sim.topics import Frame, Sub

__all__ = [
    "AMCL_MODES",
    "AMCL_TICKS",
    "AMCL_UPDATE_MIN_A",
    "AMCL_UPDATE_MIN_D",
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

_AMCL_COVARIANCE: Final = [0.0] * 36
_AMCL_COVARIANCE[0] = _AMCL_COVARIANCE[7] = AMCL_NOISE_XY**2
_AMCL_COVARIANCE[35] = AMCL_NOISE_YAW**2


class Sensors(RobotBase):
    """The robot's subscriptions and everything it publishes (see the module's docstring)."""

    # -- subscriptions -----------------------------------------------------------------------

    def _add_sub(self, sub: Sub) -> None:
        self._subs.setdefault(sub.topic, []).append(sub)

    def _remove_sub(self, sub: Sub) -> None:
        subs = self._subs.get(sub.topic)
        if subs and sub in subs:
            subs.remove(sub)
            if not subs:
                del self._subs[sub.topic]

    def _next_seq(self, topic: str) -> int:
        s = self._seqs.get(topic, 0)
        self._seqs[topic] = s + 1
        return s

    def _publish(
        self,
        topic: str,
        build: Callable[[int, float], dict[str, Any]],
        stamp: float | None = None,
    ) -> None:
        """Build (only if a subscriber takes it now) and hand one frame to every subscriber.

        ``stamp`` defaults to now; ticks pass their own sim time.
        """
        subs = self._subs.get(topic)
        if not subs:
            return
        t = self._t
        wanting = [s for s in subs if s.wants(t)]
        if not wanting:
            return
        if stamp is None:
            stamp = self.epoch()
        msg = build(self._next_seq(topic), stamp)
        frame = Frame(rb.op_publish(self.wire(topic), ros2.to_ros2(msg) if self.ros == 2 else msg))
        for s in wanting:
            s.push(frame, t)

    def _relay(self, topic: str, msg: Mapping[str, Any]) -> None:
        """A client's publish on a robot topic also reaches that topic's subscribers (ROS does)."""
        if topic in self._subs:
            frame = Frame(rb.op_publish(self.wire(topic), msg))
            t = self._clock.now()
            for s in list(self._subs[topic]):
                if s.wants(t):
                    s.push(frame, t)

    def _offer_latched(self, sub: Sub) -> None:
        """A new subscriber to a latched topic gets its last message at once (not from a
        dead node)."""
        if not self._relaying:
            return
        if sub.topic == "/map" and self._map_frame is not None:
            sub.push(self._map_frame, self._t)
        elif sub.topic == "/amcl_pose" and self._amcl_frame is not None:
            sub.push(self._amcl_frame, self._t)

    def _nav2_feedback(self, g: Goal, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.pose
        f = self._follower
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
            navigation_time=self._t - g.started,
            distance_remaining=left,
            speed=self._motion.speed,
        )

    def _publish_due(self, k: int) -> None:
        stamp = self._tick_stamp()
        if k % _ODOM_TICKS == 0:
            self._publish("/odom", self._build_odom, stamp)
        if k % AMCL_TICKS == 0:
            if self.amcl == "real":
                self._amcl_update(stamp)
            else:
                self._publish("/amcl_pose", self._build_amcl, stamp)
        if self.ros == 2:
            g = self._active
            if g is not None and g.owner is not None and g.owner.feedback:
                # One action_feedback per navigator feedback, unthrottled (20 Hz here).
                g.owner.send_feedback(self._nav2_feedback(g, stamp))
        elif k % _FEEDBACK_TICKS == 0 and self._active is not None:
            self._publish("/move_base/feedback", self._build_feedback, stamp)
        if k % _SCAN_TICKS == 0:
            self._publish("/scan", self._build_scan, stamp)
        if k % _STATUS_TICKS == 0 and self.ros == 1:
            self._publish("/move_base/status", self._build_status, stamp)
        if k % _BATTERY_TICKS == 0:
            self._publish("/battery_state", self._build_battery, stamp)

    def _amcl_update(self, stamp: float) -> None:
        """AMCL in "real" mode: publish (latched) only when forced or after enough motion.

        amcl_node.cpp updates its filter when the motion since the last update exceeds
        ``update_min_d`` or ``update_min_a`` and publishes after the first update following
        an initial pose; the notes' model of it (shared/notes/rosbridge.md) is what is coded:
        more than 0.2 m (straight-line distance) or 30 degrees since the last published pose;
        for a ROS 2 robot Nav2's amcl defaults, 0.25 m or 0.2 rad (shared/notes/ros2.md).
        """
        x, y, yaw = self.pose
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
        msg = self._build_amcl(self._next_seq("/amcl_pose"), stamp)
        frame = Frame(
            rb.op_publish(self.wire("/amcl_pose"), ros2.to_ros2(msg) if self.ros == 2 else msg)
        )
        self._amcl_frame = frame
        t = self._t
        for s in self._subs.get("/amcl_pose", ()):
            if s.wants(t):
                s.push(frame, t)

    def _publish_status(self) -> None:
        if self.ros == 1:
            self._publish("/move_base/status", self._build_status)

    def _build_status(self, seq: int, stamp: float) -> dict[str, Any]:
        return rb.goal_status_array(
            [(g.id, g.status, g.text, g.stamp) for g in self._goals], stamp=stamp, seq=seq
        )

    def _build_odom(self, seq: int, stamp: float) -> dict[str, Any]:
        o = self._odom
        return rb.odometry(o.x, o.y, o.yaw, o.vx, o.vy, o.wz, stamp=stamp, seq=seq)

    def _build_amcl(self, seq: int, stamp: float) -> dict[str, Any]:
        x, y, yaw = self.pose
        g = self._rng.gauss
        return rb.pose_with_covariance_stamped(
            x + g(0.0, AMCL_NOISE_XY),
            y + g(0.0, AMCL_NOISE_XY),
            wrap_angle(yaw + g(0.0, AMCL_NOISE_YAW)),
            stamp=stamp,
            seq=seq,
            covariance=_AMCL_COVARIANCE,
        )

    def _build_feedback(self, seq: int, stamp: float) -> dict[str, Any]:
        g = self._active
        assert g is not None
        x, y, yaw = self.pose
        return rb.move_base_feedback(
            g.id, g.status, x, y, yaw, stamp=stamp, seq=seq, goal_stamp=g.stamp
        )

    def _build_scan(self, seq: int, stamp: float) -> dict[str, Any]:
        pose = self.pose
        cache = self._scan_cache
        if cache is None or cache[0] != pose:
            # Ray-cast only when the robot moved: at rest the room looks the same.
            x, y, yaw = pose
            clean = np.asarray(
                raycast(self._map, x, y, self._scan_rel + yaw, SCAN_RANGE_MAX), dtype=np.float64
            )
            self._scan_cache = cache = (pose, clean)
        ranges = cache[1]
        if self._others:
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
        where = tuple((o._motion.x, o._motion.y) for o in self._others)
        cache = self._robots_scan
        if cache is not None and cache[0] == (x, y, yaw) and cache[1] == where:
            return cache[2]
        c = np.asarray(where, dtype=np.float64).reshape(-1, 2) - (x, y)
        r = np.fromiter((o.radius for o in self._others), np.float64, len(self._others))
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
        m = self._motion
        pct = self._battery
        if self._charging:
            status, current = (
                (rb.BatteryStatus.FULL, 0.0) if pct >= 1.0 else (rb.BatteryStatus.CHARGING, 5.0)
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
            serial_number=self.name,
            # A ROS 2 driver leaves what it does not measure NaN (null on the wire).
            temperature=math.nan if self.ros == 2 else 30.0,
        )
