"""The sensor topics both drivers read, handled once: pose, localisation, battery, laser, map,
particle cloud, tf.

The ROS1 and ROS 2 links differ in how they drive a robot (move_base's topics, Nav2's action)
but not in what its sensors say: ``/amcl_pose`` is a PoseWithCovarianceStamped in both, the
battery a BatteryState, the laser a LaserScan. So each link hands every published message to
one :class:`SensorReports`, which keeps the last pose and battery, tells the listener, and
says which liveness proof the message was (a pose, a battery, a scan) for the link's tracker.
A link handles only its own stack's topics (move_base's status and results).

A robot whose links' options name a base frame (``tf=base_link``) takes its pose from tf, not
``/amcl_pose``: the map frame's transform to that frame, composed from ``/tf`` and
``/tf_static`` (:class:`~serveur.robots.sensing.TfTree`) and reported at most
:data:`TF_POSE_PERIOD` apart (odometry's tf comes at 20-50 Hz). Such a robot says nothing of
how sure it is (tf carries no covariance).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any, Final

from serveur.clock import Clock
from serveur.robots import rosbridge as rb
from serveur.robots.driver import LinkListener
from serveur.robots.names import RosNames
from serveur.robots.sensing import TfTree, cloud_of, pose_spread

__all__ = ["TF_POSE_PERIOD", "WATCHED_STREAMS", "SensorReports", "Streams"]

#: Clock seconds between two poses reported from tf: /amcl_pose's 10 Hz at most.
TF_POSE_PERIOD: Final = 0.1


class SensorReports:
    """One robot's sensor topics: the last pose and battery, and the listener told of each."""

    def __init__(self, name: str, listener: LinkListener, names: RosNames, clock: Clock) -> None:
        self.name = name
        self._listener = listener
        self._names = names
        self._clock = clock
        self.pose: tuple[float, float, float] | None = None
        self.battery: float | None = None
        self._tf = TfTree() if names.tf_base else None
        self._tf_reported = -1e9
        self._on: dict[str, Callable[[Mapping[str, Any]], str | None]] = {
            "/amcl_pose": self._amcl_pose,
            "/battery_state": self._battery,
            "/scan": self._scan,
            "/map": self._map,
            "/particlecloud": self._cloud,
            "/tf": self._tf_msg,
            "/tf_static": self._tf_msg,
        }

    def handles(self, topic: str) -> bool:
        """Is ``topic`` (a default name, ``/amcl_pose``...) one of the sensors'?"""
        return topic in self._on

    def on_publish(self, topic: str, msg: Mapping[str, Any]) -> str | None:
        """Take one message of a sensor topic (by its default name); the liveness proof it is
        ("pose", "battery", "scan") or None. Raises for a malformed message."""
        return self._on[topic](msg)

    def pose_topics(self) -> tuple[str, ...]:
        """The default names of the topics the pose comes from (subscribe to each)."""
        return ("/tf", "/tf_static") if self._tf is not None else ("/amcl_pose",)

    # -- each topic ---------------------------------------------------------------------------

    def _amcl_pose(self, msg: Mapping[str, Any]) -> str | None:
        if self._tf is not None:
            return None  # the pose comes from tf on this robot
        x, y, yaw, stamp = rb.amcl_pose_from_msg(msg)
        self.pose = (x, y, yaw)
        self._listener.pose(self.name, x, y, yaw, stamp)
        spread = pose_spread(msg)
        if spread is not None:
            self._listener.localisation(self.name, *spread)
        return "pose"

    def _battery(self, msg: Mapping[str, Any]) -> str | None:
        fraction = rb.battery_fraction(msg)
        if fraction is not None:
            self.battery = fraction
            self._listener.battery(self.name, fraction)
        return "battery"

    def _scan(self, msg: Mapping[str, Any]) -> str | None:
        self._listener.scan(self.name, msg)
        return "scan"

    def _map(self, msg: Mapping[str, Any]) -> str | None:
        self._listener.map(self.name, msg)
        return None

    def _cloud(self, msg: Mapping[str, Any]) -> str | None:
        self._listener.cloud(self.name, cloud_of(msg))
        return None

    def _tf_msg(self, msg: Mapping[str, Any]) -> str | None:
        tree = self._tf
        if tree is None:
            return None
        tree.update(msg)
        now = self._clock.now()
        if now - self._tf_reported < TF_POSE_PERIOD:
            return None
        found = tree.lookup(self._names.frame, self._names.tf_base)
        if found is None:
            return None
        self._tf_reported = now
        x, y, yaw, stamp = found
        self.pose = (x, y, yaw)
        self._listener.pose(self.name, x, y, yaw, stamp)
        return "pose"


#: Topics streamed only while someone looks at them, and their rosbridge throttles (ms): the
#: laser at 5 Hz (a phone redraws no faster), the particle cloud at 2 Hz (AMCL publishes it
#: with every filter update; 2000 particles are ~250 kB of JSON).
WATCHED_STREAMS: Final[dict[str, int]] = {"/scan": 200, "/particlecloud": 500}


class Streams:
    """Which watched-only topics (:data:`WATCHED_STREAMS`) are wanted on one robot's link,
    and the rosbridge ops that follow a change: both links keep these the same way."""

    def __init__(
        self,
        subscribe: Callable[[str, int], dict[str, Any]],
        unsubscribe: Callable[[str], dict[str, Any]],
    ) -> None:
        self._subscribe = subscribe
        self._unsubscribe = unsubscribe
        self.wanted: set[str] = set()

    def want(self, topic: str, on: bool) -> dict[str, Any] | None:
        """Someone looks at ``topic`` now, or nobody does; the op to send, None if no change."""
        if on == (topic in self.wanted):
            return None
        if on:
            self.wanted.add(topic)
            return self._subscribe(topic, WATCHED_STREAMS[topic])
        self.wanted.discard(topic)
        return self._unsubscribe(topic)

    def resubscribe(self) -> list[dict[str, Any]]:
        """A new connection: the subscriptions of the topics wanted."""
        return [self._subscribe(t, WATCHED_STREAMS[t]) for t in sorted(self.wanted)]
