"""The centre's side of the broker: every site's stream into the centre's database.

One MQTT session, persistent (``clean_session=False``, a fixed client id): while the centre
is away the broker queues what the sites publish for it (up to its ``max_queued_messages``;
beyond that, or what a broker crash loses since its last autosave, the sites send again when
asked). Each site is followed by its own :class:`~serveur.chain.ledger.SiteLedger` (one per
site, restored from the database at start): a batch is judged, the new part stored
(:meth:`~serveur.hq.store.HqStore.take`, idempotent), the site told what is stored (the
retained ``confirmed``), a gap asked again (``resend``). A site's liveness is checked every
``tick`` seconds and each change logged and stored once.

Nothing a site sends can stop the consumer: a payload that is not a message is logged and
dropped, and a site can only speak for itself (the topic's site must be the payload's; the
broker's ACL makes the topic the site's user name).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable
from typing import Any

from serveur.chain.address import ChainAddress
from serveur.chain.ledger import Liveness, SiteLedger, Verdict
from serveur.chain.wire import Confirmed, Resend, read_alive, read_batch, site_of, topic
from serveur.errors import InvalidField, ServeurError
from serveur.hq.store import HqStore
from serveur.mqtt.session import BACKOFF, keep_session

__all__ = ["Consumer"]

log = logging.getLogger(__name__)


class Consumer:
    def __init__(
        self,
        store: HqStore,
        address: ChainAddress,
        now: Callable[[], float],
        *,
        down_after: float = 300.0,
        tick: float = 1.0,
        backoff: tuple[float, ...] = BACKOFF,
    ) -> None:
        self.store = store
        self.address = address
        self.now = now
        self.down_after = down_after
        self.tick = tick
        self.backoff = backoff
        self.ledgers: dict[str, SiteLedger] = {}
        self.connected = asyncio.Event()
        self.changed = asyncio.Event()  # set at every stored batch or liveness change
        self._tasks: list[asyncio.Task[None]] = []
        self._listening_since: float | None = None  # when the broker link last came up
        self.refused = 0  # payloads that were not messages

    async def start(self) -> None:
        for row in await self.store.sites():
            ledger = self._ledger(row.site)
            ledger.stored, ledger.head, ledger.heard_at = row.stored, row.head, row.heard_at
            ledger.state = None if row.state is None else Liveness(row.state)
        self._tasks = [
            asyncio.create_task(self._run(), name="hq-consumer"),
            asyncio.create_task(self._watch(), name="hq-liveness"),
        ]

    async def close(self) -> None:
        for task in self._tasks:
            task.cancel()
        await asyncio.gather(*self._tasks, return_exceptions=True)
        self._tasks = []

    def _ledger(self, site: str) -> SiteLedger:
        if site not in self.ledgers:
            self.ledgers[site] = SiteLedger(site, down_after=self.down_after)
        return self.ledgers[site]

    async def _run(self) -> None:
        import aiomqtt  # only where the centre runs

        a = self.address

        def client() -> aiomqtt.Client:
            # A persistent session: the broker queues what the sites send while we are away.
            return a.client(
                f"serveur-{a.user}", clean_session=False, max_queued_incoming_messages=10000
            )

        async def setup(client: aiomqtt.Client) -> None:
            await client.subscribe("chain/+/events", qos=1)
            await client.subscribe("chain/+/alive", qos=1)
            self._listening_since = self.now()

        async def session(client: aiomqtt.Client) -> None:
            async for message in client.messages:
                await self._one(client, str(message.topic), message.payload)

        def down() -> None:
            self._listening_since = None

        await keep_session(
            f"hq on {a.describe()}",
            client,
            setup,
            session,
            connected=self.connected,
            log=log,
            backoff=self.backoff,
            on_down=down,
        )

    async def _one(self, client: Any, name: str, payload: object) -> None:
        found = site_of(name)
        if found is None or found[1] not in ("events", "alive"):
            return
        site, kind = found
        data = payload if isinstance(payload, bytes) else b""
        now = self.now()
        ledger = self._ledger(site)
        try:
            ask: int | None
            if kind == "events":
                batch = read_batch(site, data)
                decision = ledger.judge(batch, now)
                ask = decision.resend_from
                if decision.verdict is Verdict.TAKE:
                    stored = await self.store.take(site, decision.first, decision.events, now)
                    ledger.stored_up_to(stored, now)
                if decision.verdict is not Verdict.GAP:
                    await self._publish(client, site, "confirmed", Confirmed(ledger.stored))
                await self.store.heard(site, now, head=batch.last, site_time=None)
            else:
                alive = read_alive(site, data)
                ask = ledger.alive(alive.head, now)
                await self.store.heard(site, now, head=alive.head, site_time=alive.at)
                if ledger.stored:
                    await self._publish(client, site, "confirmed", Confirmed(ledger.stored))
            if ask is not None:
                log.info("hq: %s misses events from %d: asked again", site, ask)
                await self._publish(client, site, "resend", Resend(ask))
            if (change := ledger.heard(now)) is not None:
                await self._changed(site, change, now)
            self.changed.set()
        except InvalidField as exc:
            self.refused += 1
            log.warning("hq: %s sent what is not a chain message: %s", site, exc)
        except ServeurError as exc:  # the database busy or gone: the site sends again
            log.warning("hq: %s: %s", site, exc)

    async def _publish(self, client: Any, site: str, kind: str, msg: Confirmed | Resend) -> None:
        await client.publish(topic(site, kind), msg.encode(), qos=1, retain=kind == "confirmed")

    async def _changed(self, site: str, change: Liveness, now: float) -> None:
        if change is Liveness.DOWN:
            log.warning("hq: site %s is down (silent for %.0f s)", site, self.down_after)
        else:
            log.info("hq: site %s is up", site)
        await self.store.set_state(site, change.value, now)
        self.changed.set()

    async def _watch(self) -> None:
        while True:
            await asyncio.sleep(self.tick)
            now = self.now()
            for site, ledger in list(self.ledgers.items()):
                if (change := ledger.check(now, self._listening_since)) is not None:
                    with contextlib.suppress(ServeurError):
                        await self._changed(site, change, now)
