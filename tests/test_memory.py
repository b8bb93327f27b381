"""serveur.memory: freed heap pages go back to the OS where the C library allows it."""

from __future__ import annotations

import platform

from serveur.memory import trim_heap


def test_trim_heap_works_on_glibc_and_is_harmless_elsewhere() -> None:
    done = trim_heap()
    if platform.system() == "Linux" and platform.libc_ver()[0] == "glibc":
        assert done is True  # the call the server relies on after its distance matrix
    else:
        assert done is False
