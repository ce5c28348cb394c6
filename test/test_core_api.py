"""Configuration, input validation, metrics, files and the flow_estimate CLI."""

import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np
import pytest
import small_frames
from synth import constant_flow, interior, pair_from_flow, texture

from flow_node import (
    ConfigError,
    FileFormatError,
    FlowConfig,
    FlowError,
    InputError,
    aee,
    angular_error,
    estimate_flow,
    flow_to_color,
    read_flo,
    write_flo,
)
from flow_node.cli.estimate import main as cli_main
from flow_node.core.api import to_grey
from flow_node.core.config import PRESETS, fields_info

FAST = FlowConfig(backend="numpy", levels=2, warps=2, iterations=20, median_filter=0)


# ------------------------------------------------------------------------------------------------ config
def test_presets_exist_and_are_valid() -> None:
    for name in ("quality", "balanced", "realtime"):
        cfg = FlowConfig.preset(name)
        assert cfg.model in ("l2_l2", "l2_tv", "l1_tv", "l1_tv_l2", "l1_tv_tv")
    assert set(PRESETS) >= {"quality", "balanced", "realtime"}
    with pytest.raises(ConfigError, match="unknown preset 'fast-ish'"):
        FlowConfig.preset("fast-ish")


def test_choices_come_from_the_modules_that_implement_them() -> None:
    """One table each: the models are MODEL_SPECS' (and each has calibrated weights), the initialisations
    the stage's own sources; every preset sets its initialisation itself (one literal, no later patching)."""
    from flow_node.core.config import INITIALISATIONS, MODEL_WEIGHTS, MODELS
    from flow_node.core.initialise import DIS_PRESETS, MATCHERS, SOURCES
    from flow_node.core.models import MODEL_SPECS

    assert MODELS == tuple(MODEL_SPECS) and set(MODEL_WEIGHTS) == set(MODELS)
    assert INITIALISATIONS == SOURCES == ("none", *DIS_PRESETS, *MATCHERS)
    for name, values in PRESETS.items():
        assert values["initialisation"] in INITIALISATIONS and "init_finest_level" in values
        assert FlowConfig.preset(name).initialisation == values["initialisation"]


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"model": "l3_tv"}, "model: 'l3_tv' is not one of"),
        ({"alpha": 0.0}, "alpha: must be > 0"),
        ({"alpha": -1.0}, "alpha: must be > 0"),
        ({"alpha": float("nan")}, "alpha: must be finite"),
        ({"iterations": 0}, "iterations: must be >= 1"),
        ({"iterations": 2.5}, "iterations: expected an integer"),
        ({"levels": True}, "levels: expected an integer"),
        ({"scale_factor": 1.0}, "scale_factor: must be <= 0.95"),
        ({"median_filter": 4}, "median_filter: 4 is not one of"),
        ({"tv_norm": "euclid"}, "tv_norm: 'euclid' is not one of"),
        ({"gradient_scheme": 3}, "gradient_scheme: expected a string"),
        ({"model": "l1_tv_l2", "alpha1": 0.0}, "alpha1 must be > 0"),
        ({"levels": 3, "finest_level": 3}, "finest_level must be < levels"),
        ({"finest_level": -1}, "finest_level: must be >= 0"),
        ({"bogus": 1}, "unknown parameter"),
    ],
)
def test_invalid_values_are_rejected_with_the_reason(changes: dict, message: str) -> None:
    with pytest.raises(ConfigError, match=message.replace("(", r"\(")):
        FlowConfig().replace(**changes)


def test_ints_are_accepted_for_floats_and_integral_floats_for_ints() -> None:
    cfg = FlowConfig(alpha=1, iterations=30.0)
    assert isinstance(cfg.alpha, float) and cfg.alpha == 1.0
    assert isinstance(cfg.iterations, int) and cfg.iterations == 30


def test_overrides_parse_by_field_type() -> None:
    cfg = FlowConfig().with_overrides(["alpha=0.1", "iterations=7", "model=l2_tv"])
    assert (cfg.alpha, cfg.iterations, cfg.model) == (0.1, 7, "l2_tv")
    with pytest.raises(ConfigError, match="iterations: expected int"):
        FlowConfig().with_overrides(["iterations=many"])
    with pytest.raises(ConfigError, match="expected key=value"):
        FlowConfig().with_overrides(["alpha"])


def test_yaml_plain_and_ros_params_forms(tmp_path: Path) -> None:
    plain = tmp_path / "plain.yaml"
    plain.write_text("preset: realtime\nalpha: 0.05\n")
    cfg = FlowConfig.from_yaml(plain)
    assert cfg.alpha == 0.05 and cfg.iterations == PRESETS["realtime"]["iterations"]
    ros = tmp_path / "ros.yaml"
    ros.write_text("flow_node:\n  ros__parameters:\n    model: l1_tv_tv\n    alpha1: 2.0\n    qos_overrides: {}\n")
    cfg = FlowConfig.from_yaml(ros)
    assert cfg.model == "l1_tv_tv" and cfg.alpha1 == 2.0
    bad = tmp_path / "bad.yaml"
    bad.write_text("alpha: [1, 2\n")
    with pytest.raises(FileFormatError, match="not valid YAML"):
        FlowConfig.from_yaml(bad)
    typo = tmp_path / "typo.yaml"
    typo.write_text("alhpa: 0.1\n")
    with pytest.raises(ConfigError, match="unknown parameter.*alhpa"):
        FlowConfig.from_yaml(typo)
    with pytest.raises(FileFormatError, match="cannot read parameter file"):
        FlowConfig.from_yaml(tmp_path / "missing.yaml")


def test_fields_info_describes_every_field() -> None:
    infos = fields_info()
    assert [i.name for i in infos] == list(FlowConfig().to_dict())
    for i in infos:
        assert i.help and (i.choices is not None or i.lo is not None or i.type is str)


# ------------------------------------------------------------------------------------------ bad input
@pytest.mark.parametrize(
    ("frame0", "frame1", "message"),
    [
        (np.zeros((20, 30)), np.zeros((20, 31)), "frames differ in size"),
        (np.zeros((0, 30)), np.zeros((0, 30)), "need at least 2x2"),
        (np.zeros((1, 1)), np.zeros((1, 1)), "need at least 2x2"),
        (np.full((8, 8), np.nan), np.zeros((8, 8)), "NaN or infinite"),
        (np.zeros((8, 8)), np.full((8, 8), np.inf), "NaN or infinite"),
        (np.zeros((8, 8), np.int64), np.zeros((8, 8), np.int64), "unsupported dtype int64"),
        (np.zeros((8, 8), bool), np.zeros((8, 8), bool), "unsupported dtype bool"),
        (np.zeros((8, 8, 2)), np.zeros((8, 8, 2)), r"expected shape \(H, W\) or"),
        (np.zeros((2, 8, 8, 3)), np.zeros((2, 8, 8, 3)), r"expected shape \(H, W\) or"),
        ([[0.0, 1.0]], [[0.0, 1.0]], "expected a numpy array"),
    ],
)
def test_bad_frames_give_clear_errors(frame0, frame1, message: str) -> None:
    with pytest.raises(InputError, match=message):
        estimate_flow(frame0, frame1, FAST)


def test_every_input_encoding_maps_to_the_same_grey_range() -> None:
    t = texture(24, 32, 0).image
    as8 = (t * 255).round().astype(np.uint8)
    as16 = (t * 65535).round().astype(np.uint16)
    rgb = np.repeat(t[..., None], 3, axis=2)
    rgba = np.concatenate([rgb, np.ones_like(t)[..., None]], axis=2)
    for img in (as8, as16, rgb, rgba, t[..., None], t.astype(np.float64)):
        assert np.abs(to_grey(img) - t).max() < 3e-3
    bgr = np.zeros((4, 4, 3), np.uint8)
    bgr[..., 2] = 255  # red in BGR order
    assert to_grey(bgr, channel_order="bgr")[0, 0] == pytest.approx(0.299, abs=1e-3)


def test_small_images_work_down_to_2x2() -> None:
    f = estimate_flow(np.zeros((2, 2)), np.zeros((2, 2)), FAST)
    assert f.shape == (2, 2, 2) and np.all(f == 0)


# ----------------------------------------------------------------------------------- metrics and files
def test_metrics_follow_middlebury_definitions() -> None:
    gt = constant_flow(4, 5, 1.0, 0.0)
    est = gt.copy()
    est[..., 1] += 1.0  # endpoint error 1 everywhere; angle between (1,0,1) and (1,1,1)
    assert aee(est, gt) == pytest.approx(1.0)
    expected = np.degrees(np.arccos(2.0 / (np.sqrt(2.0) * np.sqrt(3.0))))
    assert angular_error(est, gt) == pytest.approx(expected)
    gt_unknown = gt.copy()
    gt_unknown[0, :] = 1e10  # unknown rows are excluded
    est[0, :] = 100.0
    assert aee(est, gt_unknown) == pytest.approx(1.0)
    with pytest.raises(InputError, match="no known pixel"):
        aee(est, np.full_like(gt, np.inf))


def test_flo_round_trip_and_bad_files(tmp_path: Path) -> None:
    flow = np.random.default_rng(0).standard_normal((7, 9, 2)).astype(np.float32)
    path = tmp_path / "f.flo"
    write_flo(path, flow)
    raw = path.read_bytes()
    assert np.frombuffer(raw[:4], "<f4")[0] == np.float32(202021.25)
    assert tuple(np.frombuffer(raw[4:12], "<i4")) == (9, 7)
    assert np.array_equal(read_flo(path), flow)
    (tmp_path / "trunc.flo").write_bytes(raw[:-4])
    with pytest.raises(FileFormatError, match="header says 9x7"):
        read_flo(tmp_path / "trunc.flo")
    (tmp_path / "junk.flo").write_bytes(b"PIEH")
    with pytest.raises(FileFormatError, match="not a .flo file"):
        read_flo(tmp_path / "junk.flo")


def test_flo_parts_write_the_flow_itself_and_the_same_bytes(tmp_path: Path) -> None:
    """flowio.flo_parts: the .flo's data part is a view of a float32 C-contiguous flow (flow_estimate writes it
    without a copy), a converted copy of any other; joined, the bytes of the file write_flo writes."""
    from flow_node.core.flowio import flo_bytes, flo_parts

    flow = np.random.default_rng(1).standard_normal((5, 6, 2)).astype(np.float32)
    header, data = flo_parts(flow)
    assert np.shares_memory(np.frombuffer(data, np.float32), flow)
    write_flo(tmp_path / "f.flo", flow)
    assert header + bytes(data) == flo_bytes(flow) == (tmp_path / "f.flo").read_bytes()
    for other in (flow.astype(np.float64), flow.astype(">f4"), flow[:, ::-1]):
        header2, data2 = flo_parts(other)
        assert not np.shares_memory(np.frombuffer(data2, np.uint8), other)
        assert np.array_equal(np.frombuffer(data2, "<f4").reshape(other.shape), other.astype(np.float32))
        assert header2 == header


def test_colour_coding_uses_the_middlebury_wheel_with_fixed_scale() -> None:
    flow = np.zeros((1, 4, 2), np.float32)
    flow[0, 0] = (1, 0)  # right: red
    flow[0, 1] = (-1, 0)  # left: cyan
    flow[0, 2] = (0.5, 0)  # half the scale: pale red
    col = flow_to_color(flow, max_flow=1.0)
    assert tuple(col[0, 0]) == (255, 0, 0)
    assert col[0, 1, 0] < 30 and col[0, 1, 1] > 200 and col[0, 1, 2] > 200
    assert tuple(col[0, 2]) == (255, 127, 127)
    assert tuple(col[0, 3]) == (255, 255, 255)  # zero flow is white
    assert tuple(flow_to_color(flow, 1.0, bgr=True)[0, 0]) == (0, 0, 255)


# ------------------------------------------------------------------------------------------------- CLI
def _write_pair(tmp_path: Path) -> tuple[Path, Path, np.ndarray]:
    gt = constant_flow(48, 64, 0.7, -0.4)
    i0, i1 = pair_from_flow(texture(48, 64, 9), gt)
    p0, p1 = tmp_path / "a.png", tmp_path / "b.png"
    cv2.imwrite(str(p0), (i0 * 65535).round().astype(np.uint16))
    cv2.imwrite(str(p1), (i1 * 65535).round().astype(np.uint16))
    return p0, p1, gt


def test_cli_writes_flo_and_colour(tmp_path: Path) -> None:
    p0, p1, gt = _write_pair(tmp_path)
    out, col = tmp_path / "out.flo", tmp_path / "out.png"
    rc = cli_main([str(p0), str(p1), "--output", str(out), *small_frames.CLI_ARGS, "--color", str(col)])
    assert rc == 0
    assert aee(interior(read_flo(out)), interior(gt)) < 0.05
    assert cv2.imread(str(col)).shape == (48, 64, 3)


def test_the_executable_skips_the_final_collection_after_writing(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """flow_estimate run as the program (main() reading sys.argv) ends by process.skip_final_collection, after
    its outputs are written (on success and on a failure); a call with an argument list (tests, an embedding
    program) does not."""
    from flow_node.cli import estimate

    p0, p1, _ = _write_pair(tmp_path)
    out = tmp_path / "out.flo"
    seen: list[bool] = []
    monkeypatch.setattr(estimate, "skip_final_collection", lambda: seen.append(out.exists()))
    argv = [str(p0), str(p1), "--output", str(out), *small_frames.CLI_ARGS]
    assert estimate.main(argv) == 0 and seen == []
    out.unlink()
    monkeypatch.setattr(sys, "argv", ["flow_estimate", *argv])
    assert estimate.main() == 0 and seen == [True]
    monkeypatch.setattr(sys, "argv", ["flow_estimate", str(p0), str(tmp_path / "nope.png"), "-o", str(out)])
    assert estimate.main() == 1 and len(seen) == 2


def test_cli_errors_are_one_line_and_nonzero(tmp_path: Path) -> None:
    p0, _, _ = _write_pair(tmp_path)
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((10, 10), np.uint8))
    cases = [
        ([str(p0), str(tmp_path / "nope.png")], "no such file"),
        ([str(p0), str(small)], "frames differ in size"),
        ([str(p0), str(p0), "--set", "alpha=-1"], "alpha: must be > 0"),
        ([str(p0), str(p0), "--set", "beta=1"], "unknown parameter 'beta'"),
    ]
    for args, message in cases:
        proc = subprocess.run([sys.executable, "-m", "flow_node.cli.estimate", *args, "--output",
                               str(tmp_path / "x.flo")], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 1, proc.stderr
        lines = proc.stderr.strip().splitlines()
        assert len(lines) == 1 and message in lines[0] and "Traceback" not in proc.stderr
    proc = subprocess.run([sys.executable, "-m", "flow_node.cli.estimate", str(p0), str(p0), "--output",
                           str(tmp_path / "x.flo"), "--model", "l9"], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "invalid choice" in proc.stderr


def test_flow_error_is_the_common_base() -> None:
    assert issubclass(ConfigError, FlowError) and issubclass(InputError, FlowError)
    assert issubclass(FileFormatError, FlowError)


def test_choosing_a_model_brings_its_calibrated_weights() -> None:
    """API, mapping/YAML and CLI-style changes: a model without alpha/alpha1 gets MODEL_WEIGHTS; given wins."""
    from flow_node.core.config import MODEL_WEIGHTS, MODELS

    for model in MODELS:
        w = MODEL_WEIGHTS[model]
        assert (FlowConfig(model=model).alpha, FlowConfig(model=model).alpha1) == (w["alpha"], w["alpha1"])
        assert FlowConfig.preset("quality").replace(model=model).alpha == (
            FlowConfig.preset("quality").alpha if model == "l1_tv" else w["alpha"])  # same model: kept
        assert FlowConfig.from_mapping({"preset": "realtime", "model": model, "alpha": 0.7}).alpha == 0.7
    assert FlowConfig(model="l2_tv", alpha=0.3).alpha == 0.3
    # a preset's census alpha is chosen for its model: another model's census term weighs with that one's alpha
    census = FlowConfig.preset("realtime").replace(photometric="census")
    assert census.census_alpha > 0 and census.replace(model="l1_tv").census_alpha == census.census_alpha
    assert census.replace(model="l2_tv").census_alpha == 0.0
    assert census.with_overrides(["model=l2_l2"]).census_alpha == 0.0
    assert FlowConfig.from_mapping({"preset": "quality", "model": "l1_tv_tv"}).census_alpha == 0.0
    assert census.replace(model="l2_tv", census_alpha=0.01).census_alpha == 0.01  # given wins
    assert FlowConfig().with_overrides(["model=l2_l2"]).alpha == MODEL_WEIGHTS["l2_l2"]["alpha"]
    with pytest.raises(ConfigError, match="alpha: must be finite"):
        FlowConfig(alpha=float("nan"))  # the 'calibrated' default is a marker, not NaN
