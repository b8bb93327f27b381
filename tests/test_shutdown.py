"""Graceful shutdown and live backups.

SIGTERM: clients are closed with 1001 (Going Away), the process exits 0, and no robot is left
driving a goal nobody watches; the restarted server sends the robot on with its trip.
``serveur backup``: a consistent, checked copy of a database the server is writing to.
"""

from __future__ import annotations

import asyncio
import signal
import socket
import sqlite3
import sys
import time
from pathlib import Path

from websockets.asyncio.client import connect

from serveur.cli import main
from serveur.clock import ScaledClock
from serveur.maps.mapio import demo_map_path
from serveur.robot_sim import start_simulation
from serveur.robots import rosbridge as rb
from tests import invariants
from tests.conftest import Client, Restaurant, poll_until
from tests.subprocess_server import ServerProcess, close_quietly, staff_client
from tests.test_e2e import activate, near, new_orders, serve_current_stop, staff

TIME_SCALE = 5.0


async def settled_goals(robot_url: str) -> list[rb.GoalStatus]:
    """The robot's goals, as its move_base reports them, once none is pending or active."""
    topic = "/move_base/status"
    async with connect(robot_url) as ws:
        await ws.send(rb.encode(rb.op_subscribe(topic, rb.TOPIC_TYPES[topic])))
        async for frame in ws:
            op = rb.decode(frame)
            if op.get("topic") != topic:
                continue
            goals = [rb.GoalStatus(g["status"]) for g in op["msg"]["status_list"]]
            if goals and all(g in rb.TERMINAL_STATUSES for g in goals):
                return goals
    raise AssertionError("the robot's rosbridge closed")


async def delivering_to_t16(server: ServerProcess) -> tuple[Client, int]:
    """A staff tablet on ``server`` and its one-dish trip to T16, the robot on its way."""
    c = await staff_client(server)
    await c.subscribe("robots", "orders", "tasks", "pose:r1")
    await activate(c, "r1")
    [oid] = await new_orders(c, ("Laksa", "T16"))
    await c.ok("create", type="task", orders=[oid])
    await c.status("r1", "Delivering")
    await c.until(lambda: not near(c.streams["pose:r1"], "home1", 1.0), what="r1 leaves")
    return c, oid


async def test_sigterm_closes_clients_stops_robots_and_restart_resumes(tmp_path: Path) -> None:
    clock = ScaledClock(TIME_SCALE)
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), clock=clock)
    server = ServerProcess(tmp_path / "serveur.db", {"r1": sim.urls[0]}, time_scale=TIME_SCALE)
    try:
        await server.start()
        c, oid = await delivering_to_t16(server)
        robot = sim.robots[0]
        assert any(st is rb.GoalStatus.ACTIVE for _, st, _ in robot.goal_statuses)

        assert await server.terminate() == 0
        await asyncio.wait_for(c._reader, 10)  # the server closed the connection...
        assert c.ws.close_code == 1001  # ...as Going Away
        # The robot was told to stop: its goal is cancelled, not left running unattended.
        statuses = await asyncio.wait_for(settled_goals(sim.urls[0]), 10)
        assert statuses[-1] is rb.GoalStatus.PREEMPTED, statuses
        # What it was doing is still stored: a restarted server resumes the trip.
        row = sqlite3.connect(server.db).execute(
            "SELECT status, current_task FROM robot_info WHERE name = 'r1'"
        )
        assert row.fetchone()[0] == "Delivering"

        await server.start()
        c = await staff_client(server)
        await c.subscribe("robots", "orders", "tasks")
        stop = await serve_current_stop(c, "r1")
        assert stop["table"] == "T16"
        await c.until(lambda: c.order(oid).get("status") == "delivered", what="delivered")
        await c.close()
        assert await server.terminate() == 0
        snap = invariants.read(server.db)
        invariants.check_deliveries(snap)
        assert snap.deliveries[oid] == 1
    finally:
        await close_quietly(server.close, sim.close)


async def test_backup_of_a_live_database(one_robot: Restaurant, tmp_path: Path) -> None:
    """``serveur backup`` while a client keeps creating orders: the copy opens, passes the
    integrity check, and holds a state the server really was in (every order it has was
    created before the backup ended, none created before the backup began is missing)."""
    r = one_robot
    c = await staff(r)
    await activate(c, "r1")
    made: list[int] = []
    enough = asyncio.Event()

    async def writer() -> None:
        n = 0
        while True:
            n += 1
            made.extend(await new_orders(c, (f"dish{n}", f"T{n % 16 + 1}")))
            if len(made) % 3 == 0:
                await c.ok("create", type="task", orders=made[-3:])
            if len(made) >= 30:
                enough.set()

    writing = asyncio.create_task(writer())
    copy = tmp_path / "backups" / "serveur-copy.db"
    copy.parent.mkdir()
    try:
        await asyncio.wait_for(enough.wait(), 30)
        before = set(made)
        rc = await asyncio.to_thread(main, ["backup", str(copy), "--db", str(r.db)])
        after = set(made)
        assert not writing.done() and after > before  # the server was writing throughout
    finally:
        writing.cancel()
    assert rc == 0
    assert await asyncio.to_thread(main, ["check", "--db", str(copy)]) == 0
    snap = invariants.read(copy)
    invariants.check_deliveries(snap)
    assert before <= set(snap.orders) <= after | set(made)
    with sqlite3.connect(copy) as con:
        assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        assert con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
    assert not copy.with_name(copy.name + ".tmp").exists()


async def test_sigterm_stops_the_robot_first_whatever_a_stalled_tablet_does(
    tmp_path: Path,
) -> None:
    """A tablet whose Wi-Fi stalled never answers the closing handshake (websockets waits 10 s
    for it); the robot must be stopped within half a second of SIGTERM all the same."""
    clock = ScaledClock(TIME_SCALE)
    sim = await start_simulation(1, port=0, map_path=demo_map_path(), clock=clock)
    server = ServerProcess(tmp_path / "serveur.db", {"r1": sim.urls[0]}, time_scale=TIME_SCALE)
    stalled = None
    try:
        await server.start()
        await delivering_to_t16(server)
        robot = sim.robots[0]
        # The stalled tablet: connected, then its socket is read no more.
        stalled = await staff_client(server)
        await stalled.subscribe("robots")
        stalled.ws.transport.pause_reading()
        assert server.proc is not None
        server.proc.send_signal(signal.SIGTERM)
        sent = time.monotonic()
        await poll_until(
            lambda: not any(st is rb.GoalStatus.ACTIVE for _, st, _ in robot.goal_statuses),
            10.0,
            "the robot stopped",
        )
        took = time.monotonic() - sent
        assert took <= 0.5 + 0.3, f"robot stopped {took:.2f}s after SIGTERM"
        # The cancel taken (PREEMPTING) ends as PREEMPTED at move_base's next cycle: waited
        # for, not assumed done by now (a loaded machine saw PREEMPTING here).
        await poll_until(
            lambda: robot.goal_statuses[-1][1] is rb.GoalStatus.PREEMPTED, 10.0, "preempted"
        )
        assert await server.stop(signal.SIGTERM, timeout=30.0) == 0
    finally:
        if stalled is not None:
            stalled.ws.transport.abort()
        await close_quietly(server.close, sim.close)


async def test_run_on_a_port_in_use_says_so_and_exits(tmp_path: Path) -> None:
    """Under systemd's Restart=always a hung start is worse than a failed one."""
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        proc = await asyncio.create_subprocess_exec(
            sys.executable,
            "-m",
            "serveur.cli",
            "run",
            "--db",
            str(tmp_path / "serveur.db"),
            "--port",
            str(port),
            stdout=asyncio.subprocess.PIPE,
            stderr=asyncio.subprocess.PIPE,
        )
        try:
            _, err = await asyncio.wait_for(proc.communicate(), 30.0)
        finally:
            if proc.returncode is None:
                proc.kill()
    assert proc.returncode == 1
    text = err.decode()
    assert f"cannot listen on 127.0.0.1:{port}" in text, text
    assert "Traceback" not in text, text
