"""The replay's view of the server: one websocket client and the console it keeps up to date.

Split from :mod:`serveur.replay.service` because the replayed staff (:mod:`serveur.replay.staff`)
and guests (:mod:`serveur.replay.guests`) act only through it, exactly as people at a real
restaurant act only through the staff console: they read the robots and trips the server's updates
describe and send protocol instructions. Nothing here knows about policies or carts.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
from collections.abc import Callable
from typing import Any

import websockets
from websockets.asyncio.client import ClientConnection

__all__ = ["WAIT", "Console", "ProtocolClient", "ReplayError"]

WAIT = 60.0  # wall seconds any single protocol round trip may take before the replay gives up


class ReplayError(RuntimeError):
    """The replay could not run (server refused an instruction, robots never came up...).

    ``code`` is the server's error code when the server refused an instruction (``stale``:
    the robot had moved on from the trip or stop the instruction named), else None;
    ``details`` the refusal's details (``unreachable``: the blocked ``table``).
    """

    def __init__(
        self, message: str, code: str | None = None, details: dict[str, Any] | None = None
    ) -> None:
        super().__init__(message)
        self.code = code
        self.details = details or {}


class ProtocolClient:
    """The replay's one websocket connection: request/reply by id, updates to a callback."""

    def __init__(self, ws: ClientConnection, on_update: Callable[[str, Any], None]) -> None:
        self.ws = ws
        self._ids = itertools.count(1)
        self._pending: dict[int, asyncio.Future[dict[str, Any]]] = {}
        self._on_update = on_update
        self._reader = asyncio.create_task(self._read())

    async def _read(self) -> None:
        with contextlib.suppress(websockets.exceptions.ConnectionClosed):
            async for frame in self.ws:
                msg = json.loads(frame)
                if msg["servermsg"] == "update":
                    self._on_update(msg["topic"], msg["data"])
                else:
                    fut = self._pending.pop(msg.get("id"), None)
                    if fut is not None and not fut.done():
                        fut.set_result(msg)

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        rid = next(self._ids)
        fut: asyncio.Future[dict[str, Any]] = asyncio.get_running_loop().create_future()
        self._pending[rid] = fut
        await self.ws.send(json.dumps({"clientmsg": verb, "id": rid, **fields}))
        reply = await asyncio.wait_for(fut, WAIT)
        if reply["servermsg"] != "ok":
            code = reply.get("code")
            raise ReplayError(
                f"{verb} {fields}: {code}: {reply.get('message')}", code, reply.get("details")
            )
        return reply

    async def close(self) -> None:
        await self.ws.close()
        self._reader.cancel()
        with contextlib.suppress(asyncio.CancelledError):
            await self._reader


class Console:
    """What the staff console shows, shared by everyone the replay plays.

    The robots, trips and calls as the server's updates last described them (the service
    fills :attr:`robots`, :attr:`tasks` and :attr:`calls` and sets :attr:`changed` on each
    update), the service's clock (:meth:`now`: seconds since opening, once :attr:`t0` is
    set), the path distances staff know the floor by, and the connection instructions go
    through.
    """

    def __init__(self, clock: Any) -> None:
        self.clock = clock
        self.client: ProtocolClient | None = None
        self.t0 = 0.0
        self.distance: Callable[[str, str], float] = lambda a, b: 0.0
        self.robots: dict[str, dict[str, Any]] = {}
        self.tasks: dict[int, dict[str, Any]] = {}
        self.calls: dict[int, dict[str, Any]] = {}  # guests' calls (with calls on)
        self.changed = asyncio.Event()

    def now(self) -> float:
        return float(self.clock.now()) - self.t0

    async def call(self, verb: str, **fields: Any) -> dict[str, Any]:
        """One instruction over the connection (:meth:`ProtocolClient.call`)."""
        assert self.client is not None
        return await self.client.call(verb, **fields)

    def status_is(self, robot: str, status: str) -> bool:
        return bool(self.robots.get(robot, {}).get("status") == status)

    async def until(self, cond: Callable[[], bool], what: str, wall: float = WAIT) -> None:
        """Wait, ``wall`` seconds at most, for the console to show ``cond``."""

        async def wait() -> None:
            while not cond():
                self.changed.clear()
                await self.changed.wait()

        try:
            await asyncio.wait_for(wait(), wall)
        except TimeoutError:
            raise ReplayError(f"timed out waiting for {what}") from None

    async def settled(self, cond: Callable[[], bool]) -> None:
        """Wait, however long it takes, for the console to show ``cond`` (a service that
        never settles is ended by the service's own limit)."""
        while not cond():
            self.changed.clear()
            await self.changed.wait()
