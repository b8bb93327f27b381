"""The authorisation rules, password hashing and throttles — pure, no sockets."""

from __future__ import annotations

import json
from typing import Any

import pytest
from hypothesis import given
from hypothesis import strategies as st

from serveur import protocol as P
from serveur.errors import Forbidden, InvalidField, RateLimited, Unauthorized
from serveur.security import auth
from serveur.security.auth import Principal, Role, Scope
from tests.conftest import PRODUCT_SCRYPT_N

ROBOT = {"robot": "r1"}


def parse(body: dict[str, Any]) -> Any:
    return P.parse_client(json.dumps(body))


# One example of every instruction (verb, and sub-type where there is one).
MESSAGES: dict[str, dict[str, Any]] = {
    "data": {"clientmsg": "data", "topics": ["robots"]},
    "create waypoint": {"clientmsg": "create", "type": "waypoint", "name": "w", "x": 1, "y": 2},
    "create order": {"clientmsg": "create", "type": "order", "dish": "soup", "table": "T1"},
    "create task": {"clientmsg": "create", "type": "task", "orders": [1]},
    "create robot": {"clientmsg": "create", "type": "robot", "name": "r9", "url": "ws://h:1"},
    "control auto": {"clientmsg": "control", "action": "auto", **ROBOT},
    "control manual": {"clientmsg": "control", "action": "manual", **ROBOT},
    "control teleop": {"clientmsg": "control", "action": "teleop", "vx": 0, "wz": 0, **ROBOT},
    "control initialpose": {
        "clientmsg": "control",
        "action": "initialpose",
        "x": 1,
        "y": 1,
        "yaw": 0,
        **ROBOT,
    },
    "control goal": {"clientmsg": "control", "action": "goal", "x": 1, "y": 1, "yaw": 0, **ROBOT},
    "control goto": {"clientmsg": "control", "action": "goto", "waypoint": "T1", **ROBOT},
    "ready": {"clientmsg": "ready", **ROBOT},
    "next": {"clientmsg": "next", **ROBOT},
    "stop": {"clientmsg": "stop", **ROBOT},
    "continue": {"clientmsg": "continue", **ROBOT},
    "cancel": {"clientmsg": "cancel", **ROBOT},
    "order table": {"clientmsg": "order", "table": "T1"},
    "order robot": {"clientmsg": "order", **ROBOT},
    "go": {"clientmsg": "go", **ROBOT},
    "skip": {"clientmsg": "skip", **ROBOT},
    "dish": {"clientmsg": "dish", "order": 1, "action": "ready"},
    "ack": {"clientmsg": "ack", "alert": 1},
    "clear": {"clientmsg": "clear", "table": "T1"},
    "create dish": {"clientmsg": "create", "type": "dish", "name": "Laksa"},
    # Zones: the owner draws them (scope site); staff break a lease (scope tasks).
    "create zone": {
        "clientmsg": "create",
        "type": "zone",
        "name": "aisle",
        "points": [[0, 0], [1, 0], [1, 1]],
    },
    "release": {"clientmsg": "release", "zone": "aisle"},
    # The owner's console: the site (scope site; its audit search, scope audit) and the
    # statistics (scope stats).
    "site edit_robot": {"clientmsg": "site", "action": "edit_robot", "trays": 2, **ROBOT},
    "site remove_robot": {"clientmsg": "site", "action": "remove_robot", **ROBOT},
    "site dependents": {"clientmsg": "site", "action": "dependents", "waypoint": "T1"},
    "site rename_waypoint": {
        "clientmsg": "site",
        "action": "rename_waypoint",
        "waypoint": "T1",
        "name": "Patio 1",
    },
    "site remove_waypoint": {"clientmsg": "site", "action": "remove_waypoint", "waypoint": "T1"},
    "site remove_zone": {"clientmsg": "site", "action": "remove_zone", "zone": "aisle"},
    "site settings": {"clientmsg": "site", "action": "settings"},
    "site set_settings": {"clientmsg": "site", "action": "set_settings", "table_timeout": 60},
    "site audit": {"clientmsg": "site", "action": "audit", "verb": "site"},
    "site upload": {
        "clientmsg": "site",
        "action": "upload",
        "kind": "plan",
        "name": "plan.png",
        "size": 10,
    },
    "site upload_part": {
        "clientmsg": "site",
        "action": "upload_part",
        "upload": 1,
        "offset": 0,
        "data": "eA==",
    },
    "site set_map": {"clientmsg": "site", "action": "set_map", "yaml": 1, "image": 2},
    "site probe_robot": {"clientmsg": "site", "action": "probe_robot", "url": "ws://10.0.0.9:9090"},
    "site align_map": {
        "clientmsg": "site",
        "action": "align_map",
        "points": [{"plan": [0, 0], "map": [0.0, 0.0]}, {"plan": [100, 0], "map": [3.0, 0.0]}],
    },
    "site backups": {"clientmsg": "site", "action": "backups"},
    "site backup_now": {"clientmsg": "site", "action": "backup_now"},
    "site download_backup": {
        "clientmsg": "site",
        "action": "download_backup",
        "name": "serveur-now-20261128-221502.db",
    },
    "site restore": {"clientmsg": "site", "action": "restore", "upload": 1},
    "site plan_map": {
        "clientmsg": "site",
        "action": "plan_map",
        "upload": 1,
        "across": {"a": [0, 0], "b": [100, 0], "metres": 5.0},
        "along": {"a": [0, 0], "b": [0, 100], "metres": 5.0},
    },
    "stats figures": {"clientmsg": "stats", "action": "figures", "by": "hour"},
    "stats trips": {"clientmsg": "stats", "action": "trips", "start": "2026-11-24"},
    "stats forecast": {
        "clientmsg": "stats",
        "action": "forecast",
        "day": "2026-11-20",
        "robots": [2],
    },
    "stats forecast_cancel": {"clientmsg": "stats", "action": "forecast_cancel"},
    "site add_button": {"clientmsg": "site", "action": "add_button", "name": "b", "table": "T1"},
    "site buttons": {"clientmsg": "site", "action": "buttons"},
    "site revoke_button": {"clientmsg": "site", "action": "revoke_button", "name": "b"},
    "call open T1": {"clientmsg": "call", "action": "open", "table": "T1", "kind": "waiter"},
    "call open T2": {"clientmsg": "call", "action": "open", "table": "T2", "kind": "bill"},
    "call answer": {"clientmsg": "call", "action": "answer", "call": 1},
    "call cancel": {"clientmsg": "call", "action": "cancel", "call": 1},
    "create bussing": {"clientmsg": "create", "type": "bussing", "tables": ["T1"]},
    "charge": {"clientmsg": "charge", **ROBOT},
    "work": {"clientmsg": "work", **ROBOT},
    "cruise": {"clientmsg": "cruise", "route": ["T1", "T2"], **ROBOT},
    "stats last_service": {"clientmsg": "stats", "action": "last_service", "before": "2026-11-24"},
    # The chain's head office reached or not, and the outbox: the site's (scope site).
    "chain": {"clientmsg": "chain"},
}
#: The owner's console messages: never staff's, never a screen's.
SITE = {k for k in MESSAGES if k.startswith("site ")} | {"chain"}
#: The backups: every account is in them and a restore sets them all, so they need the accounts
#: scope, which only an owner's session has (no token can be given it).
BACKUPS = {"site backups", "site backup_now", "site download_backup", "site restore"}
STATS = {k for k in MESSAGES if k.startswith("stats ")}

OWNER = Principal(Role.OWNER, 1, user="o", scopes=auth.OWNER_SCOPES)
STAFF = Principal(Role.STAFF, 2, user="s", scopes=auth.STAFF_SCOPES)
R1_SCREEN = Principal(Role.ROBOT_SCREEN, 3, robot="r1")
R2_SCREEN = Principal(Role.ROBOT_SCREEN, 4, robot="r2")
T1_SCREEN = Principal(Role.TABLE_SCREEN, 5, table="T1")
T2_SCREEN = Principal(Role.TABLE_SCREEN, 6, table="T2")
POS = Principal(Role.INTEGRATION, 7, scopes=frozenset({Scope.ORDERS, Scope.READ}))
# Scripts given the owner's console scopes, one each.
SITE_SCRIPT = Principal(Role.INTEGRATION, 8, scopes=frozenset({Scope.SITE}))
AUDIT_SCRIPT = Principal(Role.INTEGRATION, 9, scopes=frozenset({Scope.AUDIT}))
STATS_SCRIPT = Principal(Role.INTEGRATION, 10, scopes=frozenset({Scope.STATS}))

# Who may send what. Anything not listed for a principal must be refused.
ALLOWED: dict[str, set[str]] = {
    "owner": set(MESSAGES),
    # The menu, the site (zones included) and the statistics are the owner's.
    "staff": set(MESSAGES) - {"create robot", "create dish", "create zone"} - SITE - STATS,
    "r1 screen": {"next", "stop", "continue", "cancel", "go", "skip", "order robot", "data"},
    "r2 screen": {"data"},  # its own robot's view of the robots topic
    # "Food collected" on the table's own screen: the core checks the robot is at T1. A
    # table's screen calls for its own table only.
    "T1 screen": {"order table", "next", "call open T1"},
    "T2 screen": {"next", "call open T2"},
    # A POS or kitchen display script: dishes in, dishes ready.
    "pos": {"create order", "dish", "data", "order table", "order robot"},
    # Every site action but the audit search, which needs the audit scope (and no topic:
    # ``data`` needs read).
    "site script": SITE - {"site audit"} - BACKUPS | {"create zone"},
    "audit script": {"site audit"},
    "stats script": STATS,
}
PRINCIPALS = {
    "owner": OWNER,
    "staff": STAFF,
    "r1 screen": R1_SCREEN,
    "r2 screen": R2_SCREEN,
    "T1 screen": T1_SCREEN,
    "T2 screen": T2_SCREEN,
    "pos": POS,
    "site script": SITE_SCRIPT,
    "audit script": AUDIT_SCRIPT,
    "stats script": STATS_SCRIPT,
}


@pytest.mark.parametrize("who", list(PRINCIPALS))
@pytest.mark.parametrize("what", list(MESSAGES))
def test_the_whole_permission_table(who: str, what: str) -> None:
    msg = parse(MESSAGES[what])
    p = PRINCIPALS[who]
    if what in ALLOWED[who]:
        auth.authorize(p, msg)
    else:
        with pytest.raises(Forbidden):
            auth.authorize(p, msg)


def test_anonymous_may_only_log_in() -> None:
    for body in MESSAGES.values():
        with pytest.raises(Unauthorized):
            auth.authorize(None, parse(body))
    auth.authorize(None, parse({"clientmsg": "login", "token": "srv_x"}))


def test_every_verb_and_action_is_in_the_table() -> None:
    names = {" ".join(k.split()[:2]) for k in MESSAGES}
    for verb, (_, subs) in P._SUBTAGS.items():
        if verb in ("site", "stats"):
            assert {f"{verb} {s}" for s in subs} <= names, verb


def test_the_owners_console_scopes() -> None:
    for what in SITE | STATS:
        need = auth.required_scope(parse(MESSAGES[what]))
        if what == "site audit":
            assert need is Scope.AUDIT
        elif what in BACKUPS:
            assert need is Scope.ACCOUNTS
        else:
            assert need is (Scope.SITE if what in SITE else Scope.STATS), what
        assert need in auth.OWNER_SCOPES and need not in auth.STAFF_SCOPES
    with pytest.raises(Forbidden) as refused:
        auth.authorize(STAFF, parse(MESSAGES["site audit"]))
    assert refused.value.details == {"scope": "audit"}
    assert auth.parse_scopes("site,stats") == {Scope.SITE, Scope.STATS}


def test_topics_per_role() -> None:
    assert auth.topic_allowed(STAFF, "events") and not auth.topic_allowed(STAFF, "audit")
    assert auth.topic_allowed(OWNER, "audit")
    assert auth.topic_allowed(R1_SCREEN, "pose:r1") and not auth.topic_allowed(R1_SCREEN, "pose:r2")
    assert not auth.topic_allowed(R1_SCREEN, "events")
    assert auth.topic_allowed(T1_SCREEN, "orders") and not auth.topic_allowed(T1_SCREEN, "robots")
    for who in (T1_SCREEN, R1_SCREEN):
        with pytest.raises(Forbidden):
            auth.authorize(who, parse({"clientmsg": "data", "topics": ["waypoints"]}))
    # The site's settings (the pages' languages): every role reads them, the screens too.
    for who in (OWNER, STAFF, R1_SCREEN, R2_SCREEN, T1_SCREEN, T2_SCREEN, POS):
        assert auth.topic_allowed(who, "settings"), who
        auth.authorize(who, parse({"clientmsg": "data", "topics": ["settings"]}))
    settings = _Rec(table_timeout=180.0, trays=4)
    for who in (R1_SCREEN, T1_SCREEN):
        assert auth.visible(who, "settings", settings, lambda task: None)
    for who in (SITE_SCRIPT, STATS_SCRIPT):  # without read, no topic but their scope's
        assert not auth.topic_allowed(who, "settings")
    # A forecast is the owner's (scope stats): not staff's, not a screen's.
    assert auth.topic_allowed(OWNER, "forecast") and auth.topic_allowed(STATS_SCRIPT, "forecast")
    for who in (STAFF, R1_SCREEN, T1_SCREEN, POS, SITE_SCRIPT):
        assert not auth.topic_allowed(who, "forecast"), who
    assert auth.topic_allowed(AUDIT_SCRIPT, "audit") and not auth.topic_allowed(STAFF, "audit")


@given(st.floats(min_value=1e-6, max_value=600.0), st.sampled_from([0.01, 0.1]))
def test_retry_after_is_never_below_the_wait(wait: float, step: float) -> None:
    after = RateLimited("slow down", wait=wait, step=step).details["retry_after"]
    assert after >= wait and after > 0
    assert after - wait < step + 1e-9  # rounded up by less than a step
    assert after == round(after, 2)  # a short decimal on the wire


def test_a_client_that_waits_retry_after_is_let_through() -> None:
    """The 300-request burst of issue 26 on virtual time: 4 ms waits were said as 0.0."""
    lim = auth.RateLimiter(rate=20.0, burst=40.0, now=0.0)
    now, refusals = 0.0, 0
    for _ in range(300):
        now += 0.0037  # a script sending as fast as it can
        wait = lim.allow(now)
        if wait:
            refusals += 1
            after = RateLimited("slow down", wait=wait).details["retry_after"]
            assert after > 0
            now += after  # the client does as told ...
            assert lim.allow(now) == 0.0  # ... and is served
    assert refusals > 100
    throttle = auth.LoginThrottle(free=1, base=1.0)
    throttle.failure(["k"], 0.0)  # locked 1 s
    with pytest.raises(RateLimited) as exc:
        throttle.check(["k"], 0.97)  # 30 ms left: said as 0.1 s, not 0.0
    assert exc.value.details["retry_after"] == 0.1


class _Rec:
    def __init__(self, **kw: Any) -> None:
        self.__dict__.update(kw)


def test_views_of_screens() -> None:
    tasks = {10: "r1", 11: "r2"}
    look = tasks.get
    assert auth.visible(R1_SCREEN, "robots", _Rec(name="r1"), look)
    assert not auth.visible(R1_SCREEN, "robots", _Rec(name="r2"), look)
    assert auth.visible(R1_SCREEN, "tasks", _Rec(robot="r1"), look)
    assert not auth.visible(R1_SCREEN, "tasks", _Rec(robot=None), look)
    assert auth.visible(R1_SCREEN, "orders", _Rec(task_id=10, table="T5"), look)
    assert not auth.visible(R1_SCREEN, "orders", _Rec(task_id=11, table="T5"), look)
    assert not auth.visible(R1_SCREEN, "orders", _Rec(task_id=None, table="T5"), look)
    assert auth.visible(T1_SCREEN, "orders", _Rec(table="T1"), look)
    assert not auth.visible(T1_SCREEN, "orders", _Rec(table="T2"), look)
    assert auth.visible(STAFF, "orders", _Rec(table="T2"), look)


def test_unknown_verbs_need_a_rule() -> None:
    with pytest.raises(Forbidden):
        auth.required_scope(_Rec(clientmsg="launch"))


def test_scopes_parse() -> None:
    assert auth.parse_scopes("orders, read,") == {Scope.ORDERS, Scope.READ}
    with pytest.raises(InvalidField):
        auth.parse_scopes("orders,root")


def test_passwords_hash_and_verify() -> None:
    h = auth.hash_password("correct horse", n=2**10)
    assert h.startswith("scrypt$1024$") and "correct horse" not in h
    assert auth.verify_password("correct horse", h)
    assert not auth.verify_password("correct hors", h)
    assert h != auth.hash_password("correct horse", n=2**10)  # salted
    assert not auth.verify_password("x", "garbage")
    assert not auth.verify_password("x", "bcrypt$1$2$3$4$5")
    with pytest.raises(InvalidField):
        auth.check_password_strength("short")


def test_the_product_hashes_at_n_2_15_and_tests_cheaper() -> None:
    # tests/conftest.py lowers N for this process; the product's own cost stays 2**15, and a
    # hash made at it verifies wherever N was lowered (it names its N).
    assert PRODUCT_SCRYPT_N == 2**15
    assert auth.hash_password("correct horse").startswith("scrypt$1024$")
    h = auth.hash_password("correct horse", n=PRODUCT_SCRYPT_N)
    assert h.startswith("scrypt$32768$8$1$") and auth.verify_password("correct horse", h)


def test_tokens_are_random_and_stored_as_digests() -> None:
    a, b = auth.new_token(), auth.new_token()
    assert a != b and a.startswith(auth.TOKEN_PREFIX) and len(a) > 40
    assert len(auth.token_digest(a)) == 64 and auth.token_digest(a) != auth.token_digest(b)


def test_login_throttle_doubles_and_clears() -> None:
    t = auth.LoginThrottle(free=3, base=1.0, cap=8.0)
    keys = ["addr:1.2.3.4", "user:bob"]
    for _ in range(2):
        t.failure(keys, 0.0)
    t.check(keys, 0.0)  # two failures: free
    t.failure(keys, 0.0)  # third: locked 1 s
    with pytest.raises(RateLimited) as exc:
        t.check(keys, 0.5)
    assert exc.value.details["retry_after"] == 0.5
    t.check(keys, 1.0)
    t.failure(keys, 1.0)  # fourth: 2 s
    with pytest.raises(RateLimited):
        t.check(["user:bob"], 2.9)
    for _ in range(10):
        t.failure(keys, 3.0)
    with pytest.raises(RateLimited) as exc:
        t.check(keys, 3.0)
    assert exc.value.details["retry_after"] == 8.0  # capped
    t.check(["addr:other"], 3.0)  # other keys unaffected
    t.success(keys)
    t.check(keys, 3.0)


def test_login_throttle_memory_is_bounded() -> None:
    t = auth.LoginThrottle(max_keys=100)
    for i in range(1000):
        t.failure([f"addr:{i}"], 0.0)
    assert len(t._keys) == 100


def test_rate_limiter_bucket() -> None:
    lim = auth.RateLimiter(rate=10.0, burst=5.0, now=0.0)
    assert [lim.allow(0.0) for _ in range(5)] == [0.0] * 5
    wait = lim.allow(0.0)
    assert wait == pytest.approx(0.1)
    assert lim.allow(0.1) == 0.0  # one token back after 0.1 s
    assert lim.allow(0.1) > 0
    assert [lim.allow(10.0) for _ in range(5)] == [0.0] * 5  # refilled, never above burst
    assert lim.allow(10.0) > 0
