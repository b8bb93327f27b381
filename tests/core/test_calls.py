"""Guests' calls (issue 32): from a table screen, from a Wi-Fi button's HTTP request and from
staff; merged, rate limited, escalated, answered and cancelled; a plates call answered by a
bussing robot. Real server, real simulator, real sockets, virtual time."""

from __future__ import annotations

import asyncio
import urllib.error
import urllib.request
from pathlib import Path
from typing import Any

from tests.conftest import Client, Restaurant, restaurant
from tests.core.test_service_day import owner_of, site
from tests.test_e2e import activate


async def table_screen(r: Restaurant, table: str) -> Client:
    return await r.screen("table-screen", table=table)


async def staff(r: Restaurant) -> Client:
    c = await r.client()
    await c.subscribe("robots", "tasks", "alerts", "calls")
    return c


def _request(url: str, method: str) -> tuple[int, Any]:
    try:
        with urllib.request.urlopen(urllib.request.Request(url, method=method), timeout=10) as r:
            return r.status, r.headers
    except urllib.error.HTTPError as exc:
        return exc.code, exc.headers


def calls(c: Client) -> dict[int, dict[str, Any]]:
    return c.records.get("calls", {})


async def test_a_table_calls_a_waiter_and_a_second_press_is_merged(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        t3 = await table_screen(r, "T3")
        await t3.subscribe("calls")
        first = await t3.ok("call", action="open", table="T3", kind="waiter")
        assert first["merged"] is False and first["call"]["source"] == "table"
        call_id = first["call"]["id"]
        await c.until(lambda: call_id in calls(c), what="the console sees the call")
        again = await t3.ok("call", action="open", table="T3", kind="waiter")
        assert again["merged"] is True and again["call"]["id"] == call_id
        assert again["call"]["presses"] == 2
        # A screen calls only for its own table; a table that does not exist is named.
        await t3.error("call", "forbidden", action="open", table="T4", kind="waiter")
        await c.error("call", "not_found", action="open", table="T99", kind="bill")
        await c.error("call", "invalid_field", action="open", table="pass", kind="bill")
        await c.error("call", "invalid_field", action="open", table="T3", kind="coffee")
        # The table's screen sees its own call only.
        await c.ok("call", action="open", table="T5", kind="bill")
        await t3.until(lambda: call_id in calls(t3))
        assert all(x["table"] == "T3" for x in calls(t3).values())
        answered = (await c.ok("call", action="answer", call=call_id))["call"]
        assert answered["answered_at"] is not None and answered["answered_by"] == "token:1"
        await t3.until(lambda: calls(t3)[call_id].get("answered_at") is not None)
        await c.error("call", "conflict", action="answer", call=call_id)  # already answered
        await c.error("call", "not_found", action="cancel", call=9999)
        # Answered: a new press opens a new call.
        new = await t3.ok("call", action="open", table="T3", kind="waiter")
        assert new["merged"] is False and new["call"]["id"] != call_id


async def test_a_wifi_button_calls_with_its_token_and_is_limited(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        owner = await owner_of(r)
        made = await owner.ok("site", action="add_button", name="T7 bill", table="T7", kind="bill")
        token, path = made["token"], made["path"]
        assert path == f"/call/{token}" and made["button"]["table"] == "T7"
        await owner.error("site", "conflict", action="add_button", name="T7 bill", table="T7")
        await owner.error("site", "not_found", action="add_button", name="x", table="T99")
        await c.error("site", "forbidden", action="add_button", name="y", table="T7")
        status, body, _ = await r.get(path)
        assert status == 200 and body.startswith(b"called: bill at T7"), body
        await c.until(lambda: any(x["table"] == "T7" for x in calls(c).values()))
        [call] = [x for x in calls(c).values() if x["table"] == "T7"]
        assert call["source"] == "button:T7 bill" and call["kind"] == "bill"
        status, body, _ = await r.get(path + "?kind=waiter")  # another kind, same table
        assert status == 200 and b"waiter at T7" in body
        # Pressed fifty times: merged while the bucket lasts, then refused; one call each.
        codes = [(await r.get(path))[0] for _ in range(50)]
        assert codes.count(200) == 1 and set(codes[1:]) == {429}, codes
        status, headers = await asyncio.to_thread(_request, r.http_base + path, "GET")
        assert status == 429 and int(headers["Retry-After"]) >= 1
        # A link preview's HEAD (or anything but GET) is not a press.
        status, headers = await asyncio.to_thread(_request, r.http_base + path, "HEAD")
        assert status == 405 and headers["Allow"] == "GET"
        t7 = [x for x in calls(c).values() if x["table"] == "T7"]
        assert len(t7) == 2 and max(x["presses"] for x in t7) == 2
        assert (await r.get(path + "?kind=coffee"))[0] == 400
        assert (await r.get("/call/srb_nottherighttoken"))[0] == 404
        assert (await r.get("/call/whatever"))[0] == 404
        listed = (await owner.ok("site", action="buttons"))["buttons"]
        assert [b["name"] for b in listed] == ["T7 bill"] and "token" not in listed[0]
        assert listed[0]["last_press"] is not None
        await owner.ok("site", action="revoke_button", name="T7 bill")
        status, body, _ = await r.get(path)
        assert status == 404 and b"revoked" in body


async def test_a_call_nobody_answers_is_escalated_then_cleared(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site(call_escalate=20.0)) as r:
        c = await staff(r)
        opened = (await c.ok("call", action="open", table="T2", kind="waiter"))["call"]
        assert opened["source"] == "staff"

        def alert() -> dict[str, Any] | None:
            found = [
                a
                for a in c.records.get("alerts", {}).values()
                if a["kind"] == "call_waiting" and a["cleared_at"] is None
            ]
            return found[0] if found else None

        raised = await c.until(alert, what="the call's alert")
        assert raised["subject"] == "T2/waiter" and "T2 asked for a waiter" in raised["message"]
        assert calls(c)[opened["id"]]["escalated_at"] is not None
        await c.ok("call", action="cancel", call=opened["id"])
        await c.until(lambda: alert() is None, what="the alert cleared")


async def test_a_plates_call_sends_a_bussing_robot_to_the_dish_return(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site(bussing_wait=600.0)) as r:
        c = await staff(r)
        await c.subscribe("orders")
        # Without a dish return staff take the plates: the call waits like a waiter call.
        bare = (await c.ok("call", action="open", table="T6", kind="plates"))["call"]
        assert bare["task_id"] is None
        await c.ok("call", action="cancel", call=bare["id"])
        await c.error("create", "conflict", type="bussing", tables=["T6"])
        await c.ok("create", type="waypoint", name="dish return", x=9.0, y=10.8, kind="dish_return")
        # Staff's own bussing trip, resent with its key (a tablet that lost the reply): one trip.
        sent = (await c.ok("create", type="bussing", tables=["T9", "T13"], key="bus-1"))["task"]
        again = (await c.ok("create", type="bussing", tables=["T9", "T13"], key="bus-1"))["task"]
        assert sent["id"] == again["id"] and sent["kind"] == "bussing"
        await c.error("create", "conflict", type="bussing", tables=["T9"], key="bus-1")
        await c.error("create", "invalid_field", type="bussing", tables=["T9", "T9"])
        await c.error("create", "not_found", type="bussing", tables=["T99"])
        # (Out of the way of the plates call below: no robot is active yet to take it.)
        assert r.app.core is not None
        await r.app.core.store.tasks.cancel_task(sent["id"], now=r.clock.epoch(), reason="test")
        await activate(c, "r1")
        t6 = await table_screen(r, "T6")
        call = (await t6.ok("call", action="open", table="T6", kind="plates"))["call"]
        task_id = call["task_id"]
        assert task_id is not None
        # No trays to load at the pass: the robot leaves at once, to the table.
        await c.until(lambda: c.task(task_id).get("robot") == "r1")
        assert c.task(task_id)["kind"] == "bussing"
        assert [(s["table"], s["purpose"]) for s in c.task(task_id)["stops"]] == [
            ("T6", "collect"),
            ("dish return", "unload"),
        ]
        await c.status("r1", "Delivered", timeout=60)
        # The robot at the table answered the call it was sent for.
        await c.until(lambda: calls(c)[call["id"]].get("answered_at") is not None)
        assert calls(c)[call["id"]]["answered_by"] == "robot:r1"
        # The guests press Done on the robot's screen (here: the table's screen)...
        robot = c.robot("r1")
        await t6.ok("next", robot="r1", task=task_id, stop=robot.get("current_stop", 0))
        await c.until(lambda: c.task(task_id)["current_stop"] == 1)
        await c.status("r1", "Delivered", timeout=60)  # ... at the dish return, to be emptied
        assert c.robot("r1")["current_task"] == task_id
        await c.ok("next", robot="r1", task=task_id, stop=1)
        await c.until(lambda: c.task(task_id)["status"] == "done")
        await c.status("r1", "Awaiting", timeout=60)


async def test_a_robot_back_from_a_delivery_takes_the_plates_on_its_way(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        await c.subscribe("orders", "events")
        await c.ok("create", type="waypoint", name="dish return", x=9.0, y=10.8, kind="dish_return")
        await activate(c, "r1")
        [dish] = [(await c.ok("create", type="order", dish="Laksa", table="T1"))["order"]["id"]]
        [trip] = (await c.ok("create", type="task", orders=[dish]))["tasks"]
        await c.status("r1", "Loading")
        await c.ok("go", robot="r1", task=trip["id"])
        # While it is away, T5 asks for its plates: the bussing trip waits in the queue.
        call = (await c.ok("call", action="open", table="T5", kind="plates"))["call"]
        await c.until(lambda: c.task(trip["id"]).get("stops", [{}])[0].get("status") == "arrived")
        assert c.task(call["task_id"])["status"] == "queued"
        await c.ok("next", robot="r1", task=trip["id"], stop=0)
        # Food collected at T1: straight on to T5, never home in between.
        await c.until(lambda: c.task(call["task_id"]).get("robot") == "r1")
        await c.until(lambda: calls(c)[call["id"]].get("answered_at") is not None, timeout=60)
        statuses = [
            e["data"].get("status")
            for e in sorted(c.records.get("events", {}).values(), key=lambda e: e["id"])
            if e["kind"] == "robot.status" and e["ts"] >= c.task(trip["id"])["finished_at"]
        ]
        assert "Transit" not in statuses and "Awaiting" not in statuses, statuses


async def test_a_bussing_trip_to_a_blocked_table_is_not_sent(tmp_path: Path) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        await c.ok("create", type="waypoint", name="dish return", x=9.0, y=10.8, kind="dish_return")
        assert r.app.core is not None
        await r.app.core.service.block("T6", "r9: could not reach it", "r9")
        call = (await c.ok("call", action="open", table="T6", kind="plates"))["call"]
        await activate(c, "r1")
        # No robot goes to the dish return with nothing collected: the trip is cancelled,
        # the call stays open for staff.
        await c.until(lambda: c.task(call["task_id"]).get("status") == "cancelled")
        assert c.robot("r1")["status"] == "Awaiting" and c.robot("r1")["current_task"] is None
        assert calls(c)[call["id"]]["answered_at"] is None
        # Cleared, and the guests press again: the same call, and a robot is sent this time.
        await c.ok("clear", table="T6")
        again = (await c.ok("call", action="open", table="T6", kind="plates"))["call"]
        assert again["id"] == call["id"] and again["task_id"] not in (None, call["task_id"])
        await c.until(lambda: c.task(again["task_id"]).get("robot") == "r1")


async def test_a_renamed_table_keeps_its_buttons_and_calls_a_removed_one_ends_them(
    tmp_path: Path,
) -> None:
    async with restaurant(tmp_path, robots=1, config=site()) as r:
        c = await staff(r)
        owner = await owner_of(r)
        path = (await owner.ok("site", action="add_button", name="b14", table="T14"))["path"]
        call = (await c.ok("call", action="open", table="T14", kind="bill"))["call"]
        renamed = await owner.ok("site", action="rename_waypoint", waypoint="T14", name="Terrace 1")
        assert renamed["dependents"]["buttons"] == ["b14"]
        await c.until(lambda: calls(c)[call["id"]]["table"] == "Terrace 1")
        status, body, _ = await r.get(path)
        assert status == 200 and b"waiter at Terrace 1" in body
        [listed] = (await owner.ok("site", action="buttons"))["buttons"]
        assert listed["table"] == "Terrace 1"
        # Removed: its button is revoked with it and its open calls are cancelled.
        await owner.ok("site", action="remove_waypoint", waypoint="Terrace 1")
        assert (await r.get(path))[0] == 404
        await c.until(lambda: all(x["cancelled_at"] is not None for x in calls(c).values()))
        assert {x["table"] for x in calls(c).values()} == {"Terrace 1"}
        # A robot's charger cannot be removed from under it.
        await c.ok("create", type="waypoint", name="dock1", x=4.0, y=10.8, kind="dock")
        await owner.ok("site", action="edit_robot", robot="r1", dock="dock1")
        refused = await owner.error("site", "conflict", action="remove_waypoint", waypoint="dock1")
        assert refused["details"]["docks"] == ["r1"]
        await owner.ok("site", action="rename_waypoint", waypoint="dock1", name="charger A")
        await c.until(lambda: c.robot("r1").get("dock") == "charger A")
