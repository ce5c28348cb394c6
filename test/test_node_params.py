"""Node parameters: descriptors, SetParameters accept/reject with reasons, presets, params files, YAML sync,
the launch file, and the executable's start-up/shutdown as a subprocess."""

from __future__ import annotations

import ast
import contextlib
import os
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import rclpy
from rcl_interfaces.srv import DescribeParameters, GetParameters, SetParametersAtomically
from rclpy.context import Context
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter, parameter_value_to_python
from rclpy.qos import ReliabilityPolicy
from ros_helpers import GT, I0, I1, Harness, call, image, mono8
from sensor_msgs.msg import Image
from synth import isoluminant_pair

from flow_node import middleware
from flow_node.core.config import MODEL_WEIGHTS, PRESETS, FlowConfig, fields_info
from flow_node.core.errors import ConfigError
from flow_node.core.metrics import aee
from flow_node.core.settings import fields_info as settings_fields_info
from flow_node.pipeline.codec import image_to_array
from flow_node.pipeline.derived import MotionSettings
from flow_node.ros.params import (
    MOTION_PREFIX,
    NODE_PRESET,
    motion_from_values,
    param_specs,
    render_yaml,
    settings_from_values,
)

pytestmark = pytest.mark.ros  # rclpy over DDS: a node or a publisher in this process, or a node process

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture
def harness() -> Harness:
    h = Harness("/t_params", name="flow_params")
    yield h
    h.close()


def get_values(h: Harness, names: list[str]) -> dict[str, object]:
    cli = h.client.create_client(GetParameters, f"{h.full_name}/get_parameters")
    assert cli.wait_for_service(timeout_sec=5.0)
    res = call(cli, GetParameters.Request(names=names))
    h.client.destroy_client(cli)
    return {n: parameter_value_to_python(v) for n, v in zip(names, res.values, strict=True)}


def test_valid_change_applies_on_next_frame(harness: Harness) -> None:
    flow = image_to_array(harness.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2)))
    assert flow.shape == (60, 80, 2)
    results = harness.set_params(input_scale=0.5, alpha=0.03)
    assert all(r.successful for r in results), [r.reason for r in results]
    flow = image_to_array(harness.send_pair(image(mono8(I0), "mono8", 3), image(mono8(I1), "mono8", 4)))
    assert flow.shape == (30, 40, 2)  # published at the processing resolution, vectors in its pixels
    assert aee(flow, GT[::2, ::2] * 0.5) < 0.3
    assert harness.node.settings.config.alpha == 0.03


def test_colour_channels_see_what_luma_does_not(harness: Harness) -> None:
    """An RGB camera (bgr8: the codec's channel order) whose motion only colour shows: with census on the
    colour channels the flow is right, on the luma it is not."""
    c0, c1, gt = isoluminant_pair(90)
    bgr = [np.ascontiguousarray(mono8(c)[..., ::-1]) for c in (c0, c1)]
    results = harness.set_params(photometric="census", colour="channels")
    assert all(r.successful for r in results), [r.reason for r in results]
    flow = image_to_array(harness.send_pair(image(bgr[0], "bgr8", 1), image(bgr[1], "bgr8", 2)))
    assert aee(flow[4:-4, 4:-4], gt[4:-4, 4:-4]) < 0.3
    assert all(r.successful for r in harness.set_params(colour="grey"))
    flow = image_to_array(harness.send_pair(image(bgr[0], "bgr8", 3), image(bgr[1], "bgr8", 4)))
    assert aee(flow[4:-4, 4:-4], gt[4:-4, 4:-4]) > 1.0


def test_preset_sets_its_group(harness: Harness) -> None:
    results = harness.set_params(preset="quality", alpha=0.04)  # explicit value in the same request wins
    assert all(r.successful for r in results), [r.reason for r in results]
    values = get_values(harness, ["preset", "iterations", "warps", "levels", "gradient_scheme", "alpha"])
    q = PRESETS["quality"]
    assert values == {"preset": "quality", "iterations": q["iterations"], "warps": q["warps"],
                      "levels": q["levels"], "gradient_scheme": q["gradient_scheme"], "alpha": 0.04}
    harness.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2))
    assert harness.node.settings.config == FlowConfig.preset("quality").replace(backend="numpy", alpha=0.04)


def test_model_brings_its_calibrated_weights(harness: Harness) -> None:
    """Setting `model` alone also sets alpha/alpha1 (config.MODEL_WEIGHTS) and census_alpha 0 (a preset's census
    alpha is its own model's); a weight given with it wins."""
    assert all(r.successful for r in harness.set_params(census_alpha=0.08))
    results = harness.set_params(model="l2_tv")
    assert all(r.successful for r in results), [r.reason for r in results]
    assert get_values(harness, ["model", "alpha", "census_alpha"]) == {
        "model": "l2_tv", "alpha": MODEL_WEIGHTS["l2_tv"]["alpha"], "census_alpha": 0.0}
    results = harness.set_params(model="l1_tv_tv", alpha=0.04)
    assert all(r.successful for r in results), [r.reason for r in results]
    assert get_values(harness, ["model", "alpha", "alpha1"]) == {
        "model": "l1_tv_tv", "alpha": 0.04, "alpha1": MODEL_WEIGHTS["l1_tv_tv"]["alpha1"]}
    harness.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2))
    assert harness.node.settings.config.alpha == 0.04 and harness.node.settings.config.model == "l1_tv_tv"


def test_mass_constraint_brings_the_density_mode(harness: Harness) -> None:
    """Setting `constraint` to mass alone also sets photometric=density (config.implied_by_constraint); the node
    then estimates with the mass-preservation data term; mass with a photometric mode that changes mass is
    refused with the reason."""
    results = harness.set_params(constraint="mass")
    assert all(r.successful for r in results), [r.reason for r in results]
    assert get_values(harness, ["constraint", "photometric"]) == {"constraint": "mass", "photometric": "density"}
    harness.send_pair(image(mono8(I0), "mono8", 1), image(mono8(I1), "mono8", 2))
    assert harness.node.settings.config.constraint == "mass"
    results = harness.set_params(photometric="census")
    assert not results[0].successful and "constraint 'mass' needs photometric" in results[0].reason


@pytest.mark.parametrize("name,value,reason", [
    ("alpha", 0.0, "alpha: must be > 0"),             # inside the descriptor range, caught by FlowConfig
    ("alpha", -1.0, "range"),                         # outside the descriptor range (rclpy)
    ("model", "horn", "model: 'horn' is not one of"),
    ("median_filter", 4, "median_filter: 4 is not one of"),
    ("preset", "fastest-ever", "preset"),
    ("input_scale", 1.5, "range"),
    ("backend", "numba", "read-only"),
    ("iterations", 2.5, "type"),
])
def test_invalid_values_rejected_with_reason(harness: Harness, name: str, value: object, reason: str) -> None:
    before = harness.node.settings
    (result,) = harness.set_params(**{name: value})
    assert not result.successful and reason in result.reason
    assert harness.node.get_parameter(name).value != value
    harness.send_frame(image(mono8(I0), "mono8", 1))  # a frame applies whatever was scheduled: nothing
    assert harness.node.settings == before


def test_invalid_combination_rejected_atomically(harness: Harness) -> None:
    cli = harness.client.create_client(SetParametersAtomically, f"{harness.full_name}/set_parameters_atomically")
    assert cli.wait_for_service(timeout_sec=5.0)
    req = SetParametersAtomically.Request(parameters=[Parameter("model", value="l1_tv_l2").to_parameter_msg(),
                                                      Parameter("alpha1", value=0.0).to_parameter_msg()])
    res = call(cli, req).result
    assert not res.successful and "alpha1 must be > 0 for model 'l1_tv_l2'" in res.reason
    assert harness.node.get_parameter("model").value == "l1_tv"
    # each alone is fine
    req.parameters = req.parameters[:1]
    assert call(cli, req).result.successful


def test_descriptors_come_from_the_config_table(harness: Harness) -> None:
    names = [s.name for s in param_specs()]
    cli = harness.client.create_client(DescribeParameters, f"{harness.full_name}/describe_parameters")
    assert cli.wait_for_service(timeout_sec=5.0)
    desc = {d.name: d for d in call(cli, DescribeParameters.Request(names=names)).descriptors}
    for f in [*fields_info(), *settings_fields_info(MotionSettings, MOTION_PREFIX)]:  # engine, derived outputs
        d = desc[f.name]
        assert d.description == f.help
        if f.type is float and f.lo is not None:
            assert (d.floating_point_range[0].from_value, d.floating_point_range[0].to_value) == (f.lo, f.hi)
        if f.type is int and f.choices is None and f.lo is not None:
            assert (d.integer_range[0].from_value, d.integer_range[0].to_value) == (f.lo, f.hi)
    assert desc["backend"].read_only and desc["use_compressed"].read_only and not desc["alpha"].read_only
    assert "interpolated" in desc["gradient_scheme"].additional_constraints
    assert desc["motion.mask.abs_px"].floating_point_range[0].to_value == 100.0
    assert desc["motion.detector.on_frames"].integer_range[0].from_value == 1


def test_yaml_files_are_in_sync_and_load_as_configs() -> None:
    assert (ROOT / "config/flow_node.yaml").read_text() == render_yaml()
    assert FlowConfig.from_yaml(ROOT / "config/flow_node.yaml") == FlowConfig.preset(NODE_PRESET)  # the default
    for name in PRESETS:
        path = ROOT / f"config/{name}.yaml"
        assert path.read_text() == render_yaml(name)
        assert FlowConfig.from_yaml(path) == FlowConfig.preset(name)
    text = (ROOT / "config/flow_node.yaml").read_text()
    node_default = FlowConfig.preset(NODE_PRESET)  # the node's defaults are its default preset's values
    assert f"    alpha: {node_default.alpha!r}\n" in text and "    tolerance: 0.0\n" in text
    assert "    level_alpha_factor: 1.0\n" in text


def test_settings_from_values_rejects_bad_combinations() -> None:
    with pytest.raises(ConfigError, match="alpha1"):
        settings_from_values({"model": "l1_tv_tv", "alpha1": 0.0})
    with pytest.raises(ConfigError, match="input_scale"):
        settings_from_values({"input_scale": 0.0})
    s = settings_from_values({"iterations": 7, "input_scale": 0.25, "use_sim_time": True})
    assert (s.config.iterations, s.input_scale) == (7, 0.25)
    m = motion_from_values({"motion.mask.rel": 0.2, "motion.grid_rows": 2, "motion.detector.off_frames": 9,
                            "iterations": 7})
    assert (m.mask.rel, m.mask.abs_px, m.grid, m.detector.off_frames) == (0.2, 0.5, (2, 3), 9)
    with pytest.raises(ConfigError, match=r"^motion\.detector\.area_fraction: must be > 0\.0"):
        motion_from_values({"motion.detector.area_fraction": 0.0})
    with pytest.raises(ConfigError, match=r"^motion\.grid_cols: must be <= 16"):
        motion_from_values({"motion.grid_cols": 17})


def test_launch_file_is_valid_python_with_the_documented_arguments() -> None:
    src = (ROOT / "launch/flow_node.launch.py").read_text()
    tree = ast.parse(src)
    funcs = {n.name for n in ast.walk(tree) if isinstance(n, ast.FunctionDef)}
    assert "generate_launch_description" in funcs
    strings = {n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str)}
    assert {"image", "params_file", "flow_node", "namespace"} <= strings
    compile(src, "flow_node.launch.py", "exec")


@contextlib.contextmanager
def node_process(args: list[str], tmp_path: Path) -> Iterator[subprocess.Popen]:
    """``python -m flow_node.ros.node --ros-args ARGS``; killed on the way out if still running."""
    proc = subprocess.Popen([sys.executable, "-m", "flow_node.ros.node", "--ros-args", *args], env=dict(os.environ),
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, cwd=tmp_path)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.communicate(timeout=10)


def wait_for_node(service: str) -> None:
    """Block until ``service`` (a node's get_parameters) is available, from a short-lived client."""
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node("probe_client", context=ctx)
    try:
        assert node.create_client(GetParameters, service).wait_for_service(timeout_sec=20.0), "node not up"
    finally:
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)


def test_params_file_honoured_end_to_end_and_sigterm_exits_cleanly(tmp_path: Path) -> None:
    extra = tmp_path / "mine.yaml"
    extra.write_text("/**:\n  ros__parameters:\n    iterations: 20\n    backend: numpy\n    input_scale: 0.5\n")
    with node_process(["--params-file", str(ROOT / "config/realtime.yaml"), "--params-file", str(extra),
                       "-r", "__ns:=/t_pfile"], tmp_path) as proc:
        out = check_pfile_node(proc)
    assert proc.returncode == 0, out
    assert "Traceback" not in out
    # the warm-up line is what tools wait for as "started": the start-up lines come before it
    assert 0 <= out.find("subscribed to") < out.find("engine warm-up (numpy)"), out
    # the middleware in effect is logged: the shipped Fast DDS profile unless this environment chose otherwise
    env = dict(os.environ)
    middleware.use_shipped_dds_profile(env)
    assert middleware.middleware_line(env) in out, out


def check_pfile_node(proc: subprocess.Popen) -> str:
    """Parameters of the subprocess node, one flow through it, then SIGTERM; returns its output."""
    ctx = Context()
    rclpy.init(context=ctx)
    node = Node("pfile_client", context=ctx)
    executor = SingleThreadedExecutor(context=ctx)
    executor.add_node(node)
    try:
        cli = node.create_client(GetParameters, "/t_pfile/flow_node/get_parameters")
        assert cli.wait_for_service(timeout_sec=20.0), "node did not come up"
        future = cli.call_async(GetParameters.Request(names=["preset", "warps", "iterations", "backend",
                                                             "input_scale"]))
        # the executor answers parameter services while the worker thread warms up; 30 s for a loaded machine
        executor.spin_until_future_complete(future, timeout_sec=30.0)
        assert future.done(), "no answer to get_parameters"
        got = [parameter_value_to_python(v) for v in future.result().values]
        assert got == ["realtime", PRESETS["realtime"]["warps"], 20, "numpy", 0.5]
        received: list[Image] = []
        node.create_subscription(Image, "/t_pfile/flow_node/flow", received.append, 10)
        pub = node.create_publisher(Image, "/t_pfile/image", 10)
        end = time.monotonic() + 20.0
        while pub.get_subscription_count() == 0 and time.monotonic() < end:
            executor.spin_once(timeout_sec=0.1)
        pairs = [f for f in received if f.header.stamp.nanosec % 2]
        k = 0
        while not pairs and time.monotonic() < end:  # I0 at even stamps, I1 at odd ones, paced
            pub.publish(image(mono8(I0 if k % 2 == 0 else I1), "mono8", 1000 + k))
            k += 1
            stop = time.monotonic() + 0.4
            while time.monotonic() < stop:
                executor.spin_once(timeout_sec=0.05)
            pairs = [f for f in received if f.header.stamp.nanosec % 2]
        assert pairs, "no flow from the subprocess node"
        assert (pairs[0].height, pairs[0].width) == (30, 40)
        assert aee(image_to_array(pairs[0]), GT[::2, ::2] * 0.5) < 0.3
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown(context=ctx)
        proc.send_signal(signal.SIGTERM)
        out, _ = proc.communicate(timeout=20)
    return out


def test_sigint_and_invalid_params_file(tmp_path: Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("/**:\n  ros__parameters:\n    model: l1_tv_l2\n    alpha1: 0.0\n    backend: numpy\n")
    with node_process(["--params-file", str(bad), "-r", "__ns:=/t_bad"], tmp_path) as proc:
        out, _ = proc.communicate(timeout=30)
    assert proc.returncode == 1 and "alpha1 must be > 0" in out and "Traceback" not in out
    with node_process(["-p", "backend:=numpy", "-r", "__ns:=/t_sigint"], tmp_path) as proc:
        wait_for_node("/t_sigint/flow_node/get_parameters")
        proc.send_signal(signal.SIGINT)
        out, _ = proc.communicate(timeout=20)
    assert proc.returncode == 0 and "Traceback" not in out, out


def test_qos_override_parameters() -> None:
    ns = "/t_qos"
    h = Harness(ns, {f"qos_overrides.{ns}/image.subscription.reliability": "reliable",
                     f"qos_overrides.{ns}/image.subscription.depth": 3}, name="flow_qos", color=False)
    try:
        qos = h.node.state().input_qos
        assert (qos.reliability, qos.depth) == (ReliabilityPolicy.RELIABLE, 3)
        assert h.node.get_parameter(f"qos_overrides.{ns}/image.subscription.history").value == "keep_last"
    finally:
        h.close()


def test_the_node_uses_the_shipped_dds_profile_unless_the_user_chose(tmp_path, monkeypatch) -> None:
    """middleware.use_shipped_dds_profile (main() calls it before rclpy.init): sets FASTRTPS_DEFAULT_PROFILES_FILE
    to the package's profile only if the user set no profile file, no FASTDDS_BUILTIN_TRANSPORTS and no other
    RMW; and leaves the environment alone when the package's file cannot be found."""
    shipped = middleware.shipped_dds_profile()
    assert shipped is not None and shipped.name == "fastdds_localhost.xml"
    env: dict[str, str] = {}
    assert middleware.use_shipped_dds_profile(env) == str(shipped) and env == {middleware.PROFILE_VAR: str(shipped)}
    env = {"RMW_IMPLEMENTATION": "rmw_fastrtps_cpp"}
    assert middleware.use_shipped_dds_profile(env) == str(shipped)
    for chosen in ({middleware.PROFILE_VAR: ""}, {middleware.PROFILE_VAR: str(tmp_path / "mine.xml")},
                   {"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}, {"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp"}):
        env = dict(chosen)
        assert middleware.use_shipped_dds_profile(env) is None and env == chosen
    monkeypatch.setattr(middleware, "shipped_dds_profile", lambda: None)
    env = {}
    assert middleware.use_shipped_dds_profile(env) is None and env == {}
    # what the start-up log says of each case
    assert middleware.middleware_line({}) == "middleware rmw_fastrtps_cpp, Fast DDS defaults"
    assert middleware.middleware_line({middleware.PROFILE_VAR: str(shipped)}).endswith(f"profile {shipped}")
    assert middleware.middleware_line({"FASTDDS_BUILTIN_TRANSPORTS": "UDPv4"}).endswith("built-in transports UDPv4")
    assert middleware.middleware_line({"RMW_IMPLEMENTATION": "rmw_cyclonedds_cpp", middleware.PROFILE_VAR: "x"}) \
        == "middleware rmw_cyclonedds_cpp"
