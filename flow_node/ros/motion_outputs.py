"""The node's derived motion outputs (``~/motion/*``, docs/node.md "Derived outputs"): which of them are
subscribed, the analysis of a pair (flow_node.pipeline.derived), its rclpy messages
(flow_node.pipeline.motion_msgs) and the ``motion detected`` flag's state across frames.

Plain code called by the node's worker; the node only creates the publishers and hands them in. Nothing is
computed for a pair unless one of the topics has a subscriber, and then only what the subscribed topics
need (the divergence alone needs no confidence; the mask and the flag need the dominant motion).
"""

from __future__ import annotations

import array
import time
from collections.abc import Mapping
from typing import Any

import numpy as np
from geometry_msgs.msg import Point, PointStamped, Twist, TwistStamped, Vector3
from rclpy.publisher import Publisher
from sensor_msgs.msg import Image
from std_msgs.msg import Bool, Float32MultiArray, Float64MultiArray, Header, MultiArrayDimension, MultiArrayLayout

from ..pipeline.derived import MOTION_TOPICS, MotionAnalysis, MotionSettings
from ..pipeline.motion import MotionDetector
from ..pipeline.motion_msgs import motion_messages
from ..pipeline.stream import FlowOutput
from .messages import image_msg

# The rclpy classes of every message the derived outputs are made of, by ROS type name.
_CLASSES: dict[str, type] = {
    f"{cls.__module__.split('.')[0]}/msg/{cls.__name__}": cls
    for cls in (TwistStamped, Twist, Vector3, PointStamped, Point, Float64MultiArray, Float32MultiArray,
                MultiArrayLayout, MultiArrayDimension, Bool, Image)
}

# The output publishers' message classes, by topic name relative to the node (``~/<name>``).
MOTION_TYPES: dict[str, type] = {name: _CLASSES[kind] for name, kind in MOTION_TOPICS.items()}

_TYPECODES = {np.dtype(np.float32): "f", np.dtype(np.float64): "d"}


class RclpyKit:
    """rclpy's side of :class:`~flow_node.pipeline.motion_msgs.MessageKit`: the generated classes, the
    node's Image without a Python copy (messages.image_msg), ``array.array`` for numeric sequences (what
    the generated setters store without checking each element)."""

    @staticmethod
    def make(type_name: str, **fields: Any) -> Any:
        return _CLASSES[type_name](**fields)

    @staticmethod
    def image(header: Header, fields: dict[str, Any]) -> Image:
        return image_msg(header, fields)

    @staticmethod
    def sequence(data: np.ndarray) -> array.array:
        return array.array(_TYPECODES[data.dtype], np.ascontiguousarray(data).tobytes())


class MotionOutputs:
    """The derived outputs of one stream: the settings in effect and the ``motion detected`` flag.

    ``settings`` may be replaced from another thread (:meth:`update`); the next pair uses them. The flag
    counts consecutive frames only while ``~/motion/detected`` is subscribed (a frame it does not see
    resets it, as does :meth:`reset` when the stream starts a new pair)."""

    def __init__(self, settings: MotionSettings) -> None:
        self.settings = settings
        self.detector = MotionDetector.of(settings.detector)

    def update(self, settings: MotionSettings) -> None:
        """New settings for the next pair; the flag's hysteresis changes without losing its count."""
        self.settings = settings
        self.detector.hysteresis = settings.detector

    def reset(self) -> None:
        """The stream started a new pair (size/encoding change, ``~/reset``, time jump, inactive): flag off."""
        self.detector.reset()

    def publish(self, pubs: Mapping[str, Publisher], header: Header, out: FlowOutput) -> float | None:
        """Compute and publish the subscribed derived outputs of ``out`` with ``header`` on ``pubs`` (by topic
        name); returns the seconds it took, or None when none is subscribed (nothing computed)."""
        wanted = {name for name in MOTION_TOPICS if pubs[name].get_subscription_count() > 0}
        if "motion/detected" not in wanted:
            self.detector.reset()
        if not wanted:
            return None
        start = time.perf_counter()
        analysis = MotionAnalysis.of(out, self.settings)
        detected = self.detector.update(analysis.moving_fraction) if "motion/detected" in wanted else None
        for name, msg in motion_messages(RclpyKit(), header, analysis, detected, wanted):
            pubs[name].publish(msg)
        return time.perf_counter() - start
