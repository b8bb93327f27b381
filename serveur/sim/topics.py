"""Published frames and subscriptions: what a simulated robot's graph hands its rosbridge clients.

Split from :mod:`serveur.sim.bridge` (the rosbridge server) and :mod:`serveur.sim.robot` (the
ROS graph) because both sides use these: the robot publishes a :class:`Frame` to every
:class:`Sub` of a topic, and the bridge's client task drains the subscriptions' queues. With
them here, the robot needs nothing of the bridge and the two modules import no circle.
"""

from __future__ import annotations

import asyncio
import itertools
import logging
import math
from collections import deque
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Final, Protocol

from serveur.robots import rosbridge as rb

__all__ = [
    "DEFAULT_QUEUE",
    "ActionSink",
    "Frame",
    "Sub",
    "SubParams",
    "Subscriber",
    "consume_exception",
    "next_order",
]

log = logging.getLogger("serveur.robot_sim")

DEFAULT_QUEUE: Final = 10  # per-topic buffer of a subscription without queue_length
_seq = itertools.count()  # global order of queued frames, so a client gets them in publish order


def next_order() -> int:
    """The next number of the one order every queued frame (published or a reply) is sent in."""
    return next(_seq)


class Subscriber(Protocol):
    """What a subscription needs of its client: an event to wake the client's sender task."""

    wake: asyncio.Event


class ActionSink(Protocol):
    """A ROS 2 action goal as the robot sees it: where its feedback and its result go.

    The bridge's goal object (:class:`serveur.sim.bridge.ActionGoal`) is one: it sends
    ``action_feedback`` and ``action_result`` ops to the connection that sent the goal.
    """

    feedback: bool

    def send_feedback(self, values: Mapping[str, Any]) -> None: ...

    def end(self, status: int, values: Mapping[str, Any], *, send: bool = True) -> None: ...


def consume_exception(fut: asyncio.Future[Any]) -> None:
    """Mark a dropped future's exception as seen (a plan for a goal that was since cancelled)."""
    if not fut.cancelled():
        fut.exception()


class Frame:
    """One published op, encoded at most once per format whatever the number of subscribers."""

    __slots__ = ("_cbor", "_text", "op")

    def __init__(self, op: Mapping[str, Any]) -> None:
        self.op = op
        self._text: bytes | None = None
        self._cbor: bytes | None = None

    def text(self) -> bytes:
        if self._text is None:
            self._text = rb.encode(self.op).encode()
        return self._text

    def cbor(self) -> bytes:
        if self._cbor is None:
            self._cbor = rb.encode_cbor(self.op)
        return self._cbor


@dataclass(slots=True)
class SubParams:
    throttle: float  # s sim
    queue_length: int
    cbor: bool


class Sub:
    """A client's subscription to one topic (all its subscribe ids merged, as rosbridge does)."""

    __slots__ = (
        "cbor",
        "client",
        "fixed_arrays",
        "last_offer",
        "last_sent",
        "logged",
        "params",
        "qlen",
        "queue",
        "throttle",
        "topic",
    )

    def __init__(self, client: Subscriber, topic: str, *, ros: int = 1) -> None:
        self.client = client
        self.topic = topic
        #: The topic's type holds a fixed-size array, which rosbridge 0.11 cannot CBOR-encode
        #: (a ROS1 robot's quirk only).
        self.fixed_arrays = ros == 1 and rb.TOPIC_TYPES.get(topic) in rb.FIXED_ARRAY_TYPES
        self.logged = False
        self.params: dict[str | int | None, SubParams] = {}
        self.throttle = 0.0
        self.qlen = 0
        self.cbor = False
        self.queue: deque[tuple[int, Frame]] = deque(maxlen=DEFAULT_QUEUE)
        self.last_offer = -math.inf
        self.last_sent = -math.inf

    def recompute(self) -> None:
        """Lowest throttle_rate, highest queue_length, compression of the latest subscribe."""
        ps = list(self.params.values())
        self.throttle = min(p.throttle for p in ps)
        self.qlen = max(p.queue_length for p in ps)
        self.cbor = ps[-1].cbor
        maxlen = self.qlen if self.qlen > 0 else DEFAULT_QUEUE
        if self.queue.maxlen != maxlen:
            self.queue = deque(self.queue, maxlen=maxlen)

    def wants(self, t: float) -> bool:
        """Whether a message published at sim time ``t`` is not throttled away at once.

        Without a queue, rosbridge's throttle drops what comes too soon after the last message;
        with a queue, messages wait in it (newest kept) and leave one per throttle period.
        """
        return self.throttle <= 0.0 or self.qlen > 0 or t - self.last_offer >= self.throttle - 1e-6

    def push(self, frame: Frame, t: float) -> None:
        """Queue ``frame`` for the client (the oldest is dropped from a full queue).

        A ``cbor`` subscription to a type with a fixed-size array gets nothing: rosbridge 0.11's
        CBOR encoder raises on ``float64[36]`` covariances, logs the exception and sends no
        frame (shared/notes/rosbridge.md). The real server logs every message; we log once per
        subscription.
        """
        if self.cbor and self.fixed_arrays:
            if not self.logged:
                self.logged = True
                log.error(
                    "%s: cannot CBOR-encode a message with a fixed-size array; nothing sent "
                    "(as rosbridge 0.11)",
                    self.topic,
                )
            return
        self.last_offer = t
        self.queue.append((next_order(), frame))  # a full deque drops its oldest entry
        self.client.wake.set()
