"""Keeping a robot's rosbridge connections up: the one reconnect loop every driver runs.

A robot's link lives as long as the server: connect, run the session until the connection
drops, say why (once per distinct reason: :func:`~serveur.robots.driver.connect_failed`), wait
with exponential backoff, connect again. The ROS1 driver holds one connection and the ROS 2
driver two (goals on their own, so Humble's blocked queue never delays a Stop); everything
else about reconnecting is the same, so it is written once here and each driver says only how
it opens its connections and what its session does. What a driver's tracker
(:mod:`serveur.robots.liveness`) decides is reported the same way too: :func:`announce`.

A TLS failure is reported as such: retrying will not help until someone fixes a certificate or
``--robot-cafile``, and staff must read that, not "connection refused".
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import ssl as ssl_module
from collections.abc import Coroutine
from contextlib import AbstractAsyncContextManager
from typing import Any

import websockets
from websockets.asyncio.client import connect

from serveur.clock import Clock
from serveur.robots.driver import LinkListener
from serveur.robots.liveness import (
    GoalDone,
    GoalLost,
    Instruction,
    LinkDown,
    LinkTracker,
    LinkUp,
)

__all__ = ["Nap", "Reconnecting", "announce", "open_rosbridge"]


def open_rosbridge(url: str, *, ssl: ssl_module.SSLContext | None, open_timeout: float) -> Any:
    """One websocket to a rosbridge server, as every driver opens it: no websocket pings (the
    driver's own heartbeat, over ROS, is the one that matters), no compression (rosbridge does
    not negotiate it), frames up to 16 MiB (a map)."""
    tls: dict[str, Any] = {"ssl": ssl} if ssl is not None else {}
    return connect(
        url,
        open_timeout=open_timeout,
        close_timeout=1.0,
        max_size=16 * 2**20,
        ping_interval=None,
        compression=None,
        **tls,
    )


class Nap:
    """A watchdog's sleep that may be cut short.

    A parked robot's link has nothing to judge until its silence could first exceed the
    heartbeat timeout, seconds away: polling it eight times per timeout woke an idle server
    27 times a second for ten robots. So the watchdog sleeps until then, and whatever changes
    the terms meanwhile (a goal sent, whose acknowledgement is due sooner; a heartbeat timeout
    shortened by a faster status subscription) wakes it (:meth:`wake`) to judge on the new ones.
    """

    def __init__(self) -> None:
        self._alarm: asyncio.Future[None] | None = None

    async def sleep(self, clock: Clock, seconds: float) -> None:
        """``clock.sleep(seconds)``, or less if :meth:`wake` is called meanwhile."""
        alarm = self._alarm = asyncio.get_running_loop().create_future()
        sleeper = asyncio.ensure_future(clock.sleep(seconds))
        try:
            await asyncio.wait((sleeper, alarm), return_when=asyncio.FIRST_COMPLETED)
        finally:
            self._alarm = None
            sleeper.cancel()

    def wake(self) -> None:
        """End the nap under way, if any (a no-op otherwise)."""
        alarm = self._alarm
        if alarm is not None and not alarm.done():
            alarm.set_result(None)


class Reconnecting:
    """The reconnect loop of a driver and the carrying out of its tracker's decisions; the
    driver provides its connections (the first methods below) and how it sends
    (:meth:`_perform`).

    ``last_failure`` is cleared when the robot comes up (:meth:`_announce`), not when a
    connection opens: a robot whose bridge accepts connections but which never comes up (its
    ROS side stopped, its navigator not active) is a failure to connect too, said once.
    """

    name: str
    url: str
    kind: str
    _listener: LinkListener
    _track: LinkTracker
    _jobs: set[asyncio.Task[None]]
    _backoff: tuple[float, float]
    connects: int
    last_failure: str
    #: The driver's own logger (what it reports is logged under its name).
    _log: logging.Logger

    def _open(self) -> AbstractAsyncContextManager[None]:
        """Open the robot's connections and keep them on the driver until the block exits."""
        raise NotImplementedError

    async def _serve(self) -> None:
        """The session on the open connections; returns when they close."""
        raise NotImplementedError

    def _closed(self) -> None:
        """Forget the connections (they are closed)."""
        raise NotImplementedError

    def _connect_failed(self, reason: str) -> str:
        raise NotImplementedError

    async def _perform(self, todo: list[Instruction]) -> None:
        """Send what the tracker said to send (cancels, re-sends) on the driver's connections,
        best effort; abort them on a :class:`LinkDown`."""
        raise NotImplementedError

    def _decided(self) -> None:
        """The tracker decided something (a goal ended...): the driver may adjust (rates)."""

    def _set_down(self, reason: str) -> None:
        """The connections closed (or the server stops): the link is down, said if it was up."""
        was_up = self._track.up
        self._track.link_lost()
        if was_up:
            self._log.warning("%s: link down (%s)", self.name, reason)
            self._listener.link_down(self.name, reason)

    def _apply(self, todo: list[Instruction]) -> None:
        """What a frame made the tracker decide: reports now, sends soon (on the loop)."""
        rest = [act for act in todo if not self._announce(act)]
        if rest:
            self._spawn(self._perform(rest))
        if todo:
            self._decided()

    async def _carry_out(self, todo: list[Instruction]) -> None:
        """Do what the tracker said, in order: reports, and sends awaited."""
        for act in todo:
            if not self._announce(act):
                await self._perform([act])
        self._decided()

    def _spawn(self, job: Coroutine[Any, Any, None]) -> None:
        with contextlib.suppress(RuntimeError):  # no running loop: nothing to send on
            task = asyncio.get_running_loop().create_task(job)
            self._jobs.add(task)  # the loop keeps only a weak reference
            task.add_done_callback(self._jobs.discard)

    async def _run(self) -> None:
        delay = self._backoff[0]
        while True:
            try:
                async with self._open():
                    self.connects += 1
                    delay = self._backoff[0]
                    await self._serve()
                    reason = "connection closed"
            except asyncio.CancelledError:
                self._set_down("server shutting down")
                raise
            except ssl_module.SSLError as exc:
                reason = self._connect_failed(f"TLS: {exc}")
            except (OSError, TimeoutError, websockets.exceptions.WebSocketException) as exc:
                # A wrong address or a robot switched off.
                reason = self._connect_failed(f"{type(exc).__name__}: {exc}")
            finally:
                self._closed()
            self._set_down(reason)
            await asyncio.sleep(delay)
            delay = min(delay * 2, self._backoff[1])

    def _announce(self, act: Instruction) -> bool:
        """:func:`announce` for this driver; a session that never came up is a failure to
        connect, said to the listener once per distinct reason in a row."""
        if isinstance(act, LinkUp):
            self.last_failure = ""
        elif isinstance(act, LinkDown) and not act.report:
            self._connect_failed(f"the robot never came up: {act.summary}")
        return announce(self._listener, self.name, act, self._log, f"{self.url}, {self.kind}")


def announce(
    listener: LinkListener, robot: str, act: Instruction, log: logging.Logger, where: str
) -> bool:
    """Say what a tracker instruction reports (link up or down, a goal done or lost) to the
    listener and the driver's ``log``; False for the instructions the driver carries out
    itself (sends, cancels; aborting its connections after a :class:`LinkDown`)."""
    if isinstance(act, LinkUp):
        log.info("%s: link up (%s)", robot, where)
        listener.link_up(robot)
    elif isinstance(act, LinkDown):
        if act.report:
            log.warning("%s: link down (%s)", robot, act.reason)
            listener.link_down(robot, act.reason)
        return False
    elif isinstance(act, GoalDone):
        listener.goal_done(robot, act.handle, act.status, act.text)
    elif isinstance(act, GoalLost):
        log.warning("%s: goal %s lost (%s): %s", robot, act.handle, act.cause.value, act.reason)
        listener.goal_lost(robot, act.handle, act.reason, cause=act.cause)
    else:
        return False
    return True
