"""``serveur run`` as a real process, for the tests that signal or kill it.

The simulated robots run in the test's own process (``start_simulation``) so a test can look
at what a robot was told; the server is a separate process so that SIGTERM and SIGKILL hit a
real one. :func:`staff_client` is the one place a test connects to such a server: when
clients must authenticate, it is where the credentials go.
"""

from __future__ import annotations

import asyncio
import collections
import contextlib
import os
import signal
import socket
import sys
from collections.abc import Awaitable, Callable, Sequence
from pathlib import Path

from websockets.asyncio.client import connect

from serveur.mapio import demo_waypoints_path
from tests.conftest import Client

STARTUP = 30.0  # wall seconds for the server to listen (imports dominate; busy CI box)


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


class ServerProcess:
    """One ``serveur run`` on a fixed database and port; start it again after it stopped."""

    def __init__(
        self,
        db: Path,
        robots: dict[str, str],
        *,
        time_scale: float,
        port: int = 0,
        extra: Sequence[str] = (),
    ) -> None:
        self.db = db
        self.extra = list(extra)  # more `serveur run` options, e.g. ["--map", PATH]
        self.port = port or free_port()
        self.time_scale = time_scale
        self.robots = robots  # name -> rosbridge url; homes are home1, home2, ... in order
        self.proc: asyncio.subprocess.Process | None = None
        self.output: collections.deque[str] = collections.deque(maxlen=200)
        self._drain: asyncio.Task[None] | None = None
        self.starts = 0
        self.token = ""  # a staff token, made in the database before the first start

    @property
    def url(self) -> str:
        return f"ws://127.0.0.1:{self.port}/ws"

    def args(self) -> list[str]:
        args = [
            "run",
            "--db",
            str(self.db),
            "--port",
            str(self.port),
            "--waypoints",
            str(demo_waypoints_path()),
            "--time-scale",
            str(self.time_scale),
        ]
        for i, (name, url) in enumerate(self.robots.items()):
            args += ["--robot", f"{name}={url},home=home{i + 1}"]
        return args + self.extra

    async def start(self) -> None:
        """Start the server and return once it listens (its database is open and the robots'
        statuses are reconciled by then: ``Core.start`` runs before the endpoint opens)."""
        assert self.proc is None or self.proc.returncode is not None
        if not self.token:
            self.token = await run_cli("token", "create", "--role", "staff", "--db", str(self.db))
        self.proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "serveur.cli",
            *self.args(),
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.STDOUT,
            env={**os.environ, "PYTHONUNBUFFERED": "1"},
        )
        self.starts += 1
        listening = asyncio.get_running_loop().create_future()
        self._drain = asyncio.create_task(self._read(self.proc, listening))
        try:
            await asyncio.wait_for(asyncio.shield(listening), STARTUP)
        except TimeoutError:
            raise AssertionError("server did not start:\n" + "\n".join(self.output)) from None

    async def _read(
        self, proc: asyncio.subprocess.Process, listening: asyncio.Future[None]
    ) -> None:
        """Keep the pipe drained (a full pipe would block the server's logging)."""
        assert proc.stdout is not None
        while line := await proc.stdout.readline():
            text = line.decode(errors="replace").rstrip()
            self.output.append(text)
            if " listening on " in text and not listening.done():
                listening.set_result(None)
        if not listening.done():
            listening.set_exception(AssertionError("server exited before listening"))
            listening.exception()  # seen: no "never retrieved" warning if nobody waits

    async def kill(self) -> None:
        """SIGKILL: a crash, nothing flushed, nothing closed."""
        await self._stop(signal.SIGKILL)

    async def terminate(self) -> int:
        """SIGTERM: a clean shutdown; the exit code."""
        return await self._stop(signal.SIGTERM)

    async def _stop(self, sig: signal.Signals) -> int:
        proc = self.proc
        assert proc is not None
        if proc.returncode is None:
            proc.send_signal(sig)
        rc = await asyncio.wait_for(proc.wait(), 30)
        if self._drain is not None:
            await self._drain
        return rc

    async def close(self) -> None:
        if self.proc is not None and self.proc.returncode is None:
            await self.kill()


async def run_cli(*args: str, stdin: str = "") -> str:
    """Run ``serveur ARGS`` as the operator would (``stdin`` typed in); its stdout."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        *args,
        stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    out, err = await asyncio.wait_for(proc.communicate(stdin.encode()), STARTUP)
    assert proc.returncode == 0, err.decode()
    return out.decode().strip()


async def staff_client(server: ServerProcess) -> Client:
    """A staff tablet connected to ``server`` with the server's staff token."""
    ws = await connect(
        server.url,
        max_size=2**24,
        open_timeout=STARTUP,
        additional_headers={"Authorization": f"Bearer {server.token}"},
    )
    return Client(ws)


async def close_quietly(*closers: Callable[[], Awaitable[object]]) -> None:
    for close in closers:
        with contextlib.suppress(Exception):
            await close()
