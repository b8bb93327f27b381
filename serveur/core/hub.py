"""Subscriptions and fan-out: who hears which topic, and how each client is fed.

Each update is serialised once (:meth:`Hub.publish` takes the JSON of ``data``), then spliced
into a frame per subscriber with that connection's own ``seq`` — so a pose update reaching 200
tablets costs one ``json.dumps``, not 200.

A client that stops reading must not delay anyone else nor grow memory without bound (the
classic rosbridge complaint). So every subscriber has its own writer task and bounded queues:

* stream topics (``pose:<robot>``, ``scan:<robot>``) keep only the newest frame per topic —
  a slow reader skips stale poses instead of queueing them;
* state topics (robots, orders, tasks, ...) are never dropped silently: a subscriber more than
  ``max_pending`` updates behind is disconnected with close code 4002, and resynchronises from
  a fresh snapshot when it reconnects (the ``seq`` numbers let it notice the gap).

Stream frames and replies to a client that has nothing queued are written straight to its
socket (``write_now``), not through its writer task: waking one task per subscriber for each
10 Hz pose made every AMCL tick a burst of ~100 task switches and ``send`` calls, and the
server's p99 latency was 12-14x a raw echo server's (docs/performance.md). Anything that
cannot go out at once (a state update queued, the socket's buffer full) takes the queued
path, so order and back-pressure are as before.

Stream frames are also *paced* (:class:`Pacer`): :meth:`Hub.publish` only records the newest
frame per subscriber and queues the subscriber; a callback writes ``per_turn`` subscribers'
frames per event-loop turn and yields. On loopback a frame's ``send`` costs ~20-25 us (the
kernel delivers it in the sender's time), so ten robots' poses arriving together to 200
watchers were a ~5 ms run of sends in one loop turn, and a request arriving meanwhile waited
for all of it. Paced, a request is read and answered between two chunks (its reply goes out
directly, ahead of the remaining stream frames, which are latest-only and never reordered
among themselves for one client).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections import deque
from collections.abc import Awaitable, Callable, Coroutine, Iterable, Iterator
from typing import Any, Protocol

from serveur import protocol

__all__ = ["CLOSE_TOO_SLOW", "PER_TURN", "Hub", "Pacer", "Subscriber", "View", "is_stream_topic"]

log = logging.getLogger(__name__)

CLOSE_TOO_SLOW = 4002
_CLOSE = "\x00close"  # queue marker: close here (an identity-compared sentinel, not a topic)
#: Subscribers whose stream frames the pacer writes per event-loop turn: 8 sends are
#: ~0.2 ms, the most a request arriving during a fan-out waits per turn (it needs two
#: turns: one to read the frame, one to parse and answer it). Measured with
#: ``bench/bench_server.py --latency-only --isolate``, serveur's p99 was 0.72-0.80 ms at 4,
#: 0.74-0.75 at 8, 0.92-1.06 at 16, 1.14-1.66 at 32 and 1.4-1.9 unpaced; below 8 the extra
#: loop turns (an epoll call each) buy nothing more.
PER_TURN = 8


class View(Protocol):
    """A client's filter over records (a screen bound to one robot or table)."""

    def __call__(self, topic: str, record: Any) -> bool:
        """Does this pushed update of ``record`` on ``topic`` go to the client?"""

    def snapshot(self, topic: str, records: list[Any]) -> list[Any]:
        """The part of a topic's snapshot the client sees."""


def is_stream_topic(topic: str) -> bool:
    """Pose, scan and particle-cloud streams are latest-only; the rest are state topics."""
    return topic.startswith(("pose:", "scan:", "cloud:"))


class Pacer:
    """Writes subscribers' pending stream frames ``per_turn`` subscribers per loop turn.

    Each subscriber is queued once however many frames it has pending (they wait in its
    latest-only slots), in the order its first frame was published; one turn writes all of a
    subscriber's pending frames, then the next turn goes on with the next subscribers.
    """

    def __init__(self, per_turn: int = PER_TURN) -> None:
        if per_turn < 1:
            raise ValueError("per_turn must be at least 1")
        self.per_turn = per_turn
        self._queue: deque[Subscriber] = deque()
        self._scheduled = False
        self.turns = 0  # loop turns the pacer has run

    def __len__(self) -> int:
        return len(self._queue)

    def __iter__(self) -> Iterator[Subscriber]:
        """The subscribers waiting, in the order they will be written."""
        return iter(self._queue)

    def add(self, sub: Subscriber) -> None:
        self._queue.append(sub)
        if not self._scheduled:
            self._scheduled = True
            asyncio.get_running_loop().call_soon(self._turn)

    def _turn(self) -> None:
        q = self._queue
        self.turns += 1
        for _ in range(min(self.per_turn, len(q))):
            q.popleft().flush_streams()
        if q:
            # call_soon from a callback runs on the *next* turn, after the loop has polled
            # the sockets: requests that arrived meanwhile are read before the next chunk.
            asyncio.get_running_loop().call_soon(self._turn)
        else:
            self._scheduled = False


class Subscriber:
    """One client connection's outgoing side: replies, state updates, latest stream frames."""

    def __init__(
        self,
        send: Callable[[str], Awaitable[None]],
        close: Callable[[int, str], Coroutine[Any, Any, None]],
        *,
        max_pending: int = 2000,
        name: str = "",
        write_now: Callable[[str], bool] | None = None,
    ) -> None:
        self._send = send
        self._close = close
        #: Writes a frame synchronously if the connection can take it now, else says False.
        self._write_now = write_now
        self._busy = False  # the writer task is between frames of a batch
        #: Set by :meth:`Hub.add`: stream frames then wait for the hub's pacer (else written
        #: inside ``update``).
        self.pacer: Pacer | None = None
        self._paced = False  # queued in the pacer
        self._max_pending = max_pending
        self.name = name
        self.topics: set[str] = set()
        self.seq = 0
        # Replies and state updates share one FIFO so a client never sees a reply overtaken by
        # an older update (or the reverse); only latest-only stream frames jump the queue.
        self._state: deque[tuple[str | None, str]] = deque()
        self._latest: dict[str, str] = {}
        self._wake = asyncio.Event()
        self._task: asyncio.Task[None] | None = None
        self.closed = False
        self.dropped_stream_frames = 0
        #: Which records this client may see (a screen bound to one robot or table): called
        #: with (topic, record) for each update that carries its record; None sees all.
        self.view: View | None = None
        self._closing: tuple[int, str] | None = None
        # Updates held back while a snapshot is being taken (see hold()).
        self._held: list[tuple[str, str]] | None = None

    def start(self) -> None:
        self._task = asyncio.create_task(self._writer(), name=f"writer-{self.name}")

    async def stop(self) -> None:
        self.closed = True
        task, self._task = self._task, None
        if task is not None and task is not asyncio.current_task():
            task.cancel()
            with contextlib.suppress(asyncio.CancelledError):
                await task

    def _direct(self) -> Callable[[str], bool] | None:
        """The synchronous writer if a frame may bypass the writer task now: nothing is
        queued or being sent ahead of it (so order is kept); else None."""
        return None if self._busy or self._state else self._write_now

    def reply(self, frame: str) -> None:
        """Send a reply: straight to the socket when nothing is queued for this client (so
        it is never behind stream frames waiting for the pacer), else after what is queued."""
        if self.closed:
            return
        write = self._direct()
        if write is not None and write(frame):
            return
        self._state.append((None, frame))
        self._wake.set()

    def close_after_replies(self, code: int, reason: str) -> None:
        """Close the connection once everything queued so far (the reply saying why) is sent."""
        if not self.closed:
            self._closing = (code, reason)
            self._state.append((_CLOSE, ""))
            self._wake.set()

    def hold(self) -> None:
        """Hold this client's updates back until :meth:`release`.

        A ``data`` reply's snapshot is read topic by topic, with awaits in between; an update
        published meanwhile is newer than the snapshot read before it. Sent ahead of the
        reply, it would be overwritten by the older snapshot on the client. Held, it goes out
        right after the reply, so everything a client receives after a snapshot is newer.
        """
        if self._held is None:
            self._held = []

    def release(self) -> None:
        """Queue the held updates (after the reply just queued); a no-op when not holding."""
        held, self._held = self._held, None
        for topic, data_json in held or ():
            self.update(topic, data_json)

    def update(self, topic: str, data_json: str, record: Any = None) -> None:
        if self.closed:
            return
        if self.view is not None and record is not None and not self.view(topic, record):
            return
        if self._held is not None:
            self._held.append((topic, data_json))  # bounded: one snapshot's worth of awaits
            return
        if is_stream_topic(topic):
            if topic in self._latest:
                self.dropped_stream_frames += 1
            self._latest[topic] = data_json
            if self._direct() is not None:
                if self.pacer is not None:
                    if not self._paced:
                        self._paced = True
                        self.pacer.add(self)
                    return
                self.flush_streams()
                return
        else:
            if len(self._state) >= self._max_pending:
                self.closed = True
                log.warning(
                    "client %s is %d updates behind: disconnecting", self.name, len(self._state)
                )
                asyncio.get_running_loop().create_task(
                    self._close(CLOSE_TOO_SLOW, "too slow: reconnect and resubscribe")
                )
                return
            self._state.append((topic, data_json))
        self._wake.set()

    def flush_streams(self) -> None:
        """Write this client's pending stream frames now if its connection takes them; what
        it does not (state queued ahead, writer mid-batch, socket buffer full) is left to the
        writer task, which sends them after the state updates queued before them."""
        self._paced = False
        if self.closed or not self._latest:
            return
        while self._latest and (write := self._direct()) is not None:
            topic = next(iter(self._latest))
            if not write(protocol.update_frame(topic, self.seq + 1, self._latest[topic])):
                break
            del self._latest[topic]
            self.seq += 1
        if self._latest:
            self._wake.set()

    def _next_frame(self) -> str | None:
        if self._state:
            topic, data = self._state.popleft()
            if topic is None:
                return data
            if topic is _CLOSE:
                return None
        elif self._latest:
            stream = next(iter(self._latest))
            topic, data = stream, self._latest.pop(stream)
        else:
            return None
        self.seq += 1
        return protocol.update_frame(topic, self.seq, data)

    async def _writer(self) -> None:
        try:
            while not self.closed:
                await self._wake.wait()
                self._wake.clear()
                self._busy = True
                while (frame := self._next_frame()) is not None:
                    await self._send(frame)
                self._busy = False
                if self._closing is not None and not any(t is _CLOSE for t, _ in self._state):
                    self.closed = True
                    await self._close(*self._closing)
        except asyncio.CancelledError:
            raise
        except Exception as exc:  # a dead socket ends this writer, nothing else
            log.debug("writer for %s ended: %s", self.name, exc)
            self.closed = True


class Hub:
    """Topic -> subscribers. ``on_watch`` hears when a topic gains its first or loses its last."""

    def __init__(
        self,
        on_watch: Callable[[str, bool], None] | None = None,
        *,
        per_turn: int = PER_TURN,
    ) -> None:
        self._by_topic: dict[str, set[Subscriber]] = {}
        self._on_watch = on_watch
        self.subscribers: set[Subscriber] = set()
        self.pacer = Pacer(per_turn)

    def add(self, sub: Subscriber) -> None:
        self.subscribers.add(sub)
        sub.pacer = self.pacer

    def remove(self, sub: Subscriber) -> None:
        self.subscribers.discard(sub)
        self.unsubscribe(sub, list(sub.topics))

    def subscribe(self, sub: Subscriber, topics: Iterable[str]) -> None:
        for t in topics:
            subs = self._by_topic.setdefault(t, set())
            first = not subs
            subs.add(sub)
            sub.topics.add(t)
            if first and self._on_watch is not None:
                self._on_watch(t, True)

    def unsubscribe(self, sub: Subscriber, topics: Iterable[str]) -> None:
        for t in topics:
            sub.topics.discard(t)
            subs = self._by_topic.get(t)
            if subs is None:
                continue
            subs.discard(sub)
            if not subs:
                del self._by_topic[t]
                if self._on_watch is not None:
                    self._on_watch(t, False)

    def watched(self, topic: str) -> bool:
        return topic in self._by_topic

    def publish(self, topic: str, data_json: str, record: Any = None) -> int:
        """Queue ``data_json`` (already serialised) for every subscriber of ``topic``.

        ``record`` (the object ``data_json`` was made from) lets a subscriber with a ``view``
        skip records outside it; the JSON is still made once for everyone.
        """
        subs = self._by_topic.get(topic)
        if not subs:
            return 0
        for s in subs:
            s.update(topic, data_json, record)
        return len(subs)
