"""The systemd units in ``deploy/`` do what docs/deploy.md says, as written.

Their command lines are run here with only the machine's paths swapped for a temporary
directory (``/var/lib/serveur``, ``/etc/serveur``, ``/opt/serveur/bin/serveur``) and the
address for loopback: the owner created the documented way before the first start (so no
password is printed into the journal), the server started by ``ExecStart``, the by-hand
backup's command line run against it while it serves (into the folder the server lists),
``KillSignal`` stopping it with exit 0 within ``TimeoutStopSec``, and the documented restore
bringing the backup's data back.
``systemd-analyze verify`` checks the files' syntax and keys where systemd is installed.
"""

from __future__ import annotations

import asyncio
import configparser
import json
import os
import shlex
import shutil
import signal
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from serveur.maps.mapio import demo_map_path, demo_waypoints_path
from tests.subprocess_server import STARTUP, ServeurProcess, free_port, run_cli

DEPLOY = Path(__file__).resolve().parent.parent / "deploy"
BIN = "/opt/serveur/bin/serveur"
UNITS = ("serveur.service", "serveur-backup.service")


def unit(name: str) -> configparser.ConfigParser:
    cp = configparser.ConfigParser(interpolation=None, strict=False, delimiters=("=",))
    cp.optionxform = str  # type: ignore[assignment,method-assign]  # keys are case-sensitive
    cp.read_string((DEPLOY / name).read_text())
    return cp


def local(text: str, tmp: Path, port: int) -> str:
    """A unit's command line with this machine's paths and a loopback address."""
    return (
        text.replace("/var/lib/serveur", str(tmp / "state"))
        .replace("/etc/serveur", str(tmp / "etc"))
        .replace("--host 0.0.0.0", "--host 127.0.0.1")
        .replace("--port 8765", f"--port {port}")
    )


def serveur_argv(command: str) -> list[str]:
    """``ExecStart``'s argv, the installed ``serveur`` replaced by this interpreter's."""
    argv = shlex.split(command)
    assert argv[0] == BIN, f"ExecStart runs {argv[0]}, docs/deploy.md installs {BIN}"
    return [sys.executable, "-m", "serveur.cli", *argv[1:]]


def test_units_are_valid_for_systemd(tmp_path: Path) -> None:
    analyze = shutil.which("systemd-analyze")
    if analyze is None:
        reason = "systemd-analyze not found: Debian's systemd package (.ci/run installs it)"
        if os.environ.get("CI"):
            pytest.fail(f"must run in CI: {reason}", pytrace=False)
        pytest.skip(reason)
    for name in UNITS:
        # verify insists ExecStart's program exists: point it at this interpreter
        (tmp_path / name).write_text((DEPLOY / name).read_text().replace(BIN, sys.executable))
    res = subprocess.run(
        [analyze, "verify", *(str(tmp_path / n) for n in UNITS)],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert res.returncode == 0, res.stderr
    # unknown keys and bad values are only warnings to systemd: none is accepted here
    assert res.stderr.strip() == "", res.stderr


def test_the_service_keeps_its_database_where_it_may_write() -> None:
    svc = unit("serveur.service")["Service"]
    argv = shlex.split(svc["ExecStart"])
    db = argv[argv.index("--db") + 1]
    state = f"/var/lib/{svc['StateDirectory']}/"
    assert db.startswith(state), "ProtectSystem=strict: only the StateDirectory is writable"
    assert svc["WorkingDirectory"] == state.rstrip("/")
    assert svc["KillSignal"] in ("SIGTERM", "SIGINT"), "the signals serveur stops cleanly on"
    backup = shlex.split(unit("serveur-backup.service")["Service"]["ExecStart"])
    assert backup[backup.index("--db") + 1] == db, "the backup copies the service's database"
    # The by-hand backup goes where the server keeps its nightly ones, listed in the console.
    assert backup[backup.index("--into") + 1] == argv[argv.index("--backups") + 1]


async def test_first_start_backup_stop_and_restore_as_documented(tmp_path: Path) -> None:
    port = free_port()
    state, etc = tmp_path / "state", tmp_path / "etc"
    state.mkdir()  # systemd makes the StateDirectory before ExecStart
    etc.mkdir()
    # docs/deploy.md: the map and the waypoints go to /etc/serveur
    shutil.copy(demo_map_path(), etc / "room.yaml")
    shutil.copy(demo_map_path().with_suffix(".pgm"), etc)  # the YAML's image, beside it
    shutil.copy(demo_waypoints_path(), etc / "waypoints.json")
    db = state / "serveur.db"

    # docs/deploy.md, "First start": the owner is made before the service ever runs
    await run_cli(
        "user", "add", "alice", "--role", "owner", "--db", str(db), stdin="a long pass 1\n"
    )

    svc = unit("serveur.service")["Service"]
    service = ServeurProcess(serveur_argv(local(svc["ExecStart"], tmp_path, port)), cwd=state)
    await service.start()
    try:
        await run_cli(
            "user", "add", "bob", "--role", "staff", "--db", str(db), stdin="another one\n"
        )

        # the backup by hand (before an update), its command line as the unit has it
        line = local(unit("serveur-backup.service")["Service"]["ExecStart"], tmp_path, port)
        assert "%" not in line, "a lone % is a systemd specifier: write %% in a unit"
        res = await asyncio.create_subprocess_exec(*serveur_argv(line), cwd=state)
        assert await asyncio.wait_for(res.wait(), STARTUP) == 0
        copies = list((state / "backups").glob("serveur-now-*.db"))
        assert len(copies) == 1, copies
        note = json.loads(copies[0].with_name(copies[0].name + ".json").read_text())
        assert note["check"] == "ok", note  # the console lists it, checked
        with sqlite3.connect(copies[0]) as con:
            assert con.execute("PRAGMA integrity_check").fetchone() == ("ok",)
    finally:
        rc = await service.stop(
            signal.Signals[svc["KillSignal"]], float(svc["TimeoutStopSec"].rstrip("s"))
        )
    journal = "\n".join(service.output)  # all of it: the first-start notice follows "listening"
    assert rc == 0, journal
    assert "First start" not in journal, "a password went to the journal"

    # docs/deploy.md, "Restore": a later change is lost, the backup's data is back
    await run_cli("user", "remove", "bob", "--db", str(db))
    for f in state.glob("serveur.db*"):
        f.unlink()
    shutil.copy(copies[0], db)
    await service.start()
    await service.stop(signal.SIGTERM, 20)
    users = await run_cli("user", "list", "--db", str(db))
    assert "alice\towner" in users and "bob\tstaff" in users, users
