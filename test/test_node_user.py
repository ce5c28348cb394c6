"""What a ROS 2 user of the node meets (issue 13), over real DDS: presets switch whole groups, the default is
the realtime preset, a solver slower than its camera and a missing numba are WARNs, flow in px/s with the
pair's earlier stamp on ~/flow_pair, the camera's CameraInfo scaled to the output, one-line reasons for bad
params files."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import rclpy
from diagnostic_msgs.msg import DiagnosticArray, DiagnosticStatus
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.parameter import Parameter
from ros_helpers import GT, I0, I1, Harness, image, mono8, wait_for
from sensor_msgs.msg import CameraInfo, TimeReference
from test_node_params import get_values

from flow_node.core.config import PRESETS, FlowConfig
from flow_node.core.metrics import aee
from flow_node.pipeline.codec import image_to_array
from flow_node.ros.camera_info import scaled_camera_info
from flow_node.ros.node import FlowNode
from flow_node.ros.params import NODE_PRESET

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

ROOT = Path(__file__).resolve().parents[1]


def test_preset_switch_sets_the_whole_group() -> None:
    """A setting the new preset does not list must not keep the old value: after fastest (half-size solve)
    and a hand-set min_size, switching to quality must give every engine setting of quality."""
    h = Harness("/t_preset_switch", name="flow_switch")
    try:
        results = h.set_params(preset="fastest")
        assert all(r.successful for r in results), [r.reason for r in results]
        assert get_values(h, ["finest_level"]) == {"finest_level": FlowConfig.preset("fastest").finest_level} != {
            "finest_level": 0}
        assert all(r.successful for r in h.set_params(min_size=8))
        assert "min_size" not in PRESETS["quality"]
        results = h.set_params(preset="quality")
        assert all(r.successful for r in results), [r.reason for r in results]
        got = get_values(h, ["preset", "finest_level", "levels", "iterations", "min_size", "alpha1"])
        q = FlowConfig.preset("quality")
        assert got == {"preset": "quality", "finest_level": q.finest_level, "levels": q.levels,
                       "iterations": q.iterations, "min_size": q.min_size, "alpha1": q.alpha1}
        assert q.min_size != 8
        flow = image_to_array(h.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2)))
        assert h.node.settings.config == q.replace(backend="numpy")  # backend is read-only: not in the group
        assert flow.shape == (60, 80, 2) and aee(flow, GT) < 0.25
    finally:
        h.close()


def test_default_is_the_node_preset_that_keeps_up() -> None:
    ctx = Context()
    rclpy.init(context=ctx)
    try:
        node = FlowNode("flow_defaults", parameter_overrides=[Parameter("warmup", value=False),
                                                              Parameter("backend", value="numpy")], context=ctx)
        try:
            assert NODE_PRESET == "stream_fast"  # docs/node.md, "Defaults": keeps up with 30 Hz VGA on 2 cores
            assert node.get_parameter("preset").value == NODE_PRESET
            assert node.settings.config == FlowConfig.preset(NODE_PRESET).replace(backend="numpy")
            assert node.get_parameter("flow_units").value == "px/frame"
        finally:
            node.destroy_node()
    finally:
        rclpy.try_shutdown(context=ctx)


def statuses(h: Harness) -> list[DiagnosticStatus]:
    with h.cond:
        return [st for _, st in h.received["diagnostics"]]


def test_solver_slower_than_the_camera_warns() -> None:
    """A solve of ~0.2 s against frames every 50 ms: diagnostics WARN with both times, not OK."""
    # finest_iterations 0 (= iterations): the default preset (stream_fast) sets its own for the finest level
    slow = {"preset": "", "levels": 1, "warps": 4, "iterations": 1500, "finest_iterations": 0, "median_filter": 0,
            "diagnostics_period": 0.5}
    h = Harness("/t_slow", slow, name="flow_slow", color=False)
    try:
        k, end, warn = 0, time.monotonic() + 20.0, None
        while warn is None and time.monotonic() < end:
            h.pub.publish(image(mono8(I0 if k % 2 == 0 else I1), "mono8", 1_000_000 + k * 50_000_000))
            k += 1
            time.sleep(0.05)
            warn = next((st for st in statuses(h) if st.message.startswith("solver too slow for the input")),
                        None)
        assert warn is not None, [st.message for st in statuses(h)]
        assert warn.level == DiagnosticStatus.WARN
        values = {kv.key: kv.value for kv in warn.values}
        assert float(values["solve time mean (ms)"]) > 1000.0 / float(values["input rate (Hz)"])
    finally:
        h.close()


def diagnostics_of(name: str, timeout: float = 30.0) -> DiagnosticStatus:
    """The first non-warm-up status of node ``name`` on /diagnostics."""
    ctx = Context()
    rclpy.init(context=ctx)
    node = rclpy.create_node("diag_probe", context=ctx)
    got: list[DiagnosticStatus] = []
    node.create_subscription(DiagnosticArray, "/diagnostics",
                             lambda m: got.extend(s for s in m.status if s.name == f"{name}: optical flow"
                                                  and not s.message.startswith("warming up the engine")), 10)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        end = time.monotonic() + timeout
        while not got and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.1)
        assert got, f"no diagnostics from {name}"
        return got[0]
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


NO_NUMBA = "import sys; sys.modules['numba'] = None; from flow_node.ros.node import main; sys.exit(main())"


def test_missing_numba_is_a_warn_in_log_and_diagnostics(tmp_path: Path) -> None:
    proc = subprocess.Popen([sys.executable, "-c", NO_NUMBA, "--ros-args", "-r", "__node:=flow_nonumba",
                             "-r", "__ns:=/t_nonumba", "-p", "diagnostics_period:=0.3"], env=dict(os.environ),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    try:
        st = diagnostics_of("flow_nonumba")
    finally:
        proc.send_signal(2)
        out, _ = proc.communicate(timeout=20)
    assert st.level == DiagnosticStatus.WARN, st.message
    assert st.message.startswith("no image received yet; numba not importable (import of numba halted")
    assert "numpy reference backend" in st.message
    assert {kv.key: kv.value for kv in st.values}["backend"] == "numpy"
    assert "[WARN]" in out and "numba not importable" in out, out
    assert proc.returncode == 0, out


def test_flow_in_px_per_second_with_the_pairs_earlier_stamp() -> None:
    """flow_units px/s: the 0.25 s pair's (1.5, -0.75) px becomes (6, -3) px/s; ~/flow_pair carries the
    flow's header (newer frame) and, as time_ref, the earlier frame's stamp."""
    h = Harness("/t_units", {"flow_units": "px/s"}, name="flow_units", color=False)
    pairs: list[TimeReference] = []
    h.client.create_subscription(TimeReference, "/t_units/flow_units/flow_pair", pairs.append, 10)
    try:
        wait_for(lambda: h.subscribers("flow_pair") > 0, 10.0, "flow_pair subscription")
        t0, t1 = 5_000_000_000, 5_250_000_000
        flow = image_to_array(h.send_pair(image(mono8(I0), "mono8", t0), image(mono8(I1), "mono8", t1)))
        assert aee(flow, GT * 4.0) < 4.0 * 0.25
        assert abs(float(np.median(flow[..., 0])) - 6.0) < 0.3
        wait_for(lambda: pairs, 5.0, "flow_pair message")
        p = pairs[-1]
        assert (p.header.stamp.sec, p.header.stamp.nanosec) == divmod(t1, 1_000_000_000)
        assert (p.time_ref.sec, p.time_ref.nanosec) == divmod(t0, 1_000_000_000)
        assert p.header.frame_id == h.last("flow").header.frame_id
        h.send_frame(image(mono8(I0), "mono8", t1 + 500))
        rejected, published = h.totals.rejected, h.totals.published
        h.send_frame(image(mono8(I1), "mono8", t1 + 500))  # same stamp: no interval, no velocity
        assert (h.totals.rejected, h.totals.published) == (rejected + 1, published)
        assert "the pair's stamps are 0 ns apart" in h.node.stats.last_rejection
        results = h.set_params(flow_units="px/frame")
        assert all(r.successful for r in results)
        (bad,) = h.set_params(flow_units="m/s")
        assert not bad.successful and "flow_units: 'm/s' is not one of px/frame, px/s" in bad.reason
        flow = image_to_array(h.send_pair(image(mono8(I0), "mono8", t1 + 1000), image(mono8(I1), "mono8", t1 + 2000)))
        assert aee(flow, GT) < 0.25  # px/frame again, whatever the interval
    finally:
        h.close()


def camera_info(width: int, height: int) -> CameraInfo:
    info = CameraInfo(width=width, height=height, distortion_model="plumb_bob", d=[0.1, -0.05, 0.0, 0.0, 0.0])
    info.k = [100.0, 0.0, 39.5, 0.0, 110.0, 29.5, 0.0, 0.0, 1.0]
    info.r = [1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]
    info.p = [100.0, 0.0, 39.5, -10.0, 0.0, 110.0, 29.5, 0.0, 0.0, 0.0, 1.0, 0.0]
    return info


def test_camera_info_republished_scaled_to_the_output() -> None:
    h = Harness("/t_cinfo", {"input_scale": 0.5}, name="flow_cinfo", color=False)
    got: list[CameraInfo] = []
    h.client.create_subscription(CameraInfo, "/t_cinfo/flow_cinfo/camera_info", got.append, 10)
    info_pub = h.client.create_publisher(CameraInfo, "/t_cinfo/camera_info", 10)
    try:
        assert h.node.state().camera_info_topic == "/t_cinfo/camera_info"  # beside the image topic
        wait_for(lambda: info_pub.get_subscription_count() > 0
                 and h.subscribers("camera_info") > 0, 10.0, "camera_info matched")
        info_pub.publish(camera_info(80, 60))
        wait_for(lambda: h.node.state().camera_info_received, 10.0, "camera_info received")
        flow = h.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2))
        wait_for(lambda: got, 5.0, "scaled camera_info")
        out = got[-1]
        assert (out.width, out.height) == (flow.width, flow.height) == (40, 30)
        assert out.header == flow.header
        # pixel centres aligned as in the 2x area resize: the centre of input pixels 0..1 (0.5) is output 0
        assert list(out.k) == pytest.approx([50.0, 0.0, 19.5, 0.0, 55.0, 14.5, 0.0, 0.0, 1.0])
        assert list(out.p) == pytest.approx([50.0, 0.0, 19.5, -5.0, 0.0, 55.0, 14.5, 0.0, 0.0, 0.0, 1.0, 0.0])
        assert list(out.d) == pytest.approx([0.1, -0.05, 0.0, 0.0, 0.0]) and out.distortion_model == "plumb_bob"
    finally:
        h.close()


def test_scaling_to_the_input_size_changes_nothing() -> None:
    info = camera_info(80, 60)
    same = scaled_camera_info(info, 80, 60, info.header)
    assert list(same.k) == list(info.k) and list(same.p) == list(info.p)


@pytest.mark.parametrize("content,reason", [
    (None, "cannot read parameter file missing.yaml: No such file or directory (relative to the current directory"),
    ("/**:\n  ros__parameters:\n    alpha: [0.1,\n", "is not valid YAML: "),
    ("- alpha\n", "expected a mapping at top level"),
    ("alpha: 0.1\n", "is not a ROS parameter file"),
])
def test_bad_params_file_gives_one_line(tmp_path: Path, content: str | None, reason: str) -> None:
    name = "missing.yaml" if content is None else "bad.yaml"
    if content is not None:
        (tmp_path / name).write_text(content)
    proc = subprocess.run([sys.executable, "-m", "flow_node.ros.node", "--ros-args", "--params-file", name],
                          env=dict(os.environ), capture_output=True, text=True, cwd=tmp_path, timeout=60)
    lines = (proc.stdout + proc.stderr).strip().splitlines()
    assert proc.returncode == 1 and len(lines) == 1, lines
    assert "[FATAL]" in lines[0] and "cannot start: " in lines[0] and reason in lines[0], lines[0]
