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

from pathlib import Path
from types import TracebackType
from typing import Self

from serveur.store.accounts import Accounts, Audit, TokenRecord, UserRecord
from serveur.store.calls import Calls
from serveur.store.events import Events
from serveur.store.orders import Orders
from serveur.store.outbox import Outbox
from serveur.store.robots import Robots
from serveur.store.rounds import Rounds
from serveur.store.service import Service
from serveur.store.sitemap import SiteBackdrop, SiteMap, StoredBackdrop, StoredMap
from serveur.store.sql import Db
from serveur.store.tasks import Tasks
from serveur.store.tickets import NewDish, Tickets
from serveur.store.waypoints import Waypoints
from serveur.store.zones import Zones

__all__ = ["NewDish", "Store", "StoredBackdrop", "StoredMap", "TokenRecord", "UserRecord"]


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
        self.rounds = Rounds(db)
        self.calls = Calls(db)
        self.tickets = Tickets(db)
        self.events = Events(db)
        self.outbox = Outbox(db)
        self.accounts = Accounts(db)
        self.audit = Audit(db)
        self.service = Service(db)
        self.zones = Zones(db)
        self.site_map = SiteMap(db)
        self.site_backdrop = SiteBackdrop(db)

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

    async def replace_with(self, backup: Path) -> None:
        """A restore, with the store closed: the database becomes the backup's content."""
        await self.db.replace_with(backup)
