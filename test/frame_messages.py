"""The tests' 80x60 pair with known flow and builders of sensor_msgs images of it, without rclpy (the message
classes alone need no middleware), so engine-only tests can use them under ``pytest -m "not ros"``."""

from __future__ import annotations

import array

import numpy as np
from sensor_msgs.msg import CompressedImage, Image
from synth import constant_flow, pair_from_flow, texture

from flow_node.pipeline.codec import array_to_image_fields

FRAME_ID = "cam_test"
H, W = 60, 80
GT = constant_flow(H, W, 1.5, -0.75)
I0, I1 = pair_from_flow(texture(H, W, seed=3), GT)


def image(arr: np.ndarray, encoding: str, stamp_ns: int, frame_id: str = FRAME_ID) -> Image:
    """A sensor_msgs Image of ``arr`` (already in the encoding's layout), stamped ``stamp_ns``."""
    f = array_to_image_fields(arr, encoding)
    msg = Image(height=f["height"], width=f["width"], encoding=encoding, is_bigendian=0, step=f["step"])
    msg.data = array.array("B", f["data"].tobytes())
    set_stamp(msg, stamp_ns, frame_id)
    return msg


def set_stamp(msg: Image | CompressedImage, stamp_ns: int, frame_id: str = FRAME_ID) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(stamp_ns, 1_000_000_000)
    msg.header.frame_id = frame_id


def mono8(img: np.ndarray) -> np.ndarray:
    return (np.clip(img, 0, 1) * 255).round().astype(np.uint8)
