"""A flood of frames much faster than the solver: memory stays flat, latency bounded, drops counted, and the
parameter services answer while solves run."""

from __future__ import annotations

import time

import numpy as np
from rcl_interfaces.srv import GetParameters
from ros_helpers import Harness, call, image, mono8, wait_for
from synth import constant_flow, pair_from_flow, texture

from flow_node.core.config import PRESETS
from flow_node.core.metrics import aee
from flow_node.pipeline.codec import image_to_array

H, W = 240, 320
GT = constant_flow(H, W, 1.0, 0.5)
F0, F1 = pair_from_flow(texture(H, W, seed=5), GT)
FRAMES = [mono8(F0), mono8(F1)]


def rss_mb() -> float:
    """Resident set size of this process (node and test share it), MB."""
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmRSS:"):
                return int(line.split()[1]) / 1024.0
    raise AssertionError("no VmRSS")


def flood(h: Harness, n: int, start_stamp: int) -> dict[int, float]:
    """Publish ``n`` frames back to back (F0, F1, F0, ...); returns publish times by stamp."""
    sent = {}
    for k in range(n):
        stamp = start_stamp + k
        msg = image(FRAMES[k % 2], "mono8", stamp)
        sent[stamp] = time.monotonic()
        h.pub.publish(msg)
        time.sleep(0.002)
    return sent


def test_flood_keeps_memory_flat_latency_bounded_and_counts_drops() -> None:
    # quality preset on numpy at 320x240: each solve takes far longer than the 2 ms between frames
    h = Harness("/t_flood", {"preset": "quality", "iterations": 20}, name="flow_flood", color=False)
    try:
        sent = flood(h, 150, 1_000)
        wait_for(lambda: h.totals.processed + h.totals.dropped >= h.totals.received > 0
                 and h.node._mailbox._item is None, 60.0, "the node to drain")
        rss_after_first = rss_mb()
        sent.update(flood(h, 300, 2_000))
        # parameter services answer while the worker solves
        cli = h.client.create_client(GetParameters, f"{h.full_name}/get_parameters")
        t0 = time.monotonic()
        alpha = call(cli, GetParameters.Request(names=["alpha"]), timeout=2.0).values[0].double_value
        assert alpha == PRESETS["quality"]["alpha"]
        service_seconds = time.monotonic() - t0
        wait_for(lambda: h.totals.processed + h.totals.dropped >= h.totals.received
                 and h.node._mailbox._item is None, 60.0, "the node to drain")
        time.sleep(0.3)
        t = h.totals
        # every received frame was either handled or replaced by a newer one while waiting
        assert t.processed + t.rejected + t.errors + t.dropped == t.received
        assert t.dropped > t.received / 2, (t.dropped, t.received)
        assert t.errors == 0 and t.rejected == 0
        # latency: publish -> flow received; bounded by about two solves (the one running + ours), where a
        # queue would add one solve per waiting frame
        latencies = [recv - sent[m.header.stamp.sec * 1_000_000_000 + m.header.stamp.nanosec]
                     for recv, m in h.received["flow"]]
        assert len(latencies) >= 3
        solve_max = h.node._stats.solve_max
        assert solve_max > 0.02  # the flood really was faster than the solver (2 ms between frames)
        assert max(latencies) < 2 * solve_max + 0.5, (max(latencies), solve_max)
        assert service_seconds < 1.0
        growth = rss_mb() - rss_after_first
        assert growth < 25.0, f"RSS grew {growth:.1f} MB over a second flood of 300 frames"
        # the flows are real: consecutive frames alternate F0/F1 but drops can pair any two, so each
        # published flow is GT (F0 -> F1), -GT (F1 -> F0) or ~0 (same frame twice)
        for _, m in h.received["flow"][-5:]:
            flow = image_to_array(m)
            assert min(aee(flow, GT), aee(flow, -GT), aee(flow, np.zeros_like(GT))) < 0.25
    finally:
        h.close()
