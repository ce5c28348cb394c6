"""~/confidence over real DDS: computed and published only while someone subscribes (like ~/flow_color)."""

from __future__ import annotations

import numpy as np
import pytest
from ros_helpers import I0, I1, Harness, image, mono8, wait_for
from sensor_msgs.msg import Image

from flow_node.pipeline.codec import image_to_array

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process


def test_confidence_is_published_only_while_subscribed() -> None:
    h = Harness("/t_confidence", name="flow_conf", color=False)
    try:
        h.send_pair(image(mono8(I0), "mono8", 1_000), image(mono8(I1), "mono8", 2_000))
        last = h.node.stats.last
        assert last is not None and not last.confidence_computed  # nobody subscribed: not even computed
        got: list[Image] = []
        sub = h.client.create_subscription(Image, f"{h.full_name}/confidence", got.append, 10)
        wait_for(lambda: h.subscribers("confidence") > 0, 10.0,
                 "confidence subscription matched")
        h.send_frame(image(mono8(I0), "mono8", 3_000))  # the pair (I1 -> I0) is the motion reversed
        wait_for(lambda: got, 10.0, "a confidence message")
        msg = got[-1]
        assert msg.encoding == "32FC1" and (msg.height, msg.width) == I0.shape
        assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == (0, 3_000)
        conf = image_to_array(msg)
        assert 0.0 <= conf.min() and conf.max() <= 1.0
        assert np.median(conf) > 0.5  # a textured shift solved well: confident in the interior
        assert conf[:, :2].mean() < 0.2  # the motion is -1.5 px in x from I1 to I0: the left edge leaves
        h.client.destroy_subscription(sub)
        wait_for(lambda: h.subscribers("confidence") == 0, 10.0, "confidence unsubscribed")
        h.send_frame(image(mono8(I1), "mono8", 4_000))
        assert not h.node.stats.last.confidence_computed
    finally:
        h.close()
