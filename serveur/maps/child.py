"""Run a map computation in a child process (``python -m MODULE``, JSON in on stdin, JSON out).

The server process never loads numpy or Pillow (its heap stays small on a Pi, and
tests/maps/test_distances.py checks it), and an image that is huge or hostile costs a child
that can die, not the event loop. The child answers ``{"error": {code, message, details}}``
for a refusal, which comes back here as the same :class:`~serveur.errors.ServeurError`.
"""

from __future__ import annotations

import asyncio
import json
import sys
from collections.abc import Callable
from typing import Any

from serveur.errors import InvalidField, MapError, ServeurError

__all__ = ["run_child", "serve_child"]

_ERRORS: dict[str, type[ServeurError]] = {MapError.code: MapError, InvalidField.code: InvalidField}
#: One map computation at a time: each decodes an image of up to 40 million pixels, and a Pi
#: has 1-8 GB for everything; a second request waits for the first.
_ONE_AT_A_TIME: dict[asyncio.AbstractEventLoop, asyncio.Lock] = {}


async def run_child(module: str, payload: bytes) -> dict[str, Any]:
    """The child's JSON answer; a refusal raised as its error, a crash as a MapError."""
    lock = _ONE_AT_A_TIME.setdefault(asyncio.get_running_loop(), asyncio.Lock())
    async with lock:
        return await _run(module, payload)


async def _run(module: str, payload: bytes) -> dict[str, Any]:
    proc = await asyncio.create_subprocess_exec(
        sys.executable,
        "-m",
        module,
        stdin=asyncio.subprocess.PIPE,
        stdout=asyncio.subprocess.PIPE,
        stderr=asyncio.subprocess.PIPE,
    )
    try:
        out, err = await proc.communicate(payload)
    finally:
        if proc.returncode is None:  # cancelled (the server stopping): leave nothing behind
            proc.kill()
            await proc.wait()
    try:
        reply = json.loads(out.decode())
    except ValueError:
        tail = err.decode(errors="replace").strip().splitlines()[-1:] or ["no output"]
        raise MapError(f"the map could not be made: {tail[0]}", reason="failed") from None
    if not isinstance(reply, dict):
        raise MapError("the map could not be made", reason="failed")
    if "error" in reply:
        e = reply["error"]
        cls = _ERRORS.get(str(e.get("code")), MapError)
        raise cls(str(e.get("message")), **dict(e.get("details") or {}))
    return reply


def serve_child(work: Callable[[dict[str, Any]], dict[str, Any]]) -> int:
    """The child's side: the request from stdin, ``work``'s answer (or the refusal it raised,
    as :func:`run_child` reads it) on stdout. Anything else it raises kills the child, which
    :func:`run_child` reports as a failure."""
    request = json.loads(sys.stdin.buffer.read())
    try:
        reply = work(request)
    except tuple(_ERRORS.values()) as exc:
        reply = {"error": {"code": exc.code, "message": exc.message, "details": exc.details}}
    print(json.dumps(reply))
    return 0
