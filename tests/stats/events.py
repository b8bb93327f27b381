"""A hand-made service as event records, the way the store writes them (docs/protocol.md).

Two robots, five dishes: a trip of two tables where staff skip one (its two dishes are
returned: one is sent again, the other voided), a dish voided at the pass, and a second trip
whose robot fails on the way (Error), is continued and delivers. Times are seconds after
T0 (2026-01-01 00:00 UTC).
"""

from __future__ import annotations

from typing import Any

from serveur.domain import EventRecord

T0 = 1_767_225_600.0


class Log:
    def __init__(self) -> None:
        self.events: list[EventRecord] = []

    def add(
        self,
        t: float,
        kind: str,
        *,
        robot: str | None = None,
        task: int | None = None,
        order: int | None = None,
        data: dict[str, Any] | None = None,
        **more: Any,
    ) -> None:
        self.events.append(
            EventRecord(
                id=len(self.events) + 1,
                ts=T0 + t,
                kind=kind,
                robot=robot,
                task_id=task,
                order_id=order,
                data={**(data or {}), **more},
            )
        )

    def status(self, t: float, robot: str, status: str, event: str) -> None:
        self.add(
            t,
            "robot.status",
            robot=robot,
            status=status,
            mode="auto",
            resume=None,
            last_error=None,
            event=event,
        )


def service() -> list[EventRecord]:
    g = Log()
    for r in ("r1", "r2"):
        g.add(0, "robot.restored", robot=r, status="Offline", mode="auto", resume=None)
        g.status(1, r, "Ready", "link_up")
        g.status(2, r, "Awaiting", "auto")

    def order(t: float, oid: int, table: str, dish: str, status: str = "pending") -> None:
        ready = T0 + t if status == "pending" else None
        g.add(t, "order.created", order=oid, dish=dish, table=table, key=None,
              ready_at=ready, status=status, quantity=1, note=None)  # fmt: skip

    order(5, 4, "T5", "Kopi", status="ordered")
    g.add(8, "order.cooking", order=4, data={"from": "ordered", "to": "cooking", "by": "user:k"})
    order(10, 1, "T3", "Laksa")
    order(12, 2, "T3", "Satay")
    order(14, 3, "T5", "Rendang")
    order(15, 5, "T9", "Cendol")
    g.add(20, "order.ready", order=4, data={"from": "cooking", "to": "pending", "by": "user:k"})
    stops1 = [{"table": "T3", "orders": [1, 2]}, {"table": "T5", "orders": [3, 4]}]
    g.add(22, "task.created", task=1, stops=stops1)
    # r1 takes it and visits T5 first (the planner's order).
    g.add(25, "task.started", robot="r1", task=1, data={"robot": "r1"}, stops=["T5", "T3"])
    g.status(25, "r1", "Loading", "assign")
    g.add(30, "order.voided", order=5, data={"from": "pending", "to": "voided", "by": "user:a"})
    g.status(40, "r1", "Delivering", "go")
    g.add(60, "stop.arrived", robot="r1", task=1, seq=0, table="T5")
    g.status(60, "r1", "Delivered", "arrived")
    g.add(90, "stop.skipped", robot="r1", task=1, seq=0, table="T5", orders=[3, 4],
          reason="skipped by staff", by="user:ana")  # fmt: skip
    g.status(90, "r1", "Delivering", "next_table")
    g.add(100, "stop.arrived", robot="r1", task=1, seq=1, table="T3")
    g.status(100, "r1", "Delivered", "arrived")
    g.add(120, "stop.done", robot="r1", task=1, seq=1, table="T3", orders=[1, 2])
    g.add(120, "task.finished", robot="r1", task=1)
    g.status(120, "r1", "Transit", "next_home")
    g.status(140, "r1", "Awaiting", "arrived")
    # Dish 3 is sent again; dish 4 is voided instead.
    g.add(150, "order.ready", order=3, data={"from": "returned", "to": "pending", "by": "user:a"})
    g.add(155, "order.voided", order=4, data={"from": "returned", "to": "voided", "by": "user:a"})
    g.add(160, "task.created", task=2, stops=[{"table": "T5", "orders": [3]}])
    g.add(160, "task.started", robot="r2", task=2, data={"robot": "r2"}, stops=["T5"])
    g.status(160, "r2", "Loading", "assign")
    g.status(170, "r2", "Delivering", "go")
    g.status(180, "r2", "Error", "nav_failed")
    g.status(200, "r2", "Delivering", "continue")
    g.add(210, "stop.arrived", robot="r2", task=2, seq=0, table="T5")
    g.status(210, "r2", "Delivered", "arrived")
    g.add(230, "stop.done", robot="r2", task=2, seq=0, table="T5", orders=[3])
    g.add(230, "task.finished", robot="r2", task=2)
    g.status(230, "r2", "Transit", "next_home")
    g.status(250, "r2", "Awaiting", "arrived")
    return g.events


def with_calls() -> list[EventRecord]:
    """:func:`service`, then guests' calls and bussing trips (as the server writes them, from
    serveur/store/calls.py and serveur/store/rounds.py), times after T0:

    * call 1, plates at T3 (300): bussing trip 10 at once on r1, at T3 at 320 (the call
      answered by ``robot:r1`` after 20 s), Done at 340, emptied at the dish return 400;
    * call 2, a waiter at T5 (310): escalated at 430, answered by staff at 460 (150 s);
    * call 3, the bill at T3 (330): answered by staff at 360 (30 s);
    * call 4, plates at T9 (500): bussing trip 11 queued (deliveries first), escalated at
      620, taken by r2 at 650, at T9 at 700 (200 s), on after the bussing wait at 820,
      emptied at 860;
    * call 5, a waiter at T9 (900): cancelled by staff at 905;
    * call 6, plates at T5 (950): bussing trip 12 queued, the call cancelled at 960 and the
      trip with it.
    """
    g = Log()
    g.events = service()

    def call(t: float, cid: int, kind: str, table: str) -> None:
        g.add(t, "call.opened", data={"kind": kind}, call=cid, table=table, source="table")

    def closed(t: float, how: str, cid: int, kind: str, table: str, by: str, after: float,
               task: int | None = None) -> None:  # fmt: skip
        data = {"kind": kind, "call": cid, "table": table, "by": by, "after": after}
        g.add(t, f"call.{how}", task=task, data=data)

    def bussing(t: float, task: int, table: str) -> None:
        stops = [{"table": table, "purpose": "collect"}, {"table": "dish", "purpose": "unload"}]
        g.add(t, "task.created", task=task, data={"kind": "bussing"}, stops=stops)

    def trip(task: int, robot: str, table: str, times: tuple[float, ...]) -> None:
        taken, at_table, done, at_return, emptied = times
        g.add(taken, "task.started", robot=robot, task=task, data={"robot": robot},
              stops=[table, "dish"])  # fmt: skip
        g.status(taken, robot, "Delivering", "dispatch")
        g.add(at_table, "stop.arrived", robot=robot, task=task, seq=0, table=table)
        g.status(at_table, robot, "Delivered", "arrived")
        g.add(done, "stop.done", robot=robot, task=task, seq=0, table=table, orders=[])
        g.status(done, robot, "Delivering", "next_table")
        g.add(at_return, "stop.arrived", robot=robot, task=task, seq=1, table="dish")
        g.status(at_return, robot, "Delivered", "arrived")
        g.add(emptied, "stop.done", robot=robot, task=task, seq=1, table="dish", orders=[])
        g.add(emptied, "task.finished", robot=robot, task=task)
        g.status(emptied, robot, "Transit", "next_home")
        g.status(emptied + 20, robot, "Awaiting", "arrived")

    call(300, 1, "plates", "T3")
    bussing(300, 10, "T3")
    call(310, 2, "waiter", "T5")
    call(330, 3, "bill", "T3")
    closed(360, "answered", 3, "bill", "T3", "user:ana", 30.0)
    g.add(430, "call.escalated", data={"kind": "waiter"}, call=2, table="T5")
    closed(460, "answered", 2, "waiter", "T5", "user:ana", 150.0)
    call(500, 4, "plates", "T9")
    bussing(500, 11, "T9")
    g.add(620, "call.escalated", data={"kind": "plates"}, call=4, table="T9")
    call(900, 5, "waiter", "T9")
    closed(905, "cancelled", 5, "waiter", "T9", "user:ana", 5.0)
    call(950, 6, "plates", "T5")
    bussing(950, 12, "T5")
    closed(960, "cancelled", 6, "plates", "T5", "user:ana", 10.0, task=12)
    g.add(960, "task.cancelled", task=12, reason="call 6 cancelled", orders_returned=[])
    # The robots' trips, each event at its time (the store's order: by time).
    trip(10, "r1", "T3", (300, 320, 340, 360, 400))
    closed(320, "answered", 1, "plates", "T3", "robot:r1", 20.0, task=10)
    trip(11, "r2", "T9", (650, 700, 820, 840, 860))
    closed(700, "answered", 4, "plates", "T9", "robot:r2", 200.0, task=11)
    g.events.sort(key=lambda e: e.ts)  # stable: same-time events keep their order
    return [e.model_copy(update={"id": i + 1}) for i, e in enumerate(g.events)]
