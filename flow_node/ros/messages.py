"""rclpy helpers of the node: parameter descriptors, publishing the outputs (Images without a Python copy),
the executor check.

Plain functions over rclpy types, kept out of node.py so the node class only wires ROS to them.
"""

from __future__ import annotations

import array
import time
from collections.abc import Mapping
from typing import Any

from rcl_interfaces.msg import FloatingPointRange, IntegerRange, ParameterDescriptor
from rclpy.executors import Executor, MultiThreadedExecutor
from rclpy.impl.rcutils_logger import RcutilsLogger
from rclpy.parameter import Parameter
from rclpy.publisher import Publisher
from sensor_msgs.msg import CameraInfo, Image, TimeReference
from std_msgs.msg import Header

from ..pipeline.codec import array_to_image_fields
from ..pipeline.stream import FlowOutput
from . import camera_info
from .params import ParamSpec

_TYPES = {bool: Parameter.Type.BOOL, int: Parameter.Type.INTEGER, float: Parameter.Type.DOUBLE,
          str: Parameter.Type.STRING}


def descriptor(spec: ParamSpec) -> ParameterDescriptor:
    """ROS descriptor of a parameter: type, description, choices, Integer/FloatingPointRange, read_only."""
    d = ParameterDescriptor(name=spec.name, type=_TYPES[spec.type].value, description=spec.description,
                            read_only=spec.read_only)
    if spec.choices is not None:
        d.additional_constraints = "one of: " + ", ".join(repr(c) for c in spec.choices)
    if spec.lo is not None and spec.hi is not None:
        if spec.type is float:
            d.floating_point_range = [FloatingPointRange(from_value=float(spec.lo), to_value=float(spec.hi),
                                                         step=0.0)]
        elif spec.type is int and spec.choices is None:
            d.integer_range = [IntegerRange(from_value=int(spec.lo), to_value=int(spec.hi), step=1)]
    return d


# The generated Image class keeps ``data`` in this slot; its setter turns anything but an array.array into one
# (a full copy), while the C conversion in ``publish`` takes any buffer (rosidl's fast path for arrays of
# primitives) and copies it once into the C message.
DIRECT_DATA = "_data" in getattr(Image, "__slots__", ())


def image_msg(header: Header, fields: dict[str, Any]) -> Image:
    """An rclpy Image from a header and :func:`array_to_image_fields` output, for publishing.

    The numpy payload goes into the message without a Python-side copy (``DIRECT_DATA``; at 640x480 32FC2
    the copy into an ``array.array`` cost ~0.5 ms a frame); ``publish`` copies it once into the C message.
    Such a message's ``data`` is then the numpy array, so it is for publishing, not for handing around.
    """
    msg = Image(header=header, height=fields["height"], width=fields["width"], encoding=fields["encoding"],
                is_bigendian=fields["is_bigendian"], step=fields["step"])
    payload = fields["data"]  # contiguous 1-D uint8 (array_to_image_fields)
    if DIRECT_DATA:
        msg._data = payload  # noqa: SLF001 -- see DIRECT_DATA
    else:
        data = array.array("B")
        data.frombytes(payload)
        msg.data = data
    return msg


def executor_advice(executor: Executor | None) -> str | None:
    """A warning if ``executor`` is one the node is known to run badly on, else None.

    rclpy's MultiThreadedExecutor (Jazzy's 7.1.6 at least; ros2/rclpy#1452) re-queues callbacks that have
    not started yet and keeps its spin thread polling while they wait, so under a high input rate it holds
    the GIL: the node takes a fraction of the frames and solves many times slower (docs/node.md, "Threading,
    drops and latency").
    """
    if isinstance(executor, MultiThreadedExecutor):
        return ("spun by rclpy's MultiThreadedExecutor, which can starve the solver at high input rates "
                "(ros2/rclpy#1452; docs/node.md): spin this node with a SingleThreadedExecutor (rclpy.spin)")
    return None


def stamp_ns(header: Header) -> int:
    return header.stamp.sec * 1_000_000_000 + header.stamp.nanosec


def publish_outputs(pubs: Mapping[str, Publisher], header: Header, out: FlowOutput, info: CameraInfo | None,
                    logger: RcutilsLogger) -> float:
    """Flow, magnitude, colour and confidence with the new frame's header on ``pubs`` (by output name); each is
    built and published only while its topic has subscribers (colour and confidence are not even computed
    otherwise). Then ``flow_pair`` and ``camera_info`` (``info`` scaled to the output grid). Returns the
    seconds spent inside rclpy's ``publish`` for the images (C conversion, serialisation, the middleware's
    send)."""
    publish_s = 0.0
    for name, image, encoding in (("flow", lambda: out.flow, "32FC2"), ("magnitude", lambda: out.magnitude, "32FC1"),
                                  ("flow_color", out.color, "bgr8"), ("confidence", out.confidence, "32FC1")):
        pub = pubs[name]
        if pub.get_subscription_count() > 0:
            msg = image_msg(header, array_to_image_fields(image(), encoding))
            t0 = time.perf_counter()
            pub.publish(msg)
            publish_s += time.perf_counter() - t0
    if pubs["flow_pair"].get_subscription_count() > 0:  # the pair's earlier stamp
        pair = TimeReference(header=header, source="earlier_frame")
        pair.time_ref.sec, pair.time_ref.nanosec = divmod(out.previous_stamp_ns, 1_000_000_000)
        pubs["flow_pair"].publish(pair)
    if info is not None and pubs["camera_info"].get_subscription_count() > 0:
        if reason := camera_info.unscalable(info):
            logger.warning(f"{reason}: ~/camera_info not published", throttle_duration_sec=30.0)
        else:
            h, w = out.flow.shape[:2]
            pubs["camera_info"].publish(camera_info.scaled_camera_info(info, w, h, header))
    return publish_s
