"""A flood of frames much faster than the solver: memory stays flat, latency bounded, drops counted, and the
parameter services answer while solves run; the node warns when spun by an executor that starves it."""

from __future__ import annotations

import time

import numpy as np
import pytest
from rcl_interfaces.msg import Log
from rcl_interfaces.srv import GetParameters
from rclpy.executors import Executor, MultiThreadedExecutor, SingleThreadedExecutor
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from ros_helpers import I0, I1, Harness, call, image, mono8, wait_for
from synth import constant_flow, pair_from_flow, texture

from flow_node.core.config import PRESETS
from flow_node.core.metrics import aee
from flow_node.pipeline.codec import image_to_array

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

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


def drained(h: Harness) -> bool:
    """Every frame received so far was handled or replaced, and none waits: the worker is idle."""
    return h.totals.processed + h.totals.dropped >= h.totals.received and not h.node.state().frame_waiting


def test_flood_keeps_memory_flat_latency_bounded_and_counts_drops() -> None:
    # quality preset on numpy at 320x240: each solve takes far longer than the 2 ms between frames
    h = Harness("/t_flood", {"preset": "quality", "iterations": 20}, name="flow_flood", color=False)
    try:
        cli = h.client.create_client(GetParameters, f"{h.full_name}/get_parameters")
        assert cli.wait_for_service(timeout_sec=5.0)  # discovery is not what is timed below
        sent = flood(h, 150, 1_000)
        wait_for(lambda: h.totals.received > 0 and drained(h), 60.0, "the node to drain")
        rss_after_first = rss_mb()
        sent.update(flood(h, 300, 2_000))
        # parameter services answer while the worker solves the flood's last frames
        solving = not drained(h)
        t0 = time.monotonic()
        alpha = call(cli, GetParameters.Request(names=["alpha"]), timeout=5.0).values[0].double_value
        service_seconds = time.monotonic() - t0
        assert alpha == PRESETS["quality"]["alpha"]
        wait_for(lambda: drained(h), 60.0, "the node to drain")
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
        solve_max = h.node.stats.solve_max
        assert solve_max > 0.02  # the flood really was faster than the solver (2 ms between frames)
        assert max(latencies) < 2 * solve_max + 0.5, (max(latencies), solve_max)
        # the answer did not wait for a solve (the solve is ~0.2 s, a call ~10 ms: the poll interval)
        assert solving and service_seconds < 0.5 * solve_max, (solving, service_seconds, solve_max)
        growth = rss_mb() - rss_after_first
        assert growth < 25.0, f"RSS grew {growth:.1f} MB over a second flood of 300 frames"
        # the flows are real: consecutive frames alternate F0/F1 but drops can pair any two, so each
        # published flow is GT (F0 -> F1), -GT (F1 -> F0) or ~0 (same frame twice)
        for _, m in h.received["flow"][-5:]:
            flow = image_to_array(m)
            assert min(aee(flow, GT), aee(flow, -GT), aee(flow, np.zeros_like(GT))) < 0.25
    finally:
        h.close()


@pytest.mark.parametrize("executor", [SingleThreadedExecutor, MultiThreadedExecutor])
def test_warns_once_when_spun_by_a_multithreaded_executor(executor: type[Executor]) -> None:
    tag = executor.__name__[:5].lower()
    h = Harness(f"/t_exec_{tag}", name="flow_exec", color=False, executor=executor)
    logs: list[Log] = []
    rosout = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
    try:
        h.client.create_subscription(Log, "/rosout", lambda m: logs.append(m) if m.name.endswith("flow_exec") else None,
                                     rosout)
        for k, frame in enumerate((I0, I1)):
            h.send(image(mono8(frame), "mono8", 1_000 + k), lambda n=k + 1: h.totals.processed + h.totals.resets >= n,
                   f"frame {k}")
        # the check runs on the first frame, before its "new pair started" line: once that line is here, so is
        # any warning (one writer's samples arrive in order)
        wait_for(lambda: any("new pair started" in m.msg for m in logs), 10.0, "the node's log on /rosout")
        warnings = [m for m in logs if "MultiThreadedExecutor" in m.msg]
        if executor is MultiThreadedExecutor:
            assert len(warnings) == 1 and warnings[0].level == Log.WARN, [m.msg for m in logs]
            assert "SingleThreadedExecutor" in warnings[0].msg
        else:
            assert warnings == []
    finally:
        h.close()
