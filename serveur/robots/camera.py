"""A robot's camera over its rosbridge: ``sensor_msgs/CompressedImage`` on its own connection.

The camera has a websocket of its own to the robot's rosbridge, opened only while someone
watches (:class:`serveur.core.camera.CameraRelay` runs it) and separate from the robot's link:
40 kB frames ten times a second must never hold up a goal, a cancel or the heartbeat behind
them on one socket.

It subscribes with ``compression: "cbor"``: rosbridge then sends each message as one binary
frame with the image bytes as a CBOR byte string, instead of base64 inside JSON (a third larger,
and a JSON parse of it) — what users of base64 images over rosbridge report as 10-20 s delays
(../shared/notes/video.md). Both rosbridge 2.x (ROS 2) and 0.11 (ROS1) encode CompressedImage in
CBOR: it has no fixed-size array, which is what 0.11's encoder cannot do
(../shared/notes/rosbridge.md). A bridge that answers in JSON anyway is read too (base64).
``queue_length: 1`` asks rosbridge itself to keep only the newest frame for a slow reader.

Each frame is handed to the relay with its capture time (the message's header stamp); checking
it is the relay's job. A connection that fails is opened again after a pause, doubling up to
5 s, until the relay cancels the source (:mod:`serveur.robots.camera_retry`, the loop every
camera source shares).
"""

from __future__ import annotations

import base64
import binascii
import ssl as ssl_module
from collections.abc import Callable, Mapping
from typing import Any, Final

import cbor2
from websockets.exceptions import WebSocketException

from serveur.errors import RosbridgeError
from serveur.robots import rosbridge as rb
from serveur.robots.camera_retry import keep_streaming
from serveur.robots.reconnect import open_rosbridge

__all__ = ["CAMERA_TYPES", "RosbridgeCamera", "frame_of"]

#: The message type to subscribe with, by ROS version (rosbridge 2.x wants ``pkg/msg/Type``).
CAMERA_TYPES: Final = {1: "sensor_msgs/CompressedImage", 2: "sensor_msgs/msg/CompressedImage"}


def frame_of(raw: str | bytes, topic: str) -> tuple[bytes, float] | None:
    """The image bytes and capture time of one rosbridge frame carrying ``topic``'s message,
    or None for anything else (another op, another topic, a malformed message)."""
    try:
        op: Any = cbor2.loads(raw) if isinstance(raw, bytes) else rb.decode(raw)
    except (RosbridgeError, cbor2.CBORDecodeError, ValueError, TypeError):
        return None
    if not isinstance(op, Mapping) or op.get("op") != "publish" or op.get("topic") != topic:
        return None
    msg = op.get("msg")
    if not isinstance(msg, Mapping):
        return None
    data = msg.get("data")
    if isinstance(data, str):  # JSON: uint8[] as base64
        try:
            data = base64.b64decode(data, validate=True)
        except (binascii.Error, ValueError):
            return None
    if not isinstance(data, bytes | bytearray):
        return None
    captured = 0.0
    header = msg.get("header")
    if isinstance(header, Mapping):
        try:
            captured = rb.from_ros_time(header.get("stamp") or {})
        except RosbridgeError:
            captured = 0.0
    return bytes(data), captured


class RosbridgeCamera:
    """:class:`~serveur.core.camera.CameraSource` for a CompressedImage topic over rosbridge."""

    def __init__(
        self,
        url: str,
        topic: str,
        *,
        ros: int = 1,
        ssl: ssl_module.SSLContext | None = None,
        open_timeout: float = 5.0,
    ) -> None:
        self.url = url
        self.topic = topic
        self.ros = ros
        self._ssl = ssl if url[:6].lower() == "wss://" else None
        self._open_timeout = open_timeout
        #: Connections opened (tests: one per watch, whatever the viewers).
        self.connects = 0

    async def run(self, deliver: Callable[[bytes, float], None]) -> None:
        await keep_streaming(
            lambda: self._session(deliver),
            (OSError, TimeoutError, WebSocketException),
            f"{self.url} {self.topic}",
        )

    async def _session(self, deliver: Callable[[bytes, float], None]) -> None:
        async with open_rosbridge(self.url, ssl=self._ssl, open_timeout=self._open_timeout) as ws:
            self.connects += 1
            sub = rb.op_subscribe(
                self.topic, CAMERA_TYPES[self.ros], queue_length=1, compression="cbor"
            )
            await ws.send(rb.encode(sub))
            async for raw in ws:
                got = frame_of(raw, self.topic)
                if got is not None:
                    deliver(*got)
