"""Many staff at once: every order is taken by exactly one cart, every robot obeys one of
several contradicting presses, and the losers are told so."""

from __future__ import annotations

import asyncio
import random

from tests import invariants
from tests.conftest import Client, Restaurant
from tests.test_e2e import activate, new_orders, serve_current_stop, staff

SEED = 50


async def test_fifty_clients_with_overlapping_carts(one_robot: Restaurant) -> None:
    r = one_robot
    rng = random.Random(SEED)
    c = await staff(r)
    tables = [f"T{i}" for i in range(1, 17)]
    ids = await new_orders(c, *[(f"dish{i}", tables[i % 16]) for i in range(30)])
    carts = [sorted(rng.sample(ids, rng.randint(1, 4))) for _ in range(50)]
    clients = [await r.client() for _ in carts]
    # Every client is connected before the first cart goes: the 50 requests overlap.
    replies = await asyncio.gather(
        *(
            cl.call("create", type="task", orders=cart)
            for cl, cart in zip(clients, carts, strict=True)
        )
    )
    won = [cart for cart, rep in zip(carts, replies, strict=True) if rep["servermsg"] == "ok"]
    lost = [rep for rep in replies if rep["servermsg"] != "ok"]
    assert {rep["code"] for rep in lost} == {"conflict"}, lost
    assert won and lost  # overlapping carts: some must lose
    taken = [o for cart in won for o in cart]
    assert len(taken) == len(set(taken))  # no order in two winning carts
    # The database agrees: each winner's dishes, and only those, are assigned, once.
    snap = invariants.read(r.db)
    invariants.check_deliveries(snap)
    assigned = {i for i, o in snap.orders.items() if o["status"] == "assigned"}
    assert assigned == set(taken)
    by_task: dict[int, set[int]] = {}
    for i in assigned:
        by_task.setdefault(snap.orders[i]["task_num"], set()).add(i)
    for cart, rep in zip(carts, replies, strict=True):
        if rep["servermsg"] == "ok":
            made = {o for t in rep["tasks"] for s in t["stops"] for o in s["orders"]}
            assert made == set(cart)
            assert all(by_task[t["id"]] <= made for t in rep["tasks"])
    # A loser's cart changed nothing: its dishes not won by another cart are still pending.
    assert all(snap.orders[i]["status"] == "pending" for i in set(ids) - set(taken))


async def press_together(clients: list[Client], verbs: list[str]) -> list[dict[str, object]]:
    return list(
        await asyncio.gather(
            *(cl.call(v, robot="r1") for cl, v in zip(clients, verbs, strict=True))
        )
    )


async def test_continue_and_cancel_pressed_together(one_robot: Restaurant) -> None:
    """Ten tablets, half pressing Continue and half Cancel on one stopped robot, four times:
    each time exactly one press wins, the others get ``not_allowed_in_status`` (the robot
    is no longer Stopped), and the trip is either resumed or cancelled — never both."""
    r = one_robot
    c = await staff(r)
    await activate(c, "r1")
    tablets = [await r.client() for _ in range(10)]
    outcomes: list[str] = []
    [oid] = await new_orders(c, ("Laksa", "T16"))
    await c.ok("create", type="task", orders=[oid])
    for rnd in range(4):
        await c.status("r1", "Delivering")
        task_id = c.robot("r1")["current_task"]
        await c.ok("stop", robot="r1")
        verbs = ["continue", "cancel"] * 5
        if rnd % 2:
            verbs.reverse()
        replies = await press_together(tablets, verbs)
        ok = [(v, rep) for v, rep in zip(verbs, replies, strict=True) if rep["servermsg"] == "ok"]
        assert len(ok) == 1, replies
        assert {rep["code"] for rep in replies if rep["servermsg"] == "error"} == {
            "not_allowed_in_status"
        }
        verb, rep = ok[0]
        robot = rep["robot"]
        assert isinstance(robot, dict)
        outcomes.append(verb)
        if verb == "continue":
            assert (robot["status"], robot["current_task"]) == ("Delivering", task_id)
            await c.until(lambda: c.order(oid).get("status") == "assigned")
        else:
            assert (robot["status"], robot["current_task"]) == ("Transit", None)
            await c.until(lambda: c.order(oid).get("status") == "pending", what="dish back")
            await c.until(lambda t=task_id: c.task(t).get("status") == "cancelled")
            await c.status("r1", "Awaiting")
            await c.ok("create", type="task", orders=[oid])  # send the dish again
        invariants.check_deliveries(invariants.read(r.db))
    # Whichever won, the dish is still deliverable, once.
    await c.status("r1", "Delivering")
    await serve_current_stop(c, "r1")
    await c.until(lambda: c.order(oid).get("status") == "delivered")
    snap = invariants.read(r.db)
    invariants.check_deliveries(snap)
    assert snap.deliveries[oid] == 1
    assert len(outcomes) == 4


async def test_food_collected_pressed_by_many_counts_once(one_robot: Restaurant) -> None:
    r = one_robot
    c = await staff(r)
    await activate(c, "r1")
    ids = await new_orders(c, ("Soup", "T2"), ("Tea", "T3"))
    await c.ok("create", type="task", orders=ids)
    tablets = [await r.client() for _ in range(20)]
    for _ in ids:
        await c.status("r1", "Delivered")
        replies = await press_together(tablets, ["next"] * len(tablets))
        assert sum(rep["servermsg"] == "ok" for rep in replies) == 1, replies
    await c.status("r1", "Awaiting")
    snap = invariants.read(r.db)
    invariants.check_deliveries(snap)
    assert [snap.deliveries[i] for i in ids] == [1, 1]
