"""Persistence: the :class:`Store`, what the rest of serveur keeps its state in.

Every SQL statement of serveur lives in the store modules, behind :class:`Store`, so that the
server, the scheduler and the tests speak in domain records (``serveur.domain``) and the
database can change (SQLite on the robot's Raspberry Pi, MariaDB for a bigger site) without
touching them.

The store is composed, not inherited: a few parts, each a small class written once against
:mod:`serveur.store.sql` (``store.robots``, ``store.waypoints``, ``store.orders``,
``store.tasks``, ``store.events``, ``store.accounts``, ``store.audit``, ``store.service``,
``store.zones``), all given the same :class:`~serveur.store.sql.Db`: the backend's
connections and transactions, and its :class:`~serveur.store.sql.Dialect`. A backend
(:mod:`serveur.store.sqlite`, :mod:`serveur.store.mariadb`) is only a Db.

The store, not the server, owns the invariants that money and food depend on: a dish is on at
most one trip, a robot has at most one trip, "food collected" counts once. Each mutation is one
transaction that re-checks its preconditions with conditional UPDATEs and their row counts, so
they hold even with several server processes on one database, not only within one asyncio
loop. Each mutation also appends an ``events`` row in the same transaction: the audit trail
never disagrees with the state.

Times are floats given by the caller (``now``, simulated epoch seconds from the clock), never
read here, so that replays and tests are deterministic.

Migrations are ``migrations/NNN_name.<dialect>.sql`` (or ``NNN_name.sql`` when the SQL
is the same for every dialect): one numbered history shared by all backends, shipped in the
wheel and applied in order at :meth:`Store.open`, each in its own transaction, recorded in
``schema_migrations`` so that re-opening applies nothing twice.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from types import TracebackType
from typing import Any, Concatenate, Generic, ParamSpec, Self, TypeVar, overload

from serveur.store.accounts import Accounts, Audit, TokenRecord, UserRecord
from serveur.store.events import Events
from serveur.store.orders import Orders
from serveur.store.robots import Robots
from serveur.store.service import Service
from serveur.store.sql import Db
from serveur.store.tasks import Tasks
from serveur.store.waypoints import Waypoints
from serveur.store.zones import Zones

__all__ = ["Store", "TokenRecord", "UserRecord"]

P = ParamSpec("P")
R = TypeVar("R")


class _Via(Generic[P, R]):
    """A flat name of the store that is one part's method: ``store.add_robot`` is
    ``store.robots.add_robot`` (same signature, checked by mypy from the part's method)."""

    __slots__ = ("_name", "_part")

    def __init__(self, part: str, method: Callable[Concatenate[Any, P], R]) -> None:
        self._part = part
        self._name = method.__name__

    @overload
    def __get__(self, obj: None, owner: type) -> Self: ...

    @overload
    def __get__(self, obj: object, owner: type) -> Callable[P, R]: ...

    def __get__(self, obj: object | None, owner: type) -> Self | Callable[P, R]:
        if obj is None:
            return self
        method: Callable[P, R] = getattr(getattr(obj, self._part), self._name)
        return method


class Store:
    """The restaurant's persistent state. Use as ``async with open_store(url) as store:``.

    Its parts do the work (``store.tasks.start_task(...)``); the store opens and closes the
    database they share and backs it up.

    Errors: :class:`~serveur.errors.NotFound` for a missing robot/waypoint/order/task,
    :class:`~serveur.errors.Conflict` when the state forbids the change (an order already
    assigned, a robot already busy, a key reused for other content),
    :class:`~serveur.errors.InvalidField` for a malformed request, and
    :class:`~serveur.errors.StoreError` when the database itself fails. A method that raises
    has changed nothing.
    """

    def __init__(self, db: Db) -> None:
        self.db = db
        self.robots = Robots(db)
        self.waypoints = Waypoints(db)
        self.orders = Orders(db)
        self.tasks = Tasks(db)
        self.events = Events(db)
        self.accounts = Accounts(db)
        self.audit = Audit(db)
        self.service = Service(db)
        self.zones = Zones(db)

    async def __aenter__(self) -> Self:
        await self.open()
        return self

    async def __aexit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        await self.close()

    async def open(self) -> None:
        """Connect and apply the migrations not applied yet."""
        await self.db.open()

    async def close(self) -> None:
        """Close the connection; safe to call twice."""
        await self.db.close()

    def busy(self) -> bool:
        """True while a query may be running outside the event loop (in a worker thread).

        A virtual-time loop (serveur.replay.vtime) must not let time jump meanwhile: the query's
        result would arrive "later" than it did. False for a backend that cannot tell.
        """
        return self.db.busy()

    async def backup(self, path: str | Path) -> None:
        """Write a consistent copy of the live database to ``path`` (replaced atomically)."""
        await self.db.backup(path)

    async def integrity_check(self) -> str:
        """``"ok"`` when the database is sound, else the problems found, one per line."""
        return await self.db.integrity_check()

    # -- the flat names -------------------------------------------------------------------
    # Every part's method is also the store's, under the same name, for the callers written
    # before the parts (issue 27): a table of names, no code. A caller that says which part
    # it means (``store.tasks.cancel_task``) does not need them.

    # store.robots
    add_robot = _Via("robots", Robots.add_robot)
    update_robot = _Via("robots", Robots.update_robot)
    get_robot = _Via("robots", Robots.get_robot)
    list_robots = _Via("robots", Robots.list_robots)
    save_robot_state = _Via("robots", Robots.save_robot_state)
    save_robot_pose = _Via("robots", Robots.save_robot_pose)
    edit_robot = _Via("robots", Robots.edit_robot)
    remove_robot = _Via("robots", Robots.remove_robot)
    set_trays = _Via("robots", Robots.set_trays)
    # store.waypoints
    put_waypoint = _Via("waypoints", Waypoints.put_waypoint)
    get_waypoint = _Via("waypoints", Waypoints.get_waypoint)
    list_waypoints = _Via("waypoints", Waypoints.list_waypoints)
    delete_waypoint = _Via("waypoints", Waypoints.delete_waypoint)
    waypoint_dependents = _Via("waypoints", Waypoints.waypoint_dependents)
    rename_waypoint = _Via("waypoints", Waypoints.rename_waypoint)
    remove_waypoint = _Via("waypoints", Waypoints.remove_waypoint)
    # store.orders
    add_order = _Via("orders", Orders.add_order)
    get_order = _Via("orders", Orders.get_order)
    list_orders = _Via("orders", Orders.list_orders)
    cancel_order = _Via("orders", Orders.cancel_order)
    cart = _Via("orders", Orders.cart)
    step_order = _Via("orders", Orders.step_order)
    # store.tasks
    create_tasks = _Via("tasks", Tasks.create_tasks)
    get_task = _Via("tasks", Tasks.get_task)
    list_tasks = _Via("tasks", Tasks.list_tasks)
    start_task = _Via("tasks", Tasks.start_task)
    arrive_stop = _Via("tasks", Tasks.arrive_stop)
    complete_stop = _Via("tasks", Tasks.complete_stop)
    skip_stop = _Via("tasks", Tasks.skip_stop)
    finish_task = _Via("tasks", Tasks.finish_task)
    cancel_task = _Via("tasks", Tasks.cancel_task)
    requeue_task = _Via("tasks", Tasks.requeue_task)
    drop_stops = _Via("tasks", Tasks.drop_stops)
    # store.events
    add_event = _Via("events", Events.add_event)
    list_events = _Via("events", Events.list_events)
    # store.accounts
    add_user = _Via("accounts", Accounts.add_user)
    user_credentials = _Via("accounts", Accounts.user_credentials)
    list_users = _Via("accounts", Accounts.list_users)
    count_users = _Via("accounts", Accounts.count_users)
    remove_user = _Via("accounts", Accounts.remove_user)
    set_role = _Via("accounts", Accounts.set_role)
    set_password = _Via("accounts", Accounts.set_password)
    add_token = _Via("accounts", Accounts.add_token)
    token_by_digest = _Via("accounts", Accounts.token_by_digest)
    touch_token = _Via("accounts", Accounts.touch_token)
    list_tokens = _Via("accounts", Accounts.list_tokens)
    revoke_token = _Via("accounts", Accounts.revoke_token)
    tokens_alive = _Via("accounts", Accounts.tokens_alive)
    # store.audit
    add_audit = _Via("audit", Audit.add_audit)
    list_audit = _Via("audit", Audit.list_audit)
    recent_audit = _Via("audit", Audit.recent_audit)
    search_audit = _Via("audit", Audit.search_audit)
    # store.service
    list_menu = _Via("service", Service.list_menu)
    put_dish = _Via("service", Service.put_dish)
    list_blocks = _Via("service", Service.list_blocks)
    block_table = _Via("service", Service.block_table)
    unblock_table = _Via("service", Service.unblock_table)
    get_settings = _Via("service", Service.get_settings)
    put_settings = _Via("service", Service.put_settings)
    # store.zones
    list_zones = _Via("zones", Zones.list_zones)
    put_zone = _Via("zones", Zones.put_zone)
    delete_zone = _Via("zones", Zones.delete_zone)
