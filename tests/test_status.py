"""The status machine and the allowed-actions table (pure)."""

from __future__ import annotations

import pytest

from serveur.errors import NotAllowedInStatus
from serveur.status import (
    ALLOWED,
    Action,
    Event,
    RobotMode,
    RobotState,
    RobotStatus,
    apply,
    check_allowed,
)

S = RobotStatus


def run(*events: Event, start: RobotState | None = None) -> RobotState:
    st = start or RobotState()
    for ev in events:
        st = apply(st, ev)
    return st


def test_every_status_has_a_row() -> None:
    assert set(ALLOWED) == set(RobotStatus)
    assert ALLOWED[S.OFFLINE] == frozenset()


def test_delivery_round_trip() -> None:
    st = run(Event.LINK_UP, Event.AUTO)
    assert (st.status, st.mode) == (S.AWAITING, RobotMode.AUTO)
    st = run(Event.DISPATCH, Event.ARRIVED, start=st)
    assert st.status is S.DELIVERED
    st = run(Event.NEXT_TABLE, Event.ARRIVED, Event.NEXT_HOME, start=st)
    assert st.status is S.TRANSIT
    assert run(Event.ARRIVED, start=st).status is S.AWAITING


@pytest.mark.parametrize("moving", [Event.DISPATCH, Event.GO_HOME])
def test_stop_then_continue_resumes_the_same_kind_of_move(moving: Event) -> None:
    st = run(Event.LINK_UP, Event.AUTO, moving)
    before = st.status
    st = apply(st, Event.STOP)
    assert st.status is S.STOPPED and st.resume is before
    assert apply(st, Event.CONTINUE).status is before


def test_stop_then_cancel_goes_home() -> None:
    st = run(Event.LINK_UP, Event.AUTO, Event.DISPATCH, Event.STOP, Event.CANCEL)
    assert st.status is S.TRANSIT and st.mode is RobotMode.AUTO


def test_nav_failure_is_error_and_continue_retries() -> None:
    st = run(Event.LINK_UP, Event.AUTO, Event.DISPATCH, Event.NAV_FAILED)
    assert st.status is S.ERROR and st.resume is S.DELIVERING
    assert apply(st, Event.CONTINUE).status is S.DELIVERING
    assert apply(st, Event.CANCEL).status is S.TRANSIT


def test_control_is_taken_in_one_step_and_auto_is_not_from_manual() -> None:
    # Taking control needs no "Pause deliveries" first (issue 30): from Free, on a trip, at a
    # table or stopped, one `manual` makes the robot Manual, in mode manual.
    for path in (
        (Event.AUTO,),
        (Event.AUTO, Event.DISPATCH),
        (Event.AUTO, Event.DISPATCH, Event.ARRIVED),
        (Event.AUTO, Event.DISPATCH, Event.STOP),
        (Event.AUTO, Event.GO_HOME),
    ):
        st = run(Event.LINK_UP, *path)
        check_allowed(st.status, Action.MANUAL)
        taken = apply(st, Event.MANUAL)
        assert (taken.status, taken.mode) == (S.MANUAL, RobotMode.MANUAL), path
    manual = run(Event.LINK_UP, Event.MANUAL)
    assert manual.mode is RobotMode.MANUAL
    with pytest.raises(NotAllowedInStatus):
        apply(manual, Event.AUTO)
    with pytest.raises(NotAllowedInStatus):
        check_allowed(manual.status, Action.AUTO)
    released = apply(manual, Event.RELEASE)
    assert (released.status, released.mode) == (S.READY, RobotMode.OFF)


def test_link_loss_keeps_mode_and_what_to_resume() -> None:
    st = run(Event.LINK_UP, Event.AUTO, Event.DISPATCH, Event.LINK_DOWN)
    assert (st.status, st.mode, st.resume) == (S.OFFLINE, RobotMode.AUTO, S.DELIVERING)
    assert apply(st, Event.LINK_UP).status is S.DELIVERING
    idle = run(Event.LINK_UP, Event.AUTO, Event.LINK_DOWN)
    assert idle.resume is None
    assert apply(idle, Event.LINK_UP).status is S.AWAITING
    manual = run(Event.LINK_UP, Event.MANUAL, Event.LINK_DOWN, Event.LINK_UP)
    assert manual.status is S.MANUAL
    stopped = run(Event.LINK_UP, Event.AUTO, Event.GO_HOME, Event.STOP, Event.LINK_DOWN)
    back = apply(stopped, Event.LINK_UP)
    assert back.status is S.STOPPED and back.resume is None
    assert apply(back, Event.CONTINUE).status is S.TRANSIT  # resume lost: default is home


def test_link_events_are_idempotent() -> None:
    off = RobotState()
    assert apply(off, Event.LINK_DOWN) == off
    up = apply(off, Event.LINK_UP)
    assert apply(up, Event.LINK_UP) == up


@pytest.mark.parametrize("status", list(RobotStatus))
def test_allowed_table_is_enforced(status: RobotStatus) -> None:
    for action in Action:
        if action in ALLOWED[status]:
            check_allowed(status, action)
        else:
            with pytest.raises(NotAllowedInStatus) as ei:
                check_allowed(status, action)
            assert ei.value.code == "not_allowed_in_status"
            assert ei.value.details["status"] == status.value


def test_every_allowed_action_has_a_transition_or_needs_none() -> None:
    """Actions that change status must be accepted by apply() in every status allowing them."""
    changes = {
        Action.AUTO: Event.AUTO,
        Action.MANUAL: Event.MANUAL,
        Action.READY: Event.RELEASE,
        Action.STOP: Event.STOP,
        Action.CONTINUE: Event.CONTINUE,
        Action.CANCEL: Event.CANCEL,
    }
    for status, actions in ALLOWED.items():
        for action in actions & set(changes):
            apply(RobotState(status, RobotMode.AUTO, S.DELIVERING), changes[action])
        if Action.NEXT in actions:
            apply(RobotState(status), Event.NEXT_TABLE)
            apply(RobotState(status), Event.NEXT_HOME)
