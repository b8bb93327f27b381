"""The alert rules without sockets: when a condition is an alert, raised once, acknowledged,
cleared when the cause ends (serveur.core.alerts)."""

from __future__ import annotations

import pytest

from serveur.core.alerts import AlertBook, DishFact, RobotFact, Thresholds, conditions
from serveur.domain import AlertKind
from serveur.errors import Conflict, NotFound
from serveur.status import RobotMode, RobotStatus

S = RobotStatus
K = AlertKind
LIMITS = Thresholds(offline_after=10, low_battery=0.2, battery_ok=0.25, wait_at_table=60)


def robot(
    status: RobotStatus, since: float = 0.0, battery: float | None = 0.9, **kw: object
) -> RobotFact:
    return RobotFact("r1", status, RobotMode.AUTO, since, battery, **kw)  # type: ignore[arg-type]


def kinds(facts: list[RobotFact], now: float, **kw: object) -> set[AlertKind]:
    return {k for k, _ in conditions(facts, [], {}, now=now, limits=LIMITS, **kw)}  # type: ignore[arg-type]


def test_each_robot_condition_and_its_threshold() -> None:
    assert kinds([robot(S.ERROR, error="move_base ABORTED")], 0) == {K.ROBOT_ERROR}
    assert kinds([robot(S.OFFLINE, since=0)], 9.9) == set()  # a Wi-Fi blip is no alert
    assert kinds([robot(S.OFFLINE, since=0)], 10) == {K.ROBOT_OFFLINE}
    assert kinds([robot(S.DELIVERED, since=0, table="T5")], 59) == set()
    [(key, message)] = conditions(
        [robot(S.DELIVERED, since=0, table="T5")], [], {}, now=130, limits=LIMITS
    ).items()
    assert key == (K.WAITING_AT_TABLE, "r1") and message == "r1 waiting at T5 for 2 min"
    assert kinds([robot(S.AWAITING, battery=0.19)], 0) == {K.LOW_BATTERY}


def test_low_battery_clears_only_above_the_hysteresis() -> None:
    active = {(K.LOW_BATTERY, "r1")}
    assert kinds([robot(S.AWAITING, battery=0.22)], 0) == set()  # not raised at 22 %
    assert kinds([robot(S.AWAITING, battery=0.22)], 0, active=active) == {K.LOW_BATTERY}
    assert kinds([robot(S.AWAITING, battery=0.26)], 0, active=active) == set()


def test_dishes_waiting_at_the_pass_per_table_but_not_for_a_blocked_table() -> None:
    dishes = [DishFact("T1", 0.0), DishFact("T1", 100.0), DishFact("T2", 50.0), DishFact("T3", 0)]
    limits = Thresholds(dish_at_pass=120)
    got = conditions([], dishes, {"T3": "r1: no path"}, now=130, limits=limits)
    assert set(got) == {(K.DISH_WAITING, "T1"), (K.TABLE_UNREACHABLE, "T3")}
    assert got[(K.DISH_WAITING, "T1")] == "dishes for T1 at the pass for 2 min"
    assert "no path" in got[(K.TABLE_UNREACHABLE, "T3")]


def test_an_alert_is_raised_once_acknowledged_once_and_cleared_with_its_cause() -> None:
    book = AlertBook()
    key = (K.ROBOT_ERROR, "r1")
    [raised] = book.update({key: "r1 is stuck"}, now=1.0)
    assert (raised.id, raised.severity, raised.cleared_at) == (1, "critical", None)
    assert book.update({key: "r1 is stuck"}, now=2.0) == []  # still holding: not raised again
    acked = book.ack(raised.id, "user:ana", now=3.0)
    assert (acked.acked_by, acked.acked_at) == ("user:ana", 3.0)
    with pytest.raises(Conflict):
        book.ack(raised.id, "user:bo", now=4.0)
    [cleared] = book.update({}, now=5.0)
    assert (cleared.id, cleared.cleared_at, cleared.acked_by) == (1, 5.0, "user:ana")
    assert book.active() == []
    with pytest.raises(NotFound):
        book.ack(raised.id, "user:ana", now=6.0)
    # The same cause again later is a new alert, with a new number.
    [again] = book.update({key: "r1 is stuck"}, now=7.0)
    assert again.id == 2 and again.acked_at is None


def test_a_robot_waiting_a_minute_for_a_zone_is_an_alert_naming_who_holds_it() -> None:
    waiting = robot(S.DELIVERING, waiting_for=("aisle",), waiting_since=100.0, blockers=("r2",))
    assert kinds([waiting], 159.0) == set()  # a leg waits seconds for an aisle
    [(key, message)] = conditions([waiting], [], {}, now=160.0, limits=LIMITS).items()
    assert key == (K.ZONE_WAIT, "r1")
    assert message == "r1 has waited 1 min for aisle (held by r2)"
    assert kinds([robot(S.DELIVERING)], 1e6) == set()  # not waiting: nothing
