"""``stats`` ``last_service``: the latest service day a forecast can replay (issue 30, point 8).

"How many robots do I need?" used to start from yesterday, often a day the restaurant was
closed (Start then refused: nothing to replay). The console now asks the server for the last
day before today on which a dish was ready at the pass — exactly the days ``stats``
``forecast`` accepts (voided dishes left out, as the forecast leaves them out).

The store's one aggregate on both backends; then over a real server's socket, on a clock the
test moves: none on a new restaurant, the day of the dishes (in the request's time zone, service
days from 04:00), never the day asked about itself, a voided dish not counted, a bad day and
staff refused.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from websockets.asyncio.client import connect

from serveur.clock import FakeClock
from serveur.domain import DishAction
from serveur.store.base import Store
from tests.security.test_security import bare_server, login, request
from tests.store.test_store import T0, backend, seed, store  # noqa: F401  (its fixtures)

KL = "+08:00"  # FakeClock's epoch 1_700_000_000 is 2023-11-14 22:13 UTC, 06:13 in KL


def _last(before: str, offset: str = KL) -> dict[str, Any]:
    return {
        "clientmsg": "stats",
        "action": "last_service",
        "before": before,
        "utc_offset": offset,
    }


async def test_the_latest_ready_dish_before_a_time_on_either_backend(store: Store) -> None:  # noqa: F811
    await seed(store)
    assert await store.orders.last_ready(T0 + 1e6) is None
    first = await store.orders.add_order("Laksa", "T1", ready_at=T0, now=T0)
    await store.orders.add_order("Satay", "T2", ready_at=T0 + 60, now=T0 + 60)
    late = await store.orders.add_order("Kopi", "T3", ready_at=T0 + 3600, now=T0 + 3600)
    assert await store.orders.last_ready(T0 + 1e6) == T0 + 3600
    assert await store.orders.last_ready(T0 + 3600) == T0 + 60  # strictly before
    assert await store.orders.last_ready(T0) is None
    await store.orders.step_order(late.id, DishAction.VOID, now=T0 + 3700)
    assert await store.orders.last_ready(T0 + 1e6) == T0 + 60  # a voided dish never left
    assert first.ready_at == T0


async def test_the_last_service_day_over_the_protocol(tmp_path: Path) -> None:
    async with bare_server(tmp_path) as app:
        ws = await connect(app.url)
        await login(ws, username="owner", password=app.first_owner_password)
        # A new restaurant: no service yet.
        none = await request(ws, _last("2023-11-16"))
        assert none == {"servermsg": "ok", "id": "q", "last_service": None}, none
        assert isinstance(app.clock, FakeClock)
        made = await request(
            ws, {"clientmsg": "create", "type": "order", "dish": "Laksa", "table": "T1"}
        )
        assert made["servermsg"] == "ok", made
        # Ready at 06:13 on 2023-11-15 in Kuala Lumpur: that service day, never the day asked.
        assert (await request(ws, _last("2023-11-16")))["last_service"] == "2023-11-15"
        assert (await request(ws, _last("2023-12-31")))["last_service"] == "2023-11-15"
        assert (await request(ws, _last("2023-11-15")))["last_service"] is None
        # In UTC the same dish was ready at 22:13 on the 14th.
        assert (await request(ws, _last("2023-11-16", "+00:00")))["last_service"] == "2023-11-14"
        # A day later a dish is ready, then voided: that day had nothing a replay could serve.
        await app.clock.advance(86_400.0)
        await login(ws, username="owner", password=app.first_owner_password)  # expired
        voided = await request(
            ws, {"clientmsg": "create", "type": "order", "dish": "Satay", "table": "T2"}
        )
        assert voided["servermsg"] == "ok", voided
        gone = await request(
            ws, {"clientmsg": "dish", "order": voided["order"]["id"], "action": "void"}
        )
        assert gone["servermsg"] == "ok", gone
        assert (await request(ws, _last("2023-11-20")))["last_service"] == "2023-11-15"
        bad = await request(ws, _last("2023-02-30"))
        assert (bad["code"], bad["details"]) == ("invalid_field", {"field": "before"}), bad
        missing = await request(ws, {"clientmsg": "stats", "action": "last_service"})
        assert missing["code"] == "invalid_field", missing
        await ws.close()
        staff = await connect(app.url)
        await login(staff, token=await app.issue_token("staff"))
        refused = await request(staff, _last("2023-11-16"))
        assert refused["code"] == "forbidden", refused
        await staff.close()
