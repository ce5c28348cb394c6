"""The derived outputs of one pair as ROS messages, for either binding: rclpy's generated classes (the node,
flow_node.ros.motion_outputs) or rosbags' (``flow_bag eval --motion``, flow_node.bag.motion_topics).

Duck-typed like the codec: both bindings build a message from keyword fields with the same names, so one
function fills them and a :class:`MessageKit` of the binding supplies the classes, its Image and the storage
of a numeric sequence (rclpy: ``array.array``; rosbags: a numpy array). Topics, types and units:
:data:`~flow_node.pipeline.derived.MOTION_TOPICS`, docs/node.md ("Derived outputs"). No rclpy, no rosbags.
"""

from __future__ import annotations

from collections.abc import Collection, Iterator
from typing import Any, Protocol

import numpy as np

from .codec import array_to_image_fields
from .derived import MOTION_TOPICS, MotionAnalysis, dominant_twist, grid_dims


class MessageKit(Protocol):
    """What :func:`motion_messages` needs of a ROS binding."""

    def make(self, type_name: str, **fields: Any) -> Any:
        """A message of ``type_name`` (``geometry_msgs/msg/Vector3``) with every field given."""

    def image(self, header: Any, fields: dict[str, Any]) -> Any:
        """A sensor_msgs/Image from a header and :func:`array_to_image_fields` output."""

    def sequence(self, data: np.ndarray) -> Any:
        """A 1-D float32 or float64 array as the binding stores a ``float32[]`` / ``float64[]`` field."""


def _multiarray(kit: MessageKit, topic: str, rows: int, cols: int, data: np.ndarray) -> Any:
    dims = [kit.make("std_msgs/msg/MultiArrayDimension", label=label, size=size, stride=stride)
            for label, size, stride in grid_dims(rows, cols)]
    layout = kit.make("std_msgs/msg/MultiArrayLayout", dim=dims, data_offset=0)
    return kit.make(MOTION_TOPICS[topic], layout=layout, data=kit.sequence(data.ravel()))


def _vector(kit: MessageKit, kind: str, x: float, y: float, z: float) -> Any:
    return kit.make(kind, x=float(x), y=float(y), z=float(z))


def motion_messages(kit: MessageKit, hdr: Any, a: MotionAnalysis, detected: bool | None,
                    wanted: Collection[str] = tuple(MOTION_TOPICS)) -> Iterator[tuple[str, Any]]:
    """(topic name relative to the node, message) of each derived output in ``wanted`` (names of
    MOTION_TOPICS) that there is for this pair, in MOTION_TOPICS order; only what is wanted is computed
    (the analysis is lazy). The dominant twist and the TTC grid need the pair's interval, the homography a
    dominant motion, the focus of expansion a finite focus, ``motion/detected`` the flag (``detected``, the
    caller's MotionDetector after this frame; None: not published). Messages with a header get ``hdr``."""
    vector3 = "geometry_msgs/msg/Vector3"
    if "motion/dominant" in wanted and a.dominant is not None and a.interval_s is not None:
        linear, angular = dominant_twist(a.dominant, a.interval_s)
        twist = kit.make("geometry_msgs/msg/Twist", linear=_vector(kit, vector3, *linear),
                         angular=_vector(kit, vector3, *angular))
        yield "motion/dominant", kit.make(MOTION_TOPICS["motion/dominant"], header=hdr, twist=twist)
    if "motion/homography" in wanted and a.dominant is not None:
        yield "motion/homography", _multiarray(kit, "motion/homography", 3, 3,
                                               np.asarray(a.dominant.homography, np.float64))
    if "motion/divergence" in wanted:
        yield "motion/divergence", kit.image(hdr, array_to_image_fields(a.divergence, "32FC1"))
    if "motion/ttc" in wanted and a.interval_s is not None:
        t = a.ttc
        yield "motion/ttc", _multiarray(kit, "motion/ttc", t.rows, t.cols, t.grid("ttc_seconds").astype(np.float32))
    if "motion/foe" in wanted and (f := a.foe) is not None:
        point = _vector(kit, "geometry_msgs/msg/Point", f.x, f.y, 1.0 if f.expanding else -1.0)
        yield "motion/foe", kit.make(MOTION_TOPICS["motion/foe"], header=hdr, point=point)
    if "motion/moving_mask" in wanted:
        yield "motion/moving_mask", kit.image(hdr, array_to_image_fields(a.moving_mask, "mono8"))
    if "motion/detected" in wanted and detected is not None:
        yield "motion/detected", kit.make(MOTION_TOPICS["motion/detected"], data=bool(detected))
