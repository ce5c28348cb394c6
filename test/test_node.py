"""The node over real DDS: outputs, encodings, bad images, resets, diagnostics, compressed input.

Frames of a known constant motion (1.5, -0.75) px at 80x60; the engine runs the realtime preset on the
numpy backend, so every number here is deterministic. AEE bounds are stated per test (measured ~0.06-0.1).
"""

from __future__ import annotations

import array
import time
from pathlib import Path

import cv2
import numpy as np
import pytest
import rclpy
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.qos import ReliabilityPolicy
from ros_helpers import FRAME_ID, GT, I0, I1, H, Harness, W, call, image, mono8, set_stamp, wait_for
from sensor_msgs.msg import CompressedImage, Image
from std_msgs.msg import Header
from std_srvs.srv import Trigger

from flow_node.core.metrics import aee
from flow_node.pipeline.codec import array_to_image_fields, image_to_array
from flow_node.ros import messages

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

AEE_BOUND = 0.25  # px; the same pair through the pipeline directly gives 0.06


@pytest.fixture
def harness(request: pytest.FixtureRequest) -> Harness:
    tag = "".join(c if c.isalnum() else "_" for c in request.node.name)[5:40]
    h = Harness(f"/t_{tag}", name=f"flow_{tag}")
    yield h
    h.close()


def test_known_motion_outputs_with_new_frame_header(harness: Harness) -> None:
    qos = harness.node.state().input_qos  # sensor-data QoS, depth 1
    assert (qos.reliability, qos.depth) == (ReliabilityPolicy.BEST_EFFORT, 1)
    stamp0, stamp1 = 1_700_000_000_000_000_000, 1_700_000_000_033_000_000
    flow_msg = harness.send_pair(image(mono8(I0), "mono8", stamp0), image(mono8(I1), "mono8", stamp1))
    assert (flow_msg.encoding, flow_msg.height, flow_msg.width, flow_msg.step) == ("32FC2", H, W, W * 8)
    assert (flow_msg.header.stamp.sec, flow_msg.header.stamp.nanosec) == divmod(stamp1, 1_000_000_000)
    assert flow_msg.header.frame_id == FRAME_ID
    flow = image_to_array(flow_msg)
    assert aee(flow, GT) < AEE_BOUND
    wait_for(lambda: harness.count("magnitude") and harness.count("flow_color"), 5.0, "magnitude and colour")
    mag_msg, col_msg = harness.last("magnitude"), harness.last("flow_color")
    assert (mag_msg.encoding, col_msg.encoding) == ("32FC1", "bgr8")
    assert mag_msg.header.stamp == flow_msg.header.stamp == col_msg.header.stamp
    np.testing.assert_allclose(image_to_array(mag_msg), np.hypot(flow[..., 0], flow[..., 1]), rtol=1e-5)
    col = image_to_array(col_msg)  # decoded to RGB
    assert col.shape == (H, W, 3) and col.dtype == np.uint8
    assert col[10:50, 10:70, 0].mean() > col[10:50, 10:70, 2].mean()  # rightward motion is red-ish


def bayer_rggb(grey: np.ndarray) -> np.ndarray:
    """A grey image seen through an RGGB mosaic is the grey image itself."""
    return mono8(grey)


def yuv422(grey: np.ndarray) -> np.ndarray:
    """UYVY pairs with neutral chroma (128) and luma = the grey image."""
    out = np.full((grey.shape[0], grey.shape[1], 2), 128, np.uint8)
    out[..., 1] = mono8(grey)
    return out


ENCODED = {
    "mono16": lambda g: (np.clip(g, 0, 1) * 65535).round().astype(np.uint16),
    "32FC1": lambda g: g.astype(np.float32),
    "rgb8": lambda g: np.repeat(mono8(g)[..., None], 3, axis=2),
    "bgra8": lambda g: np.concatenate([np.repeat(mono8(g)[..., None], 3, axis=2),
                                       np.full(g.shape + (1,), 255, np.uint8)], axis=2),
}


def raw_image(payload: np.ndarray, encoding: str, step: int, stamp_ns: int, big: bool = False) -> Image:
    msg = Image(height=H, width=W, encoding=encoding, is_bigendian=int(big), step=step)
    msg.data = array.array("B", np.ascontiguousarray(payload).tobytes())
    set_stamp(msg, stamp_ns)
    return msg


def test_encodings_through_dds_each_reset_on_change(harness: Harness) -> None:
    stamp = 10_000
    cases: list[tuple[str, Image, Image]] = []
    for enc, fn in ENCODED.items():
        cases.append((enc, image(fn(I0), enc, stamp), image(fn(I1), enc, stamp + 1)))
        stamp += 2
    # big-endian mono16 with 6 bytes of row padding
    msgs = []
    for k, g in enumerate((I0, I1)):
        be = (np.clip(g, 0, 1) * 65535).round().astype(">u2").view(np.uint8).reshape(H, -1)
        msgs.append(raw_image(np.pad(be, ((0, 0), (0, 6)), constant_values=0xEE), "mono16", W * 2 + 6,
                              stamp + k, big=True))
    cases.append(("mono16 big-endian padded", *msgs))
    stamp += 2
    cases.append(("bayer_rggb8", raw_image(bayer_rggb(I0), "bayer_rggb8", W, stamp),
                  raw_image(bayer_rggb(I1), "bayer_rggb8", W, stamp + 1)))
    cases.append(("yuv422", raw_image(yuv422(I0), "yuv422", 2 * W, stamp + 2),
                  raw_image(yuv422(I1), "yuv422", 2 * W, stamp + 3)))
    resets = harness.totals.resets
    for name, f0, f1 in cases:
        flow = image_to_array(harness.send_pair(f0, f1))
        assert aee(flow, GT) < AEE_BOUND, name
    # each case's first frame has another encoding than the frame before it: one reset per case
    assert harness.totals.resets - resets == len(cases)


def test_bad_image_rejected_next_good_processed_and_reported(harness: Harness) -> None:
    good0 = image(mono8(I0), "mono8", 100)
    harness.send_frame(good0)
    bad = raw_image(np.zeros(H * (W - 1), np.uint8), "mono8", W - 1, 101)  # step < width
    harness.send_frame(bad)
    unsupported = raw_image(np.zeros(H * W, np.uint8), "nv21", W, 102)
    harness.send_frame(unsupported)
    assert harness.totals.rejected == 2
    # the previous good frame is kept: the next good one pairs with it
    n = harness.count("flow")
    harness.send_frame(image(mono8(I1), "mono8", 103))
    wait_for(lambda: harness.count("flow") > n, 5.0, "flow after the bad images")
    assert aee(image_to_array(harness.last("flow")), GT) < AEE_BOUND
    st = wait_for(lambda: harness.count("diagnostics") and harness.last("diagnostics"), 5.0, "diagnostics")
    values = {kv.key: kv.value for kv in st.values}
    assert values["frames rejected"] == "2"
    assert "nv21" in values["last rejection"]


def test_resets_on_stamp_back_size_change_and_service(harness: Harness) -> None:
    harness.send_pair(image(mono8(I0), "mono8", 5_000), image(mono8(I1), "mono8", 6_000))
    published, resets = harness.totals.published, harness.totals.resets
    harness.send_frame(image(mono8(I0), "mono8", 1_000))  # stamp went back: a looping bag
    assert harness.totals.resets == resets + 1 and harness.totals.published == published
    assert harness.node.stats.last_reset.startswith("stamp went back")
    harness.send_frame(image(mono8(I1[:40, :60]), "mono8", 2_000))  # size changed
    assert harness.totals.resets == resets + 2
    assert harness.node.stats.last_reset.startswith("size changed")
    cli = harness.client.create_client(Trigger, f"{harness.full_name}/reset")
    assert cli.wait_for_service(timeout_sec=5.0)
    res = call(cli, Trigger.Request())
    assert res.success
    harness.send_frame(image(mono8(I0[:40, :60]), "mono8", 3_000))
    assert harness.totals.resets == resets + 3 and harness.totals.published == published
    assert harness.node.stats.last_reset == "reset requested"
    # after the reset the next frame pairs again
    flow = image_to_array(harness.send_pair(image(mono8(I0), "mono8", 4_000), image(mono8(I1), "mono8", 4_100)))
    assert aee(flow, GT) < AEE_BOUND


def test_diagnostics_report_state(harness: Harness) -> None:
    n0 = harness.count("diagnostics")
    harness.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2))
    n = harness.count("diagnostics")
    # the period holding the solve: its node overhead includes the time in publish (flow is subscribed)
    solved = wait_for(lambda: [v for v in ({kv.key: kv.value for kv in s.values}
                                           for _, s in harness.received["diagnostics"][n0:])
                               if v["solve time mean (ms)"] != "n/a"], 5.0, "diagnostics of the solve")[0]
    assert 0.0 < float(solved["publish time mean (ms)"]) <= float(solved["node overhead mean (ms)"])
    st = wait_for(lambda: harness.count("diagnostics") > n and harness.last("diagnostics"), 5.0, "diagnostics")
    values = {kv.key: kv.value for kv in st.values}
    assert st.hardware_id == FRAME_ID
    assert values["backend"] == "numpy" and values["model"] == "l1_tv"
    assert values["frames published"] == "1" and values["frames rejected"] == "0"
    assert values["resolution"] == f"{W}x{H}"
    for key in ("input rate (Hz)", "output rate (Hz)", "solve time mean (ms)", "solve time max (ms)",
                "flow magnitude mean (px)", "flow magnitude p95 (px)", "flow magnitude max (px)",
                "frames dropped"):
        assert key in values
    assert abs(float(values["flow magnitude mean (px)"]) - np.hypot(1.5, 0.75)) < 0.3
    assert float(values["flow magnitude max (px)"]) >= float(values["flow magnitude p95 (px)"])
    # no input for a while -> WARN with the reason
    st = wait_for(lambda: [s for _, s in harness.received["diagnostics"][n:] if s.message.startswith("no image")],
                  8.0, "stale-input warning")[-1]
    assert st.level == st.WARN


def test_compressed_input() -> None:
    h = Harness("/t_compressed", {"use_compressed": True}, name="flow_cmp", color=False)
    try:
        msgs = []
        for k, g in enumerate((I0, I1)):
            ok, buf = cv2.imencode(".png", mono8(g))
            msg = CompressedImage(format="png")
            msg.data = array.array("B", buf.tobytes())
            set_stamp(msg, 77 + k)
            msgs.append(msg)
        flow = image_to_array(h.send_pair(*msgs))
        assert aee(flow, GT) < AEE_BOUND
        assert h.node.state().input_topic == "/t_compressed/image/compressed"
        last = h.node.stats.last
        assert last is not None and not last.color_computed  # nobody subscribed
    finally:
        h.close()


_FAULTS_SCRIPT = """
import resource, sys
import numpy as np
from flow_node.process import keep_freed_memory
applied = keep_freed_memory() if sys.argv[1] == "keep" else None
src = np.ones((480, 640), np.uint8)
for _ in range(3):  # warm up
    (src.astype(np.float32) / 255.0).sum()
before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
for _ in range(50):  # what to_grey does per frame: two fresh 1.2 MB arrays, touched, freed
    (src.astype(np.float32) / 255.0).sum()
print(applied, resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)
"""


def test_node_process_keeps_freed_memory_instead_of_faulting_in_fresh_pages() -> None:
    """keep_freed_memory (which every executable's main() calls): per-frame arrays then reuse heap pages (page
    faults counted by the OS)."""
    import subprocess
    import sys

    def faults(mode: str) -> tuple[str, int]:
        out = subprocess.run([sys.executable, "-c", _FAULTS_SCRIPT, mode], capture_output=True, text=True,
                             check=True).stdout.split()
        return out[0], int(out[1])

    applied, kept = faults("keep")
    _, default = faults("default")
    assert applied == "True"
    assert kept < 50 * 10  # under 10 page faults a frame: the freed heap pages are reused
    # With glibc's defaults numpy 2 faults ~2 x 300 pages in again every frame (28400 measured); numpy 1.26
    # (Ubuntu 24.04's) already reuses them itself (0 measured), so there keep_freed_memory changes nothing.
    if np.__version__.startswith("2."):
        assert default > 50 * 200 and kept < default / 20


class _Applied(Exception):
    """Raised by the stand-in process setting: main() got as far as applying it."""


@pytest.mark.parametrize("setting", ["keep_freed_memory", "passive_thread_waits", "defer_kernel_bitcode"])
@pytest.mark.parametrize("module, argv", [
    ("flow_node.ros.node", []),
    ("flow_node.bag.cli", ["synth", "--frames", "2", "unused_bag"]),
    ("flow_node.cli.estimate", ["f0.png", "f1.png", "-o", "unused.flo"]),
])
def test_every_executable_applies_the_process_settings_before_its_work(setting: str, module: str, argv: list[str],
                                                                       tmp_path: Path,
                                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    """flow_node, flow_bag and flow_estimate all apply flow_node/process.py's settings in main(), before they
    touch any input: keep_freed_memory (the fault test above shows what it buys: without it every frame's
    arrays fault in fresh pages) and passive_thread_waits (idle numba threads sleep; libgomp reads it when
    the first parallel kernel runs, so it must come before any flow) and defer_kernel_bitcode (numba's cached
    kernels read without their bitcode parsed: before the first flow reads them)."""
    import importlib

    mod = importlib.import_module(module)

    def applied() -> bool:
        raise _Applied

    monkeypatch.setattr(mod, setting, applied)
    monkeypatch.chdir(tmp_path)  # nothing is written if it works; if it does not, the work lands here
    with pytest.raises(_Applied):
        mod.main(argv)


@pytest.mark.parametrize("direct", [True, False])
def test_published_payload_is_the_array_on_both_message_paths(direct: bool, monkeypatch: pytest.MonkeyPatch) -> None:
    """image_msg hands the numpy payload to publish without a Python copy where the generated class allows it
    (messages.DIRECT_DATA), else through an array.array; over DDS both arrive as exactly the array sent."""
    assert messages.DIRECT_DATA  # the fast path exists on Jazzy; if rosidl changes, this says so
    monkeypatch.setattr(messages, "DIRECT_DATA", direct)
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        n = Node("payload_test", context=ctx)
        got: list[Image] = []
        n.create_subscription(Image, "payload", got.append, 10)
        pub = n.create_publisher(Image, "payload", 10)
        executor = SingleThreadedExecutor(context=ctx)
        executor.add_node(n)
        end = time.monotonic() + 10.0
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.05)
        flow = np.random.default_rng(5).normal(size=(H, W, 2)).astype(np.float32)
        msg = messages.image_msg(Header(frame_id=FRAME_ID), array_to_image_fields(flow, "32FC2"))
        assert isinstance(msg.data, np.ndarray) == direct
        while not got and time.monotonic() < end:
            pub.publish(msg)
            executor.spin_once(timeout_sec=0.2)
        assert got, "payload not received"
        assert (got[0].encoding, got[0].height, got[0].width, got[0].step) == ("32FC2", H, W, W * 8)
        assert np.array_equal(image_to_array(got[0]), flow)
    finally:
        rclpy.try_shutdown(context=ctx)


def test_stream_preset_predicts_pairs_and_reports_its_fallbacks() -> None:
    """The stream mode in the node (preset stream_fast): the second pair of a steady motion is solved from
    the previous pair's state, a scene cut falls back to the full solve, and /diagnostics counts both."""
    from synth import texture

    t = texture(H, W, seed=3)  # frame_messages' texture: I0 = T(x + GT), I1 = T
    ys, xs = np.mgrid[0:H, 0:W].astype(np.float64)
    before = t.sample(xs + 2 * GT[..., 0], ys + 2 * GT[..., 1])  # moves by GT onto I0
    other = texture(H, W, seed=11).image
    h = Harness("/t_stream", {"preset": "stream_fast", "finest_level": 0, "backend": "numpy"}, name="flow_stream")
    try:
        h.send_frame(image(mono8(before), "mono8", 1_000))
        h.send_pair(image(mono8(I0), "mono8", 2_000), image(mono8(I1), "mono8", 3_000))
        assert h.node.stats.totals.predicted == 1
        assert aee(image_to_array(h.last("flow")), GT) < AEE_BOUND
        h.send_frame(image(mono8(other), "mono8", 4_000))
        assert h.node.stats.totals.stream_fallbacks == 1
        values = wait_for(lambda: [v for v in ({kv.key: kv.value for kv in s.values}
                                               for _, s in h.received["diagnostics"])
                                   if v["stream fallbacks (full solves)"] == "1"], 5.0, "diagnostics")[-1]
        assert values["stream frames predicted"] == "1" and values["last stream fallback"] != "none"
    finally:
        h.close()
