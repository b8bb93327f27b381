"""What a robot's localisation says beyond its pose, read from its messages (pure):
how spread AMCL's estimate is, its particle cloud, the pose composed along tf."""

from __future__ import annotations

import math

import pytest

from serveur.robots import rosbridge as rb
from serveur.robots.sensing import TfTree, cloud_of, pose_spread, spread_of
from serveur.sim import ros2


def _cov(xx: float, yy: float, aa: float, xy: float = 0.0) -> list[float]:
    c = [0.0] * 36
    c[0], c[7], c[35] = xx, yy, aa
    c[1] = c[6] = xy
    return c


def test_amcls_initial_covariance_is_half_a_metre_and_a_quarter_radian() -> None:
    # AMCL's default initial covariance (what /initialpose carries): 0.25 m², 0.068 rad².
    msg = rb.pose_with_covariance_stamped(1.0, 2.0, 0.0, stamp=0.0)
    metres, radians = pose_spread(msg) or (0.0, 0.0)
    assert metres == pytest.approx(0.5) and radians == pytest.approx(0.2618, abs=1e-3)


def test_the_spread_is_along_the_worst_direction() -> None:
    # A long thin ellipse at 45 degrees: variances 4 and 0 along its axes -> 2 m, not 1.4.
    assert spread_of(_cov(2.0, 2.0, 0.01, xy=2.0))[0] == pytest.approx(2.0)
    assert spread_of(_cov(1.0, 0.04, 0.01))[0] == pytest.approx(1.0)


def test_a_covariance_that_cannot_be_one_is_infinitely_spread() -> None:
    assert spread_of(_cov(math.nan, 0.1, 0.1)) == (math.inf, math.inf)
    assert spread_of(_cov(-1.0, 0.1, 0.1)) == (math.inf, math.inf)


def test_a_pose_without_a_covariance_says_nothing_of_its_spread() -> None:
    msg = rb.pose_with_covariance_stamped(1.0, 2.0, 0.0, stamp=0.0)
    msg["pose"]["covariance"] = []
    assert pose_spread(msg) is None
    assert rb.amcl_pose_from_msg(msg)[:2] == (1.0, 2.0)  # the pose itself still reads


def test_a_ros1_pose_array_and_a_nav2_particle_cloud_read_alike() -> None:
    poses = [rb.pose_msg(x, 0.0, 0.0) for x in (-1.0, 1.0)]
    ros1 = cloud_of({"header": rb.header(1, 5.0, "map"), "poses": poses})
    nav2 = cloud_of(
        ros2.to_ros2(
            {
                "header": rb.header(1, 5.0, "map"),
                "particles": [{"pose": p, "weight": 0.5} for p in poses],
            }
        )
    )
    for cloud in (ros1, nav2):
        assert len(cloud) == 2 and cloud.stamp == pytest.approx(5.0)
        assert cloud.spread() == pytest.approx(1.0)


def test_weights_pull_the_spread_and_the_order_shown() -> None:
    poses = [rb.pose_msg(x, 0.0, 0.0) for x in (0.0, 10.0)]
    msg = {"particles": [{"pose": poses[0], "weight": 0.99}, {"pose": poses[1], "weight": 0.01}]}
    cloud = cloud_of(msg)
    assert cloud.spread() == pytest.approx(math.sqrt(0.99 * 0.01) * 10.0)
    assert cloud.shown(1) == [[0.0, 0.0, 0.0]]  # the most likely first


def test_a_cloud_that_is_not_one_is_refused() -> None:
    from serveur.errors import RosbridgeError

    with pytest.raises(RosbridgeError):
        cloud_of({"header": {}})
    with pytest.raises(RosbridgeError):
        cloud_of({"poses": [5]})


def _tf(parent: str, child: str, x: float, y: float, yaw: float, stamp: float = 1.0) -> dict:
    return {"transforms": [rb.transform_stamped(parent, child, x, y, yaw, stamp=stamp)]}


def test_the_pose_composes_map_odom_and_odometry() -> None:
    tree = TfTree()
    assert tree.update(_tf("odom", "base_link", 1.0, 0.0, 0.0, stamp=2.0)) == {"base_link"}
    assert tree.lookup("map", "base_link") is None  # map -> odom not yet known
    tree.update(_tf("map", "odom", 2.0, 3.0, math.pi / 2, stamp=1.5))
    x, y, yaw, stamp = tree.lookup("map", "base_link") or (0, 0, 0, 0)
    # One metre ahead in odom is one metre along map's y once odom is turned 90 degrees.
    assert (x, y, yaw) == pytest.approx((2.0, 4.0, math.pi / 2))
    assert stamp == pytest.approx(2.0)


def test_ros1_frames_with_a_leading_slash_are_the_same_frames() -> None:
    tree = TfTree()
    tree.update(_tf("/map", "/odom", 1.0, 0.0, 0.0))
    tree.update(_tf("odom", "base_footprint", 0.0, 1.0, 0.0))
    assert tree.lookup("map", "base_footprint")[:2] == pytest.approx((1.0, 1.0))  # type: ignore[index]


def test_a_loop_in_a_broken_tree_is_no_pose() -> None:
    tree = TfTree()
    tree.update(_tf("a", "b", 1.0, 0.0, 0.0))
    tree.update(_tf("b", "a", 1.0, 0.0, 0.0))
    assert tree.lookup("map", "a") is None


def test_ros2_tf_stamps_read_too() -> None:
    tree = TfTree()
    tree.update(ros2.to_ros2(_tf("map", "base_link", 1.0, 2.0, 0.5, stamp=7.25)))
    found = tree.lookup("map", "base_link")
    assert found is not None and found[3] == pytest.approx(7.25)
