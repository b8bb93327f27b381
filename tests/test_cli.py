"""The `serveur` command as a user runs it: real subprocesses, real ports."""

from __future__ import annotations

import asyncio
import json
import os
import re
import signal
import sys
import urllib.request
from pathlib import Path

from websockets.asyncio.client import connect

from serveur.cli import main
from tests.subprocess_server import free_port


def test_schema_lists_every_verb(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["schema"]) == 0
    text = capsys.readouterr().out
    schema = json.loads(text)
    for verb in (
        "data",
        "create",
        "control",
        "ready",
        "next",
        "stop",
        "continue",
        "cancel",
        "order",
    ):
        assert f'"{verb}"' in text, verb
    assert {"client", "server"} <= set(schema)


async def read_until(proc: asyncio.subprocess.Process, marker: str, timeout: float = 30) -> str:
    assert proc.stdout is not None
    seen = ""

    async def read() -> str:
        nonlocal seen
        while marker not in seen:
            line = await proc.stdout.readline()  # type: ignore[union-attr]
            if not line:
                raise AssertionError(f"process ended before {marker!r}:\n{seen}")
            seen += line.decode()
        return seen

    return await asyncio.wait_for(read(), timeout)


async def test_demo_runs_the_restaurant_and_stops_on_sigterm(tmp_path: Path) -> None:
    port, sim_port = free_port(), free_port(2)
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "demo",
        "--robots",
        "2",
        "--port",
        str(port),
        "--sim-port",
        str(sim_port),
        "--time-scale",
        "5",
        "--db",
        str(tmp_path / "demo.db"),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        out = await read_until(proc, "Ctrl-C")
        assert f"ws://127.0.0.1:{port}/ws" in out
        assert "robot r1" in out and "robot r2" in out
        # The demo prints its credentials: log in with the staff password it shows.
        password = re.search(r"log in as staff / (\S+)", out)
        assert password, out
        async with connect(f"ws://127.0.0.1:{port}/ws") as ws:
            await ws.send(json.dumps({"clientmsg": "data", "id": 0, "topics": ["robots"]}))
            refused = json.loads(await asyncio.wait_for(ws.recv(), 10))
            assert refused["code"] == "unauthorized"
            login = {"clientmsg": "login", "username": "staff", "password": password[1]}
            await ws.send(json.dumps(login))
            session = json.loads(await asyncio.wait_for(ws.recv(), 10))
            assert session["session"]["role"] == "staff", session
            await ws.send(
                json.dumps({"clientmsg": "data", "id": 1, "topics": ["robots", "waypoints"]})
            )

            async def snapshot() -> dict:  # type: ignore[type-arg]
                while True:
                    msg = json.loads(await ws.recv())
                    if msg.get("id") == 1:
                        return msg  # type: ignore[no-any-return]

            reply = await asyncio.wait_for(snapshot(), 10)
        robots = reply["data"]["robots"]
        assert [r["name"] for r in robots] == ["r1", "r2"]
        assert [r["home"] for r in robots] == ["home1", "home2"]
        tables = [w for w in reply["data"]["waypoints"] if w["kind"] == "table"]
        assert len(tables) >= 12
        # The demo room has a dish return, a charger for each robot, and a call button.
        kinds = {w["name"]: w["kind"] for w in reply["data"]["waypoints"]}
        assert kinds["dish return"] == "dish_return"
        assert [r["dock"] for r in robots] == ["dock1", "dock2"]
        assert kinds["dock1"] == kinds["dock2"] == "dock"
        button = re.search(r"call button of (\S+) .*: GET (\S+)", out)
        assert button, out

        def press() -> tuple[int, bytes]:
            with urllib.request.urlopen(button[2], timeout=10) as resp:
                return resp.status, resp.read()

        status, body = await asyncio.to_thread(press)
        assert status == 200 and body.startswith(f"called: waiter at {button[1]}".encode())
        proc.send_signal(signal.SIGTERM)
        assert await asyncio.wait_for(proc.wait(), 20) == 0
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()


async def test_sim_command_prints_urls_and_stops(tmp_path: Path) -> None:
    port = free_port()
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "sim",
        "--robots",
        "2",
        "--port",
        str(port),
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )
    try:
        out = await read_until(proc, f"ws://127.0.0.1:{port + 1}")
        assert f"ws://127.0.0.1:{port}" in out
        proc.send_signal(signal.SIGINT)
        assert await asyncio.wait_for(proc.wait(), 20) in (0, 130)
    finally:
        if proc.returncode is None:
            proc.kill()
            await proc.wait()


async def _demo(*args: str) -> asyncio.subprocess.Process:
    return await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        "serveur.cli",
        "demo",
        "--robots",
        "1",
        *args,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.STDOUT,
        env={**os.environ, "PYTHONUNBUFFERED": "1"},
    )


async def _stopped(proc: asyncio.subprocess.Process) -> int:
    if proc.returncode is None:
        proc.send_signal(signal.SIGTERM)
    return await asyncio.wait_for(proc.wait(), 20)


async def test_a_second_demo_says_what_is_taken_and_a_demo_database_can_be_reused(
    tmp_path: Path,
) -> None:
    db = str(tmp_path / "demo.db")
    port, sim_port = free_port(), free_port(2)
    first = await _demo("--port", str(port), "--sim-port", str(sim_port), "--db", db)
    procs = [first]
    try:
        await read_until(first, "Ctrl-C")
        # Same robot ports: one clear line, exit 1, no traceback.
        second = await _demo("--port", str(free_port()), "--sim-port", str(sim_port))
        procs.append(second)
        out, _ = await asyncio.wait_for(second.communicate(), 30)
        assert second.returncode == 1, out.decode()
        assert "--sim-port" in out.decode() and "Traceback" not in out.decode(), out.decode()
        # Same server port: the same, naming --port.
        third = await _demo("--port", str(port), "--sim-port", "0")
        procs.append(third)
        out, _ = await asyncio.wait_for(third.communicate(), 30)
        assert third.returncode == 1 and "--port" in out.decode(), out.decode()
        assert "Traceback" not in out.decode(), out.decode()
        assert await _stopped(first) == 0
        # The same database again: the demo accounts get new passwords (before: "user 'owner'
        # already exists").
        again = await _demo("--port", str(port), "--sim-port", "0", "--db", db)
        procs.append(again)
        out_again = await read_until(again, "Ctrl-C")
        assert re.search(r"log in as staff / (\S+)", out_again), out_again
        assert await _stopped(again) == 0
        # Without --db: a temporary database, removed when the demo stops.
        temp = await _demo("--port", str(free_port()), "--sim-port", "0")
        procs.append(temp)
        out_temp = await read_until(temp, "Ctrl-C")
        where = re.search(r"database: (\S+) \(removed", out_temp)
        assert where, out_temp
        folder = Path(where[1]).parent
        assert folder.exists()
        assert await _stopped(temp) == 0
        assert not folder.exists()
    finally:
        for proc in procs:
            if proc.returncode is None:
                proc.kill()
                await proc.wait()
