"""The rosbridge v2 server side of a simulated robot: its websocket endpoint and clients.

Split from :mod:`serveur.robot_sim` (which keeps the robot's ROS graph, the physics loop and
the command line) because what a rosbridge_server does with its clients is a subject of its
own: op parsing and errors as rosbridge_server words them, subscriptions merged per topic with
``throttle_rate``/``queue_length``, cbor for the clients that ask, advertised services, and
per-client bounded queues so a slow client only loses its own old messages and never blocks
the robot or grows memory. :class:`Endpoint` is one robot's server; :class:`Sub` is one
client's subscription to one of the robot's topics, which the robot feeds
(:class:`serveur.sim.robot.SimRobot`) with :class:`Frame` objects encoded at most
once per format.

What rosbridge_server 0.11 (ROS1) really does, and so does this server (shared/notes/rosbridge.md,
checked against a real stack, and rosbridge_library's protocol.py):

* No ``status`` op reaches a client that never sent ``set_level``: the real server only logs.
  After ``set_level`` a client gets the ``status`` ops at that level and more severe ones.
* ``fragment_size`` in any op sets the client's fragment size (protocol.py ``incoming``); every
  later text frame longer than that goes out as ``fragment`` ops whose ``total`` is a float
  (:func:`serveur.robots.rosbridge.fragment_ops`) and whose ``id`` is the op's ``id``, or 0 for
  ops without one (fragmentation.py's seed is reset per message).
* ``compression: "cbor"`` on a type with a fixed-size array (``/amcl_pose``, ``/odom``) sends
  nothing (see :meth:`serveur.sim.topics.Sub.push`).

A ROS 2 robot's server is rosbridge 2.x (shared/notes/ros2.md; ROSBRIDGE_PROTOCOL.md and
rosbridge_library's capabilities/send_action_goal.py, internal/actions.py): the same ops plus
``send_action_goal`` and ``cancel_action_goal`` (:meth:`BridgeClient._send_action_goal`), whose
goals live in one table per robot (:attr:`Endpoint.actions`) and answer their sender with
``action_feedback`` and ``action_result`` (:class:`ActionGoal`); rosapi answers in ROS 2 forms
and adds ``/rosapi/action_servers``. With the robot's ``humble_queue`` (rosbridge's
``send_action_goals_in_new_thread`` false), a goal holds its connection: the frames that arrive
meanwhile wait in :attr:`BridgeClient.backlog` and are handled, in order, once it ends. A ROS1
robot's rosbridge 0.11 knows no action op (``unknown op``).

A ROS 2 robot made with ``docking`` also serves ``dock_robot`` and ``undock_robot``
(:mod:`serveur.sim.docking`) the same way: goals of those actions, with their types
(:func:`serveur.sim.ros2.action_of`), go to its docking server, cancels to whichever server has
the goal.

A ROS 2 robot also serves Nav2's ``/bt_navigator/get_state`` (``active``), and its bridge has
the two failures measured on a real stack (shared/notes/ros2.md, "Liveness, measured on the
same stack"; the robot's hooks ``stop_bridge_ros_side`` and ``kill_node``): a bridge whose ROS
side stopped answers every call ``result: false`` and does nothing else; a bridge in front of a
dead robot node still answers rosapi, never the robot's services, and sends nothing for goals.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import math
import socket
import ssl as ssl_module
from collections import deque
from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Final, cast

import cbor2
from websockets.asyncio.server import Server, ServerConnection, serve
from websockets.exceptions import ConnectionClosed

from serveur.errors import RosbridgeError, ServeurError
from serveur.robots import rosbridge as rb
from serveur.sim import ros2
from serveur.sim.robot import ROS1_SUBSCRIBES
from serveur.sim.topics import (
    Frame,
    Sub,
    SubParams,
    consume_exception,
    next_order,
)

if TYPE_CHECKING:
    from serveur.sim.robot import SimRobot

__all__ = [
    "BACKLOG",
    "CONTROL_QUEUE",
    "MAX_CALLS",
    "MAX_FRAGMENTED",
    "MAX_FRAME",
    "MAX_QUEUE",
    "MAX_SUB_IDS",
    "ROBOT_SUBSCRIBES",
    "SEND_BUFFER",
    "ActionGoal",
    "BridgeClient",
    "Endpoint",
]

log = logging.getLogger("serveur.robot_sim")

MAX_FRAME: Final = 1 << 20  # bytes: larger incoming frames close the connection with 1009
MAX_QUEUE: Final = 100  # cap on a client's queue_length (memory bound)
CONTROL_QUEUE: Final = 256  # replies (status, service_response) kept for a client that lags
SEND_BUFFER: Final = 64 * 1024  # SO_SNDBUF of client sockets (the kernel doubles it)
MAX_FRAGMENTED: Final = 8  # messages being reassembled from fragments at once, per client
MAX_CALLS: Final = 64  # service calls in progress at once, per client
MAX_SUB_IDS: Final = 64  # subscribe ids merged into one subscription
#: Ops a connection held by a goal (the queue trap) keeps waiting; beyond, the oldest are lost.
BACKLOG: Final = 4096

#: Topics a ROS1 robot subscribes to (clients may publish here; anything else is refused).
ROBOT_SUBSCRIBES: Final = ROS1_SUBSCRIBES
_LEVELS: Final = rb.STATUS_LEVELS
#: Every op this server handles; ``fragment_size`` is only taken from these (protocol.py drops
#: an unknown op before it looks at the op's fields).
_OPS: Final = frozenset(
    {
        "publish",
        "subscribe",
        "unsubscribe",
        "advertise",
        "unadvertise",
        "call_service",
        "service_response",
        "advertise_service",
        "unadvertise_service",
        "fragment",
        "set_level",
        "send_action_goal",
        "cancel_action_goal",
    }
)
#: rosbridge 2.x's action ops: unknown to a ROS1 robot's rosbridge 0.11.
_ACTION_OPS: Final = frozenset({"send_action_goal", "cancel_action_goal"})
#: Ops a bridge whose ROS side stopped still answers (with an error): the rest do nothing.
_DEAD_SIDE_OPS: Final = frozenset({"call_service", "send_action_goal", "fragment", "set_level"})

# ---------------------------------------------------------------------------------------------
# One client connection
# ---------------------------------------------------------------------------------------------


def _op_id(msg: Mapping[str, Any]) -> str | int | None:
    v = msg.get("id")
    return v if isinstance(v, str | int) and not isinstance(v, bool) else None


def _req_str(msg: Mapping[str, Any], key: str) -> str:
    v = msg.get(key)
    if not isinstance(v, str) or not v:
        raise RosbridgeError(f"'{key}' must be a non-empty string")
    return v


def _opt_int(msg: Mapping[str, Any], key: str) -> int:
    v = msg.get(key, 0)
    if v is None:
        return 0
    if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v) or v < 0:
        raise RosbridgeError(f"'{key}' must be a non-negative number")
    return int(v)


class ActionGoal:
    """One ``send_action_goal`` of a ROS 2 robot's client, as rosbridge 2.x's handler for it.

    Its feedback and result go to the connection that sent it, even after a cancel from
    another connection; with the queue trap it holds that connection until it ends.
    """

    __slots__ = ("action", "client", "done", "feedback", "id")

    def __init__(
        self, client: BridgeClient, action: str, gid: str | int | None, feedback: bool
    ) -> None:
        self.client = client
        self.action = action
        self.id = gid
        self.feedback = feedback
        self.done = False

    def _op(self, op: str, **fields: Any) -> dict[str, Any]:
        out: dict[str, Any] = {"op": op, "action": self.action}
        if self.id is not None:
            out["id"] = self.id
        out.update(fields)
        return out

    def send_feedback(self, values: Mapping[str, Any]) -> None:
        if self.feedback and not self.done:
            self.client.reply(self._op("action_feedback", values=values))

    def end(self, status: int, values: Mapping[str, Any], *, send: bool = True) -> None:
        """The goal ended: the result (unless dropped), then the connection is free again.

        rosbridge's goal table is keyed by id and the handler deletes its id when it ends,
        whichever goal holds that id by then (send_action_goal.py): so it is done here too.
        """
        if self.done:
            return
        self.done = True
        self.client.endpoint.actions.pop(self.id, None)
        if send:
            self.client.reply(self._op("action_result", values=values, status=status, result=True))
        self.client.release(self)

    def fail(self, text: str) -> None:
        """What rosbridge sends when building or sending the goal raised: ``result`` false."""
        self.done = True
        self.client.endpoint.actions.pop(self.id, None)
        self.client.reply(self._op("action_result", values=text, status=0, result=False))


class BridgeClient:
    """One websocket client of a robot: its subscriptions, its send queues, its op handlers."""

    def __init__(self, endpoint: Endpoint, ws: ServerConnection) -> None:
        self.endpoint = endpoint
        self.robot = endpoint.robot
        self.clock = endpoint.robot.state.clock
        self.ws = ws
        self.subs: dict[str, Sub] = {}
        self.advertised: set[str] = set()
        self.control: deque[tuple[int, Frame]] = deque(maxlen=CONTROL_QUEUE)
        self.wake = asyncio.Event()
        #: Status ops sent at this level and below; "none" until the client sends set_level,
        #: as rosbridge 0.11 sends no status op at all by default (shared/notes/rosbridge.md).
        self.level = _LEVELS["none"]
        #: Text frames longer than this many characters go out as fragments (None: never).
        self.fragment_size: int | None = None
        self.fragments: dict[str | int, dict[int, str]] = {}
        self.calls: dict[str, asyncio.Future[tuple[Any, bool]]] = {}  # calls we forwarded to it
        self.tasks: set[asyncio.Task[None]] = set()
        #: ROS 2 with the queue trap: the goal this connection's op thread is inside, and the
        #: frames that arrived meanwhile (handled in order once it ends).
        self.blocker: ActionGoal | None = None
        self.backlog: deque[str | bytes] = deque()
        self.closed = False

    # -- sending -----------------------------------------------------------------------------

    def reply(self, op: Mapping[str, Any]) -> None:
        self.control.append((next_order(), Frame(op)))
        self.wake.set()

    def status(self, level: str, text: str, id: str | int | None) -> None:
        """A ``status`` op, only if the client asked for ``level`` with ``set_level``."""
        if _LEVELS[level] <= self.level:
            self.reply(rb.op_status(level, text, id))

    def _pop_next(self, now: float) -> tuple[bytes, bool, Frame] | float | None:
        """The next frame to send (bytes, binary, frame); else when a throttled one is due;
        else None."""
        best: deque[tuple[int, Frame]] | None = None
        best_sub: Sub | None = None
        best_seq = 0
        due: float | None = None
        if self.control:
            best, best_seq = self.control, self.control[0][0]
        for sub in self.subs.values():
            q = sub.queue
            if not q:
                continue
            if sub.throttle > 0.0 and sub.qlen > 0:
                ready = sub.last_sent + sub.throttle
                if now < ready - 1e-6:
                    due = ready if due is None else min(due, ready)
                    continue
            if best is None or q[0][0] < best_seq:
                best, best_sub, best_seq = q, sub, q[0][0]
        if best is None:
            return due
        _, frame = best.popleft()
        if best_sub is None:
            return frame.text(), False, frame
        best_sub.last_sent = now
        return (frame.cbor(), True, frame) if best_sub.cbor else (frame.text(), False, frame)

    async def writer(self) -> None:
        """Send queued frames in order; only this task waits on the socket, never the robot."""
        ws, clock, wake = self.ws, self.clock, self.wake
        while True:
            nxt = self._pop_next(clock.now())
            if isinstance(nxt, tuple):
                data, binary, frame = nxt
                size = self.fragment_size
                if size is not None and not binary and len(data) > size:
                    await self._send_fragments(data.decode(), size, frame)
                    continue
                await ws.send(data, text=not binary)
                continue
            wake.clear()
            if nxt is None:
                await wake.wait()
                continue
            waiter = asyncio.ensure_future(wake.wait())
            sleeper = asyncio.ensure_future(clock.sleep(nxt - clock.now()))
            try:
                await asyncio.wait({waiter, sleeper}, return_when=asyncio.FIRST_COMPLETED)
            finally:
                waiter.cancel()
                sleeper.cancel()

    async def _send_fragments(self, text: str, size: int, frame: Frame) -> None:
        """One text frame as consecutive ``fragment`` ops (rosbridge 0.11's protocol.py ``send``).

        The fragments' ``id`` is the op's own ``id`` (a ``service_response``'s call id), else 0:
        fragmentation.py numbers id-less messages from a seed it keeps on a fresh instance per
        message, so every one of them is fragment id 0. Binary (cbor) frames are never cut.
        """
        if len(text) <= size:  # a multi-byte character made the bytes longer than the text
            await self.ws.send(text)
            return
        fid = _op_id(frame.op)
        for part in rb.fragment_ops(text, size, 0 if fid is None else fid):
            await self.ws.send(rb.encode(part))

    # -- receiving ---------------------------------------------------------------------------

    def feed(self, frame: str | bytes) -> None:
        """One frame off the socket: handled now, or queued behind a goal holding the
        connection (the queue trap, :meth:`_send_action_goal`)."""
        if self.blocker is not None or self.backlog:
            if len(self.backlog) >= BACKLOG:
                self.backlog.popleft()
            self.backlog.append(frame)
            return
        self.handle_frame(frame)

    def release(self, goal: ActionGoal) -> None:
        """``goal`` ended: if it held this connection, handle what waited behind it (soon,
        not inside the robot's step that ended the goal)."""
        if self.blocker is goal:
            self.blocker = None
            asyncio.get_running_loop().call_soon(self._drain)

    def _drain(self) -> None:
        while self.blocker is None and self.backlog and not self.closed:
            self.handle_frame(self.backlog.popleft())

    def handle_frame(self, frame: str | bytes, depth: int = 0) -> None:
        """Decode and run one frame; every problem becomes a status reply, never an exception."""
        msg: dict[str, Any] | None = None
        try:
            if isinstance(frame, bytes) and frame[:1] not in (b"{", b" ", b"\n", b"\r", b"\t"):
                msg = self._decode_cbor(frame)
            else:
                msg = rb.decode(frame)
            self.handle_op(msg, depth)
        except ServeurError as exc:
            oid = _op_id(msg) if msg is not None else exc.details.get("id")
            self.status("error", exc.message, oid)
        except Exception as exc:  # a bug must not take the robot or the connection down
            log.exception("%s: error handling a frame", self.robot.name)
            self.status("error", f"internal error: {type(exc).__name__}: {exc}", _op_id(msg or {}))

    @staticmethod
    def _decode_cbor(frame: bytes) -> dict[str, Any]:
        try:
            obj = cbor2.loads(frame)
        except Exception as exc:
            raise RosbridgeError(f"binary frame is not CBOR: {exc}") from exc
        if not isinstance(obj, dict) or not isinstance(obj.get("op"), str):
            raise RosbridgeError("frame is not an object with a string 'op'")
        return cast(dict[str, Any], obj)

    def handle_op(self, msg: dict[str, Any], depth: int = 0) -> None:
        op = msg["op"]
        oid = _op_id(msg)
        if op in _ACTION_OPS and self.robot.ros == 1:
            raise RosbridgeError(f"unknown op {op!r}")  # rosbridge 0.11 has no action ops
        if self.robot.ros_side_dead and op not in _DEAD_SIDE_OPS:
            return  # the bridge's ROS side is gone: subscribing, publishing... do nothing
        if op in _OPS and "fragment_size" in msg:
            # Any op may carry it and it holds for the client from then on (protocol.py).
            size = _opt_int(msg, "fragment_size")
            self.fragment_size = size if size > 0 else None
        if op == "publish":
            self._publish(msg, oid)
        elif op == "subscribe":
            self._subscribe(msg, oid)
        elif op == "unsubscribe":
            self._unsubscribe(msg, oid)
        elif op == "advertise":
            self._advertise(msg)
        elif op == "unadvertise":
            topic = self._topic(msg)
            if topic not in self.advertised:
                self.status("warning", f"{topic} is not advertised by this client", oid)
            self.advertised.discard(topic)
        elif op == "call_service":
            service = _req_str(msg, "service")
            if len(self.tasks) >= MAX_CALLS:
                why = f"more than {MAX_CALLS} service calls in progress"
                self.reply(rb.op_service_response(service, oid, why, result=False))
                raise RosbridgeError(why)
            task = asyncio.ensure_future(self._call_service(msg, oid))
            self.tasks.add(task)
            task.add_done_callback(self.tasks.discard)
        elif op == "service_response":
            self._service_response(msg, oid)
        elif op == "advertise_service":
            self._advertise_service(msg)
        elif op == "unadvertise_service":
            service = _req_str(msg, "service")
            if self.endpoint.services.get(service) is self:
                del self.endpoint.services[service]
        elif op == "fragment":
            self._fragment(msg, depth)
        elif op == "send_action_goal":
            self._send_action_goal(msg, oid)
        elif op == "cancel_action_goal":
            self._cancel_action_goal(msg, oid)
        elif op == "set_level":
            # ROSBRIDGE_PROTOCOL.md (ROS1): status ops at this level and more severe ones.
            level = msg.get("level")
            if level not in _LEVELS:
                raise RosbridgeError(f"level must be one of {sorted(_LEVELS)}")
            self.level = _LEVELS[level]
        else:
            raise RosbridgeError(f"unknown op {op!r}")

    # -- ROS 2 actions (rosbridge 2.x) ------------------------------------------------------

    def _send_action_goal(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        """rosbridge 2.x's ``send_action_goal`` (capabilities/send_action_goal.py and
        internal/actions.py, before the 2026 fix; shared/notes/ros2.md):

        * no acknowledgement frame; ``action_feedback`` only if ``feedback`` is true;
        * a goal the action server rejects, or for an action nobody serves, gets no frame at
          all (the handler waits for ever; with the robot's ``rosbridge_fix``, the 2026 fix,
          ``action_result`` with ``result`` false, at once or after 1 s); an unknown action
          type or a goal rosbridge cannot populate gets ``action_result`` with ``result``
          false, status 0 and the error text;
        * ids live in one table for the whole bridge (``cancel_action_goal`` by any connection);
        * with the queue trap (``send_action_goals_in_new_thread`` false, Humble's default) the
          connection's op thread runs the goal itself: every later op of this connection waits
          until the goal ends; for a goal that never ends, for ever.
        """
        action = _req_str(msg, "action")
        action_type = _req_str(msg, "action_type")
        feedback = msg.get("feedback", False) is True
        name = action.split("#", 1)[0]
        if oid is None and "#" in action:  # the deprecated "action#id" form
            oid = action.split("#", 1)[1]
        goal = ActionGoal(self, action, oid, feedback)
        self.endpoint.actions[oid] = goal
        if self.robot.humble_queue:
            self.blocker = goal
        if self.robot.ros_side_dead:
            self._fail(goal, ros2.ROS_SIDE_DEAD)
            return
        robot = self.robot
        typ = action_type.strip("/")
        docking = robot.docking
        if not ros2.importable(typ, robot.release, docking is not None):
            self._fail(goal, f"Unable to import action type {action_type!r}")
            return
        served = ros2.action_of(robot.local(name), typ, robot.release, docking is not None)
        if served is None or robot.node_dead:
            # No action server: rosbridge waits for one for ever and sends nothing; with the
            # fix it gives up after wait_for_server's 1 s.
            if robot.rosbridge_fix:
                loop = asyncio.get_running_loop()
                loop.call_later(
                    self.clock.wall(1.0), self._fail, goal, "No action server available"
                )
            return
        args = msg.get("args")
        try:
            if served == "dock" and docking is not None:
                docking.dock(goal, ros2.dock_goal_from_args(args))
                return
            if served == "undock" and docking is not None:
                docking.undock(goal, ros2.undock_goal_from_args(args)[1])
                return
            frame, x, y, q = ros2.goal_from_args(args)
        except ServeurError as exc:
            self._fail(goal, exc.message)
            return
        taken = robot.inbox.nav2_goal(goal, frame, x, y, q, None if oid is None else str(oid))
        if taken is None and robot.rosbridge_fix:
            self._fail(goal, "Action goal was rejected")
        # Rejected without the fix: no frame, the handler waits for ever.

    def _fail(self, goal: ActionGoal, text: str) -> None:
        goal.fail(text)
        self.release(goal)

    def _cancel_action_goal(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        """``cancel_action_goal``: the goal with this id in the bridge's table, whichever
        connection sent it; an unknown id is silently ignored."""
        _req_str(msg, "action")
        action = cast(str, msg["action"])
        if oid is None and "#" in action:
            oid = action.split("#", 1)[1]
        goal = self.endpoint.actions.get(oid)
        if goal is not None and not goal.done and not self.robot.node_dead:
            robot = goal.client.robot
            robot.inbox.nav2_cancel(goal)
            if robot.docking is not None:
                robot.docking.cancel(goal)

    def _topic(self, msg: Mapping[str, Any]) -> str:
        """The op's topic as the robot names it inside (its namespace taken off).

        A robot started in a namespace (``/r1``) has every topic under it, as a ROS node pushed
        into a namespace does; a name outside it is a topic the robot does not have.
        """
        topic = _req_str(msg, "topic")
        local = self.robot.local(topic)
        return local if local is not None else f"(outside {self.robot.namespace}) {topic}"

    def _publish(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = self._topic(msg)
        if "msg" not in msg:
            raise RosbridgeError("publish needs a 'msg'")
        body = msg["msg"]
        if not isinstance(body, Mapping):
            raise RosbridgeError("'msg' must be an object")
        if topic not in self.robot.subscribes:
            if topic in self.robot.topic_types:
                raise RosbridgeError(
                    f"{topic} is published by the robot; it does not subscribe to it"
                )
            raise RosbridgeError(f"unknown topic {topic}: the robot does not subscribe to it")
        if self.robot.node_dead:
            return  # published to a topic whose only subscriber died: nobody gets it
        warning = self.robot.inbox.handle_publish(topic, body)
        if warning:
            self.status("warning", warning, oid)

    def _subscribe(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = self._topic(msg)
        known = self.robot.topic_types.get(topic)
        if known is None:
            raise RosbridgeError(f"unknown topic {topic}")
        typ = msg.get("type")
        if typ not in (None, "") and (not isinstance(typ, str) or not _same_type(typ, known)):
            raise RosbridgeError(f"{topic} is of type {known}, not {typ!r}")
        throttle = _opt_int(msg, "throttle_rate") / 1000.0
        qlen = min(_opt_int(msg, "queue_length"), MAX_QUEUE)
        compression = msg.get("compression") or "none"
        if compression not in ("none", "cbor", "png", "cbor-raw"):
            raise RosbridgeError(f"unknown compression {compression!r}")
        if compression in ("png", "cbor-raw"):
            self.status(
                "warning", f"compression {compression!r} is not supported; sending JSON", oid
            )
        sub = self.subs.get(topic)
        new = sub is None
        if sub is None:
            sub = self.subs[topic] = Sub(self, topic, ros=self.robot.ros)
        if oid not in sub.params and len(sub.params) >= MAX_SUB_IDS:
            raise RosbridgeError(f"more than {MAX_SUB_IDS} subscriptions to {topic}")
        sub.params.pop(oid, None)  # re-subscribing with an id makes it the latest
        sub.params[oid] = SubParams(throttle, qlen, compression == "cbor")
        sub.recompute()
        if new:
            self.robot.outbox.add(sub)
        self.robot.outbox.offer_latched(sub)

    def _unsubscribe(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        topic = self._topic(msg)
        sub = self.subs.get(topic)
        if sub is None:
            self.status("warning", f"not subscribed to {topic}", oid)
            return
        if oid is not None and oid in sub.params and len(sub.params) > 1:
            del sub.params[oid]
            sub.recompute()
            return
        if oid is not None and oid not in sub.params:
            self.status("warning", f"no subscription {oid!r} on {topic}", oid)
            return
        self._drop_sub(sub)

    def _drop_sub(self, sub: Sub) -> None:
        self.subs.pop(sub.topic, None)
        self.robot.outbox.remove(sub)

    def _advertise(self, msg: Mapping[str, Any]) -> None:
        topic = self._topic(msg)
        typ = _req_str(msg, "type")
        known = self.robot.topic_types.get(topic)
        if known is None or topic not in self.robot.subscribes:
            raise RosbridgeError(f"cannot advertise {topic}: the robot does not subscribe to it")
        if not _same_type(typ, known):
            raise RosbridgeError(f"{topic} is of type {known}, not {typ!r}")
        self.advertised.add(topic)

    # -- services ----------------------------------------------------------------------------

    async def _call_service(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        service = cast(str, msg["service"])
        args = msg.get("args")
        robot = self.robot
        if robot.ros_side_dead:
            self.reply(rb.op_service_response(service, oid, ros2.ROS_SIDE_DEAD, result=False))
            return
        try:
            if args is not None and not isinstance(args, Mapping | list):
                raise RosbridgeError("'args' must be an object or a list")
            builtin = _rosapi(self).get(service)
            if builtin is not None:
                values, ok = builtin(self, args), True
            elif robot.ros == 2 and robot.local(service) == ros2.GET_STATE:
                if robot.node_dead:
                    return  # the dead node is still listed: rosbridge waits, nothing comes
                values, ok = ros2.lifecycle_state("active"), True
            elif service in self.endpoint.services:
                values, ok = await self._forward_call(service, args, msg.get("timeout"))
            else:
                raise RosbridgeError(f"service {service} does not exist")
        except ServeurError as exc:
            self.reply(rb.op_service_response(service, oid, exc.message, result=False))
            self.status("error", exc.message, oid)
            return
        self.reply(rb.op_service_response(service, oid, values, result=ok))

    async def _forward_call(self, service: str, args: Any, limit_s: object) -> tuple[Any, bool]:
        provider = self.endpoint.services[service]
        fid = f"service_request:{service}:{next_order()}"
        fut: asyncio.Future[tuple[Any, bool]] = asyncio.get_running_loop().create_future()
        fut.add_done_callback(consume_exception)  # the caller may be gone when it fails
        provider.calls[fid] = fut
        provider.reply({"op": "call_service", "service": service, "args": args or {}, "id": fid})
        limit = float(limit_s) if isinstance(limit_s, int | float) and limit_s > 0 else 10.0
        try:
            return await asyncio.wait_for(fut, self.clock.wall(limit))
        except TimeoutError as exc:
            raise RosbridgeError(f"service {service} did not answer within {limit} s") from exc
        finally:
            provider.calls.pop(fid, None)

    def _service_response(self, msg: Mapping[str, Any], oid: str | int | None) -> None:
        fut = self.calls.get(oid) if isinstance(oid, str) else None
        if fut is None:
            raise RosbridgeError("service_response for no call this server made")
        result = msg.get("result", True)
        if not fut.done():
            fut.set_result((msg.get("values"), result is not False))

    def _advertise_service(self, msg: Mapping[str, Any]) -> None:
        service = _req_str(msg, "service")
        _req_str(msg, "type")
        if service in _rosapi(self):
            raise RosbridgeError(f"{service} is provided by rosapi")
        self.endpoint.services[service] = self

    def _fragment(self, msg: Mapping[str, Any], depth: int) -> None:
        fid = msg.get("id")
        data, num, total = msg.get("data"), msg.get("num"), msg.get("total")
        if not isinstance(fid, str | int) or isinstance(fid, bool):
            raise RosbridgeError("a fragment needs an 'id'")
        if not isinstance(data, str) or not isinstance(num, int) or not isinstance(total, int):
            raise RosbridgeError("a fragment needs 'data' (string), 'num' and 'total' (integers)")
        if not 0 <= num < total or total > MAX_FRAME:
            raise RosbridgeError("fragment 'num' must be in [0, total)")
        parts = self.fragments.get(fid)
        if parts is None:
            if len(self.fragments) >= MAX_FRAGMENTED:  # forget the oldest incomplete message
                self.fragments.pop(next(iter(self.fragments)))
            parts = self.fragments[fid] = {}
        parts[num] = data
        if sum(len(p) for p in parts.values()) > MAX_FRAME:
            del self.fragments[fid]
            raise RosbridgeError("fragmented message is larger than the frame limit")
        if len(parts) == total:
            del self.fragments[fid]
            if depth >= 2:
                raise RosbridgeError("fragments nested too deeply")
            self.handle_frame("".join(parts[i] for i in range(total)), depth + 1)

    def close(self) -> None:
        # The robot's goals go on: closing a websocket does not cancel them (ROS 2 measured).
        self.closed = True
        self.backlog.clear()
        for sub in list(self.subs.values()):
            self._drop_sub(sub)
        for name, provider in list(self.endpoint.services.items()):
            if provider is self:
                del self.endpoint.services[name]
        for fut in self.calls.values():
            if not fut.done():
                fut.set_exception(RosbridgeError("the service provider disconnected"))
        for task in list(self.tasks):
            task.cancel()


def _same_type(a: str, b: str) -> bool:
    """``pkg/Type`` and ``pkg/msg/Type`` are one type (rosbridge's loaders take both)."""
    return rb.normalize_type(a.strip("/")) == rb.normalize_type(b.strip("/"))


def _rosapi_topics(client: BridgeClient, args: Any) -> dict[str, Any]:
    types = client.robot.topic_types
    topics = sorted(types)
    return {"topics": [client.robot.wire(t) for t in topics], "types": [types[t] for t in topics]}


def _rosapi_get_time(client: BridgeClient, args: Any) -> dict[str, Any]:
    t = client.robot.epoch()  # the robot's clock, offset included
    return {"time": ros2.time(t) if client.robot.ros == 2 else rb.ros_time(t)}


def _rosapi_topic_type(client: BridgeClient, args: Any) -> dict[str, Any]:
    """The type of a topic (ROS 2: ``pkg/msg/Type``, e.g. whether /cmd_vel is stamped)."""
    topic = args.get("topic") if isinstance(args, Mapping) else (args[0] if args else None)
    local = client.robot.local(topic) if isinstance(topic, str) else None
    return {"type": client.robot.topic_types.get(local, "") if local is not None else ""}


def _rosapi_services(client: BridgeClient, args: Any) -> dict[str, Any]:
    own = [client.robot.wire(ros2.GET_STATE)] if client.robot.ros == 2 else []
    return {"services": sorted([*_rosapi(client), *own, *client.endpoint.services])}


def _rosapi_action_servers(client: BridgeClient, args: Any) -> dict[str, Any]:
    """rosapi 2.x's ``/rosapi/action_servers``: the robot's navigator, and its docking
    server's actions when it runs one."""
    robot = client.robot
    names = [ros2.NAVIGATE_TO_POSE]
    if robot.docking is not None:
        names += [ros2.DOCK_ROBOT, ros2.UNDOCK_ROBOT]
    return {"action_servers": sorted(robot.wire(n) for n in names)}


_ROSAPI: Final[dict[str, Callable[[BridgeClient, Any], dict[str, Any]]]] = {
    "/rosapi/topics": _rosapi_topics,
    "/rosapi/get_time": _rosapi_get_time,
    "/rosapi/topic_type": _rosapi_topic_type,
    "/rosapi/services": _rosapi_services,
}
_ROSAPI2: Final[dict[str, Callable[[BridgeClient, Any], dict[str, Any]]]] = {
    **_ROSAPI,
    "/rosapi/action_servers": _rosapi_action_servers,
}


def _rosapi(client: BridgeClient) -> dict[str, Callable[[BridgeClient, Any], dict[str, Any]]]:
    return _ROSAPI2 if client.robot.ros == 2 else _ROSAPI


# ---------------------------------------------------------------------------------------------
# One robot's websocket endpoint
# ---------------------------------------------------------------------------------------------


class Endpoint:
    """The rosbridge websocket server of one robot; can be stopped and restarted on its port.

    With ``ssl`` it speaks only TLS (``wss://``), as a robot whose rosbridge_server was started
    with ``ssl:=true`` does, so the server's certificate checks are exercised for real.
    """

    def __init__(
        self, robot: SimRobot, host: str, port: int, ssl: ssl_module.SSLContext | None = None
    ) -> None:
        self.robot = robot
        self.host = host
        self.port = port
        self.ssl = ssl
        self.server: Server | None = None
        self.clients: set[BridgeClient] = set()
        self.services: dict[str, BridgeClient] = {}
        #: ROS 2: the bridge's goal table, one for all its connections (send_action_goal.py).
        self.actions: dict[str | int | None, ActionGoal] = {}

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        scheme = "wss" if self.ssl is not None else "ws"
        return f"{scheme}://{host}:{self.port}"

    async def start(self) -> None:
        if self.server is not None:
            return
        self.server = await serve(
            self._handler,
            self.host,
            self.port,
            compression=None,  # rosbridge_server does not deflate; it would cost CPU per client
            max_size=MAX_FRAME,
            close_timeout=2.0,
            reuse_address=True,
            ssl=self.ssl,
        )
        if self.port == 0:
            self.port = int(self.server.sockets[0].getsockname()[1])

    async def stop(self, close_timeout: float = 2.0) -> None:
        """Stop listening and close every connection with 1001 (Going Away).

        websockets' own ``Server.close`` waits for each close handshake while flushing what is
        queued, and a client that stopped reading never lets that flush end; so each client
        gets ``close_timeout`` wall seconds, then its TCP connection is aborted.
        """
        server, self.server = self.server, None
        if server is None:
            return
        server.close(close_connections=False)

        async def close_one(ws: ServerConnection) -> None:
            try:
                await asyncio.wait_for(ws.close(1001, "endpoint stopped"), close_timeout)
            except TimeoutError:
                ws.transport.abort()

        await asyncio.gather(*(close_one(c.ws) for c in list(self.clients)))
        await server.wait_closed()

    async def _handler(self, ws: ServerConnection) -> None:
        sock = ws.transport.get_extra_info("socket")
        if sock is not None:
            # A small kernel send buffer: a client that stops reading then backs up into our
            # bounded per-topic queues (which drop the oldest) within a few frames, instead of
            # into megabytes of stale scans in the kernel (loopback autotunes up to 4 MiB).
            with contextlib.suppress(OSError):
                sock.setsockopt(socket.SOL_SOCKET, socket.SO_SNDBUF, SEND_BUFFER)
        client = BridgeClient(self, ws)
        self.clients.add(client)
        writer = asyncio.ensure_future(client.writer())
        try:
            async for frame in ws:
                client.feed(frame)
        except ConnectionClosed:
            pass
        finally:
            client.close()
            self.clients.discard(client)
            writer.cancel()
            with contextlib.suppress(asyncio.CancelledError, ConnectionClosed):
                await writer
