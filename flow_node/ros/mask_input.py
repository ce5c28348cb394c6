"""The node's validity mask (core/validity.py, docs/node.md "Validity mask"): the static ``mask_file`` read at
configure, then the latest ``~/mask`` message (mono8, nonzero = valid, the input frames' size) while active.

Each frame is solved with the mask in effect when it arrived (:meth:`~flow_node.pipeline.stream.FlowStream.set_mask`).
A ``~/mask`` message replaces the file's mask; a bad message (not mono8, nothing valid) is rejected with a
warning and the mask in effect is kept. The subscription is reliable with depth 1 and volatile: publish the
mask after the node subscribed (or periodically); a mask that never changes belongs in ``mask_file``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from rclpy.lifecycle import LifecycleNode
from rclpy.subscription import Subscription
from sensor_msgs.msg import Image

from ..core.api import to_grey
from ..core.errors import FileFormatError, FlowError, InputError, short_path
from ..pipeline.codec import decode, decode_bytes
from ..pipeline.stream import FlowStream

MASK_ENCODING = "mono8"


def mask_from_file(path: str) -> np.ndarray:
    """A mask image file (PNG, ...; any channel count) -> (H, W) bool, nonzero grey = valid; FileFormatError
    naming the file when it cannot be read or decoded."""
    try:
        data = Path(path).read_bytes()
    except OSError as exc:
        raise FileFormatError(f"mask_file {short_path(path)}: {exc.strerror or exc}") from None
    return to_grey(decode_bytes(np.frombuffer(data, np.uint8), f"mask_file {short_path(path)}"), "mask_file") > 0


def mask_from_message(msg: Image) -> np.ndarray:
    """A ``~/mask`` message -> (H, W) uint8 (nonzero = valid); InputError unless it is mono8."""
    if msg.encoding != MASK_ENCODING:
        raise InputError(f"~/mask must be {MASK_ENCODING}, got {msg.encoding!r}")
    return decode(msg)[0]


class MaskInput:
    """The mask sources of one node: :meth:`configure` (the file), :meth:`open` / :meth:`close` (the topic)."""

    def __init__(self, node: LifecycleNode) -> None:
        self._node = node
        self._sub: Subscription | None = None

    def configure(self, stream: FlowStream, path: str) -> None:
        """Set the stream's mask from ``path`` ('' = none); a FlowError fails the configure transition."""
        if path:
            stream.set_mask(mask_from_file(path))

    def open(self, stream: FlowStream) -> None:
        """Subscribe to ``~/mask``; each message becomes the stream's mask for the frames after it."""
        def on_mask(msg: Image) -> None:
            try:
                stream.set_mask(mask_from_message(msg))
            except FlowError as exc:
                self._node.get_logger().warning(f"mask rejected: {exc}", throttle_duration_sec=5.0)

        self._sub = self._node.create_subscription(Image, "~/mask", on_mask, 1)

    def close(self) -> None:
        if self._sub is not None:
            self._node.destroy_subscription(self._sub)
            self._sub = None
