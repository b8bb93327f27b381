"""The restaurant's backups from the console (issue 29), over real sockets on real SQLite files:
a backup made and downloaded once by its link, a restore that brings back a known state (from
the box's list and from a file sent), the state it replaced kept, bad files refused with their
reason and nothing changed; and the shelf's nightly copies on virtual time."""

from __future__ import annotations

import asyncio
import sqlite3
from datetime import UTC, datetime
from pathlib import Path

import pytest
from websockets.asyncio.client import connect

from serveur.clock import FakeClock
from serveur.core.backups import BackupKind
from serveur.core.shelf import BackupShelf
from serveur.errors import BackupError
from serveur.server import CLOSE_RESTART
from serveur.store.factory import open_store
from tests.conftest import Client, Restaurant, restaurant
from tests.test_site_map import upload

PNG = b"\x89PNG\r\n\x1a\n" + bytes(200)


async def owner(r: Restaurant, password: str) -> Client:
    c = Client(await connect(r.app.url, max_size=2**24))
    r.clients.append(c)
    await c.ok("login", username="owner", password=password)
    return c


async def name_and_orders(r: Restaurant, c: Client) -> tuple[str, int]:
    """The restaurant's name as the console reads it, and the dishes in its database."""
    settings = (await c.ok("site", action="settings"))["settings"]
    return settings["name"], len(await r.app.store.orders.list_orders())


async def restored(r: Restaurant, c: Client, **source: object) -> dict[str, object]:
    """Confirm a restore; the reply, once the server is back on the backup. Dishes are
    created ``ordered`` (the kitchen has them): no robot takes them meanwhile."""
    assert r.app.server is not None and r.app.server.backups is not None
    desk = r.app.server.backups
    got = await c.ok("site", action="restore", confirm=True, **source)
    await asyncio.wait_for(c.ws.wait_closed(), 10)
    assert c.ws.close_code == CLOSE_RESTART
    assert desk.restarting is not None
    await asyncio.wait_for(desk.restarting, 30)
    r.clients.remove(c)
    return dict(got["restore"])


@pytest.fixture(params=["sqlite", "mariadb"])
def db_url(request: pytest.FixtureRequest) -> str | None:
    """None (a SQLite file) or a new MariaDB database: a restore works the same on both."""
    if request.param == "sqlite":
        return None
    return str(request.getfixturevalue("mariadb_url"))


async def test_a_restore_brings_back_the_backed_up_state(
    tmp_path: Path, db_url: str | None
) -> None:
    async with restaurant(tmp_path, db_url=db_url, backups=True) as r:
        password = r.app.first_owner_password
        assert password is not None
        c = await owner(r, password)
        await c.ok("site", action="set_settings", name="Chez Backup")
        await c.ok("create", type="order", dish="Laksa", table="T3", status="ordered")
        made = await c.ok("site", action="backup_now")
        assert made["backup"]["check"] == "ok" and made["backup"]["kind"] == "now"
        status, body, _ = await r.get(made["download"])
        assert status == 200 and body.startswith(b"SQLite format 3\x00")
        # The link is good once.
        assert (await r.get(made["download"]))[0] == 403
        link = await c.ok("site", action="download_backup", name=made["backup"]["name"])
        wrong = link["download"].replace(made["backup"]["name"], "serveur-now-20000101-000000.db")
        assert (await r.get(wrong))[0] == 403

        # Service goes on after the backup.
        await c.ok("site", action="set_settings", name="Chez Later")
        for dish in ("Satay", "Roti", "Teh"):
            await c.ok("create", type="order", dish=dish, table="T5", status="ordered")
        assert await name_and_orders(r, c) == ("Chez Later", 4)

        # Asked without confirm: what it holds and what would be lost, nothing changed.
        preview = (await c.ok("site", action="restore", name=made["backup"]["name"]))["restore"]
        assert preview["check"] == "ok" and preview["orders"] == 1
        assert preview["lost"] == {"orders": 3, "trips": 0} and preview["restarting"] is False
        assert await name_and_orders(r, c) == ("Chez Later", 4)

        got = await restored(r, c, name=made["backup"]["name"])
        assert got["restarting"] is True
        c = await owner(r, password)
        assert await name_and_orders(r, c) == ("Chez Backup", 1)
        listed = (await c.ok("site", action="backups"))["backups"]
        before = [b for b in listed if b["kind"] == "before_restore"]
        assert len(before) == 1 and before[0]["check"] == "ok"

        # Undone with a file: the state replaced, downloaded and sent back as an upload.
        link = await c.ok("site", action="download_backup", name=before[0]["name"])
        status, body, _ = await r.get(link["download"])
        assert status == 200
        sent = await upload(c, "backup", "from-my-tablet.db", body)
        await restored(r, c, upload=sent)
        c = await owner(r, password)
        assert await name_and_orders(r, c) == ("Chez Later", 4)
        # The robot is back with the server (reconciled as after any restart).
        await c.subscribe("robots")
        await c.status("r1", "Ready")


def newer_copy(src: bytes, folder: Path) -> bytes:
    path = folder / "newer.db"
    path.write_bytes(src)
    con = sqlite3.connect(path)
    con.execute("INSERT INTO schema_migrations VALUES (999, 'from_the_future', 0)")
    con.commit()
    con.close()
    return path.read_bytes()


def with_extra(src: bytes, folder: Path, sql: str) -> bytes:
    """A real backup with one object added (the live database would run it after a restore)."""
    path = folder / "extra.db"
    path.write_bytes(src)
    con = sqlite3.connect(path)
    con.execute(sql)
    con.commit()
    con.close()
    return path.read_bytes()


def other_program(folder: Path) -> bytes:
    path = folder / "other.db"
    con = sqlite3.connect(path)
    con.execute("CREATE TABLE moz_places (id INTEGER PRIMARY KEY, url TEXT)")
    con.commit()
    con.close()
    return path.read_bytes()


async def test_bad_backups_are_refused_and_nothing_changes(tmp_path: Path) -> None:
    async with restaurant(tmp_path, backups=True) as r:
        password = r.app.first_owner_password
        assert password is not None
        c = await owner(r, password)
        await c.ok("site", action="set_settings", name="Untouched")
        good = await c.ok("site", action="backup_now")
        body = (await r.get(good["download"]))[1]
        damaged = bytearray(body)
        damaged[4096 * 3 : 4096 * 4] = bytes(4096)  # a page of a table zeroed
        cases = {
            "not_a_backup": [PNG, other_program(tmp_path), body[: len(body) // 3]],
            "newer": [newer_copy(body, tmp_path)],
            "not_a_backup ": [  # a serveur copy with something of its own planted in it
                with_extra(
                    body,
                    tmp_path,
                    "CREATE TRIGGER planted AFTER INSERT ON orders BEGIN DELETE FROM users; END",
                ),
                with_extra(
                    body,
                    tmp_path,
                    "CREATE VIEW endless AS WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL"
                    " SELECT x + 1 FROM c) SELECT x FROM c",
                ),
            ],
        }
        for reason, files in cases.items():
            for data in files:
                sent = await upload(c, "backup", "x.db", data)
                err = await c.error("site", "backup_error", action="restore", upload=sent)
                assert err["details"]["reason"] == reason.strip(), err
        # A damaged page is either no database at all or one that fails its check.
        sent = await upload(c, "backup", "x.db", bytes(damaged))
        err = await c.error("site", "backup_error", action="restore", upload=sent, confirm=True)
        assert err["details"]["reason"] in ("damaged", "not_a_backup"), err
        err = await c.error(
            "site", "backup_error", action="restore", name="serveur-now-20000101-000000.db"
        )
        assert err["details"]["reason"] == "not_found"
        await c.error("site", "invalid_field", action="restore", name="../serveur.db")
        # Nothing changed: the same state, no restart, no copy of a state "before" anything.
        assert (await name_and_orders(r, c))[0] == "Untouched"
        listed = (await c.ok("site", action="backups"))["backups"]
        assert [b["kind"] for b in listed] == ["now"]
        assert not list(tmp_path.glob("*.restoring"))  # noqa: ASYNC240 - a test's look


async def test_a_server_without_backups_says_so(tmp_path: Path) -> None:
    async with restaurant(tmp_path) as r:
        password = r.app.first_owner_password
        assert password is not None
        c = await owner(r, password)
        err = await c.error("site", "backup_error", action="backup_now")
        assert err["details"]["reason"] == "off"


async def test_the_shelf_backs_up_every_night_and_keeps_a_week(tmp_path: Path) -> None:
    start = datetime(2026, 11, 28, 22, 0, tzinfo=UTC).timestamp()
    clock = FakeClock(start_epoch=start)
    async with open_store(str(tmp_path / "serveur.db")) as store:
        shelf = BackupShelf(tmp_path / "backups", store, clock, UTC)
        shelf.start()
        try:
            for night in range(1, 10):
                await asyncio.wait_for(clock.someone_sleeps(), 10)
                await clock.advance(24 * 3600)
                await asyncio.wait_for(shelf.night(night), 10)
        finally:
            await shelf.close()
        got = await shelf.entries()
    assert [e.kind for e in got] == [BackupKind.NIGHTLY] * 7
    assert all(e.check == "ok" for e in got)
    # One a night (named when made: FakeClock jumps a whole day, so the time of day varies).
    assert [e.name[:24] for e in got] == [f"serveur-nightly-202612{d:02d}" for d in range(7, 0, -1)]
    # Each one is a serveur database another server can open.
    con = sqlite3.connect(tmp_path / "backups" / got[0].name)
    assert con.execute("SELECT count(*) FROM schema_migrations").fetchone()[0] >= 9
    con.close()


async def test_a_name_from_a_client_never_reaches_another_file(tmp_path: Path) -> None:
    async with open_store(str(tmp_path / "serveur.db")) as store:
        shelf = BackupShelf(tmp_path / "backups", store, FakeClock())
        made = await shelf.make(BackupKind.NOW)
        assert shelf.path(made.name).is_file()
        (tmp_path / "backups" / "secret.db").write_bytes(b"x")
        for name in ("secret.db", "../serveur.db", "serveur-now-20000101-000000.db"):
            with pytest.raises(BackupError):
                shelf.path(name)
