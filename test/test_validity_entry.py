"""The validity mask from the entry points without ROS: the CLI's --mask and the stream's set_mask (the node's
~/mask topic and mask_file go through the latter: test_node_mask.py)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from synth import pair_from_flow, rotation_flow, texture

from flow_node.cli.estimate import main as flow_estimate
from flow_node.core.config import FlowConfig
from flow_node.core.errors import InputError
from flow_node.core.flowio import read_flo
from flow_node.pipeline.stream import FlowStream, StreamSettings

H, W = 96, 128
GT = rotation_flow(H, W, 1.5)
CFG = FlowConfig.preset("realtime")


def garbage_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """uint8 frames with garbage in a blob (the same place in both frames) and its validity mask."""
    i0, i1 = (np.clip(f, 0, 1) for f in pair_from_flow(texture(H, W, seed=7), GT))
    valid = np.ones((H, W), bool)
    valid[30:62, 40:80] = False
    rng = np.random.default_rng(0)
    frames = []
    for f in (i0, i1):
        g = (f * 255).round().astype(np.uint8)
        g[~valid] = rng.integers(0, 256, int((~valid).sum()))
        frames.append(g)
    return frames[0], frames[1], valid


def hole_error(flow: np.ndarray, valid: np.ndarray) -> float:
    return float(np.linalg.norm(flow - GT, axis=-1)[~valid].mean())


def test_cli_mask(tmp_path: Path, capfd: pytest.CaptureFixture[str]) -> None:
    """--mask FILE (both frames) and --mask FILE FILE (one each) cut the hole's error; wrong size or three
    files: exit 1 with one line naming the problem."""
    f0, f1, valid = garbage_pair()
    paths = [tmp_path / n for n in ("f0.png", "f1.png", "mask.png", "small.png")]
    for p, img in zip(paths, (f0, f1, valid.astype(np.uint8) * 255, np.ones((5, 5), np.uint8)), strict=True):
        cv2.imwrite(str(p), img)
    base = [str(paths[0]), str(paths[1]), "--preset", "realtime"]
    errs = {}
    for name, extra in (("off", []), ("one", ["--mask", str(paths[2])]),
                        ("two", ["--mask", str(paths[2]), str(paths[2])])):
        out = tmp_path / f"{name}.flo"
        assert flow_estimate(base + ["-o", str(out)] + extra) == 0
        errs[name] = hole_error(read_flo(out), valid)
    assert errs["one"] < 0.5 * errs["off"] and errs["one"] == pytest.approx(errs["two"], abs=1e-6), errs
    assert flow_estimate(base + ["-o", str(tmp_path / "x.flo"), "--mask", str(paths[3])]) == 1
    assert "mask: expected shape" in capfd.readouterr().err
    assert flow_estimate(base + ["-o", str(tmp_path / "x.flo"), "--mask"] + [str(paths[2])] * 3) == 1
    assert "--mask takes one file" in capfd.readouterr().err
    assert not (tmp_path / "x.flo").exists()


def test_stream_mask_latest_applies() -> None:
    """set_mask applies from the next frame on (each frame keeps its own), at input_scale too; a mask of the
    wrong size rejects the frame (state unchanged), a float mask is refused when set."""
    f0, f1, valid = garbage_pair()
    plain = FlowStream(StreamSettings(config=CFG))
    masked = FlowStream(StreamSettings(config=CFG))
    masked.set_mask(valid.astype(np.uint8) * 255)
    for s in (plain, masked):
        assert s.process(f0, 1) is None
    off, on = plain.process(f1, 2).flow, masked.process(f1, 2).flow
    assert hole_error(on, valid) < 0.5 * hole_error(off, valid)
    masked.set_mask(None)
    masked.process(f0, 3)
    assert masked.process(f1, 4) is not None
    masked.set_mask(np.ones((10, 10), bool))
    with pytest.raises(InputError, match="mask is 10x10"):
        masked.process(f0, 5)
    with pytest.raises(InputError, match="dtype"):
        masked.set_mask(np.ones((H, W), np.float32))
    half = FlowStream(StreamSettings(config=CFG, input_scale=0.5))
    half.set_mask(valid)
    half.process(f0, 1)
    assert half.process(f1, 2).flow.shape == (H // 2, W // 2, 2)
