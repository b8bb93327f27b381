"""Pure tests of the shared rosbridge v2 pieces: encoding rules, message shapes, conversions."""

from __future__ import annotations

import json
import math
import struct

import cbor2
import numpy as np
import pytest

from serveur.errors import RosbridgeError
from serveur.maps.navigation import OccupancyMap
from serveur.robots import rosbridge as rb

# -- encode / decode ------------------------------------------------------------------------


def test_encode_is_compact_json() -> None:
    text = rb.encode({"op": "publish", "topic": "/x", "msg": {"a": [1, 2]}})
    assert text == '{"op":"publish","topic":"/x","msg":{"a":[1,2]}}'


def test_encode_nan_and_inf_become_null_at_any_depth() -> None:
    op = {
        "a": math.nan,
        "b": [1.0, math.inf, -math.inf],
        "c": {"d": [{"e": math.nan}]},
        "big": [0.5] * 100 + [math.nan],
        "t": (math.inf, 2.0),
    }
    out = json.loads(rb.encode(op))
    assert out["a"] is None
    assert out["b"] == [1.0, None, None]
    assert out["c"] == {"d": [{"e": None}]}
    assert out["big"][-1] is None and out["big"][:100] == [0.5] * 100
    assert out["t"] == [None, 2.0]
    assert "NaN" not in rb.encode(op) and "Infinity" not in rb.encode(op)


def test_encode_keeps_nan_strings_intact() -> None:
    # The NaN rewrite works on values, never on text inside strings.
    assert json.loads(rb.encode({"s": "NaN Infinity", "x": math.nan})) == {
        "s": "NaN Infinity",
        "x": None,
    }


def test_encode_numpy_arrays_by_ros_type() -> None:
    out = json.loads(
        rb.encode(
            {
                "u8": np.array([0, 1, 2, 255], dtype=np.uint8),
                "i8": np.array([-1, 0, 100], dtype=np.int8),
                "f32": np.array([1.5, np.inf, np.nan], dtype=np.float32),
                "scalar": np.float32(2.5),
                "bytes": b"\x00\x01\x02\xff",
            }
        )
    )
    assert out["u8"] == "AAEC/w=="  # uint8[] travels as base64, as rosbridge sends it
    assert out["i8"] == [-1, 0, 100]  # int8[] (OccupancyGrid.data) stays a list
    assert out["f32"] == [1.5, None, None]
    assert out["scalar"] == 2.5
    assert out["bytes"] == "AAEC/w=="


def test_decode_accepts_text_and_bytes() -> None:
    assert rb.decode('{"op":"x","id":1}') == {"op": "x", "id": 1}
    assert rb.decode(b'{"op":"x"}') == {"op": "x"}


@pytest.mark.parametrize(
    "frame",
    [
        "",
        "{not json",
        "[1, 2]",
        '"op"',
        "null",
        '{"id": "a"}',
        '{"op": 3}',
        '{"op": null}',
        b"\xff\xfe",
        "[" * 100_000 + "]" * 100_000,  # deep nesting: RecursionError inside json
    ],
)
def test_decode_rejects_what_is_not_an_op(frame: str | bytes) -> None:
    with pytest.raises(RosbridgeError):
        rb.decode(frame)


def test_decode_error_carries_the_id_when_there_is_one() -> None:
    with pytest.raises(RosbridgeError) as info:
        rb.decode('{"id": "req-7", "topic": "/x"}')
    assert info.value.details == {"id": "req-7"}
    assert info.value.code == "rosbridge_error"


# -- cbor -------------------------------------------------------------------------------------


def _typed(tag: cbor2.CBORTag) -> tuple[int, list[float] | list[int]]:
    fmt = {85: "f", 86: "d", 72: "b", 77: "h", 78: "i", 79: "q", 69: "H", 70: "I", 71: "Q"}[tag.tag]
    size = struct.calcsize(fmt)
    return tag.tag, list(struct.unpack(f"<{len(tag.value) // size}{fmt}", tag.value))


def test_cbor_typed_arrays_decode_back() -> None:
    op = rb.op_publish(
        "/scan",
        {
            "ranges": np.array([1.25, 2.5, np.inf], dtype=np.float32),
            "grid": np.array([-1, 0, 100], dtype=np.int8),
            "raw": np.array([0, 7, 255], dtype=np.uint8),
            "cov": [0.5, 0.0, 2.0],
            "i32": np.array([-5, 70000], dtype=np.int32),
            "nested": {"x": 1.5, "s": "text", "empty": []},
        },
    )
    decoded = cbor2.loads(rb.encode_cbor(op))
    msg = decoded["msg"]
    assert decoded["op"] == "publish" and decoded["topic"] == "/scan"
    tag, ranges = _typed(msg["ranges"])
    assert tag == 85 and ranges[:2] == [1.25, 2.5] and math.isinf(ranges[2])
    assert _typed(msg["grid"]) == (72, [-1, 0, 100])
    assert msg["raw"] == b"\x00\x07\xff"
    assert _typed(msg["cov"]) == (86, [0.5, 0.0, 2.0])
    assert _typed(msg["i32"]) == (78, [-5, 70000])
    assert msg["nested"] == {"x": 1.5, "s": "text", "empty": []}


def test_cbor_of_a_real_occupancy_grid_has_width_times_height_cells() -> None:
    m = OccupancyMap(np.array([[0, -1, 100], [0, 0, 50]], dtype=np.int8), 0.1, (1.0, 2.0, 0.0))
    grid = rb.occupancy_grid(m, stamp=10.0, seq=3)
    decoded = cbor2.loads(rb.encode_cbor(rb.op_publish("/map", grid)))["msg"]
    assert _typed(decoded["data"]) == (72, [0, -1, 100, 0, 0, 50])
    assert decoded["info"]["width"] == 3 and decoded["info"]["height"] == 2
    as_json = json.loads(rb.encode(grid))
    assert as_json["data"] == [0, -1, 100, 0, 0, 50]
    assert as_json["info"]["origin"]["position"] == {"x": 1.0, "y": 2.0, "z": 0.0}
    assert as_json["info"]["resolution"] == pytest.approx(0.1)


# -- time, quaternions, poses -------------------------------------------------------------


@pytest.mark.parametrize("t", [0.0, 1.5, 1_700_000_000.123456789, 2.9999999999, 42.000000001])
def test_ros_time_round_trip(t: float) -> None:
    d = rb.ros_time(t)
    assert set(d) == {"secs", "nsecs"}
    assert 0 <= d["nsecs"] < 1_000_000_000
    assert rb.from_ros_time(d) == pytest.approx(t, abs=1e-6)


def test_ros_time_never_rounds_to_a_full_second_of_nanoseconds() -> None:
    assert rb.ros_time(1.9999999999) == {"secs": 2, "nsecs": 0}


def test_from_ros_time_reads_ros2_spelling_and_rejects_strings() -> None:
    assert rb.from_ros_time({"sec": 3, "nanosec": 500_000_000}) == pytest.approx(3.5)
    with pytest.raises(RosbridgeError):
        rb.from_ros_time({"secs": "three", "nsecs": 0})


@pytest.mark.parametrize("yaw", [0.0, 0.3, -1.2, math.pi / 2, 3.1, -3.1])
def test_quaternion_round_trip(yaw: float) -> None:
    q = rb.quaternion_from_yaw(yaw)
    assert math.hypot(q["x"], q["y"], q["z"], q["w"]) == pytest.approx(1.0)
    assert rb.yaw_from_quaternion(q) == pytest.approx(yaw)


def test_pose_round_trip_and_shapes() -> None:
    msg = rb.pose_msg(1.5, -2.0, 0.7)
    assert set(msg) == {"position", "orientation"}
    assert rb.pose_from_msg(msg) == pytest.approx((1.5, -2.0, 0.7))
    with pytest.raises(RosbridgeError):
        rb.pose_from_msg({"position": {"x": "1"}})
    with pytest.raises(RosbridgeError):
        rb.pose_from_msg({"position": [1, 2]})
    with pytest.raises(RosbridgeError):
        rb.pose_from_msg("pose")  # type: ignore[arg-type]
    # Missing fields take ROS defaults, as rosbridge fills them in.
    assert rb.pose_from_msg({"position": {"x": 1}}) == (1.0, 0.0, 0.0)


def test_pose_with_covariance_stamped_shape() -> None:
    msg = rb.pose_with_covariance_stamped(1.0, 2.0, 0.5, stamp=100.25, seq=4)
    assert msg["header"] == {
        "seq": 4,
        "stamp": {"secs": 100, "nsecs": 250_000_000},
        "frame_id": "map",
    }
    assert len(msg["pose"]["covariance"]) == 36
    assert rb.pose_from_msg(msg["pose"]["pose"]) == pytest.approx((1.0, 2.0, 0.5))


def test_twist_round_trip_and_wrong_shapes() -> None:
    assert rb.twist_from_msg(rb.twist(0.3, -0.1, 0.5)) == (0.3, -0.1, 0.5)
    for bad in (
        {"linear": {"x": "fast"}},
        {"linear": 3},
        {"angular": {"z": [1]}},
        {"linear": {"x": True}},
    ):
        with pytest.raises(RosbridgeError):
            rb.twist_from_msg(bad)
    x, _, _ = rb.twist_from_msg({"linear": {"x": None}})
    assert math.isnan(x)  # null is how NaN travels; the receiver decides what to do with it


# -- actionlib and sensors ------------------------------------------------------------------


def test_move_base_action_goal_shape() -> None:
    g = rb.move_base_action_goal("g-1", 2.0, 3.0, 1.0, stamp=5.5)
    assert g["goal_id"] == {"stamp": {"secs": 5, "nsecs": 500_000_000}, "id": "g-1"}
    target = g["goal"]["target_pose"]
    assert target["header"]["frame_id"] == "map"
    assert rb.pose_from_msg(target["pose"]) == pytest.approx((2.0, 3.0, 1.0))
    assert rb.goal_id_from_msg(g["goal_id"]) == ("g-1", 5.5)
    assert rb.goal_id_from_msg({}) == ("", 0.0)  # roslibpy's cancel-all


def test_goal_status_array_result_and_feedback_shapes() -> None:
    arr = rb.goal_status_array(
        [("a", rb.GoalStatus.ACTIVE, ""), ("b", rb.GoalStatus.ABORTED, "blocked", 7.0)],
        stamp=1.0,
        seq=2,
    )
    assert [s["status"] for s in arr["status_list"]] == [1, 4]
    assert arr["status_list"][1] == {
        "goal_id": {"stamp": {"secs": 7, "nsecs": 0}, "id": "b"},
        "status": 4,
        "text": "blocked",
    }
    res = rb.move_base_result("a", rb.GoalStatus.SUCCEEDED, "done", stamp=2.0, seq=0)
    assert res["status"]["status"] == 3 and res["result"] == {}
    fb = rb.move_base_feedback("a", rb.GoalStatus.ACTIVE, 1.0, 2.0, 0.0, stamp=2.0, seq=1)
    assert rb.pose_from_msg(fb["feedback"]["base_position"]["pose"]) == pytest.approx((1, 2, 0))
    assert {rb.GoalStatus.SUCCEEDED, rb.GoalStatus.ABORTED} <= rb.TERMINAL_STATUSES
    assert rb.GoalStatus.ACTIVE not in rb.TERMINAL_STATUSES


def test_sensor_message_fields() -> None:
    odom = rb.odometry(1.0, 2.0, 0.0, 0.1, 0.0, 0.2, stamp=3.0, seq=1)
    assert set(odom) == {"header", "child_frame_id", "pose", "twist"}
    assert odom["twist"]["twist"]["angular"]["z"] == 0.2
    scan = rb.laser_scan(
        [1.0, 2.0, math.inf],
        stamp=1.0,
        seq=0,
        angle_min=-1.0,
        angle_increment=0.5,
        range_min=0.1,
        range_max=8.0,
        scan_time=0.2,
    )
    assert scan["angle_max"] == pytest.approx(0.0)
    assert json.loads(rb.encode(scan))["ranges"] == [1.0, 2.0, None]
    bat = rb.battery_state(
        0.5, stamp=1.0, seq=0, voltage=24.0, current=-1.0, status=rb.BatteryStatus.DISCHARGING
    )
    assert 0.0 <= bat["percentage"] <= 1.0 and bat["power_supply_status"] == 2
    assert {"cell_voltage", "present", "location", "serial_number"} <= set(bat)


def test_topic_types_cover_the_robot_graph() -> None:
    assert rb.TOPIC_TYPES["/move_base/goal"] == "move_base_msgs/MoveBaseActionGoal"
    assert rb.TOPIC_TYPES["/map"] == "nav_msgs/OccupancyGrid"
    assert rb.normalize_type("geometry_msgs/msg/Twist") == "geometry_msgs/Twist"


def test_op_builders() -> None:
    assert rb.op_subscribe("/scan", compression="cbor", id="s1", throttle_rate=100) == {
        "op": "subscribe",
        "topic": "/scan",
        "throttle_rate": 100,
        "queue_length": 0,
        "compression": "cbor",
        "id": "s1",
    }
    assert rb.op_service_response("/s", "c1", "boom", result=False)["result"] is False
    assert "id" not in rb.op_status("error", "x")
    assert rb.op_call_service("/rosapi/topics", id=3) == {
        "op": "call_service",
        "service": "/rosapi/topics",
        "id": 3,
    }
