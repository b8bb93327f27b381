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
