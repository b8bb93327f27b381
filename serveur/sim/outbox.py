"""A simulated robot's topics as its clients see them: subscriptions, sequence numbers, frames.

Split from :mod:`serveur.sim.sensors` (what the robot publishes, at which rates) so the
navigator (:mod:`serveur.sim.navigator`: move_base's status and results) and the inbox
(:mod:`serveur.sim.inbox`: a client's publish relayed to the topic's subscribers) publish
through the same plumbing without knowing the sensors. A client's subscriptions are kept per
topic; a frame is built only when a subscriber takes it now; a latched topic (``/map``, AMCL's
``/amcl_pose`` in "real" mode) offers its last frame to a new subscriber.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.state import RobotState
from serveur.sim.topics import Frame, Sub

__all__ = ["Outbox"]


class Outbox:
    """One robot's subscriptions and the frames it hands them (see the module's docstring)."""

    def __init__(self, state: RobotState, map_frame: Frame | None = None) -> None:
        self.state = state
        self.subs: dict[str, list[Sub]] = {}
        self._seqs: dict[str, int] = {}
        #: The last frame of each latched topic (the map's from the start).
        self._latched: dict[str, Frame] = {} if map_frame is None else {"/map": map_frame}

    def add(self, sub: Sub) -> None:
        self.subs.setdefault(sub.topic, []).append(sub)

    def remove(self, sub: Sub) -> None:
        subs = self.subs.get(sub.topic)
        if subs and sub in subs:
            subs.remove(sub)
            if not subs:
                del self.subs[sub.topic]

    def next_seq(self, topic: str) -> int:
        s = self._seqs.get(topic, 0)
        self._seqs[topic] = s + 1
        return s

    def frame(self, topic: str, msg: dict[str, Any]) -> Frame:
        """A message of the robot's on ``topic`` as the wire carries it (ROS 2 shapes on a
        ROS 2 robot)."""
        st = self.state
        return Frame(rb.op_publish(st.wire(topic), ros2.to_ros2(msg) if st.ros == 2 else msg))

    def publish(
        self,
        topic: str,
        build: Callable[[int, float], dict[str, Any]],
        stamp: float | None = None,
    ) -> None:
        """Build (only if a subscriber takes it now) and hand one frame to every subscriber.

        ``stamp`` defaults to now; ticks pass their own sim time.
        """
        subs = self.subs.get(topic)
        if not subs:
            return
        t = self.state.t
        wanting = [s for s in subs if s.wants(t)]
        if not wanting:
            return
        if stamp is None:
            stamp = self.state.epoch()
        frame = self.frame(topic, build(self.next_seq(topic), stamp))
        for s in wanting:
            s.push(frame, t)

    def publish_latched(self, topic: str, frame: Frame) -> None:
        """Keep ``frame`` as the latched topic's last and hand it to every subscriber."""
        self._latched[topic] = frame
        t = self.state.t
        for s in self.subs.get(topic, ()):
            if s.wants(t):
                s.push(frame, t)

    def relay(self, topic: str, msg: Mapping[str, Any]) -> None:
        """A client's publish on a robot topic also reaches that topic's subscribers (ROS does)."""
        if topic in self.subs:
            frame = Frame(rb.op_publish(self.state.wire(topic), msg))
            t = self.state.clock.now()
            for s in list(self.subs[topic]):
                if s.wants(t):
                    s.push(frame, t)

    def offer_latched(self, sub: Sub) -> None:
        """A new subscriber to a latched topic gets its last message at once (not from a
        dead node)."""
        if not self.state.relaying:
            return
        frame = self._latched.get(sub.topic)
        if frame is not None:
            sub.push(frame, self.state.t)
