"""A real Mosquitto for the chain's tests (issue 34), set up the way production runs it.

The broker is what enforces the topic layout (each site only under ``chain/<site>/``, hq the
only writer of ``resend`` and ``confirmed``), so the tests run the repo's own
``deploy/chain/acl`` verbatim, behind TLS and a password file made by ``mosquitto_passwd``:
a test that passes here passes because of the file that ships, not a copy of it.
"""

from __future__ import annotations

import os
import pwd
import re
import shutil
import signal
import socket
import ssl
import subprocess
import time
from pathlib import Path
from types import TracebackType
from urllib.parse import quote

import pytest
import trustme

from tests.subprocess_server import free_port

MOSQUITTO = shutil.which("mosquitto") or "/usr/sbin/mosquitto"
MOSQUITTO_PASSWD = shutil.which("mosquitto_passwd") or "/usr/bin/mosquitto_passwd"

#: The production ACL, copied verbatim into each test broker's config.
ACL = Path(__file__).parents[2] / "deploy" / "chain" / "acl"

#: Wall seconds for mosquitto to listen (it takes tens of milliseconds; a loaded CI box more).
STARTUP = 10.0


def need_mosquitto() -> None:
    """Skip the test without Mosquitto on a developer's machine, but fail in CI: there the
    chain's broker tests must run, and a silent skip would hide that they never did."""
    missing = [p for p in (MOSQUITTO, MOSQUITTO_PASSWD) if not os.path.exists(p)]
    if not missing:
        return
    if os.environ.get("CI"):
        pytest.fail(f"the chain's MQTT tests must run in CI: apt-get install mosquitto ({missing})")
    pytest.skip(f"mosquitto not installed: apt-get install mosquitto ({missing})")


class ChainBroker:
    """Mosquitto with the chain's ACL, a throwaway CA and one password per user.

    Everything lives in ``workdir``: ``ca.pem`` (what clients trust), the server's
    certificate and key, the password file, ``mosquitto.conf``, the persistence database in
    ``data/`` and ``mosquitto.log``. The port is chosen once, so a restarted broker is found
    where the clients left it, as a real one would be.
    """

    def __init__(
        self, workdir: Path, users: dict[str, str], *, autosave_interval: int = 60
    ) -> None:
        self.workdir = workdir
        self.users = dict(users)
        self.autosave_interval = autosave_interval
        self.port = free_port()
        self.ca = workdir / "ca.pem"
        self.cert = workdir / "server.pem"
        self.key = workdir / "server.key"
        self.passwd = workdir / "passwd"
        self.acl = workdir / "acl"
        self.data = workdir / "data"
        self.log = workdir / "mosquitto.log"
        self.stderr = workdir / "mosquitto.stderr"
        self.conf = workdir / "mosquitto.conf"
        self.proc: subprocess.Popen[bytes] | None = None
        workdir.mkdir(parents=True, exist_ok=True)
        self.data.mkdir(exist_ok=True)
        self._write_pki()
        self._write_passwords()
        self._write_conf()

    # -- files -------------------------------------------------------------------------------

    def _write_pki(self) -> None:
        """A CA of our own and a certificate for this machine: clients verify the broker
        exactly as a site verifies the chain's real one (name and chain), only the CA differs."""
        ca = trustme.CA()
        leaf = ca.issue_cert("127.0.0.1", "localhost")
        ca.cert_pem.write_to_path(str(self.ca))
        for i, blob in enumerate(leaf.cert_chain_pems):
            blob.write_to_path(str(self.cert), append=i > 0)
        leaf.private_key_pem.write_to_path(str(self.key))
        self.key.chmod(0o600)

    def _write_passwords(self) -> None:
        """The password file as an operator makes it (``mosquitto_passwd -b``, hashed), mode
        0600: mosquitto 2.x only warns about a world-readable one, production must not have it."""
        self.passwd.write_text("")
        self.passwd.chmod(0o600)
        for user, password in self.users.items():
            subprocess.run(
                [MOSQUITTO_PASSWD, "-b", str(self.passwd), user, password],
                check=True,
                capture_output=True,
            )
        self.passwd.chmod(0o600)

    def _write_conf(self) -> None:
        """One TLS listener on loopback and the production ACL, persistence and queue limit
        (``deploy/chain/mosquitto.conf``); only paths, the port and the autosave differ."""
        shutil.copyfile(ACL, self.acl)
        # As root, mosquitto drops to the "mosquitto" user, which could not read our files in
        # a root-owned temporary directory: stay whoever runs the tests (no effect otherwise).
        me = pwd.getpwuid(os.geteuid()).pw_name
        self.conf.write_text(
            "\n".join(
                [
                    f"user {me}",
                    "per_listener_settings false",
                    f"listener {self.port} 127.0.0.1",
                    f"cafile {self.ca}",
                    f"certfile {self.cert}",
                    f"keyfile {self.key}",
                    "allow_anonymous false",
                    f"password_file {self.passwd}",
                    f"acl_file {self.acl}",
                    "persistence true",
                    f"persistence_location {self.data}/",
                    f"autosave_interval {self.autosave_interval}",
                    "autosave_on_changes false",
                    "max_queued_messages 10000",
                    "max_inflight_messages 20",
                    "persistent_client_expiration 14d",
                    f"log_dest file {self.log}",
                    "log_type all",
                    "connection_messages true",
                    "",
                ]
            )
        )

    # -- the process -------------------------------------------------------------------------

    def start(self) -> None:
        """Start mosquitto and return once *this* process listens on the TLS port.

        A port that accepts is not proof enough: another broker (the previous one, not yet
        gone) may hold it. So we also wait for this run's "running" line in the log, which
        mosquitto writes only after it opened its listeners. A restart that finds the port
        still taken sees "Address already in use" and tries again until the same deadline.
        """
        if self.proc is not None and self.proc.poll() is None:
            raise RuntimeError("mosquitto is already running")
        deadline = time.monotonic() + STARTUP
        while True:
            logged = self.log.stat().st_size if self.log.exists() else 0
            with self.stderr.open("ab") as err:
                self.proc = subprocess.Popen(
                    [MOSQUITTO, "-c", str(self.conf)], stdout=subprocess.DEVNULL, stderr=err
                )
            if self._wait_listening(self.proc, logged, deadline):
                return
            self.stop(kill=True)
            in_use = "Address already in use" in self._log_since(logged)
            if in_use and time.monotonic() < deadline:
                # Nothing to wait on for a port to come free: pace the retries (each one is
                # a new mosquitto), bounded by the deadline. Only a restart ever gets here.
                time.sleep(0.05)
                continue
            raise RuntimeError(
                f"mosquitto did not listen on 127.0.0.1:{self.port} "
                f"(exit {self.proc.returncode}):\n{self.log_tail()}"
            )

    def _log_since(self, offset: int) -> str:
        """What mosquitto logged after ``offset`` bytes (this run only)."""
        if not self.log.exists():
            return ""
        with self.log.open("rb") as f:
            f.seek(offset)
            return f.read().decode(errors="replace")

    def _wait_listening(self, proc: subprocess.Popen[bytes], logged: int, deadline: float) -> bool:
        """True once this run logged "running" and 127.0.0.1:port accepts a TCP connection;
        False if mosquitto exited, failed to bind, or the deadline passed. Between tries we
        wait on the process exiting (an event) for 20 ms."""
        while time.monotonic() < deadline:
            since = self._log_since(logged)
            if "Address already in use" in since:
                return False
            if re.search(r"mosquitto version \S+ running", since):
                try:
                    with socket.create_connection(("127.0.0.1", self.port), timeout=1):
                        return True
                except OSError:
                    pass
            try:
                proc.wait(0.02)
                return False
            except subprocess.TimeoutExpired:
                continue
        return False

    def stop(self, *, kill: bool = False) -> None:
        """SIGTERM (mosquitto saves its database, then exits) or SIGKILL (a crash: whatever
        was not autosaved is lost). Waits for the process to be gone."""
        proc = self.proc
        if proc is None or proc.poll() is not None:
            return
        proc.send_signal(signal.SIGKILL if kill else signal.SIGTERM)
        try:
            proc.wait(STARTUP)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def restart(self, *, kill: bool = False) -> None:
        """Stop (gracefully, or a crash with ``kill``) and start again on the same port."""
        self.stop(kill=kill)
        self.start()

    # -- for clients -------------------------------------------------------------------------

    def url(self, user: str) -> str:
        """Where ``user`` connects, with its password, as a site's configuration holds it."""
        password = self.users[user]
        return f"mqtts://{quote(user, safe='')}:{quote(password, safe='')}@127.0.0.1:{self.port}"

    def client_context(self) -> ssl.SSLContext:
        """A TLS context that trusts only this broker's CA (hostname checked)."""
        return ssl.create_default_context(cafile=str(self.ca))

    def log_tail(self, n: int = 30) -> str:
        """The last ``n`` lines of the broker's log and stderr (startup errors go there,
        before the log file is open): what a failed test needs to say why."""
        lines: list[str] = []
        for path in (self.stderr, self.log):
            if path.exists():
                lines += path.read_text(errors="replace").splitlines()[-n:]
        return "\n".join(lines[-n:])

    def __enter__(self) -> ChainBroker:
        self.start()
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.stop(kill=True)
