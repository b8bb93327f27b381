"""The pure rules of the modes besides delivering (serveur.core.calls, serveur.core.modes) and
their rows of the status machine: no sockets, no clock."""

from __future__ import annotations

import pytest

from serveur.core.calls import ButtonLimits, answer_times, button_digest, due, new_button_token
from serveur.core.modes import RISE_WITHIN, ChargeWatch, charge_due, charged, stop_wait
from serveur.domain import Call, CallKind, StopPurpose
from serveur.errors import NotAllowedInStatus
from serveur.status import Action, Event, RobotMode, RobotState, RobotStatus, apply, check_allowed

S = RobotStatus


def call(i: int, opened: float, **kw: object) -> Call:
    return Call(id=i, table="T1", kind=CallKind.WAITER, source="table", opened_at=opened, **kw)


def test_a_button_may_press_three_times_then_once_every_ten_seconds() -> None:
    limits = ButtonLimits()
    assert [limits.allow("b", 0.0) for _ in range(3)] == [0.0, 0.0, 0.0]
    assert limits.allow("b", 0.0) == pytest.approx(10.0)
    assert limits.allow("other", 0.0) == 0.0  # per button
    assert limits.allow("b", 5.0) == pytest.approx(5.0)
    assert limits.allow("b", 10.0) == 0.0
    limits.forget("b")
    assert limits.allow("b", 10.0) == 0.0


def test_button_tokens_are_random_and_kept_as_digests() -> None:
    a, b = new_button_token(), new_button_token()
    assert a != b and a.startswith("srb_") and len(a) > 40
    assert button_digest(a) != button_digest(b) and len(button_digest(a)) == 64
    assert a not in button_digest(a)


def test_calls_escalate_once_when_nobody_answered_in_time() -> None:
    calls = [
        call(1, 0.0),
        call(2, 50.0),
        call(3, 0.0, escalated_at=120.0),
        call(4, 0.0, answered_at=10.0),
        call(5, 0.0, cancelled_at=5.0),
    ]
    assert due(calls, 130.0, 120.0) == [1]
    assert due(calls, 170.0, 120.0) == [1, 2]
    assert answer_times(calls) == {CallKind.WAITER: [10.0]}


def test_how_long_a_robot_waits_at_each_kind_of_stop() -> None:
    limits = dict(table_timeout=180.0, bussing_wait=120.0, cruise_pause=20.0)
    assert stop_wait(StopPurpose.DELIVER, special=False, **limits) == 180.0
    assert stop_wait(StopPurpose.DELIVER, special=True, **limits) is None  # a birthday
    assert stop_wait(StopPurpose.COLLECT, special=False, **limits) == 120.0
    assert stop_wait(StopPurpose.UNLOAD, special=False, **limits) is None  # staff empty it
    assert stop_wait(StopPurpose.VISIT, special=False, **limits) == 20.0
    off = {**limits, "table_timeout": None}
    assert stop_wait(StopPurpose.DELIVER, special=False, **off) is None


def test_a_free_robot_with_a_dock_charges_below_the_level_and_returns_above() -> None:
    assert charge_due(S.AWAITING, 0.2, has_dock=True, below=0.25)
    assert not charge_due(S.AWAITING, 0.2, has_dock=False, below=0.25)
    assert not charge_due(S.DELIVERING, 0.2, has_dock=True, below=0.25)  # finishes its trip
    assert not charge_due(S.AWAITING, None, has_dock=True, below=0.25)
    assert not charge_due(S.AWAITING, 0.3, has_dock=True, below=0.25)
    assert charged(S.CHARGING, 0.9, until=0.9) and not charged(S.CHARGING, 0.89, until=0.9)
    assert not charged(S.AWAITING, 1.0, until=0.9)


def test_a_battery_that_does_not_rise_on_the_dock_is_noticed() -> None:
    w = ChargeWatch()
    assert not w.not_charging(0.0, 0.3)  # not docked
    w.docked(0.0, 0.30)
    assert not w.not_charging(RISE_WITHIN - 1, 0.305)
    assert w.not_charging(RISE_WITHIN, 0.305)
    assert not w.not_charging(RISE_WITHIN + 1, 0.32)  # it rose: the count starts again
    assert not w.not_charging(2 * RISE_WITHIN, 0.32)
    assert w.not_charging(2 * RISE_WITHIN + 2, 0.32)
    w.docked(0.0, 1.0)
    assert not w.not_charging(10 * RISE_WITHIN, 1.0)  # full: nothing to rise
    w.left()
    assert not w.not_charging(20 * RISE_WITHIN, 0.1)


def test_charging_in_the_status_machine() -> None:
    st = RobotState(S.AWAITING, RobotMode.AUTO)
    check_allowed(S.AWAITING, Action.CHARGE)
    check_allowed(S.AWAITING, Action.CRUISE)
    st = apply(st, Event.CHARGE)
    assert st.status is S.TRANSIT
    st = apply(st, Event.DOCKED)
    assert st.status is S.CHARGING
    with pytest.raises(NotAllowedInStatus):
        check_allowed(S.CHARGING, Action.GO)
    check_allowed(S.CHARGING, Action.WORK)
    # Offline on the dock, it comes back Charging.
    down = apply(st, Event.LINK_DOWN)
    assert (down.status, down.resume) == (S.OFFLINE, S.CHARGING)
    assert apply(down, Event.LINK_UP).status is S.CHARGING
    assert apply(st, Event.UNDOCK).status is S.TRANSIT
    assert apply(st, Event.MANUAL).status is S.MANUAL
    with pytest.raises(NotAllowedInStatus):
        apply(RobotState(S.DELIVERING, RobotMode.AUTO), Event.DOCKED)
    # A cruise called back goes home from a move or a stop.
    assert apply(RobotState(S.DELIVERING, RobotMode.AUTO), Event.RECALL).status is S.TRANSIT
    assert apply(RobotState(S.DELIVERED, RobotMode.AUTO), Event.RECALL).status is S.TRANSIT
