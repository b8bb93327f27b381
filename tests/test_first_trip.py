"""The README's first trip, as a newcomer runs it: ``serveur demo --robots 1`` as a real process,
the README's JSON lines sent as they are, then ``examples/first_trip.py`` as a real process.

One demo for both (its start plans the paths between the tables: the slow part). On its fresh
database the README's lines come first (the robot Ready, the order numbered 1, as the README
says); the robot is then handed back (``ready``) and the example runs from Ready as well.
Nothing sleeps: each wait is on the demo's output or the server's updates, with a timeout.
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import os
import re
import signal
import sys
from collections.abc import AsyncIterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from tests.conftest import WAIT, Client
from tests.subprocess_server import free_port

ROOT = Path(__file__).resolve().parents[1]
EXAMPLE = ROOT / "examples" / "first_trip.py"
TIME_SCALE = "10"  # the README says 5; 10 keeps the test short, as the other tests run


@dataclass
class Demo:
    """A running ``serveur demo``; its output drained all along (a full pipe would block it)."""

    proc: asyncio.subprocess.Process
    url: str
    output: list[str] = field(default_factory=list)
    ready: asyncio.Event = field(default_factory=asyncio.Event)

    async def drain(self) -> None:
        assert self.proc.stdout is not None
        while line := await self.proc.stdout.readline():
            self.output.append(line.decode(errors="replace").rstrip())
            if "Ctrl-C stops everything" in self.output[-1]:
                self.ready.set()
        self.ready.set()  # ended: whoever waits sees it has no password

    def staff_password(self) -> str:
        found = re.search(r"log in as staff / (\S+)", "\n".join(self.output))
        assert found, "\n".join(self.output)
        return found[1]


@contextlib.asynccontextmanager
async def demo() -> AsyncIterator[Demo]:
    """``serveur demo --robots 1`` on free ports and a temporary database, as the README
    starts it; stopped with SIGTERM at the end, which it must survive cleanly (exit 0)."""
    port = free_port()
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "demo",
        "--robots",
        "1",
        "--time-scale",
        TIME_SCALE,
        "--port",
        str(port),
        "--sim-port",
        "0",
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    d = Demo(proc, f"ws://127.0.0.1:{port}/ws")
    drain = asyncio.create_task(d.drain())
    try:
        await asyncio.wait_for(d.ready.wait(), WAIT)
        yield d
        proc.send_signal(signal.SIGTERM)
        assert await asyncio.wait_for(proc.wait(), WAIT) == 0, "\n".join(d.output)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()
        await drain


def readme_lines() -> list[str]:
    """The JSON lines of the README's "Talking to it", as a reader pastes them."""
    section = (ROOT / "README.md").read_text().split("\n## Talking to it\n", 1)[1]
    block = section.split("```json\n", 1)[1].split("```", 1)[0]
    return [line for line in block.splitlines() if line.strip()]


async def reply(c: Client, rid: Any) -> dict[str, Any]:
    def found() -> dict[str, Any] | None:
        replies = (f for f in c.frames if f["servermsg"] != "update")
        return next((f for f in replies if f.get("id") == rid), None)

    msg: dict[str, Any] = await c.until(found, WAIT, f"the reply to request {rid}")
    return msg


async def delivered(url: str, password: str, table: str) -> dict[int, dict[str, Any]]:
    """The table's dishes on the way or delivered, as the server tells a new staff tablet."""
    c = Client(await connect(url))
    try:
        await c.ok("login", username="staff", password=password)
        return {o["id"]: o for o in (await c.ok("order", table=table))["orders"]}
    finally:
        await c.close()


async def test_the_readme_messages_and_the_example_make_a_whole_trip() -> None:
    lines = readme_lines()
    verbs = [json.loads(line)["clientmsg"] for line in lines]
    assert verbs == ["login", "data", "control", "create", "create", "go", "next"], verbs
    async with demo() as d:
        password = d.staff_password()

        # The README's lines, as they are (the password filled in), each when the README says.
        c = Client(await connect(d.url))
        try:
            for line in lines:
                msg = json.loads(line)
                if msg["clientmsg"] == "control":
                    await c.status("r1", "Ready")  # "the reply lists the robots, r1 Ready"
                elif msg["clientmsg"] == "go":
                    await c.status("r1", "Loading")
                elif msg["clientmsg"] == "next":
                    await c.status("r1", "Delivered")
                await c.ws.send(line.replace("PASSWORD", password))
                answer = await reply(c, msg["id"])
                assert answer["servermsg"] == "ok", (line, answer)
                if msg["clientmsg"] == "create" and msg["type"] == "order":
                    assert answer["order"]["id"] == 1, answer  # "1 on a fresh demo"
            await c.status("r1", "Awaiting")
            # Back to Ready, as a fresh demo has it, for the example.
            await c.ok("ready", robot="r1")
            await c.status("r1", "Ready")
        finally:
            await c.close()
        assert delivered_ok(await delivered(d.url, password, "T3"), 1)

        # The example, as the README runs it (--url: this demo's port).
        text = await run_example("--url", d.url, "--password", password)
        for step in (
            "logged in as staff (staff)",
            "r1 is in automatic mode",
            "order 2: Laksa for T3, ready at the pass",
            "r1 is Loading at the pass",
            "r1 is Delivering to T3",
            "r1 is at T3: Delivered",
            "food collected; r1 goes home (Transit)",
            "r1 is home, Awaiting orders; order 2 is delivered",
        ):
            assert step in text, (step, text)
        # The server agrees: the example's dish reached T3 and was taken there.
        assert delivered_ok(await delivered(d.url, password, "T3"), 2)


async def run_example(*args: str) -> str:
    """Run examples/first_trip.py; its output, once it exited 0 (it fails the test otherwise,
    or if it is still running after 2 * WAIT s, with what it printed so far)."""
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        str(EXAMPLE),
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
    )
    assert proc.stdout is not None
    lines: list[str] = []

    async def read() -> None:
        assert proc.stdout is not None
        while line := await proc.stdout.readline():
            lines.append(line.decode(errors="replace"))

    reader = asyncio.create_task(read())
    try:
        await asyncio.wait_for(proc.wait(), 2 * WAIT)
    except TimeoutError:
        proc.kill()
        await proc.wait()
        raise AssertionError("the example is stuck; it printed:\n" + "".join(lines)) from None
    finally:
        await reader
    assert proc.returncode == 0, "".join(lines)
    return "".join(lines)


def delivered_ok(orders: dict[int, dict[str, Any]], oid: int) -> bool:
    order = orders.get(oid, {})
    assert order.get("dish") == "Laksa" and order.get("status") == "delivered", orders
    assert order["delivered_at"] is not None and order["task_id"] is not None, order
    return True
