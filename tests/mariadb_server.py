"""A private MariaDB server for the tests: Debian's ``mariadbd`` on a free port and a data
directory under pytest's temp folder, started once per session and stopped at its end.

Nothing touches the machine's own MariaDB (if any): ``--no-defaults`` ignores /etc/mysql, the
socket, pid file and data live in the temp folder, and it listens on 127.0.0.1 only. The
tests connect as ``serveur_test``, a user with exactly the rights docs/mariadb.md asks for, on
databases named ``serveur_t...`` (one fresh database per test); root, over the private socket,
only creates those databases and does what a DBA would (break a foreign key, pull the plug).

In CI (``$CI`` set) a missing ``mariadbd`` fails the tests instead of skipping them: the
backend must not go untested because an install step broke.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import os
import shutil
import signal
import socket
import subprocess
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import pytest

__all__ = ["MariaDBServer", "mariadb_server", "mariadb_url", "query"]

USER = "serveur_test"
PASSWORD = "test-Pa55;word"  # a ';' and a '-' on purpose: URLs and the client must cope
START_TIMEOUT = 30.0
# What docs/mariadb.md grants the serveur user; the tests run with no more than that.
GRANTS = "SELECT, INSERT, UPDATE, DELETE, CREATE, ALTER, INDEX, CREATE VIEW"


def _binary(name: str) -> str | None:
    return shutil.which(name) or next(
        (p for d in ("/usr/sbin", "/usr/bin") if os.access(p := f"{d}/{name}", os.X_OK)), None
    )


def _free_port() -> int:
    from tests.subprocess_server import free_port

    return free_port()


@dataclass
class MariaDBServer:
    """One ``mariadbd`` process; :meth:`restart` keeps its data, port and users."""

    base: Path
    port: int = field(default_factory=_free_port)
    proc: subprocess.Popen[bytes] | None = None
    _names: Iterator[int] = field(default_factory=lambda: itertools.count(1))

    @property
    def socket(self) -> str:
        return str(self.base / "mysqld.sock")

    @property
    def log(self) -> Path:
        return self.base / "error.log"

    @property
    def tmpdir(self) -> Path:
        """The server's own temporary folder: in the shared /tmp, its temporary tables' files
        were deleted under it once (mariadb-install-db: "Error on delete of
        '/tmp/#sql-temptable-...'", 11 tests errored)."""
        path = self.base / "tmp"
        path.mkdir(parents=True, exist_ok=True)
        return path

    def install(self) -> None:
        tool = _binary("mariadb-install-db")
        if tool is None:  # pragma: no cover - it comes with mariadbd
            raise RuntimeError("mariadb-install-db not found")
        subprocess.run(
            [
                tool,
                "--no-defaults",
                f"--datadir={self.base / 'data'}",
                "--auth-root-authentication-method=normal",
                "--skip-test-db",
                *(["--user=root"] if os.geteuid() == 0 else []),
            ],
            check=True,
            capture_output=True,
            timeout=60,
            env={**os.environ, "TMPDIR": str(self.tmpdir)},
        )

    def start(self) -> None:
        mariadbd = _binary("mariadbd")
        assert mariadbd is not None
        args = [
            mariadbd,
            "--no-defaults",
            f"--datadir={self.base / 'data'}",
            f"--socket={self.socket}",
            f"--tmpdir={self.tmpdir}",
            f"--port={self.port}",
            "--bind-address=127.0.0.1",
            f"--pid-file={self.base / 'mysqld.pid'}",
            f"--log-error={self.log}",
            "--skip-name-resolve",
            # Small and quick: a test server, not a production one. A commit still survives
            # the process being killed (it is in the OS's page cache), just not a power cut.
            "--innodb-buffer-pool-size=32M",
            "--innodb-log-file-size=16M",
            "--innodb-flush-log-at-trx-commit=2",
            "--innodb-doublewrite=0",
            *(["--user=root"] if os.geteuid() == 0 else []),
        ]
        self.proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
        self.wait_ready()

    def wait_ready(self) -> None:
        """Poll until the server answers over TCP (as the test user would), or fail."""
        deadline = time.monotonic() + START_TIMEOUT
        while True:
            if self.proc is not None and self.proc.poll() is not None:
                raise RuntimeError(f"mariadbd exited ({self.proc.returncode}):\n{self.tail()}")
            try:
                with socket.create_connection(("127.0.0.1", self.port), timeout=1) as s:
                    s.settimeout(1)
                    if s.recv(1):  # the server greets first: it is accepting sessions
                        return
            except OSError:
                pass
            if time.monotonic() > deadline:
                raise RuntimeError(f"mariadbd did not start in {START_TIMEOUT} s:\n{self.tail()}")
            time.sleep(0.05)  # polling interval, bounded by the deadline above

    def stop(self, *, kill: bool = False) -> None:
        """Shut down (SIGTERM: clean; ``kill``: SIGKILL, a crash) and wait for the exit."""
        proc, self.proc = self.proc, None
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(signal.SIGKILL if kill else signal.SIGTERM)
        try:
            proc.wait(timeout=START_TIMEOUT)
        except subprocess.TimeoutExpired:  # pragma: no cover - a wedged server
            proc.kill()
            proc.wait()

    def restart(self, *, kill: bool = False) -> None:
        self.stop(kill=kill)
        self.start()

    def tail(self, lines: int = 20) -> str:
        with contextlib.suppress(OSError):
            return "\n".join(self.log.read_text(errors="replace").splitlines()[-lines:])
        return "(no error log)"

    def admin(self, sql: str) -> str:
        """Run SQL as root over the private socket with the ``mariadb`` client."""
        client = _binary("mariadb") or _binary("mysql")
        assert client is not None
        done = subprocess.run(
            [client, "--no-defaults", f"--socket={self.socket}", "-uroot", "--batch", "-e", sql],
            capture_output=True,
            text=True,
            timeout=30,
        )
        if done.returncode != 0:
            raise RuntimeError(f"mariadb client failed: {done.stderr}")
        return done.stdout

    def create_user(self) -> None:
        self.admin(
            f"CREATE USER '{USER}'@'127.0.0.1' IDENTIFIED BY '{PASSWORD}';"
            f" GRANT {GRANTS} ON `serveur\\_t%`.* TO '{USER}'@'127.0.0.1';"
        )

    def new_database(self) -> str:
        """A fresh, empty database for one test; its URL (password in the environment)."""
        name = f"serveur_t{next(self._names)}"
        self.admin(f"CREATE DATABASE {name}")
        return self.url(name)

    def url(self, database: str) -> str:
        return f"mariadb://{USER}@127.0.0.1:{self.port}/{database}?retry_for=20"


def mariadb_missing() -> str | None:
    for tool in ("mariadbd", "mariadb-install-db"):
        if _binary(tool) is None:
            return f"{tool} not found: apt-get install mariadb-server"
    try:
        import asyncmy  # noqa: F401
    except ImportError:
        return "asyncmy not installed: pip install -e '.[test]'"
    return None


@pytest.fixture(scope="session")
def mariadb_server(tmp_path_factory: pytest.TempPathFactory) -> Iterator[MariaDBServer]:
    missing = mariadb_missing()
    if missing:
        if os.environ.get("CI"):
            pytest.fail(f"MariaDB tests must run in CI: {missing}", pytrace=False)
        pytest.skip(missing)
    server = MariaDBServer(tmp_path_factory.mktemp("mariadb"))
    server.install()
    server.start()
    try:
        server.create_user()
        # The URLs carry no password: the store reads it from the environment, as in production.
        saved = os.environ.get("SERVEUR_DB_PASSWORD")
        os.environ["SERVEUR_DB_PASSWORD"] = PASSWORD
        yield server
    finally:
        if "saved" in locals():
            if saved is None:
                os.environ.pop("SERVEUR_DB_PASSWORD", None)
            else:
                os.environ["SERVEUR_DB_PASSWORD"] = saved
        server.stop()


@pytest.fixture
def mariadb_url(mariadb_server: MariaDBServer) -> str:
    """A new empty database on the session's server, as a ``mariadb://`` URL."""
    if mariadb_server.proc is None or mariadb_server.proc.poll() is not None:
        mariadb_server.start()  # a test that stopped it and failed before starting it again
    return mariadb_server.new_database()


def query(url: str, sql: str) -> list[dict[str, Any]]:
    """Rows of ``sql`` on ``url``, from synchronous test code (a raw look, no store)."""

    async def fetch() -> list[dict[str, Any]]:
        import asyncmy
        from asyncmy.cursors import DictCursor

        from serveur.store.mariadb.db import MariaDBConfig

        cfg = MariaDBConfig.from_url(url, {"SERVEUR_DB_PASSWORD": PASSWORD})

        conn = await asyncmy.connect(
            host=cfg.host,
            port=cfg.port,
            user=cfg.user,
            password=cfg.password,
            database=cfg.database,
            charset="utf8mb4",
            autocommit=True,
        )
        try:
            async with conn.cursor(DictCursor) as cur:
                await cur.execute(sql)
                return list(await cur.fetchall())
        finally:
            conn.close()

    with ThreadPoolExecutor(1) as pool:  # its own event loop: the test's is busy awaiting
        return pool.submit(asyncio.run, fetch()).result(timeout=30)
