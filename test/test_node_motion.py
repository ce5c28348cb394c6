"""The derived motion outputs (~/motion/*) of the live node over real DDS: computed only while subscribed
(and only what the subscribed topics need), near the truth on an exactly rendered pan with a moving object,
``motion detected`` with hysteresis and reset with the stream, runtime parameters, silent while inactive.

The scene (flow_node.bag.motion_scenes, seed 6, 128x96): the background pans (-0.787, 1.185) px/frame, one
object covering 20 % of the frame moves 1.5-3 px/frame relative to it. Through the test engine (realtime on
numpy) the pipeline gives a translation error of 0.005-0.009 px and a mask IoU of 0.91-0.93 on its pairs.
"""

from __future__ import annotations

import math
import time
from typing import Any

import numpy as np
import pytest
from geometry_msgs.msg import PointStamped, TwistStamped
from lifecycle_msgs.msg import Transition
from ros_helpers import Harness, call, image, wait_for
from sensor_msgs.msg import Image
from std_msgs.msg import Bool, Float32MultiArray, Float64MultiArray
from std_srvs.srv import Trigger

from flow_node.bag.motion_scenes import motion_scene
from flow_node.pipeline.codec import image_to_array

W, H = 128, 96
SCENE, TRUTH = motion_scene("pan", (W, H), np.random.default_rng(6), object_share=0.2, objects=1)
INTERVAL_NS = 100_000_000  # frames 0.1 s apart: the dominant twist is 10x the px/frame motion
TYPES: dict[str, Any] = {"motion/dominant": TwistStamped, "motion/homography": Float64MultiArray,
                         "motion/divergence": Image, "motion/ttc": Float32MultiArray, "motion/foe": PointStamped,
                         "motion/moving_mask": Image, "motion/detected": Bool}


def frame(t: int) -> Image:
    """Frame ``t`` of the scene as mono8, stamped t x 0.1 s (+1 s, so that stamps are never 0)."""
    grey = SCENE.render(t) @ np.array([0.299, 0.587, 0.114])
    return image(np.rint(np.clip(grey, 0.0, 1.0) * 255.0).astype(np.uint8), "mono8", (10 + t) * INTERVAL_NS)


class Outputs:
    """Subscriptions to some of the node's ~/motion/* topics, collecting what arrives."""

    def __init__(self, h: Harness, names: list[str]) -> None:
        self.h, self.got = h, {n: [] for n in names}
        self.subs = [h.client.create_subscription(TYPES[n], f"{h.full_name}/{n}", self.got[n].append, 10)
                     for n in names]
        for n in names:
            wait_for(lambda n=n: h.subscribers(n) > 0, 10.0, f"{n} subscription matched")

    def close(self) -> None:
        for sub in self.subs:
            self.h.client.destroy_subscription(sub)
        for n in self.got:
            wait_for(lambda n=n: self.h.subscribers(n) == 0, 10.0, f"{n} unsubscribed")


def analysed(h: Harness) -> int:
    return h.totals.analysed


def diagnostics_value(h: Harness, key: str, where: str, value: str) -> str:
    """``key`` of the first diagnostics status (from now on) whose ``where`` equals ``value``."""
    start = h.count("diagnostics")

    def found() -> str | None:
        for _, st in h.received["diagnostics"][start:]:
            values = {kv.key: kv.value for kv in st.values}
            if values.get(where) == value:
                return values[key]
        return None
    return wait_for(found, 10.0, f"diagnostics with {where} = {value}")


@pytest.fixture
def harness(request: pytest.FixtureRequest) -> Harness:
    tag = "".join(c if c.isalnum() else "_" for c in request.node.name)[5:30]
    h = Harness(f"/t_m_{tag}", {"diagnostics_period": 0.3}, name=f"flow_{tag}", color=False)
    yield h
    h.close()


def test_computed_only_while_subscribed_and_near_the_truth(harness: Harness) -> None:
    h = harness
    assert set(TYPES) <= set(h.node.state().subscribers)  # created at configure
    h.send_frame(frame(0))
    h.send_frame(frame(1))
    # nobody subscribes to ~/motion/*: nothing analysed, not even the confidence
    assert analysed(h) == 0 and h.node.stats.last is not None and not h.node.stats.last.confidence_computed
    assert diagnostics_value(h, "frames analysed (motion)", "frames published", "1") == "0"

    div = Outputs(h, ["motion/divergence"])  # the divergence alone needs no confidence
    h.send_frame(frame(2))
    wait_for(lambda: div.got["motion/divergence"], 10.0, "a divergence image")
    assert analysed(h) == 1 and not h.node.stats.last.confidence_computed
    msg = div.got["motion/divergence"][-1]
    assert (msg.encoding, msg.height, msg.width) == ("32FC1", H, W)
    assert (msg.header.stamp.sec, msg.header.stamp.nanosec) == divmod(12 * INTERVAL_NS, 1_000_000_000)
    assert np.median(np.abs(image_to_array(msg))) < 0.01  # a pan: no expansion (1/frame)

    out = Outputs(h, ["motion/dominant", "motion/moving_mask", "motion/homography", "motion/ttc"])
    h.send_frame(frame(3))  # the pair 2 -> 3
    wait_for(lambda: all(out.got.values()), 10.0, "dominant, mask, homography, ttc")
    # the fits take the confidence at their samples, the mask where the deviating pixels survive its opening
    assert analysed(h) == 2 and not h.node.stats.last.confidence_computed
    twist = out.got["motion/dominant"][-1]
    assert (twist.header.stamp.sec, twist.header.stamp.nanosec) == divmod(13 * INTERVAL_NS, 1_000_000_000)
    assert twist.header.frame_id == "cam_test"
    dt = INTERVAL_NS / 1e9
    tx, ty = twist.twist.linear.x * dt, twist.twist.linear.y * dt  # px/s back to px/frame
    assert math.hypot(tx - TRUTH.tx, ty - TRUTH.ty) < 0.05  # the target
    assert abs(twist.twist.linear.z) < 0.01 and abs(twist.twist.angular.z) < 0.01  # no zoom, no rotation
    mask_msg = out.got["motion/moving_mask"][-1]
    assert mask_msg.encoding == "mono8" and mask_msg.header.stamp == twist.header.stamp
    mask, objects = image_to_array(mask_msg) > 0, SCENE.layer_map(2) > 0  # the object in the earlier frame
    assert set(np.unique(image_to_array(mask_msg))) <= {0, 255}
    assert np.sum(mask & objects) / np.sum(mask | objects) > 0.8
    hom = np.asarray(out.got["motion/homography"][-1].data).reshape(3, 3)
    assert np.allclose(hom[:2, 2] - [TRUTH.tx, TRUTH.ty], 0.0, atol=0.1) and hom[2, 2] == 1.0
    ttc = out.got["motion/ttc"][-1]
    assert [(d.label, d.size) for d in ttc.layout.dim] == [("rows", 3), ("cols", 3)]
    assert np.all(np.asarray(ttc.data) > 10.0)  # a pan approaches nothing: +inf or > 100 frames (s, 0.1 s a frame)

    div.close()
    out.close()
    before = analysed(h)
    h.send_frame(frame(4))
    assert analysed(h) == before  # unsubscribed again: nothing computed


def test_detected_flips_with_hysteresis_and_resets_with_the_stream(harness: Harness) -> None:
    h = harness
    results = h.set_params(**{"motion.detector.on_frames": 2, "motion.detector.off_frames": 2})
    assert all(r.successful for r in results), [r.reason for r in results]
    (bad,) = h.set_params(**{"motion.mask.abs_px": 0.0})  # validated like every parameter
    assert not bad.successful and bad.reason == "motion.mask.abs_px: must be > 0.0, got 0.0"
    out = Outputs(h, ["motion/detected"])
    flags: list[bool] = []

    def feed(msg: Image, pair: bool = True) -> None:
        n = len(out.got["motion/detected"])
        h.send_frame(msg)
        if pair:
            wait_for(lambda: len(out.got["motion/detected"]) > n, 10.0, "motion/detected")
            flags.append(out.got["motion/detected"][-1].data)

    feed(frame(0), pair=False)
    for t in (1, 2, 3):  # the object moves: on after 2 frames
        feed(frame(t))
    still = frame(3)
    for _ in (1, 2):  # the same frame again, newer stamps: nothing moves, off after 2 frames
        still.header.stamp.nanosec += 1
        feed(still)
    assert flags == [False, True, True, True, False]

    feed(frame(4))  # moving again: 1 frame counted ...
    reset = h.client.create_client(Trigger, f"{h.full_name}/reset")
    assert reset.wait_for_service(timeout_sec=5.0) and call(reset, Trigger.Request()).success
    feed(frame(5), pair=False)  # ... the stream starts a new pair: the count starts again
    feed(frame(6))
    feed(frame(7))
    assert flags[5:] == [False, False, True]  # without the reset frame 6 would have been the 2nd moving frame


def test_managed_node_inactive_publishes_none_of_them() -> None:
    h = Harness("/t_m_life", {"managed": True}, name="flow_m_life", color=False)  # configured, activated
    try:
        out = Outputs(h, list(TYPES))
        h.send_frame(frame(0))
        h.send_frame(frame(1))
        wait_for(lambda: all(out.got[n] for n in TYPES if n != "motion/foe"), 10.0, "every output but the focus")
        assert not out.got["motion/foe"]  # a pan has no finite focus of expansion

        assert h.change_state(Transition.TRANSITION_DEACTIVATE)
        counts = {n: len(v) for n, v in out.got.items()}
        for n in TYPES:  # the (lifecycle) publishers stay, disabled
            assert h.client.count_publishers(f"{h.full_name}/{n}") == 1
        for t in (2, 3, 4):  # the camera goes on: the inactive node neither takes frames nor publishes
            h.pub.publish(frame(t))
            time.sleep(0.3)
        assert h.node.state().input_topic is None  # unsubscribed until activate
        time.sleep(1.0)
        assert {n: len(v) for n, v in out.got.items()} == counts
        assert (h.totals.received, h.totals.analysed) == (2, 1)

        assert h.change_state(Transition.TRANSITION_ACTIVATE)  # active again: a new pair, then outputs
        wait_for(lambda: h.pub.get_subscription_count() > 0, 10.0, "the node's image subscription")
        h.send_frame(frame(5))
        h.send_frame(frame(6))
        wait_for(lambda: len(out.got["motion/dominant"]) > counts["motion/dominant"], 10.0, "dominant again")
    finally:
        h.close()
