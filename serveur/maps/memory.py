"""Give freed heap memory back to the operating system (glibc only; a no-op elsewhere).

Why this exists: the start-up distance matrix builds ~35 MB of distance fields in a worker
thread (``asyncio.to_thread``) and drops them once the distances are known. Python frees
the numpy buffers, but glibc keeps the pages in that thread's malloc arena for reuse, so
the server's resident size stayed at the peak (~115 MB with 200 clients) for its whole
life: on a Raspberry Pi that is memory the OS could use for the database's page cache.
``malloc_trim(0)`` walks every arena and returns whole free pages with ``madvise``; called
once after a known peak it costs a few milliseconds. docs/performance.md has the figures.
"""

from __future__ import annotations

import ctypes
import ctypes.util
import functools
import gc
import logging
from collections.abc import Callable

__all__ = ["freeze_heap", "trim_heap"]

log = logging.getLogger(__name__)


@functools.cache
def _malloc_trim() -> Callable[[int], int] | None:
    name = ctypes.util.find_library("c")
    if name is None:
        return None
    try:
        libc = ctypes.CDLL(name)
        fn = libc.malloc_trim  # glibc only: musl, macOS and Windows have no such call
    except (OSError, AttributeError):
        return None
    fn.argtypes = [ctypes.c_size_t]
    fn.restype = ctypes.c_int
    return fn


def trim_heap() -> bool:
    """Return free heap pages to the OS; True if the C library could (glibc), else False."""
    fn = _malloc_trim()
    if fn is None:
        return False
    fn(0)
    return True


def freeze_heap() -> int:
    """Collect, then move every object alive now out of the cyclic collector's reach.

    Called once the server has started: its modules, pydantic models, map and records are
    ~300,000 objects that live as long as the process, and each full (generation 2)
    collection walked all of them — a 70 ms pause of the event loop, which every request and
    pose frame in flight then waited for. Frozen, they are never traversed again (objects
    made later are collected as usual; one dropped from a reference cycle among the frozen
    objects would not be, which is why the collection runs first). Returns how many objects
    were frozen.
    """
    gc.collect()
    gc.freeze()
    return gc.get_freeze_count()
