"""Is a robot sure where it is (serveur.core.localisation, pure): the thresholds, the
hysteresis between them, the particle cloud's spread counting while it streams."""

from __future__ import annotations

import math

from serveur.core.localisation import Limits, Localisation
from serveur.scheduler import Candidate, choose_robot


def test_a_converged_robot_is_sure_and_a_spread_one_lost() -> None:
    loc = Localisation()
    assert not loc.pose(0.02, 0.01) and not loc.lost
    assert loc.pose(1.5, 0.1) and loc.lost  # changed: lost
    assert not loc.pose(2.0, 0.1) and loc.lost  # still lost: no change to report


def test_the_heading_alone_can_lose_it() -> None:
    loc = Localisation()
    assert loc.pose(0.1, Limits().lost_rad + 0.1) and loc.lost


def test_between_the_thresholds_it_keeps_what_it_was() -> None:
    lim = Limits()
    between = (lim.sure_m + lim.lost_m) / 2
    sure, lost = Localisation(), Localisation()
    lost.pose(3.0, 1.0)
    for loc in (sure, lost):
        loc.pose(between, 0.1)
    assert not sure.lost and lost.lost  # no flapping around one number


def test_an_initial_pose_from_the_map_makes_it_sure_again() -> None:
    loc = Localisation()
    loc.pose(3.0, 1.5)
    # AMCL answers an initial pose with its initial covariance: 0.5 m, 0.26 rad.
    assert loc.pose(0.5, 0.26) and not loc.lost


def test_a_nan_spread_is_lost() -> None:
    loc = Localisation()
    assert loc.pose(math.nan, 0.0) and loc.lost


def test_the_cloud_counts_while_it_streams() -> None:
    loc = Localisation()
    loc.pose(0.05, 0.02)
    assert loc.cloud(2.0) and loc.lost  # the particles disagree with the covariance
    assert loc.spread == 2.0
    assert loc.cloud(None) and not loc.lost  # the cloud stopped: the pose's spread judges


def test_a_lost_robot_gets_no_trip() -> None:
    free = [Candidate("r1", 0.0, 1.0, lost=True), Candidate("r2", 5.0, 1.0)]
    assert choose_robot(free) == "r2"  # r1 waited longer but would serve the wrong table
    assert choose_robot(free[:1]) is None
