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
import logging
from collections.abc import Callable

__all__ = ["trim_heap"]

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
