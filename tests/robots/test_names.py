"""A robot's ROS names: namespaces, renamed topics, the map frame; kept with the robot."""

from __future__ import annotations

from pathlib import Path

import pytest
from websockets.asyncio.client import connect

from serveur.app import parse_robot_spec
from serveur.robots.names import OPTION_KEYS, RosNames
from serveur.store.factory import open_store
from tests.conftest import Client, Restaurant


def test_defaults_are_the_bare_names() -> None:
    n = RosNames.from_options({})
    assert n.topic("/move_base/goal") == "/move_base/goal"
    assert n.topic("/amcl_pose") == "/amcl_pose"
    assert n.frame == "map"
    assert n == RosNames()


def test_a_namespace_prefixes_every_default_and_single_names_override() -> None:
    n = RosNames.from_options({"ns": "r1", "battery": "/battery", "pose": "localization_pose"})
    assert n.topic("/move_base/goal") == "/r1/move_base/goal"
    assert n.topic("/move_base/status") == "/r1/move_base/status"
    assert n.topic("/cmd_vel") == "/r1/cmd_vel"
    assert n.topic("/battery_state") == "/battery"  # absolute: as given
    assert n.topic("/amcl_pose") == "/r1/localization_pose"  # relative: under ns
    assert n.default_of("/r1/localization_pose") == "/amcl_pose"
    assert n.default_of("/r1/move_base/result") == "/move_base/result"
    assert n.default_of("/somebody_else") is None


def test_the_action_and_the_frame_can_be_renamed() -> None:
    n = RosNames.from_options({"move_base": "/nav/move_base", "frame": "world"})
    assert n.topic("/move_base/cancel") == "/nav/move_base/cancel"
    assert n.frame == "world"


@pytest.mark.parametrize(
    "options",
    [{"nss": "/r1"}, {"ns": "r 1"}, {"cmd_vel": "9cmd"}, {"frame": "/map frame"}, {"pose": ""}],
)
def test_bad_options_are_refused_with_the_option_named(options: dict[str, str]) -> None:
    with pytest.raises(ValueError, match=next(iter(options))):
        RosNames.from_options(options)


def test_robot_spec_takes_link_options() -> None:
    spec = parse_robot_spec("r1=ws://10.0.0.21:9090,home=home1,ns=/r1,frame=world")
    assert (spec.home, dict(spec.link)) == ("home1", {"ns": "/r1", "frame": "world"})
    with pytest.raises(ValueError, match="unknown robot option"):
        parse_robot_spec("r1=ws://h:9090,namespace=/r1")
    assert parse_robot_spec("r1=ws://h:9090,trays=2").trays == 2
    with pytest.raises(ValueError, match="trays"):
        parse_robot_spec("r1=ws://h:9090,trays=0")
    with pytest.raises(ValueError, match="not a valid ROS name"):
        parse_robot_spec("r1=ws://h:9090,ns=/r 1")
    assert set(OPTION_KEYS) >= {"ns", "move_base", "cmd_vel", "pose", "frame"}


async def test_link_options_are_stored_with_the_robot_and_updated(tmp_path: Path) -> None:
    db = tmp_path / "serveur.db"
    async with open_store(str(db)) as store:
        r = await store.robots.add_robot(
            "r1", "ws://h:9090", home=None, link={"ns": "/r1"}, now=1.0
        )
        assert r.link == {"ns": "/r1"}
        again = await store.robots.add_robot(
            "r1", "ws://h:9090", home=None, link={"ns": "/r1"}, now=2.0
        )
        assert again == r  # an identical resend
    async with open_store(str(db)) as store:
        assert (await store.robots.get_robot("r1")).link == {"ns": "/r1"}
        r = await store.robots.update_robot("r1", link={"ns": "/r2", "frame": "world"})
        assert r.link == {"ns": "/r2", "frame": "world"}
        events = [e for e in await store.events.list_events() if e.kind == "robot.updated"]
        assert events[-1].data["link"] == {"ns": "/r2", "frame": "world"}


async def test_create_robot_takes_link_options_and_refuses_bad_ones(one_robot: Restaurant) -> None:
    password = one_robot.app.first_owner_password
    assert password is not None
    c = Client(await connect(one_robot.app.url))
    one_robot.clients.append(c)
    await c.ok("login", username="owner", password=password)
    await c.subscribe("robots")
    err = await c.error(
        "create",
        "invalid_field",
        type="robot",
        name="r9",
        url="ws://127.0.0.1:1",
        link={"ns": "a b"},
    )
    assert "not a valid ROS name" in err["message"]
    assert "r9" not in {r["name"] for r in c.records["robots"].values()}
    reply = await c.ok(
        "create", type="robot", name="r9", url="ws://127.0.0.1:1", link={"ns": "/r9"}
    )
    assert reply["robot"]["link"] == {"ns": "/r9"}


def test_a_ros2_robots_heartbeat_service_is_named_like_its_topics() -> None:
    # Nav2's lifecycle service by default, under the robot's namespace; renamed for a robot
    # whose navigator is another node (or a std_srvs/Trigger service).
    assert RosNames().heartbeat == "/bt_navigator/get_state"
    assert RosNames.from_options({"ros": "2", "ns": "r2"}).heartbeat == (
        "/r2/bt_navigator/get_state"
    )
    n = RosNames.from_options({"ros": "2", "heartbeat": "/robot/ready"})
    assert n.heartbeat == "/robot/ready"
    assert "heartbeat" in OPTION_KEYS


def test_the_particle_cloud_and_tf_names_follow_each_stack() -> None:
    assert RosNames.from_options({}).cloud == "/particlecloud"  # ROS1 amcl
    assert RosNames.from_options({"ros": "2"}).cloud == "/particle_cloud"  # Nav2 amcl
    ns = RosNames.from_options({"ns": "r1", "ros": "2", "tf": "base_link"})
    assert (ns.cloud, ns.tf_topic, ns.tf_base) == ("/r1/particle_cloud", "/r1/tf", "base_link")
    assert ns.default_of("/r1/particle_cloud") == "/particlecloud"
    assert RosNames.from_options({}).tf_base == ""  # the pose from /amcl_pose


def test_a_camera_url_is_an_http_url() -> None:
    url = "http://10.0.0.21:8080/stream?topic=/camera/image/compressed&type=ros_compressed"
    assert RosNames.from_options({"camera_url": url}).camera_url == url
    long = "http://a/" + "x" * 300
    for bad in ("ftp://x/y", "http://", "javascript:alert(1)", "http://a b/", long):
        with pytest.raises(ValueError, match="camera_url"):
            RosNames.from_options({"camera_url": bad})
    with pytest.raises(ValueError, match="tf"):
        RosNames.from_options({"tf": "base link"})


def test_a_ros2_robot_names_its_docking_server() -> None:
    n = RosNames.from_options({"ros": "2", "ns": "r2", "docking": "nav2"})
    assert n.docking == "nav2" and "docking" in OPTION_KEYS
    assert n.topic("/dock_robot") == "/r2/dock_robot"  # the docking server's own names
    assert n.topic("/undock_robot") == "/r2/undock_robot"
    assert RosNames.from_options({"ros": "2", "docking": "opennav"}).docking == "opennav"
    assert RosNames.from_options({"ros": "2"}).docking == ""  # none: docks are goals
    with pytest.raises(ValueError, match="docking='nav3'"):
        RosNames.from_options({"ros": "2", "docking": "nav3"})
    with pytest.raises(ValueError, match="ros=2"):
        RosNames.from_options({"docking": "nav2"})  # a ROS1 robot has no such server
