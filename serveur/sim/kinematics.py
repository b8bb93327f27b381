"""Pure motion models of the simulated robots: base kinematics, path following, wheel odometry.

Kept apart from the websocket/actionlib code of :mod:`serveur.robot_sim` so the physics can be
tested with plain numbers and no event loop: a unit test steps :class:`MotionModel` with a fixed
``dt`` and checks that limits hold and that :class:`PathFollower` lands inside the tolerances.

Two bases, because the fleet has both:

* ``"omni"`` — the "Serveur" waiter robot (mecanum/omni wheels): body velocity (vx, vy, wz).
* ``"diff"`` — a differential drive (TurtleBot): (vx, wz); it cannot move sideways, so any vy
  in a command is dropped.

Limits are enforced on every step whatever the command source (controller or teleop), the way a
motor controller would: acceleration first (|dv| <= a dt, |dw| <= alpha dt), then speed.
"""

from __future__ import annotations

import math
import random
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Final, Literal

__all__ = [
    "KINDS",
    "Kind",
    "Limits",
    "MotionModel",
    "OdometryModel",
    "PathFollower",
    "wrap_angle",
]

Kind = Literal["omni", "diff"]
KINDS: Final[tuple[Kind, ...]] = ("omni", "diff")

_TWO_PI: Final = 2.0 * math.pi


def wrap_angle(a: float) -> float:
    """The same angle in [-pi, pi)."""
    return (a + math.pi) % _TWO_PI - math.pi


@dataclass(frozen=True, slots=True)
class Limits:
    """Speed and acceleration limits of a base (defaults: a cautious restaurant robot)."""

    max_speed: float = 0.7  # m/s, norm of the linear velocity
    max_accel: float = 0.5  # m/s²
    max_wz: float = 1.5  # rad/s
    max_alpha: float = 2.0  # rad/s²


def _clamp(v: float, lo: float, hi: float) -> float:
    return lo if v < lo else hi if v > hi else v


class MotionModel:
    """True pose and body velocity of a base, advanced by :meth:`step` with limited commands."""

    __slots__ = ("kind", "limits", "vx", "vy", "wz", "x", "y", "yaw")

    def __init__(
        self, kind: Kind, limits: Limits, x: float = 0.0, y: float = 0.0, yaw: float = 0.0
    ) -> None:
        if kind not in KINDS:
            raise ValueError(f"kinematics must be one of {KINDS}, not {kind!r}")
        self.kind: Kind = kind
        self.limits = limits
        self.x, self.y, self.yaw = x, y, wrap_angle(yaw)
        self.vx = self.vy = self.wz = 0.0

    @property
    def speed(self) -> float:
        """Norm of the linear velocity (m/s)."""
        return math.hypot(self.vx, self.vy)

    def teleport(self, x: float, y: float, yaw: float) -> None:
        """Put the base somewhere else, at rest (relocalisation, tests)."""
        self.x, self.y, self.yaw = x, y, wrap_angle(yaw)
        self.vx = self.vy = self.wz = 0.0

    def step(
        self,
        cmd_vx: float,
        cmd_vy: float,
        cmd_wz: float,
        dt: float,
        is_free: Callable[[float, float], bool] | None = None,
    ) -> bool:
        """Move towards the commanded body velocity within the limits, then integrate ``dt``.

        ``is_free(x, y)`` models the bumper: a step that would enter an occupied spot from a free
        one is not taken and the linear velocity drops to zero (rotation still happens). Returns
        False when that happened, so that navigation can notice it is stuck.
        """
        lim = self.limits
        if self.kind == "diff":
            cmd_vy = 0.0
        # Speed limit on the command, keeping its direction.
        n = math.hypot(cmd_vx, cmd_vy)
        if n > lim.max_speed:
            s = lim.max_speed / n
            cmd_vx, cmd_vy = cmd_vx * s, cmd_vy * s
        cmd_wz = _clamp(cmd_wz, -lim.max_wz, lim.max_wz)
        # Acceleration limit on the change, as one vector for the linear part.
        dvx, dvy = cmd_vx - self.vx, cmd_vy - self.vy
        dv = math.hypot(dvx, dvy)
        max_dv = lim.max_accel * dt
        if dv > max_dv:
            s = max_dv / dv
            dvx, dvy = dvx * s, dvy * s
        self.vx += dvx
        self.vy += dvy
        max_dw = lim.max_alpha * dt
        self.wz += _clamp(cmd_wz - self.wz, -max_dw, max_dw)
        # Integrate with the mid-step heading (second order, exact enough at 20 Hz).
        mid = self.yaw + 0.5 * self.wz * dt
        c, s_ = math.cos(mid), math.sin(mid)
        nx = self.x + (self.vx * c - self.vy * s_) * dt
        ny = self.y + (self.vx * s_ + self.vy * c) * dt
        self.yaw = wrap_angle(self.yaw + self.wz * dt)
        moved = True
        if (
            is_free is not None
            and (nx != self.x or ny != self.y)
            and not is_free(nx, ny)
            and is_free(self.x, self.y)
        ):
            self.vx = self.vy = 0.0
            moved = False
        else:
            self.x, self.y = nx, ny
        return moved


def _approach_speed(distance: float, v_max: float, accel: float, gain: float) -> float:
    """Fastest speed from which the base can still stop within ``distance`` (plus a P term).

    sqrt(2 a d) is the braking profile; the proportional cap ``gain * d`` keeps the last
    centimetres from overshooting with a fixed integration step.
    """
    if distance <= 0.0:
        return 0.0
    return min(v_max, math.sqrt(2.0 * accel * distance), gain * distance)


class PathFollower:
    """Follows a smoothed path (list of (x, y)) then turns to the goal heading.

    A carrot-on-a-stick controller: aim at the point ``lookahead`` metres further along the path
    than the base's projection, at the speed from which it can still brake before the end. The
    carrot is 0.3 m ahead: further ahead it cuts the corner where a path turns round a table,
    and the planner's paths turn right at the edge of the robot's inflated footprint (at 0.5 m
    the omni base clipped table corners on 21 of the demo room's 506 waypoint-to-waypoint
    drives; at 0.3 m on none, for drives 4 % longer). Once within a fraction of the xy
    tolerance the position is latched (as move_base's ``latch_xy_goal_tolerance``) and only the
    heading is corrected. ``done`` turns True when both are well within tolerance, so that the
    pose at rest is inside the tolerances.
    """

    def __init__(
        self,
        path: Sequence[tuple[float, float]],
        goal_yaw: float,
        kind: Kind,
        limits: Limits,
        *,
        xy_tolerance: float = 0.1,
        yaw_tolerance: float = 0.1,
        lookahead: float = 0.3,
    ) -> None:
        if not path:
            raise ValueError("empty path")
        self.path: list[tuple[float, float]] = [(float(x), float(y)) for x, y in path]
        self.goal_yaw = wrap_angle(goal_yaw)
        self.kind: Kind = kind
        self.limits = limits
        self.xy_tolerance = xy_tolerance
        self.yaw_tolerance = yaw_tolerance
        self.lookahead = lookahead
        self._seg = 0
        self.xy_reached = False
        self.done = False
        # Remaining length after the end of each segment, for the braking profile.
        n = len(self.path)
        self._tail = [0.0] * max(1, n - 1)
        for i in range(n - 3, -1, -1):
            (ax, ay), (bx, by) = self.path[i + 1], self.path[i + 2]
            self._tail[i] = self._tail[i + 1] + math.hypot(bx - ax, by - ay)

    @property
    def goal(self) -> tuple[float, float]:
        """Final (x, y) of the path."""
        return self.path[-1]

    def _project(self, x: float, y: float) -> tuple[float, float, float]:
        """Advance the current segment and return (projection x, y, remaining path length)."""
        path = self.path
        if len(path) == 1:
            gx, gy = path[0]
            return gx, gy, 0.0
        best: tuple[float, int, float, float, float] | None = None
        last = len(path) - 2
        # Search a few segments ahead only: the path may come back near itself.
        for i in range(self._seg, min(self._seg + 4, last + 1)):
            (ax, ay), (bx, by) = path[i], path[i + 1]
            sx, sy = bx - ax, by - ay
            seg_len2 = sx * sx + sy * sy
            t = (
                0.0
                if seg_len2 == 0.0
                else _clamp(((x - ax) * sx + (y - ay) * sy) / seg_len2, 0.0, 1.0)
            )
            px, py = ax + t * sx, ay + t * sy
            d = math.hypot(x - px, y - py)
            if best is None or d < best[0] - 1e-9:
                rem = (1.0 - t) * math.sqrt(seg_len2) + self._tail[i]
                best = (d, i, px, py, rem)
        assert best is not None
        _, self._seg, px, py, rem = best
        return px, py, rem

    def _carrot(self, px: float, py: float) -> tuple[float, float]:
        """The point ``lookahead`` metres along the path from the projection (px, py)."""
        left = self.lookahead
        cx, cy = px, py
        for i in range(self._seg, len(self.path) - 1):
            bx, by = self.path[i + 1]
            d = math.hypot(bx - cx, by - cy)
            if d >= left:
                f = left / d
                return cx + (bx - cx) * f, cy + (by - cy) * f
            left -= d
            cx, cy = bx, by
        return self.path[-1]

    def command(self, x: float, y: float, yaw: float) -> tuple[float, float, float]:
        """Body-frame velocity command (vx, vy, wz) for the base at (x, y, yaw)."""
        lim = self.limits
        gx, gy = self.path[-1]
        d_goal = math.hypot(gx - x, gy - y)
        stop_xy = 0.25 * self.xy_tolerance
        if self.xy_reached and d_goal > self.xy_tolerance:
            self.xy_reached = False  # pushed away (relocalised): drive again
        if not self.xy_reached and d_goal <= stop_xy:
            self.xy_reached = True
        brake_v = 0.8 * lim.max_accel  # brake a bit under the limit: the model must follow
        brake_w = 0.8 * lim.max_alpha
        if self.xy_reached:
            e = wrap_angle(self.goal_yaw - yaw)
            if abs(e) <= 0.25 * self.yaw_tolerance:
                self.done = True
                return 0.0, 0.0, 0.0
            self.done = False
            return 0.0, 0.0, math.copysign(_approach_speed(abs(e), lim.max_wz, brake_w, 2.0), e)
        self.done = False
        px, py, rem = self._project(x, y)
        rem = max(rem + math.hypot(x - px, y - py), d_goal)
        cx, cy = self._carrot(px, py)
        if math.hypot(cx - x, cy - y) < 1e-9:
            cx, cy = gx, gy
        speed = _approach_speed(rem, lim.max_speed, brake_v, 2.0)
        heading = math.atan2(cy - y, cx - x)
        if self.kind == "omni":
            # Drive straight at the carrot in any direction while turning to the goal heading.
            c, s = math.cos(heading - yaw), math.sin(heading - yaw)
            e = wrap_angle(self.goal_yaw - yaw)
            wz = math.copysign(_approach_speed(abs(e), lim.max_wz, brake_w, 2.0), e)
            return speed * c, speed * s, wz
        # Differential drive: face the carrot, turning in place when far off; close to the goal
        # it may back up rather than orbit around it.
        e_h = wrap_angle(heading - yaw)
        if d_goal < 0.3 and abs(e_h) > 0.5 * math.pi:
            e_h = wrap_angle(e_h - math.pi)
            speed = -speed
        vx = 0.0 if abs(e_h) > 0.6 else speed * math.cos(e_h)
        wz = math.copysign(_approach_speed(abs(e_h), lim.max_wz, brake_w, 3.0), e_h)
        return vx, 0.0, wz


class OdometryModel:
    """Wheel odometry: integrates the measured body velocity, which is the true one with noise.

    A per-robot scale error (a wheel radius a little off) makes the odometry drift like a real
    one, and white noise on each measurement makes the twist jitter; both come from the robot's
    seeded ``rng`` so a run is reproducible. The odometry frame starts at (0, 0, 0), as at boot.
    """

    __slots__ = ("_gauss", "_noise", "_scale", "vx", "vy", "wz", "x", "y", "yaw")

    def __init__(
        self, rng: random.Random, *, scale_error: float = 0.01, noise: float = 0.02
    ) -> None:
        self._gauss = rng.gauss
        self._scale = 1.0 + rng.uniform(-scale_error, scale_error)
        self._noise = noise
        self.x = self.y = self.yaw = 0.0
        self.vx = self.vy = self.wz = 0.0

    def update(self, vx: float, vy: float, wz: float, dt: float) -> None:
        """Measure the true body velocity (vx, vy, wz) during ``dt`` and integrate it."""
        if vx == 0.0 and vy == 0.0 and wz == 0.0:
            # Encoders read exactly zero when the wheels do not turn: no drift at rest.
            self.vx = self.vy = self.wz = 0.0
            return
        g, k, sd = self._gauss, self._scale, self._noise
        self.vx = vx * k * (1.0 + g(0.0, sd))
        self.vy = vy * k * (1.0 + g(0.0, sd))
        self.wz = wz * k * (1.0 + g(0.0, sd))
        mid = self.yaw + 0.5 * self.wz * dt
        c, s = math.cos(mid), math.sin(mid)
        self.x += (self.vx * c - self.vy * s) * dt
        self.y += (self.vx * s + self.vy * c) * dt
        self.yaw = wrap_angle(self.yaw + self.wz * dt)
