"""The owner's ``chain`` verb (issue 34: "the outbox's size and the oldest unsent event are
shown to the owner"), over real sockets to a real server on a SQLite file.

A restaurant in no chain still numbers its events: as it works (dishes ordered, a robot's trip),
``head``, ``unsent`` and ``size`` grow and ``oldest_unsent_at`` is the first event's time; what
the broker acknowledges (``store.outbox.mark_sent``, as the shipper notes a PUBACK) moves
``sent``, ``sent_at`` and the oldest waiting event on. A server started with a chain says so,
names its site and broker and never the password; whether the broker is connected is read live
from the shipper. No broker runs here (tests/chain has a real one): the chain's address is a
loopback port where nothing listens. Staff and screens are refused; the owner's repeated reads
are not in the audit trail, a refusal is.
"""

from __future__ import annotations

import asyncio
import json
import re
import socket
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from pathlib import Path
from typing import Any

import pytest
from websockets.asyncio.client import connect

from serveur import protocol as P
from serveur.app import App
from serveur.chain.address import ChainAddress
from serveur.chain.shipper import Shipper
from serveur.core.runtime import CoreConfig
from serveur.store.site import AuditQuery
from tests.conftest import Client, restaurant, test_clock

pytestmark = pytest.mark.timeout(120)

DOC = Path(__file__).resolve().parent.parent / "docs" / "protocol.md"
PASSWORD = "s3cret-chain-pw"
OUTBOX_KEYS = {"head", "sent", "confirmed", "unsent", "size", "oldest_unsent_at", "sent_at"}


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


async def owner(url: str, password: str | None) -> Client:
    c = Client(await connect(url, max_size=2**24))
    await c.ok("login", username="owner", password=password or "")
    return c


async def chain(c: Client) -> dict[str, Any]:
    reply = await c.ok("chain")
    P.SERVER_ADAPTER.validate_python(reply)  # what the server sends is what the docs say
    return dict(reply["chain"])


@asynccontextmanager
async def chain_site(tmp_path: Path, address: ChainAddress | None) -> AsyncIterator[App]:
    """The demo room without robots, started with the chain ``address`` (or none)."""
    from serveur.maps.navigation import load_demo

    nav_map, waypoints = load_demo()
    app = App(
        tmp_path / "serveur.db",
        port=0,
        clock=test_clock(),
        nav_map=nav_map,
        waypoints=waypoints,
        config=CoreConfig(heartbeat=10.0, ack_timeout=5.0),
        plan_in_child=False,
        chain=address,
    )
    await app.start()
    try:
        yield app
    finally:
        await app.close()


async def grows(c: Client, before: dict[str, Any]) -> dict[str, Any]:
    """The ``chain`` reply once the outbox has numbered something more than in ``before``."""
    for _ in range(200):
        now = await chain(c)
        if now["outbox"]["head"] > before["outbox"]["head"]:
            return now
        await asyncio.sleep(0.05)
    raise AssertionError(f"the outbox stayed at {before['outbox']}")


async def test_the_outbox_counts_what_a_restaurant_in_no_chain_records(tmp_path: Path) -> None:
    async with restaurant(tmp_path) as r:
        c = await owner(r.app.url, r.app.first_owner_password)
        r.clients.append(c)
        first = await chain(c)
        assert {k: first[k] for k in ("configured", "site", "broker", "connected")} == {
            "configured": False,
            "site": None,
            "broker": None,
            "connected": False,
        }
        box = first["outbox"]
        assert set(box) == OUTBOX_KEYS
        # Events are numbered from the start (the robot came online): none ever sent.
        assert box["head"] == box["unsent"] == box["size"] > 0
        assert (box["sent"], box["confirmed"], box["sent_at"]) == (0, 0, None)
        oldest = box["oldest_unsent_at"]
        assert isinstance(oldest, float) and oldest <= r.clock.epoch()

        # The restaurant works: the robot set to work, a dish ordered, taken to its table.
        staff = await r.client()
        await staff.subscribe("robots", "orders")
        await staff.status("r1", "Ready")
        await staff.ok("control", robot="r1", action="auto")
        await staff.status("r1", "Awaiting")
        order = (await staff.ok("create", type="order", dish="Laksa", table="T3"))["order"]
        after_order = await grows(c, first)
        await staff.ok("create", type="task", orders=[order["id"]])
        await staff.status("r1", "Delivered")
        working = await grows(c, after_order)
        for before, after in ((first, after_order), (after_order, working)):
            b, a = before["outbox"], after["outbox"]
            assert a["head"] > b["head"] and a["size"] > b["size"] and a["unsent"] > b["unsent"]
            assert a["unsent"] == a["head"] and a["oldest_unsent_at"] == oldest
        assert working["configured"] is False

        # The broker acknowledges the first events (the shipper's note of a PUBACK): they are
        # sent, the oldest waiting event is a later one, and still every row is kept.
        head = working["outbox"]["head"]
        half = head // 2
        await r.app.store.outbox.mark_sent(half, r.clock.epoch())
        acked = (await chain(c))["outbox"]
        assert acked["sent"] == half and acked["unsent"] >= head - half
        assert acked["sent_at"] is not None and acked["sent_at"] >= oldest
        assert acked["oldest_unsent_at"] is not None and acked["oldest_unsent_at"] >= oldest
        assert acked["size"] >= head and acked["confirmed"] == 0
        # All of them: nothing waits; the head office confirms, and the rows are still kept
        # (a week) for a head office that must ask again.
        head = acked["head"]
        await r.app.store.outbox.mark_sent(head, r.clock.epoch())
        await r.app.store.outbox.confirm(head)
        done = (await chain(c))["outbox"]
        if done["head"] == head:  # (the robot may have recorded one more meanwhile)
            assert done["unsent"] == 0 and done["oldest_unsent_at"] is None
        assert done["sent"] == head and done["confirmed"] == head and done["size"] >= head


async def test_a_site_in_a_chain_names_its_broker_never_the_password(tmp_path: Path) -> None:
    # Nothing listens at the broker's address: the shipper tries, and is not connected.
    address = ChainAddress("127.0.0.1", free_port(), "lyon", PASSWORD, tls=False)
    async with chain_site(tmp_path, address) as app:
        assert app.server is not None and app.shipper is not None
        c = await owner(app.url, app.first_owner_password)
        try:
            got = await chain(c)
            assert {k: got[k] for k in ("configured", "site", "broker", "connected")} == {
                "configured": True,
                "site": "lyon",
                "broker": f"mqtt://lyon@127.0.0.1:{address.port}",
                "connected": False,
            }
            assert got["outbox"]["unsent"] == got["outbox"]["head"] > 0
            assert not any(PASSWORD in json.dumps(f) for f in c.frames)

            # Connected is read from the shipper when asked (a stand-in shipper, never started,
            # whose broker says yes: tests/chain connects a real one).
            stand_in = Shipper(app.store, address, app.clock)
            app.server.chain = stand_in
            stand_in.connected.set()
            assert (await chain(c))["connected"] is True
            stand_in.connected.clear()
            assert (await chain(c))["connected"] is False

            # The doc's reply of a site in a chain has the shape this server answers.
            doc = documented_chain_reply()
            P.SERVER_ADAPTER.validate_python(doc)
            assert shape(doc["chain"]) == shape(got)
        finally:
            await c.close()


async def test_staff_and_screens_are_refused_and_reads_are_not_audited(tmp_path: Path) -> None:
    async with restaurant(tmp_path) as r:
        c = await owner(r.app.url, r.app.first_owner_password)
        r.clients.append(c)
        for _ in range(3):
            await chain(c)
        staff = await r.client()
        refused = await staff.error("chain", "forbidden")
        assert refused["details"] == {"scope": "site"}
        table = await r.screen("table-screen", table="T3")
        await table.error("chain", "forbidden")
        robot = await r.screen("robot-screen", robot="r1")
        await robot.error("chain", "forbidden")
        # (A request's audit row is written once its reply is queued: wait for the third.)
        for _ in range(100):
            found = await r.app.store.audit.search_audit(AuditQuery(verb="chain"))
            if len(found) >= 3:
                break
            await asyncio.sleep(0.05)
        assert sorted(rec.outcome for rec in found) == ["forbidden"] * 3, found


def documented_chain_reply() -> dict[str, Any]:
    """docs/protocol.md's reply of a restaurant in a chain (a text block: the replay's
    restaurant is in none)."""
    text = DOC.read_text(encoding="utf-8")
    blocks = re.findall(r"^```text\n(.*?)^```", text, re.M | re.S)
    (found,) = [b for b in blocks if '"configured":true' in b]
    return dict(json.loads(found))


def shape(value: Any) -> Any:
    """A JSON object's keys, recursively (the types are the schema's: validated apart)."""
    if isinstance(value, dict):
        return {k: shape(v) for k, v in value.items()}
    return None


def test_the_reply_is_documented_field_by_field() -> None:
    fields = set(P.ChainInfo.model_fields) | set(P.OutboxInfo.model_fields)
    section = DOC.read_text(encoding="utf-8").split("### `chain`")[1].split("\n### ")[0]
    for name in fields:
        assert f"`{name}`" in section, name
    assert set(P.OutboxInfo.model_fields) == OUTBOX_KEYS
