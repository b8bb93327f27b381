"""The server's rosbridge v2 client to one robot: pose, goals with acknowledgement, reconnect.

A real ROS1 robot (or ``serveur sim``) is driven exactly as RViz and move_base expect: goals on
``/move_base/goal`` with our own ``goal_id``, cancel on ``/move_base/cancel``, teleop on
``/cmd_vel``, calibration on ``/initialpose``.

Two failure modes users of other fleet managers report are designed out here:

* **A goal the robot never confirmed.** Every goal is tracked until its id appears in
  ``/move_base/status``; if it does not within ``ack_timeout`` it is re-sent under a fresh id,
  and after ``ack_retries`` re-sends it is reported lost and cancelled — never left hanging,
  never left driving.
* **A robot silently gone.** move_base publishes its status list at several Hz even when idle,
  so that stream (and AMCL's pose) is the heartbeat: nothing for
  :meth:`RobotLink.heartbeat_timeout` and the link is declared down at once, the socket
  aborted (a dead path never answers a closing handshake, so waiting for one would take
  websockets' 10 s close timeout) and reconnection starts with backoff. The timeout is
  derived from the status rate actually subscribed plus a Wi-Fi stall allowance in wall
  seconds (``stall``), so ordinary restaurant Wi-Fi jitter never takes a robot Offline.

What proves the robot alive, when a goal is unacknowledged or lost, and that a lost goal is
cancelled (``/move_base/cancel`` with its id) are decided by the tracker both drivers share,
:class:`~serveur.robots.liveness.LinkTracker`; this module reads frames into it and carries
out what it says. A goal of an earlier connection is cancelled when the link reconnects.

A dock (:meth:`RobotLink.dock`) is a move_base goal to the dock's pose; undock does nothing.

Goals, cancels and initial poses carry a **zero stamp**. actionlib's SimpleActionServer
cancels (RECALLED) any goal stamped earlier than the last goal it accepted, and a Raspberry Pi
has no hardware clock: stamped with the server's time, every goal after a reboot would be
thrown away whenever the robot had accepted a goal stamped by a clock ahead of ours (its own,
RViz, roslibpy). A zero stamp is stamped by the robot's own clock when the goal arrives
(actionlib's ActionServer), which is what roslibpy and roslibjs send; for ``/initialpose`` and
``target_pose`` a zero stamp asks tf for the latest transform instead of one at a time the
robot may not have.

**Teleop** is a dead man's switch: a joystick sends twists several times a second, and if none
comes for ``teleop_timeout`` wall seconds (the tablet slept, the Wi-Fi went) the link sends a
zero twist itself, because a robot base keeps its last velocity.

The link is "up" only once both a status and a pose have arrived, so the server never acts on
a robot whose position it does not know. Everything the robot sends is treated as untrusted:
malformed frames are logged and dropped, never allowed to kill the link.

A ``wss://`` robot is verified like any TLS server — its certificate must chain to the given
CA (or the system store) and name the URL's host — because whoever answers as the robot gets
to report its position and receive its goals. A robot failing verification stays Offline and
the link keeps retrying (the certificate may be fixed), logging the reason once, not per try.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import logging
import math
import secrets
import ssl as ssl_module
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
from serveur.robots.reconnect import Nap, Reconnecting, open_rosbridge
from serveur.robots.sensor_reports import SensorReports, Streams

__all__ = ["LinkListener", "RobotLink"]

log = logging.getLogger(__name__)

_SUBSCRIPTIONS = ("/move_base/result",)
#: A pose this close (m) to one set by /initialpose is AMCL's answer to it.
RELOCALISED = 0.5
#: /amcl_pose throttle (ms) while nobody watches the robot's pose and it is not moving: the
#: server then only needs to know where the robot stands (a 10 Hz AMCL stream costs ~90 us a
#: message to decode and apply, most of an idle server's CPU with ten robots).
IDLE_POSE_MS = 1000
#: /move_base/status throttle (ms) while the robot has no goal and no joystick command, capped
#: at half the heartbeat: an idle move_base repeats an empty status list 5 times a second, which
#: is only a heartbeat then, and half of those prove life as well (goal acks need the full rate,
#: restored before a goal goes out).
IDLE_STATUS_MS = 500
#: move_base's own status rate (actionlib's status_frequency, 5 Hz): the period assumed when
#: the status subscription is not throttled.
STATUS_PERIOD = 0.2
#: Wall seconds of silence restaurant Wi-Fi may have (a microwave, a roaming tablet, a busy
#: access point) without the robot being declared Offline: measured stalls of 0.5-1.5 s are
#: common on 2.4 GHz, so 2 s keeps a delivery going through them while a robot really gone
#: still shows Offline within about 3 s.
STALL_ALLOWANCE = 2.0
#: Wall seconds without a joystick twist before the server stops the robot itself.
TELEOP_TIMEOUT = 0.5
#: /battery_state throttle floor (ms): staff see whole percent, which takes minutes to change;
#: a robot's 1 Hz battery stream would be a tenth of an idle server's messages for nothing.
BATTERY_MS = 5000
#: actionlib's GoalID with an empty id and a zero stamp: cancel every goal of the server.
_CANCEL_ALL: Mapping[str, Any] = {"stamp": rb.ros_time(0.0), "id": ""}
_PUBLICATIONS = ("/move_base/goal", "/move_base/cancel", "/cmd_vel", "/initialpose")

#: The goal's server, in every goal report (the core shows it as it is).
STACK = "move_base"


class RobotLink(Reconnecting):
    """One ROS1 robot's rosbridge connection, kept up for the life of the server."""

    kind = "ROS1 move_base"
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
        idle_pose_ms: int = IDLE_POSE_MS,
        pose_watched: bool = False,
        moving_pose_ms: int = 0,
        status_ms: int = 0,
        battery_ms: int = 0,
        stall: float = STALL_ALLOWANCE,
        teleop_timeout: float = TELEOP_TIMEOUT,
        names: RosNames | None = None,
    ) -> None:
        self.name = name
        self.url = url
        self._listener = listener
        self._clock = clock
        self._heartbeat = heartbeat
        self._stall = stall
        self._names = names or RosNames()
        self._deadman = DeadManSwitch(name, clock, teleop_timeout, self._deadman_stop)
        self._halted = False  # stopped for shutdown: nothing may move the robot any more
        self._ack_timeout = ack_timeout
        self._ack_retries = ack_retries
        self._want_map = want_map
        self._backoff = (backoff_min, backoff_max)
        self._open_timeout = open_timeout
        # Only for wss:// (websockets refuses a context for ws://); None there means the
        # system trust store, which websockets' own default context uses.
        self._ssl = ssl if url[:6].lower() == "wss://" else None
        self._ws: ClientConnection | None = None
        self._task: asyncio.Task[None] | None = None
        self._seq = itertools.count(1)
        self._token = secrets.token_hex(3)
        # Up once move_base's status and a pose came: the server never acts on a robot whose
        # position it does not know.
        self._track = LinkTracker(
            stack=STACK,
            proofs_words="move_base status",
            required=frozenset({"status", "pose"}),
            paced="status",
            ack_timeout=ack_timeout,
            ack_retries=ack_retries,
            new_id=self._new_goal_id,
        )
        self._sensors = SensorReports(name, listener, self._names, clock)
        self._streams = Streams(
            lambda topic, ms: self._sub(topic, throttle_rate=ms),
            lambda topic: rb.op_unsubscribe(self._t(topic)),
        )
        # Throttles (ms, robot clock) that accelerated replays raise to cut rosbridge traffic:
        # the pose of an unwatched moving robot, move_base status (heartbeat, goal acks;
        # terminal goal states come unthrottled on /move_base/result) and the battery.
        # 0: every message.
        self._idle_pose_ms = max(idle_pose_ms, moving_pose_ms)
        self._moving_pose_ms = moving_pose_ms
        self._status_ms = status_ms
        self._battery_ms = max(battery_ms, BATTERY_MS)
        self._pose_watched = pose_watched
        self._pose_ms: int | None = None  # the throttle of our /amcl_pose subscription
        #: (x, y, clock time) of an /initialpose sent: /amcl_pose at full rate until it shows.
        self._relocalising: tuple[float, float, float] | None = None
        self._idle_status_ms = max(status_ms, min(IDLE_STATUS_MS, int(heartbeat * 500)))
        self._status_sub_ms: int | None = None  # ... and of our /move_base/status one
        self._jobs: set[asyncio.Task[None]] = set()
        self._nap = Nap()  # the watchdog's, while nothing can be judged for a while
        self.connects = 0
        #: Why the last attempt to connect failed ("" once connected): for the console.
        self.last_failure = ""

    # -- lifecycle ---------------------------------------------------------------------------

    @property
    def up(self) -> bool:
        return self._track.up

    @property
    def pose(self) -> tuple[float, float, float] | None:
        return self._sensors.pose

    @property
    def battery(self) -> float | None:
        return self._sensors.battery

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
        if self._ws is not None:
            await self._ws.close()
            self._ws = None

    async def drop(self) -> None:
        """Close the socket as if the network failed (the link reconnects by itself)."""
        if self._ws is not None:
            await self._ws.close(code=1001, reason="dropped")

    @contextlib.asynccontextmanager
    async def _open(self) -> AsyncIterator[None]:
        async with open_rosbridge(self.url, ssl=self._ssl, open_timeout=self._open_timeout) as ws:
            self._ws = ws
            yield

    async def _serve(self) -> None:
        assert self._ws is not None
        await self._session(self._ws)

    def _closed(self) -> None:
        self._ws = None

    def _connect_failed(self, reason: str) -> str:
        return connect_failed(self, self._listener, reason, log)

    async def _session(self, ws: ClientConnection) -> None:
        stale = self._track.start(self._clock.now())
        for topic in _PUBLICATIONS:
            await ws.send(rb.encode(rb.op_advertise(self._t(topic), rb.TOPIC_TYPES[topic])))
        await self._carry_out(stale)  # goals of the last connection, before anything moves
        for topic in _SUBSCRIPTIONS:
            await ws.send(rb.encode(self._sub(topic)))
        await ws.send(rb.encode(self._sub("/battery_state", throttle_rate=self._battery_ms)))
        self._pose_ms = self._status_sub_ms = None
        await self._update_rates(ws)
        if self._want_map:
            await ws.send(rb.encode(self._sub("/map")))
        for op in self._streams.resubscribe():
            await ws.send(rb.encode(op))
        if self._names.tf_base:
            for topic in self._sensors.pose_topics():
                await ws.send(rb.encode(self._sub(topic)))
        watchdog = asyncio.create_task(self._watchdog(ws), name=f"watchdog-{self.name}")
        try:
            async for frame in ws:
                self._handle(frame)
        except websockets.exceptions.ConnectionClosed:
            pass
        finally:
            watchdog.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await watchdog

    async def _watchdog(self, ws: ClientConnection) -> None:
        while True:
            timeout = self.heartbeat_timeout()
            # Judged an eighth of a timeout after it could first say something: a silent
            # robot is Offline at most an eighth late; a goal's ack every eighth of the ack
            # timeout. With no goal, nothing can be said before the silence limit, so the
            # watchdog naps until then (a parked robot's link wakes every few seconds, not 8
            # times per timeout); a goal sent or a faster heartbeat wakes it (``_nap``).
            tick = min(timeout, self._ack_timeout) / 8 if self._track.goal else timeout / 8
            now = self._clock.now()
            quiet = self._track.quiet_until(timeout)
            wait = tick if quiet is None else max(tick, quiet - now)
            due = now + wait
            if wait > tick:
                await self._nap.sleep(self._clock, wait)
            else:
                await self._clock.sleep(tick)
            now = self._clock.now()
            if now - due > tick:
                # Our own event loop was starved: the robot's status frames may be sitting
                # unread in the socket. Judge the robot on the next, timely tick instead.
                continue
            todo = self._track.check(now, timeout, self.pose)
            await self._carry_out(todo)
            if any(isinstance(act, LinkDown) for act in todo):
                return

    def heartbeat_timeout(self) -> float:
        """Seconds (clock) of status silence after which the robot is declared Offline.

        Two periods of the status stream as subscribed (a throttled stream arrives once per
        throttle; an unthrottled one at move_base's 5 Hz), plus the Wi-Fi stall allowance,
        which is wall time and so scaled to the clock; never less than ``heartbeat``.
        """
        period = max((self._status_sub_ms or 0) / 1000.0, STATUS_PERIOD)
        stall = self._stall * self._clock.time_scale
        return max(self._heartbeat, 2.0 * period + stall)

    async def _perform(self, todo: list[Instruction]) -> None:
        """Cancels and re-sends go out even while the link is coming down (best effort: a
        dead path loses them); a :class:`LinkDown` aborts the socket."""
        ws = self._ws
        if ws is None:
            return
        for act in todo:
            with contextlib.suppress(websockets.exceptions.ConnectionClosed):
                if isinstance(act, Cancel):
                    for gid in act.ids:
                        cancel = {"stamp": rb.ros_time(0.0), "id": gid}
                        await ws.send(rb.encode(self._pub("/move_base/cancel", cancel)))
                elif isinstance(act, SendGoal):
                    log.warning("%s: goal not acknowledged, re-sent as %s", self.name, act.goal.id)
                    msg = self._goal_msg(act.goal)
                    await ws.send(rb.encode(self._pub("/move_base/goal", msg)))
            if isinstance(act, LinkDown):
                # Down now, not after a closing handshake a dead path will never answer.
                ws.transport.abort()

    # -- incoming ----------------------------------------------------------------------------

    def _handle(self, frame: str | bytes) -> None:
        try:
            op = rb.decode(frame)
            if op["op"] == "publish":
                topic = str(op.get("topic"))
                self._on_publish(self._names.default_of(topic) or topic, op.get("msg"))
            elif op["op"] == "status":
                log.info("%s: rosbridge says %s: %s", self.name, op.get("level"), op.get("msg"))
        except rb.MALFORMED as exc:
            log.warning("%s: dropped malformed frame from robot: %s", self.name, exc)
        except Exception:
            # Nothing a robot sends may kill its link: whatever this frame broke, the next
            # frame is read, and the heartbeat still judges whether the robot is alive.
            log.exception("%s: error handling a frame from the robot (dropped)", self.name)

    def _on_publish(self, topic: str, msg: Any) -> None:
        if not isinstance(msg, dict):
            raise RosbridgeError(f"{topic}: msg is not an object")
        if topic == "/move_base/status":
            self._on_status(msg)
        elif topic == "/move_base/result":
            st = msg["status"]
            self._apply(self._goal_state(st))
        elif self._sensors.handles(topic):
            proof = self._sensors.on_publish(topic, msg)
            if proof == "pose":
                self._relocalised()
                # A throttled /amcl_pose comes through a queue (see _update_rates): late.
                fresh = not self._pose_ms or bool(self._names.tf_base)
                self._apply(self._track.proof(self._clock.now(), "pose", fresh=fresh))

    def _relocalised(self) -> None:
        """A pose came: if it shows the pose set by :meth:`initial_pose` (or a second has
        passed), AMCL took it (or will not): back to the idle rates."""
        set_at, pose = self._relocalising, self._sensors.pose
        if (
            set_at is not None
            and pose is not None
            and (
                math.hypot(pose[0] - set_at[0], pose[1] - set_at[1]) < RELOCALISED
                or self._clock.now() - set_at[2] > 1.0
            )
        ):
            self._relocalising = None
            self._rates_changed()

    def _on_status(self, msg: Mapping[str, Any]) -> None:
        todo: list[Instruction] = []
        for st in msg["status_list"]:
            todo += self._goal_state(st)
        todo += self._track.proof(self._clock.now(), "status")
        self._apply(todo)

    def _goal_state(self, st: Mapping[str, Any]) -> list[Instruction]:
        """One actionlib GoalStatus: its end, if it is our goal's, in move_base's words."""
        status = rb.GoalStatus(int(st["status"]))
        text = str(st.get("text", ""))
        words = f"{STACK} {status.name}: {text}" if text else f"{STACK} {status.name}"
        return self._track.goal_state(str(st["goal_id"]["id"]), status, words)

    # -- outgoing ----------------------------------------------------------------------------

    # -- this robot's names ------------------------------------------------------------------

    def _t(self, default: str) -> str:
        """The robot's own name for a default topic name (namespaced, renamed)."""
        return self._names.topic(default)

    def _pub(self, default: str, msg: Mapping[str, Any]) -> dict[str, Any]:
        return rb.op_publish(self._t(default), msg)

    def _sub(
        self, default: str, *, throttle_rate: int = 0, queue_length: int = 0
    ) -> dict[str, Any]:
        return rb.op_subscribe(
            self._t(default),
            rb.TOPIC_TYPES[default],
            throttle_rate=throttle_rate,
            queue_length=queue_length,
        )

    def _goal_msg(self, goal: TrackedGoal) -> dict[str, Any]:
        # Zero stamps: see the module's docstring (SimpleActionServer's stamp rule).
        return rb.move_base_action_goal(
            goal.id, goal.x, goal.y, goal.yaw, stamp=0.0, frame_id=self._names.frame
        )

    async def halt(self) -> None:
        """Stop the robot for good (shutdown): cancel every goal, send a zero twist.

        After this the link refuses every goal, joystick and pose command, so no report or
        client still being handled while the server shuts down can set the robot moving.
        """
        self._halted = True
        self._track.cancelled()
        self._deadman.release()
        with contextlib.suppress(LinkError):
            await self._send(self._pub("/move_base/cancel", _CANCEL_ALL), halting=True)
            await self._send(self._pub("/cmd_vel", rb.twist(0.0, 0.0, 0.0)), halting=True)

    async def _send(self, op: Mapping[str, Any], *, halting: bool = False) -> None:
        if self._halted and not halting:
            raise LinkError(f"robot {self.name} is stopped: the server is shutting down")
        ws = self._ws
        if ws is None or not self._track.up:
            raise LinkError(f"robot {self.name} is not connected")
        try:
            await ws.send(rb.encode(op))
        except websockets.exceptions.ConnectionClosed as exc:
            raise LinkError(f"robot {self.name}: connection lost while sending") from exc

    def _new_goal_id(self) -> str:
        return f"serveur-{self.name}-{self._token}-{next(self._seq)}"

    @property
    def goal_id(self) -> str | None:
        goal = self._track.goal
        return goal.handle if goal else None

    async def send_goal(self, x: float, y: float, yaw: float) -> str:
        """Send a move_base goal; its fate arrives as ``goal_done`` or ``goal_lost``.

        Returns the goal's handle: re-sends go out under fresh ids, reports use the handle.
        A new goal preempts the one under way on move_base's side (SimpleActionServer).
        """
        goal, _ = self._track.new_goal(self._clock.now(), x, y, yaw)
        self._nap.wake()  # its acknowledgement is judged from now on
        await self._update_rates()  # full rates before the robot starts to move
        await self._send(self._pub("/move_base/goal", self._goal_msg(goal)))
        return goal.handle

    async def dock(self, x: float, y: float, yaw: float, dock_id: str) -> str:
        """A ROS1 robot has no docking server serveur knows (opennav_docking is ROS 2's): a
        dock is a move_base goal to the dock's pose, reported as any goal."""
        return await self.send_goal(x, y, yaw)

    async def undock(self) -> None:
        """Nothing to do: move_base drives the robot off its dock with the next goal."""

    async def cancel_goal(self) -> None:
        """Cancel every goal on the robot (empty id), as a stop button must."""
        self._track.cancelled()
        await self._send(self._pub("/move_base/cancel", _CANCEL_ALL))
        self._rates_changed()

    async def teleop(self, vx: float, vy: float, wz: float) -> None:
        """Send a joystick twist; with none after it for ``teleop_timeout``, a zero twist.

        move_base does not listen to ``/cmd_vel`` (its controller drives the base while a goal
        is active), so callers cancel a goal before steering by hand.
        """
        self._deadman.twist((vx, vy, wz) != (0.0, 0.0, 0.0))
        await self._update_rates()
        await self._send(self._pub("/cmd_vel", rb.twist(vx, vy, wz)))

    async def _deadman_stop(self) -> None:
        with contextlib.suppress(LinkError):
            await self._send(self._pub("/cmd_vel", rb.twist(0.0, 0.0, 0.0)))
        await self._update_rates()

    async def initial_pose(self, x: float, y: float, yaw: float) -> None:
        """Set the robot's pose. AMCL answers with one pose (it publishes only on motion
        otherwise), which a throttled /amcl_pose subscription would drop, not delay, if it came
        within the throttle of the last one (rosbridge's throttle): so /amcl_pose streams at
        full rate from now until a pose near the one set (or a second later) has come."""
        self._relocalising = (x, y, self._clock.now())
        await self._update_rates()
        await self._send(
            self._pub(
                "/initialpose",
                rb.pose_with_covariance_stamped(x, y, yaw, stamp=0.0, frame_id=self._names.frame),
            )
        )

    async def want_pose(self, on: bool) -> None:
        """Someone watches this robot's pose (full AMCL rate) or nobody does any more."""
        self._pose_watched = on
        await self._update_rates()

    def _moving(self) -> bool:
        return self._track.goal is not None or self._deadman.held

    def _pose_throttle(self) -> int:
        """Full rate while watched or moving (arrival checks need a fresh pose), else idle."""
        if self._pose_watched or self._relocalising is not None:
            return 0
        return self._moving_pose_ms if self._moving() else self._idle_pose_ms

    def _status_throttle(self) -> int:
        """Full rate while a goal needs its ack and end (or teleop), else heartbeat only."""
        return self._status_ms if self._moving() else self._idle_status_ms

    def _decided(self) -> None:
        self._rates_changed()

    def _rates_changed(self) -> None:
        """From a synchronous callback (a goal ended): re-subscribe soon if a rate changed."""
        stale = (
            self._pose_throttle() != self._pose_ms or self._status_throttle() != self._status_sub_ms
        )
        if self._ws is not None and stale:
            self._spawn(self._update_rates())

    async def _update_rates(self, ws: ClientConnection | None = None) -> None:
        """(Re-)subscribe /amcl_pose and /move_base/status at the wanted throttles; rosbridge
        replaces a client's earlier subscription to the same topic."""
        ws = ws or self._ws
        if ws is None:
            return
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            rates = [("/move_base/status", self._status_throttle(), "_status_sub_ms")]
            if not self._names.tf_base:  # a pose from tf: /tf is not throttled (see sensors)
                rates.append(("/amcl_pose", self._pose_throttle(), "_pose_ms"))
            for topic, ms, attr in rates:
                if getattr(self, attr) != ms:
                    setattr(self, attr, ms)
                    self._nap.wake()  # the heartbeat timeout follows the status rate
                    # A queue of one: rosbridge then delays a pose that comes within the
                    # throttle of the last instead of dropping it — AMCL publishes only after
                    # motion, so a dropped pose (a robot that just lost its localisation, or
                    # was set elsewhere) would not come again until the robot moves.
                    queue = 1 if topic == "/amcl_pose" and ms else 0
                    await ws.send(rb.encode(self._sub(topic, throttle_rate=ms, queue_length=queue)))

    async def want_scan(self, on: bool) -> None:
        """Stream /scan only while someone looks at it (it is the heaviest topic)."""
        await self._stream("/scan", on)

    async def want_cloud(self, on: bool) -> None:
        """Stream AMCL's particle cloud only while someone looks at it."""
        await self._stream("/particlecloud", on)

    async def _stream(self, topic: str, on: bool) -> None:
        op = self._streams.want(topic, on)
        if op is not None and self._ws is not None:
            with contextlib.suppress(websockets.exceptions.ConnectionClosed):
                await self._ws.send(rb.encode(op))
