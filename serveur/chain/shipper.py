"""The site's outbox to the chain's broker, in order, QoS 1 (``serveur run --chain``).

One task per site server. It reads the outbox after what the broker last acknowledged
(``outbox_state.sent``, kept in the site's database), publishes the events in batches on
``chain/<site>/events`` and, once the broker's PUBACK is in (aiomqtt's ``publish`` waits for
it at QoS 1), notes the new ``sent`` — so a restart, a kill -9, a day without internet or a
broker restart resumes exactly there. A crash between the PUBACK and the note sends a batch
twice: the centre ignores what it has (:mod:`serveur.chain.ledger`). A PUBACK is the broker's
word only: what the centre stored comes back as the retained ``confirmed`` message, and only
then (and after ``retention``) are outbox rows deleted. When the centre misses something it
says ``resend`` and the shipper goes back there.

Every ``heartbeat`` seconds the site says it is alive with its last number (the centre shows
a silent site as down, and asks for a lost tail).
The connection is kept by :func:`serveur.mqtt.session.keep_session` (the broker logged once
down and once up).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from typing import Any

from serveur.chain.address import ChainAddress
from serveur.chain.wire import (
    Alive,
    batches,
    read_confirmed,
    read_resend,
    site_of,
    topic,
)
from serveur.clock import Clock
from serveur.errors import InvalidField
from serveur.mqtt.session import BACKOFF, keep_session
from serveur.store.base import Store

__all__ = ["PRUNE_EVERY", "Shipper"]

log = logging.getLogger(__name__)

#: Wall seconds between two prunes of the outbox.
PRUNE_EVERY = 60.0


class Shipper:
    """Ships one site's outbox while the server runs."""

    def __init__(
        self,
        store: Store,
        address: ChainAddress,
        clock: Clock,
        *,
        poll: float = 1.0,
        spacing: float = 0.25,
        heartbeat: float = 30.0,
        retention: float = 7 * 86400.0,
        batch_events: int = 500,
        batch_bytes: int = 256 * 1024,
        backoff: tuple[float, ...] = BACKOFF,
    ) -> None:
        """``poll``: seconds between two looks at the outbox when nothing woke it (the server
        wakes it as it records events; the look finds what another process wrote);
        ``spacing``: the least time between two batches outside a catch-up (wall time);
        ``retention``: seconds a confirmed row stays (for a centre that must ask again)."""
        self.store = store
        self.address = address
        self.site = address.user
        self.clock = clock
        self.poll = poll
        self.spacing = spacing
        self._last_batch_at = -spacing
        self.heartbeat = heartbeat
        self.retention = retention
        self.batch_events = batch_events
        self.batch_bytes = batch_bytes
        self.backoff = backoff
        self.connected = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self._rewind: int | None = None
        self._wake = asyncio.Event()
        self.published = 0  # batches acknowledged by the broker (for the benchmark)
        self._pruned_at = -PRUNE_EVERY  # loop time of the last prune

    def start(self) -> None:
        if self._task is None:
            self._task = asyncio.create_task(self._run(), name="chain-shipper")

    async def close(self) -> None:
        if self._task is not None:
            self._task.cancel()
            await asyncio.gather(self._task, return_exceptions=True)
            self._task = None

    def wake(self) -> None:
        """New events were recorded: look now rather than at the next poll."""
        self._wake.set()

    async def _run(self) -> None:
        import aiomqtt  # only where a chain is configured

        a = self.address

        def client() -> aiomqtt.Client:
            return a.client(f"serveur-site-{self.site}")

        async def setup(client: aiomqtt.Client) -> None:
            await client.subscribe(topic(self.site, "resend"), qos=1)
            await client.subscribe(topic(self.site, "confirmed"), qos=1)

        async def session(client: aiomqtt.Client) -> None:
            listen = asyncio.create_task(self._listen(client))
            try:
                await self._send(client)
            finally:
                listen.cancel()
                with contextlib.suppress(asyncio.CancelledError, aiomqtt.MqttError):
                    await listen

        await keep_session(
            f"chain: site {self.site!r} on {a.describe()}",
            client,
            setup,
            session,
            connected=self.connected,
            log=log,
            backoff=self.backoff,
        )

    async def _send(self, client: Any) -> None:
        state = await self.store.outbox.state()
        cursor = state.sent
        beat_due = 0.0
        loop = asyncio.get_running_loop()
        while True:
            if self._rewind is not None:
                if self._rewind < cursor:
                    await self.store.outbox.rewind(self._rewind)
                    cursor = self._rewind
                self._rewind = None
            self._wake.clear()  # before reading: a wake from here on is for what comes next
            found = await self.store.outbox.after(cursor, limit=self.batch_events)
            numbered = [(n.seq, n.event) for n in found]
            for batch in batches(self.site, numbered, self.batch_bytes):
                await client.publish(topic(self.site, "events"), batch.encode(), qos=1)
                await self.store.outbox.mark_sent(batch.last, self.clock.epoch())
                cursor = batch.last
                self.published += 1
                self._last_batch_at = loop.time()
                if self._rewind is not None:
                    break
            if loop.time() >= beat_due:
                head = (await self.store.outbox.state()).head
                alive = Alive(self.site, head, self.clock.epoch())
                await client.publish(topic(self.site, "alive"), alive.encode(), qos=1)
                beat_due = loop.time() + self.heartbeat
            if len(found) < self.batch_events and self._rewind is None:
                with contextlib.suppress(TimeoutError):
                    await asyncio.wait_for(self._wake.wait(), self.poll)
                # Woken at once, but a batch at most every ``spacing`` in a busy service:
                # the events of the rest of it go together (a batch costs the same CPU
                # for one event as for fifty). A backlog (a full batch) never waits.
                rest = self.spacing - (loop.time() - self._last_batch_at)
                if rest > 0 and self._rewind is None:
                    await asyncio.sleep(rest)

    async def _listen(self, client: Any) -> None:
        async for message in client.messages:
            found = site_of(str(message.topic))
            if found is None or found[0] != self.site:
                continue
            payload = message.payload if isinstance(message.payload, bytes) else b""
            try:
                if found[1] == "resend":
                    start = read_resend(payload).start
                    log.info("chain: the centre asks again from event %d", start)
                    self._rewind = start - 1
                    self._wake.set()
                elif found[1] == "confirmed":
                    await self.store.outbox.confirm(read_confirmed(payload).seq)
                    now = asyncio.get_running_loop().time()
                    if now - self._pruned_at >= PRUNE_EVERY:  # not at every batch
                        self._pruned_at = now
                        await self.store.outbox.prune(self.clock.epoch(), self.retention)
            except InvalidField as exc:
                log.warning("chain: a message on %s is not one: %s", message.topic, exc)
