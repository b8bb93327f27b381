"""serveur.maps.memory: freed heap pages go back to the OS where the C library allows it."""

from __future__ import annotations

import gc
import platform

from serveur.maps.memory import freeze_heap, trim_heap


def test_trim_heap_works_on_glibc_and_is_harmless_elsewhere() -> None:
    done = trim_heap()
    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        assert done is True  # the call the server relies on after its distance matrix
    else:
        assert done is False


def test_freeze_heap_takes_live_objects_out_of_full_collections() -> None:
    survivors = [[i] for i in range(1000)]  # lists: tracked by the cyclic collector
    try:
        frozen = freeze_heap()
        assert frozen >= len(survivors) and gc.get_freeze_count() == frozen
        # A full collection walks generation 2: the frozen objects are no longer in it.
        oldest = {id(o) for o in gc.get_objects(2)}
        assert not any(id(o) in oldest for o in survivors)
    finally:
        gc.unfreeze()  # the rest of the test session collects as usual
    gc.collect()
    assert all(id(o) in {id(x) for x in gc.get_objects(2)} for o in survivors[:3])
