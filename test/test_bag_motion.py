"""`flow_bag eval --motion`: the derived motion outputs as topics of the output bag and in the report, on
the bundled bags (exact ground truth): the messages hold what flow_node.pipeline.derived computes from the
bag's own flow and confidence, with the input headers."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import small_frames
from test_bag_bundled import BAGS, messages, pixels

from flow_node.bag.bagio import stamp_ns
from flow_node.bag.cli import main as flow_bag
from flow_node.pipeline.derived import MOTION_TOPICS, MotionAnalysis

NODE = "/flow_node/"


@pytest.fixture(scope="module")
def evaluated(tmp_path_factory) -> dict[str, Path]:
    root = tmp_path_factory.mktemp("motion")
    for name in ("zoom", "objects"):
        args = ["eval", str(BAGS / name), "--output", str(root / name), "--motion", "-q"] + small_frames.CLI_ARGS
        assert flow_bag(args) == 0
    return {name: root / name for name in ("zoom", "objects")}


def test_motion_topics_match_the_pipeline(evaluated):
    out = messages(evaluated["zoom"] / "bag")
    assert {NODE + t for t in MOTION_TOPICS} - {"/flow_node/motion/foe"} <= set(out)
    flows = out[NODE + "flow"]
    assert all(len(out[NODE + t]) == len(flows) == 5 for t in MOTION_TOPICS)  # the zoom has a focus every pair
    for k, (t, flow_msg) in enumerate(flows):
        interval = 1e-9 * (stamp_ns(flow_msg) - stamp_ns(out["/camera/image_raw"][k][1]))  # the pair's
        a = MotionAnalysis(pixels(flow_msg, "<f4", 2).copy(), pixels(out[NODE + "confidence"][k][1], "<f4", 1).copy(),
                           interval)
        (td, twist), (_, hom), (_, div), (_, ttc), (_, foe), (_, mask), (_, det) = (
            out[NODE + name][k] for name in MOTION_TOPICS)
        assert td == t and twist.header.stamp == flow_msg.header.stamp == foe.header.stamp == mask.header.stamp
        d = a.dominant
        assert interval == pytest.approx(0.1)
        assert twist.twist.linear.x == pytest.approx(d.tx / interval) and twist.twist.linear.z > 0.15  # expanding
        assert twist.twist.angular.z == pytest.approx(math.radians(d.rotation_deg) / interval)
        assert [(x.label, x.size, x.stride) for x in hom.layout.dim] == [("rows", 3, 9), ("cols", 3, 3)]
        assert np.allclose(np.asarray(hom.data).reshape(3, 3), d.homography)
        assert div.encoding == "32FC1" and np.array_equal(pixels(div, "<f4", 1), a.divergence)
        grid = np.asarray(ttc.data, np.float32).reshape(3, 3)
        assert np.allclose(grid, a.ttc.grid("ttc_seconds"), equal_nan=True)
        assert 0.5 < np.nanmedian(grid) < 10.0  # the bag zooms by 2-3.5 % a frame: 30-50 frames, 3-5 s
        assert foe.point.z == 1.0 and abs(foe.point.x - 63.5) < 3 and abs(foe.point.y - 47.5) < 3
        assert mask.encoding == "mono8" and np.array_equal(pixels(mask, "u1", 1), a.moving_mask)
        assert det.data is False  # a camera zoom: nothing moves on its own


def test_motion_report_against_the_ground_truth(evaluated):
    report = json.loads((evaluated["objects"] / "report.json").read_text())
    frames = [f for f in report["models"][0]["frames"] if f["motion"] is not None]
    assert len(frames) == 9
    truth = [f["motion"]["vs_ground_truth"] for f in frames]
    assert max(t["translation_err_px"] for t in truth) < 0.05
    assert np.median([t["mask_iou"] for t in truth]) > 0.8
    assert [f["motion"]["detected"] for f in frames][:2] == [False, False]  # on after 3 frames
    assert all(f["motion"]["detected"] for f in frames[2:])  # three objects move all the time
    summary = report["models"][0]["summary"]["motion"]
    assert summary["pairs"] == 9 and summary["pairs_detected"] == 7
    assert summary["mask_iou_median"] == pytest.approx(np.median([t["mask_iou"] for t in truth]))
    assert "## Derived motion (--motion)" in (evaluated["objects"] / "report.md").read_text()


def test_no_motion_topics_without_the_flag(tmp_path):
    assert flow_bag(["eval", str(BAGS / "translation"), "--output", str(tmp_path / "o"), "-q"]
                    + small_frames.CLI_ARGS) == 0
    out = messages(tmp_path / "o" / "bag")
    assert not any("/motion/" in t for t in out)
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    assert report["models"][0]["summary"]["motion"] is None


@pytest.mark.parametrize("scene", ["approach", "pan_objects"])
def test_synth_scenes_with_known_derived_outputs(tmp_path, scene):
    """`flow_bag synth --scene approach | pan_objects`: exact ground truth, and eval --motion's derived outputs
    against what the ground-truth flow gives (time to contact within 15 %; the objects' mask and the pan)."""
    bag = tmp_path / scene
    assert flow_bag(["synth", str(bag), "--scene", scene, "--frames", "4", "--seed", "3"]) == 0
    assert flow_bag(["eval", str(bag), "--output", str(tmp_path / "o"), "--motion", "-q", "--preset", "realtime"]) == 0
    report = json.loads((tmp_path / "o" / "report.json").read_text())
    truth = [f["motion"]["vs_ground_truth"] for f in report["models"][0]["frames"] if f["motion"] is not None]
    assert len(truth) == 3
    if scene == "approach":
        assert max(t["ttc_centre_rel_err"] for t in truth) < 0.15
    else:
        assert max(t["translation_err_px"] for t in truth) < 0.05
        assert min(t["mask_iou"] for t in truth) > 0.7
