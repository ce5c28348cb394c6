"""The node's validity mask over real DDS: the static mask_file, then the latest ~/mask (mono8) message."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.parameter import Parameter
from ros_helpers import FAST, GT, I0, I1, H, Harness, W, image, mono8, wait_for
from sensor_msgs.msg import Image

from flow_node.core.errors import FlowError
from flow_node.pipeline.codec import image_to_array
from flow_node.ros.node import FlowNode

pytestmark = pytest.mark.ros  # rclpy over DDS: a node and a publisher in this process

VALID = np.ones((H, W), bool)
VALID[15:45, 25:55] = False


def garbage(img: np.ndarray, seed: int) -> np.ndarray:
    out = mono8(img)
    out[~VALID] = np.random.default_rng(seed).integers(0, 256, int((~VALID).sum()))
    return out


def hole_error(msg: Image) -> float:
    return float(np.linalg.norm(image_to_array(msg) - GT, axis=-1)[~VALID].mean())


def replace_by_topic(h: Harness) -> None:
    """A ~/mask message replaces the file's mask; a non-mono8 one and one with nothing valid are rejected."""
    pub = h.client.create_publisher(Image, f"{h.full_name}/mask", 1)
    wait_for(lambda: pub.get_subscription_count() > 0, 10.0, "~/mask matched")
    pub.publish(image(np.full((H, W), 255, np.uint8), "mono8", 0))
    wait_for(lambda: h.node.state().mask.all(), 10.0, "the topic's mask in effect")
    pub.publish(image(np.zeros((H, W, 3), np.uint8), "rgb8", 0))
    pub.publish(image(np.zeros((H, W), np.uint8), "mono8", 0))
    pub.publish(image(mono8(VALID.astype(np.float32)), "mono8", 0))
    wait_for(lambda: not h.node.state().mask.all(), 10.0, "the last good mask in effect")
    assert (h.node.state().mask == VALID).all()


def test_mask_file_then_mask_topic(tmp_path: Path) -> None:
    path = tmp_path / "mask.png"
    cv2.imwrite(str(path), VALID.astype(np.uint8) * 255)
    f0, f1 = garbage(I0, 1), garbage(I1, 2)
    errs = {}
    for name, params in (("off", {}), ("file", {"mask_file": str(path)})):
        h = Harness(f"/t_mask_{name}", params=params, color=False)
        try:
            errs[name] = hole_error(h.send_pair(image(f0, "mono8", 1_000), image(f1, "mono8", 2_000)))
            if name == "file":
                replace_by_topic(h)
        finally:
            h.close()
    assert errs["file"] < 0.5 * errs["off"], errs


def test_unreadable_mask_file_fails_configure(tmp_path: Path) -> None:
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        params = {**FAST, "warmup": False, "mask_file": str(tmp_path / "missing.png")}
        with pytest.raises(FlowError, match="mask_file"):
            FlowNode("mask_bad", namespace="/t_mask_bad", context=ctx,
                     parameter_overrides=[Parameter(k, value=v) for k, v in params.items()])
    finally:
        rclpy.try_shutdown(context=ctx)
