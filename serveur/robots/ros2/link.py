"""The server's link to a ROS 2 robot: Nav2's navigate_to_pose over rosbridge 2.x.

It implements :class:`~serveur.robots.driver.RobotDriver`, so the core drives a ROS 2 robot
exactly as a ROS1 one. What the real stack does, and what this driver does about it (facts
from rosbridge_suite 2.x, Nav2 and a Jazzy stack measured in ../shared/notes/ros2.md):

* **Two connections.** With ``send_action_goals_in_new_thread`` false (Humble's default) a
  navigate goal holds its connection's queue until the robot arrives: a cancel or a joystick
  command sent behind it waits too (rosbridge_suite #909). Goals therefore go on a connection
  of their own; cancels, teleop, the pose and the heartbeat use the other, so Stop works at
  once whatever the robot's bridge is set to. (With the parameter true one connection would
  do; docs/robots.md says to set it anyway.)
* **No acknowledgement frame.** rosbridge answers neither ``send_action_goal`` nor
  ``cancel_action_goal``, and a goal the robot rejects or nobody serves gets no frame at all.
  The goal asks for feedback, which Nav2 sends while it executes: feedback within
  ``ack_timeout`` means accepted; none and the goal is re-sent under a new id (the old one
  cancelled), and reported lost — and cancelled — after ``ack_retries`` re-sends.
* **A result that never comes** (about one in 200 on the measured stack): feedback stopped for
  ``ack_timeout`` with no result. The robot standing at the goal counts as arrived (the core
  checks the distance again); elsewhere the goal is reported lost and cancelled.
* **Outcomes.** ``action_result`` has ``result: true`` for every normal end; the outcome is
  ``status`` (4 succeeded, 5 canceled, 6 aborted), see :func:`messages.outcome`. Nav2 aborts
  the active goal when a new one arrives: a result for a goal we replaced is ignored, never a
  failure.
* **Ids.** The goal table is shared by every client of the bridge: ids are UUIDs.
* **Closing the socket does not cancel the robot's goal**: :meth:`halt` cancels explicitly.
* **Release differences** found at run time: ``/cmd_vel`` is Twist or TwistStamped (Jazzy's
  diff_drive_controller, Kilted's Nav2), asked from rosapi's ``topic_type`` at each connection.
* **Liveness** (shared/notes/ros2.md, "Liveness, measured on the same stack"). ROS 2 has no
  move_base status stream to serve as a heartbeat: the robot's heartbeat service (Nav2's
  ``/bt_navigator/get_state``, the robot's ``heartbeat`` name) is called every
  :data:`PING_PERIOD`. Only the robot proves itself alive: that service answering ``active``,
  its topics (pose, battery, scan) and our goal's feedback. A reply with ``result: false`` is
  *not* life — rosbridge stopped with SIGTERM or SIGINT keeps its websocket open and answers
  every call so — and neither is a rosapi answer (rosapi lives in the bridge, and answers
  while the robot's node is dead); rosapi's ``get_time`` is asked only while the robot is
  silent, to say which of the two failed. Silence beyond :meth:`heartbeat_timeout` takes the
  link down (sockets aborted, reconnect); the goal under way is cancelled (best effort, and
  again when the link reconnects), and the core keeps the trip with the robot Offline. The
  decisions are the shared :class:`~serveur.robots.liveness.LinkTracker`'s.
* Goals, cancels and initial poses carry zero stamps in frame ``map`` (AMCL ignores an
  ``/initialpose`` in another frame), as on ROS1.
* **Docking** (the robot's ``docking`` link option: ``nav2`` or ``opennav``; see
  :mod:`serveur.robots.ros2.messages` for the actions, read in Nav2's sources):
  :meth:`Nav2Link.dock` sends a DockRobot goal to ``dock_robot`` (``use_dock_id`` false, the
  dock's pose in ``map``, ``navigate_to_staging_pose`` true) and tracks it as a navigate goal
  is tracked — acknowledged by its first feedback, re-sent, lost, cancelled, replaced — by the
  same :class:`~serveur.robots.liveness.LinkTracker`, in its own words (``Nav2 dock_robot``).
  Its feedback stops while Nav2 drives to the staging pose, so its silence is believed only
  after :data:`MAX_STAGING_TIME` (sent with the goal: the server gives up by then) and the
  dock's perception time. A result with ``success`` false is ABORTED with its error code in
  words. :meth:`Nav2Link.undock` sends an UndockRobot goal to ``undock_robot`` and waits for
  its result (it has no feedback): SUCCEEDED, or ABORTED without an error code — opennav's
  "Robot is not in the dock, no need to undock", which ends the goal unfinished and Nav2's
  SimpleActionServer aborts — returns; any other end, or none within
  :data:`MAX_UNDOCKING_TIME` and :data:`UNDOCK_GRACE`, raises :class:`LinkError` (the undock
  cancelled). Without the option a dock is :meth:`Nav2Link.send_goal` to the dock's pose and
  undock does nothing.
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl as ssl_module
import uuid
from collections.abc import AsyncIterator, Mapping
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection

from serveur.clock import Clock
from serveur.errors import LinkError, RosbridgeError
from serveur.robots import rosbridge as rb
from serveur.robots.deadman import DeadManSwitch
from serveur.robots.driver import LinkListener, connect_failed
from serveur.robots.liveness import (
    Cancel,
    Instruction,
    LinkDown,
    LinkTracker,
    SendGoal,
    TrackedGoal,
)
from serveur.robots.names import RosNames
from serveur.robots.reconnect import Reconnecting, open_rosbridge
from serveur.robots.ros2 import messages as m2
from serveur.robots.sensor_reports import SensorReports, Streams

__all__ = ["MAX_STAGING_TIME", "MAX_UNDOCKING_TIME", "PING_PERIOD", "UNDOCK_GRACE", "Nav2Link"]

log = logging.getLogger(__name__)

#: Clock seconds between two heartbeat calls on the control connection.
PING_PERIOD = 0.5
#: Wall seconds of Wi-Fi silence allowed before the robot is down (as for ROS1 robots).
STALL_ALLOWANCE = 2.0
TELEOP_TIMEOUT = 0.5
BATTERY_MS = 5000
#: Heartbeat answers without feedback, besides the ack timeout, before a goal's silence is
#: believed: after a stall of the server (or of a Pi's Wi-Fi) the pings and the feedback
#: queued behind them arrive together, and time alone would misjudge a goal under way.
SILENT_PINGS = 3
#: Robot seconds a docking server may let Nav2 take to a dock's staging pose (sent as the
#: DockRobot goal's ``max_staging_time``; Nav2's default is 1000 s): a restaurant's longest
#: drive with waits for other robots, after which the server gives up (FAILED_TO_STAGE).
MAX_STAGING_TIME = 300.0
#: Robot seconds the docking server may stay silent after the dock's initial perception
#: feedback (opennav_docking's ``initial_perception_timeout``, 5 s by default) and margin.
DOCK_PERCEPTION = 15.0
#: Robot seconds the docking server may take to back the robot off its dock (UndockRobot's
#: ``max_undocking_time``, its default), and what is waited on top for its result.
MAX_UNDOCKING_TIME = 30.0
UNDOCK_GRACE = 5.0
#: Goal ids whose action is remembered (to cancel each on its own action).
_ACTIONS_KEPT = 64


class Nav2Link(Reconnecting):
    """One ROS 2 robot's rosbridge 2.x connections, kept up for the life of the server."""

    kind = "ROS 2 Nav2"
    _log = log

    def __init__(
        self,
        name: str,
        url: str,
        listener: LinkListener,
        clock: Clock,
        *,
        heartbeat: float = 1.0,
        ack_timeout: float = 2.0,
        ack_retries: int = 2,
        want_map: bool = False,
        backoff_min: float = 0.2,
        backoff_max: float = 5.0,
        open_timeout: float = 5.0,
        ssl: ssl_module.SSLContext | None = None,
        stall: float = STALL_ALLOWANCE,
        teleop_timeout: float = TELEOP_TIMEOUT,
        names: RosNames | None = None,
        **_rates: Any,  # the ROS1 link's throttles: AMCL is sparse on ROS 2 already
    ) -> None:
        self.name = name
        self.url = url
        self._listener = listener
        self._clock = clock
        self._heartbeat = heartbeat
        self._ack_timeout = ack_timeout
        self._ack_retries = ack_retries
        self._want_map = want_map
        self._backoff = (backoff_min, backoff_max)
        self._open_timeout = open_timeout
        self._ssl = ssl if url[:6].lower() == "wss://" else None
        self._stall = stall
        self._names = names or RosNames(ros=2)
        self._ctl: ClientConnection | None = None  # subscriptions, cancels, teleop, pings
        self._nav: ClientConnection | None = None  # goals only (the Humble queue)
        self._task: asyncio.Task[None] | None = None
        # Up once the heartbeat said the robot is ready and a pose came.
        self._track = LinkTracker(
            stack=m2.STACK,
            proofs_words=f"answer from {self._names.heartbeat}, pose or battery",
            required=frozenset({"heartbeat", "pose"}),
            paced="heartbeat",
            ack_timeout=ack_timeout,
            ack_retries=ack_retries,
            new_id=lambda: str(uuid.uuid4()),
            confirmations=SILENT_PINGS,
            progress=True,
            cancel_replaced=True,
            unacked_words=" (no feedback)",
        )
        self._halted = False
        self._stamped_cmd_vel = False
        self._deadman = DeadManSwitch(name, clock, teleop_timeout, self._deadman_stop)
        self._sensors = SensorReports(name, listener, self._names, clock)
        self._streams = Streams(
            lambda topic, ms: self._sub(topic, throttle_rate=ms),
            lambda topic: rb.op_unsubscribe(self._t(topic)),
        )
        self._pings = 0
        #: The docking server's (DockRobot, UndockRobot) types; None: docks are goals.
        self._dock_types = m2.DOCK_ACTION_TYPES.get(self._names.docking)
        #: The action (default name) each goal id we sent went to, for its cancel and result.
        self._action_of: dict[str, str] = {}
        #: Undock goals waiting for their result, by id.
        self._undocks: dict[str, asyncio.Future[Mapping[str, Any]]] = {}
        self._cmd_vel_type: str | None = None  # /cmd_vel's type, once rosapi said it
        self._jobs: set[asyncio.Task[None]] = set()
        self.connects = 0
        self.last_failure = ""

    # -- lifecycle -----------------------------------------------------------------------

    @property
    def up(self) -> bool:
        return self._track.up

    @property
    def pose(self) -> tuple[float, float, float] | None:
        return self._sensors.pose

    @property
    def battery(self) -> float | None:
        return self._sensors.battery

    @property
    def goal_id(self) -> str | None:
        goal = self._track.goal
        return goal.handle if goal else None

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name=f"link-{self.name}")

    async def close(self) -> None:
        self._deadman.release()
        task, self._task = self._task, None
        if task is not None:
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    async def drop(self) -> None:
        for ws in (self._ctl, self._nav):
            if ws is not None:
                await ws.close(code=1001, reason="dropped")

    def _connect(self) -> Any:
        return open_rosbridge(self.url, ssl=self._ssl, open_timeout=self._open_timeout)

    @contextlib.asynccontextmanager
    async def _open(self) -> AsyncIterator[None]:
        async with self._connect() as ctl, self._connect() as nav:
            self._ctl, self._nav = ctl, nav
            yield

    async def _serve(self) -> None:
        assert self._ctl is not None and self._nav is not None
        await self._session(self._ctl, self._nav)

    def _closed(self) -> None:
        self._ctl = self._nav = None
        for fut in self._undocks.values():
            if not fut.done():
                fut.set_exception(LinkError(f"robot {self.name}: connection lost while undocking"))

    def _connect_failed(self, reason: str) -> str:
        return connect_failed(self, self._listener, reason, log)

    async def _session(self, ctl: ClientConnection, nav: ClientConnection) -> None:
        # Goals of the last connection may still run (closing a socket cancels nothing).
        await self._perform(self._track.start(self._clock.now()))
        # /cmd_vel is advertised once its type is known (rosbridge 2.x refuses a publisher of
        # another type than the topic's): see _on_service.
        self._cmd_vel_type = None
        topic = "/initialpose"
        await ctl.send(rb.encode(rb.op_advertise(self._t(topic), m2.TOPIC_TYPES[topic])))
        for pose_topic in self._sensors.pose_topics():
            await ctl.send(rb.encode(self._sub(pose_topic)))
        await ctl.send(rb.encode(self._sub("/battery_state", throttle_rate=BATTERY_MS)))
        if self._want_map:
            await ctl.send(rb.encode(self._sub("/map")))
        for op in self._streams.resubscribe():
            await ctl.send(rb.encode(op))
        # Twist or TwistStamped: the release decides (Jazzy's controllers, Kilted's Nav2).
        args = {"topic": self._t("/cmd_vel")}
        await ctl.send(rb.encode(rb.op_call_service("/rosapi/topic_type", args, id="cmd_vel")))
        await self._ping(ctl)
        tasks = [
            asyncio.create_task(self._read(ctl), name=f"ctl-{self.name}"),
            asyncio.create_task(self._read(nav), name=f"nav-{self.name}"),
            asyncio.create_task(self._watchdog(ctl, nav), name=f"watchdog-{self.name}"),
        ]
        try:
            await asyncio.wait(tasks, return_when=asyncio.FIRST_COMPLETED)
        finally:
            for t in tasks:
                t.cancel()
            await asyncio.gather(*tasks, return_exceptions=True)

    async def _read(self, ws: ClientConnection) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in ws:
                self._handle(frame)

    async def _ping(self, ctl: ClientConnection) -> None:
        """The heartbeat call; while the robot is silent, rosapi's too (is the bridge up?)."""
        self._pings += 1
        await ctl.send(rb.encode(rb.op_call_service(self._names.heartbeat, {}, id="ping")))
        if self._track.silent(self._clock.now(), 1.5 * PING_PERIOD):
            await ctl.send(rb.encode(rb.op_call_service("/rosapi/get_time", {}, id="bridge")))

    async def _watchdog(self, ctl: ClientConnection, nav: ClientConnection) -> None:
        while True:
            await self._clock.sleep(PING_PERIOD)
            todo = self._track.check(self._clock.now(), self.heartbeat_timeout(), self.pose)
            await self._carry_out(todo)
            if any(isinstance(act, LinkDown) for act in todo):
                return
            with contextlib.suppress(websockets.exceptions.ConnectionClosed):
                await self._ping(ctl)

    def heartbeat_timeout(self) -> float:
        """Two ping periods plus the Wi-Fi stall allowance (wall, scaled to the clock)."""
        return max(self._heartbeat, 2.0 * PING_PERIOD + self._stall * self._clock.time_scale)

    async def _perform(self, todo: list[Instruction]) -> None:
        """Cancels (on the control connection: never queued behind a goal) and re-sends go
        out even while the link is coming down (best effort: a dead bridge loses them); a
        :class:`LinkDown` aborts both connections."""
        ctl, nav = self._ctl, self._nav
        for act in todo:
            with contextlib.suppress(websockets.exceptions.ConnectionClosed):
                if isinstance(act, Cancel) and ctl is not None:
                    for gid in act.ids:
                        await ctl.send(rb.encode(self._cancel_op(gid)))
                elif isinstance(act, SendGoal) and nav is not None:
                    log.warning("%s: goal not accepted, re-sent as %s", self.name, act.goal.id)
                    await nav.send(rb.encode(self._goal_op(act.goal)))
            if isinstance(act, LinkDown):
                for ws in (ctl, nav):
                    if ws is not None:
                        ws.transport.abort()

    # -- incoming ------------------------------------------------------------------------

    def _handle(self, frame: str | bytes) -> None:
        try:
            op = rb.decode(frame)
            kind = op["op"]
            if kind == "publish":
                topic = str(op.get("topic"))
                self._on_publish(self._names.default_of(topic) or topic, op.get("msg"))
            elif kind == "service_response":
                self._on_service(op)
            elif kind == "action_feedback":
                self._on_feedback(op)
            elif kind == "action_result":
                self._on_result(op)
            elif kind == "status":
                log.info("%s: rosbridge says %s: %s", self.name, op.get("level"), op.get("msg"))
        except rb.MALFORMED as exc:
            log.warning("%s: dropped malformed frame from robot: %s", self.name, exc)
        except Exception:
            log.exception("%s: error handling a frame from the robot (dropped)", self.name)

    def _on_service(self, op: Mapping[str, Any]) -> None:
        now = self._clock.now()
        if op.get("id") == "ping":
            alive, why, cause = m2.heartbeat_verdict(op)
            if alive:
                self._apply(self._track.proof(now, "heartbeat"))
            else:
                self._track.refused(now, why, cause)
        elif op.get("id") == "bridge":
            if op.get("result") is False:
                self._track.refused(now, str(op.get("values")))
            else:
                self._track.bridge_answered(now)
        elif op.get("id") == "cmd_vel":
            values = op.get("values")
            kind = str(values.get("type", "")) if isinstance(values, Mapping) else ""
            self._stamped_cmd_vel = kind.endswith("TwistStamped")
            # Unknown (nobody subscribes yet): the plain Twist Nav2 Humble and Jazzy publish.
            self._cmd_vel_type = kind or m2.TOPIC_TYPES["/cmd_vel"]
            if self._stamped_cmd_vel:
                log.info("%s: /cmd_vel is TwistStamped", self.name)
            ctl = self._ctl
            if ctl is not None:
                adv = rb.op_advertise(self._t("/cmd_vel"), self._cmd_vel_type)
                self._spawn(ctl.send(rb.encode(adv)))

    def _on_publish(self, topic: str, msg: Any) -> None:
        if not isinstance(msg, dict):
            raise RosbridgeError(f"{topic}: msg is not an object")
        if not self._sensors.handles(topic):
            return
        # After the report: the core knows where the robot is before it hears it is up.
        proof = self._sensors.on_publish(topic, msg)
        if proof is not None:
            self._apply(self._track.proof(self._clock.now(), proof))

    def _on_feedback(self, op: Mapping[str, Any]) -> None:
        goal = self._track.goal
        if goal is not None and op.get("id") == goal.id:
            now = self._clock.now()
            self._track.goal_progress(now, goal.id)
            self._apply(self._track.proof(now, "feedback"))

    def _on_result(self, op: Mapping[str, Any]) -> None:
        # A goal we replaced (Nav2 aborted it for the new one) or cancelled is ignored.
        gid = str(op.get("id"))
        undock = self._undocks.get(gid)
        if undock is not None:
            if not undock.done():
                undock.set_result(op)
            return
        dock = self._action_of.get(gid) == "/dock_robot"
        if op.get("result") is False:
            stack = m2.DOCK_STACK if dock else m2.STACK
            reason = f"{stack}: the bridge could not run the goal: {op.get('values')}"
            self._apply(self._track.goal_failed(gid, reason))
            return
        status, text = m2.dock_outcome(op) if dock else m2.outcome(op)
        self._apply(self._track.goal_state(gid, status, text))

    # -- outgoing ------------------------------------------------------------------------

    def _t(self, default: str) -> str:
        return self._names.topic(default)

    def _sub(self, default: str, *, throttle_rate: int = 0) -> dict[str, Any]:
        return rb.op_subscribe(
            self._t(default), m2.TOPIC_TYPES[default], throttle_rate=throttle_rate
        )

    async def _send(
        self, op: Mapping[str, Any], *, nav: bool = False, halting: bool = False
    ) -> None:
        if self._halted and not halting:
            raise LinkError(f"robot {self.name} is stopped: the server is shutting down")
        ws = self._nav if nav else self._ctl
        if ws is None or not self._track.up:
            raise LinkError(f"robot {self.name} is not connected")
        try:
            await ws.send(rb.encode(op))
        except websockets.exceptions.ConnectionClosed as exc:
            raise LinkError(f"robot {self.name}: connection lost while sending") from exc

    async def send_goal(self, x: float, y: float, yaw: float) -> str:
        # A goal under way is cancelled first, freeing a Humble bridge's goal queue: Nav2
        # would abort it for the new one anyway, but the new goal would wait behind it.
        goal, todo = self._track.new_goal(self._clock.now(), x, y, yaw)
        await self._perform(todo)
        await self._send(self._goal_op(goal), nav=True)
        return goal.handle

    async def dock(self, x: float, y: float, yaw: float, dock_id: str) -> str:
        """A DockRobot goal to the docking server (the module's docstring), tracked as a
        goal; without a docking server, a goal to the dock's pose."""
        if self._dock_types is None:
            return await self.send_goal(x, y, yaw)
        goal, todo = self._track.new_goal(
            self._clock.now(),
            x,
            y,
            yaw,
            dock_id=dock_id,
            stack=m2.DOCK_STACK,
            quiet=MAX_STAGING_TIME + DOCK_PERCEPTION,
        )
        await self._perform(todo)
        await self._send(self._goal_op(goal), nav=True)
        return goal.handle

    async def undock(self) -> None:
        """An UndockRobot goal, waited for (the module's docstring); nothing to do without a
        docking server."""
        if self._dock_types is None:
            return
        if self._track.goal is not None:  # a dock still running: the server runs one at once
            await self.cancel_goal()
        gid = str(uuid.uuid4())
        action = self._remember(gid, "/undock_robot")
        op = m2.op_send_undock_goal(
            action, self._dock_types[1], gid, max_undocking_time=MAX_UNDOCKING_TIME
        )
        fut: asyncio.Future[Mapping[str, Any]] = asyncio.get_running_loop().create_future()
        self._undocks[gid] = fut
        try:
            await self._send(op, nav=True)
            wait = self._clock.wall(MAX_UNDOCKING_TIME + UNDOCK_GRACE)
            try:
                result = await asyncio.wait_for(fut, wait)
            except TimeoutError:
                with contextlib.suppress(LinkError):
                    await self._send(m2.op_cancel_action_goal(action, gid))
                raise LinkError(
                    f"robot {self.name}: no result from {m2.UNDOCK_STACK} within "
                    f"{MAX_UNDOCKING_TIME + UNDOCK_GRACE:g}s (cancelled)"
                ) from None
        finally:
            self._undocks.pop(gid, None)
        off, text = m2.undock_verdict(result)
        if not off:
            raise LinkError(f"robot {self.name} could not leave its dock: {text}")
        log.info("%s: undocked (%s)", self.name, text)

    def _remember(self, gid: str, action: str) -> str:
        """Note that goal ``gid`` went to ``action`` (a default name); its wire name."""
        self._action_of[gid] = action
        while len(self._action_of) > _ACTIONS_KEPT:
            del self._action_of[next(iter(self._action_of))]
        return self._t(action)

    def _goal_op(self, goal: TrackedGoal) -> dict[str, Any]:
        if goal.dock_id is not None and self._dock_types is not None:
            return m2.op_send_dock_goal(
                self._remember(goal.id, "/dock_robot"),
                self._dock_types[0],
                goal.id,
                goal.x,
                goal.y,
                goal.yaw,
                dock_id=goal.dock_id,
                frame_id=self._names.frame,
                max_staging_time=MAX_STAGING_TIME,
            )
        return m2.op_send_action_goal(
            self._remember(goal.id, "/navigate_to_pose"),
            goal.id,
            goal.x,
            goal.y,
            goal.yaw,
            frame_id=self._names.frame,
        )

    def _cancel_op(self, goal_id: str) -> dict[str, Any]:
        """Cancel goal ``goal_id`` on the action it was sent to (navigate_to_pose if not
        remembered: every goal of an earlier server run went there)."""
        action = self._action_of.get(goal_id, "/navigate_to_pose")
        return m2.op_cancel_action_goal(self._t(action), goal_id)

    async def _cancel(self, goal_id: str, *, halting: bool = False) -> None:
        await self._send(self._cancel_op(goal_id), halting=halting)

    async def cancel_goal(self) -> None:
        """Cancel our goals on the robot (on the control connection: never queued behind
        the goal itself). An unknown id is ignored by the bridge."""
        for gid in self._track.cancelled():
            await self._cancel(gid)

    async def halt(self) -> None:
        self._halted = True
        self._deadman.release()
        with contextlib.suppress(LinkError):
            for gid in (*self._track.cancelled(), *self._undocks):
                await self._cancel(gid, halting=True)
            await self._send(self._twist_op(0.0, 0.0, 0.0), halting=True)

    def _twist_op(self, vx: float, vy: float, wz: float) -> dict[str, Any]:
        msg = m2.twist_stamped(vx, vy, wz) if self._stamped_cmd_vel else rb.twist(vx, vy, wz)
        return rb.op_publish(self._t("/cmd_vel"), msg)

    async def teleop(self, vx: float, vy: float, wz: float) -> None:
        self._deadman.twist((vx, vy, wz) != (0.0, 0.0, 0.0))
        await self._send(self._twist_op(vx, vy, wz))

    async def _deadman_stop(self) -> None:
        with contextlib.suppress(LinkError):
            await self._send(self._twist_op(0.0, 0.0, 0.0))

    async def initial_pose(self, x: float, y: float, yaw: float) -> None:
        msg = m2.pose_with_covariance_stamped(x, y, yaw, stamp=0.0, frame_id=self._names.frame)
        await self._send(rb.op_publish(self._t("/initialpose"), msg))

    async def want_pose(self, on: bool) -> None:
        """AMCL on ROS 2 publishes only after 0.25 m / 0.2 rad of motion: nothing to throttle."""

    async def want_scan(self, on: bool) -> None:
        await self._stream("/scan", on)

    async def want_cloud(self, on: bool) -> None:
        """Nav2's particle_cloud is best effort (SensorDataQoS): rosbridge 2.x subscribes to
        it with a matching QoS, so it streams like the laser."""
        await self._stream("/particlecloud", on)

    async def _stream(self, topic: str, on: bool) -> None:
        op, ctl = self._streams.want(topic, on), self._ctl
        if op is not None and ctl is not None:
            with contextlib.suppress(websockets.exceptions.ConnectionClosed):
                await ctl.send(rb.encode(op))
