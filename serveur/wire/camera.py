"""Camera frames on the staff websocket: one binary message per picture (docs/protocol.md,
"Camera frames").

Layout: 2 bytes (big-endian) giving the length ``n`` of a UTF-8 JSON header, the header, then
the robot's JPEG bytes exactly as the robot sent them::

    [n: uint16 BE][header: n bytes of JSON][JPEG: the rest]

The header says which robot, the frame's number, and how old it is:

* ``camera``: the robot's name; ``seq``: the relay's count of frames from it (a gap is frames
  this viewer skipped because it was still receiving an older one);
* ``captured``: the robot's capture stamp (Unix seconds, the robot's clock; 0 if it gave none);
* ``age``: seconds from the server receiving the frame to sending it (the server's clock);
* ``lag``: seconds from capture to the server receiving it, when the two clocks agree within
  ``_CLOCKS_AGREE`` (a Pi has no RTC: its clock and the robot's can be minutes apart), else
  null.

A page adds the time since the message arrived to ``age`` and ``lag`` to know how old the
picture it shows is. Binary, not base64 in JSON: a third smaller, nothing to parse. Pure.
"""

from __future__ import annotations

import json
import math
import struct
from typing import Any, Final

__all__ = ["camera_frame", "read_camera_frame"]

#: The robot's and the server's clocks are taken to agree when a capture stamp is within this
#: many seconds before the server received the frame (and not after it).
_CLOCKS_AGREE: Final = 5.0
_LEN: Final = struct.Struct(">H")


def camera_frame(
    robot: str, seq: int, captured: float, received: float, now: float, jpeg: bytes
) -> bytes:
    """One binary camera message (``received`` and ``now`` on the server's epoch clock)."""
    if not math.isfinite(captured):
        captured = 0.0  # a robot's stamp that is no time: "gave none"
    lag = received - captured
    shown_lag = round(lag, 3) if captured > 0 and -0.05 <= lag <= _CLOCKS_AGREE else None
    # Written out rather than json.dumps of a dict: sent per tablet per picture, and a third
    # of the cost of relaying one picture to one tablet was building its header.
    head = (
        f'{{"camera":{json.dumps(robot)},"seq":{int(seq)},"captured":{round(captured, 3)!r},'
        f'"age":{round(max(0.0, now - received), 3)!r},'
        f'"lag":{"null" if shown_lag is None else repr(shown_lag)}}}'
    ).encode()
    return b"".join((_LEN.pack(len(head)), head, jpeg))


def read_camera_frame(data: bytes) -> tuple[dict[str, Any], bytes]:
    """The header and JPEG of a camera message (tests and clients; ValueError if malformed)."""
    if len(data) < _LEN.size:
        raise ValueError("camera frame shorter than its length prefix")
    (n,) = _LEN.unpack_from(data)
    head = data[_LEN.size : _LEN.size + n]
    if len(head) != n:
        raise ValueError("camera frame shorter than its header")
    header = json.loads(head)
    if not isinstance(header, dict):
        raise ValueError("camera frame header is not an object")
    return header, data[_LEN.size + n :]
