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
import random
import signal
import socket
import sys
from collections.abc import Awaitable, Callable, Sequence
from pathlib import Path

from websockets.asyncio.client import connect

from serveur.maps.mapio import demo_waypoints_path
from tests.conftest import Client

STARTUP = 30.0  # wall seconds for the server to listen (imports dominate; busy CI box)


#: Ports handed to child processes come from below Linux's ephemeral range (32768-60999 by
#: default), which every ``port=0`` socket of the other test workers draws from: a port taken
#: there and released could be any worker's next client socket before the child binds it.
_PORTS = range(10_000, 32_000)


def free_port(count: int = 1) -> int:
    """The first of ``count`` consecutive loopback ports free now (a demo's simulated robots
    listen on ``--sim-port`` and the ports after it), outside the ephemeral range."""
    rng = random.Random()
    for _ in range(200):
        base = rng.randrange(_PORTS.start, _PORTS.stop - count)
        with contextlib.ExitStack() as held:
            try:
                for port in range(base, base + count):
                    s = held.enter_context(socket.socket())
                    s.bind(("127.0.0.1", port))
            except OSError:
                continue
        return base
    raise RuntimeError(f"no {count} free consecutive ports in {_PORTS}")


class ServeurProcess:
    """A command that runs a serveur as a real process (``argv``, in ``cwd``); start it again
    after it stopped. Its output is drained all along into :attr:`output`."""

    def __init__(self, argv: Sequence[str] = (), *, cwd: Path | None = None) -> None:
        self.argv = list(argv)
        self.cwd = cwd
        self.proc: asyncio.subprocess.Process | None = None
        self.output: collections.deque[str] = collections.deque(maxlen=200)
        self._drain: asyncio.Task[None] | None = None
        self.starts = 0

    def command(self) -> list[str]:
        return self.argv

    async def start(self) -> None:
        """Start the process and return once the server prints that it listens."""
        assert self.proc is None or self.proc.returncode is not None
        self.proc = await asyncio.create_subprocess_exec(
            *self.command(),
            cwd=self.cwd,
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
            await self.kill()  # not left running, orphaned, when the test fails here
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
        await self.stop(signal.SIGKILL)

    async def terminate(self) -> int:
        """SIGTERM: a clean shutdown; the exit code."""
        return await self.stop(signal.SIGTERM)

    async def stop(self, sig: signal.Signals, timeout: float = 30.0) -> int:
        """Send ``sig``; the exit code, once the process ended (within ``timeout`` s) and all
        its output is in :attr:`output`."""
        proc = self.proc
        assert proc is not None
        if proc.returncode is None:
            proc.send_signal(sig)
        rc = await asyncio.wait_for(proc.wait(), timeout)
        if self._drain is not None:
            await self._drain
        return rc

    async def close(self) -> None:
        if self.proc is not None and self.proc.returncode is None:
            await self.kill()


class ServerProcess(ServeurProcess):
    """One ``serveur run`` on a fixed database and port, with simulated robots."""

    def __init__(
        self,
        db: Path,
        robots: dict[str, str],
        *,
        time_scale: float,
        port: int = 0,
        extra: Sequence[str] = (),
    ) -> None:
        super().__init__()
        self.db = db
        self.extra = list(extra)  # more `serveur run` options, e.g. ["--map", PATH]
        self.port = port or free_port()
        self.time_scale = time_scale
        self.robots = robots  # name -> rosbridge url; homes are home1, home2, ... in order
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
            # These tests drive whole trips as a script would, without pressing Go.
            "--auto-depart",
        ]
        for i, (name, url) in enumerate(self.robots.items()):
            args += ["--robot", f"{name}={url},home=home{i + 1}"]
        return args + self.extra

    def command(self) -> list[str]:
        return [sys.executable, "-m", "serveur.cli", *self.args()]

    async def start(self) -> None:
        """Start the server and return once it listens (its database is open and the robots'
        statuses are reconciled by then: ``Core.start`` runs before the endpoint opens)."""
        if not self.token:
            self.token = await run_cli("token", "create", "--role", "staff", "--db", str(self.db))
        await super().start()


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
