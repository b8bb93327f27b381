"""Is a robot sure where it is? Judged from the spread of its localisation (pure; no I/O).

A robot that no longer knows where it is drives to the wrong table, or into one; AMCL says so
in the covariance it publishes with every pose and in how spread its particles are
(:mod:`serveur.robots.sensing`). A robot whose estimate is spread beyond :class:`Limits` is
*lost*: staff read "Not sure where it is — set where the robot is", it gets no trips, and an
alert is raised (:mod:`serveur.core.alerts`), until it is sure again.

The thresholds (standard deviations, worst floor direction and heading):

* **lost** above 1.0 m or 0.8 rad (46 degrees): a table is a metre wide, so an estimate that
  may be a metre off can serve the wrong one; AMCL converged on a known map sits at a few
  centimetres, so only a filter that has really spread out crosses it;
* **sure again** below 0.6 m and 0.4 rad: AMCL's own initial pose (0.5 m, 0.26 rad: its
  default initial covariance 0.25 m², 0.068 rad²) counts as sure, so setting where the robot
  is on the map ends the alert at once, as staff expect.

The gap between the two is hysteresis: a spread wavering around one number does not make the
alert come and go. When the particle cloud is streamed (someone shows it), its spread counts
too — the larger of the two is judged — until the cloud stops.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

__all__ = ["Limits", "Localisation"]


@dataclass(frozen=True, slots=True)
class Limits:
    """When an estimate is lost, and when it is sure again (standard deviations)."""

    lost_m: float = 1.0
    lost_rad: float = 0.8
    sure_m: float = 0.6
    sure_rad: float = 0.4


class Localisation:
    """One robot's judgement: sure (the start: a robot that never said otherwise) or lost."""

    def __init__(self, limits: Limits = Limits()) -> None:
        self.limits = limits
        self.lost = False
        self.metres = 0.0
        self.radians = 0.0
        self._cloud_m: float | None = None

    def pose(self, metres: float, radians: float) -> bool:
        """A pose's spread came; True if that changed the judgement."""
        self.metres = metres if not math.isnan(metres) else math.inf
        self.radians = radians if not math.isnan(radians) else math.inf
        return self._judge()

    def cloud(self, metres: float | None) -> bool:
        """The particle cloud's spread (None: the cloud stopped streaming); True if that
        changed the judgement."""
        self._cloud_m = None if metres is None or math.isnan(metres) else metres
        return self._judge()

    @property
    def spread(self) -> float:
        """The spread judged (m): the pose's, or the cloud's when that is larger."""
        return max(self.metres, self._cloud_m or 0.0)

    def _judge(self) -> bool:
        lim, m = self.limits, self.spread
        if self.lost:
            lost = not (m < lim.sure_m and self.radians < lim.sure_rad)
        else:
            lost = m > lim.lost_m or self.radians > lim.lost_rad
        changed = lost != self.lost
        self.lost = lost
        return changed
