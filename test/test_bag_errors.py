"""flow_bag eval on bad input: one-line errors, nothing partial left behind; bags without ground truth."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pytest
import small_frames

from flow_node.bag.bagio import IMAGE, BagError, BagWriter, header, image_message
from flow_node.bag.cli import main as flow_bag
from flow_node.bag.evaluate import run_eval
from flow_node.bag.results import EvalOptions
from flow_node.bag.synth import SynthSpec, render_frames
from flow_node.core import FlowConfig
from flow_node.pipeline.codec import array_to_image_fields

BAGS = Path(__file__).resolve().parent.parent / "bags"
FAST = small_frames.CLI_ARGS + ["-q"]


def copy_bag(name: str, dst: Path) -> Path:
    shutil.copytree(BAGS / name, dst)
    return dst


def write_bag(path: Path, frames: list[np.ndarray], gts: list[np.ndarray] | None, gt_encoding: str = "32FC2",
              storage: str = "mcap") -> Path:
    """A hand-made bag: mono8 frames on /cam/image, optional GT (for frames 1..) on /camera/flow_gt."""
    with BagWriter(path, storage) as bag:
        bag.add_topic("/cam/image", IMAGE)
        if gts is not None:
            bag.add_topic("/camera/flow_gt", IMAGE)
        for k, f in enumerate(frames):
            t = (k + 1) * 10**8
            bag.write("/cam/image", t, image_message(header(t, "cam"), array_to_image_fields(f, "mono8")))
            if gts is not None and k > 0:
                bag.write("/camera/flow_gt", t, image_message(header(t, "cam"),
                                                              array_to_image_fields(gts[k - 1], gt_encoding)))
    return path


def frames_and_gt(w: int = 48, h: int = 40) -> tuple[list[np.ndarray], list[np.ndarray]]:
    """Three mono8 frames of the synthetic translation scene and its two ground truths."""
    return render_frames(SynthSpec(scene="translation", frames=3, size=(w, h), seed=3))


def run_cli(tmp_path: Path, capsys, bag: Path, *extra: str) -> str:
    """Run eval expecting failure; return its single stderr line; check nothing was written."""
    out = tmp_path / "out"
    assert flow_bag(["eval", str(bag), "--output", str(out), *FAST, *extra]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("flow_bag eval: error: ")
    assert not out.exists()
    assert not [p for p in tmp_path.iterdir() if p.name.startswith(".out")]  # no partial folder either
    return lines[0]


def test_missing_bag(tmp_path, capsys):
    assert "no such bag" in run_cli(tmp_path, capsys, tmp_path / "nothing")


def test_not_a_bag(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    assert "cannot open bag" in run_cli(tmp_path, capsys, tmp_path / "empty")


# (an MCAP cut short is a crashed recording: read as far as intact, test_harden_bags.py)
@pytest.mark.parametrize("name,cut", [("deformation", 0.5), ("rotation", 0.3)])
def test_truncated_bag(tmp_path, capsys, name, cut):
    bag = copy_bag(name, tmp_path / "bag")
    store = next(p for p in bag.iterdir() if p.suffix in (".mcap", ".db3"))
    store.write_bytes(store.read_bytes()[: int(store.stat().st_size * cut)])
    msg = run_cli(tmp_path, capsys, bag)
    assert "bag" in msg and ("truncated" in msg or "malformed" in msg or "invalid" in msg)


def test_corrupt_sqlite_pages(tmp_path, capsys):
    bag = copy_bag("rotation", tmp_path / "bag")
    store = bag / "rotation.db3"
    data = bytearray(store.read_bytes())
    data[300_000:305_000] = b"\xff" * 5000
    store.write_bytes(bytes(data))
    assert "corrupt or truncated" in run_cli(tmp_path, capsys, bag)


def test_missing_topics(tmp_path, capsys):
    assert "image topic /nope is not in the bag" in run_cli(tmp_path, capsys, BAGS / "zoom", "--image-topic", "/nope")
    assert "gt topic /gt is not in the bag" in run_cli(tmp_path, capsys, BAGS / "zoom", "--gt-topic", "/gt")
    assert "expected sensor_msgs/msg/Image" in run_cli(tmp_path, capsys, BAGS / "translation",
                                                       "--gt-topic", "/camera/image_raw/compressed")


def test_ground_truth_of_another_size(tmp_path, capsys):
    frames, _ = frames_and_gt()
    bag = write_bag(tmp_path / "bag", frames, [np.zeros((12, 16, 2), np.float32)] * 2)
    assert "is 16x12 but the images are 48x40" in run_cli(tmp_path, capsys, bag)


def test_ground_truth_of_another_encoding(tmp_path, capsys):
    frames, _ = frames_and_gt()
    bag = write_bag(tmp_path / "bag", frames, [np.zeros((40, 48), np.float32)] * 2, gt_encoding="32FC1")
    assert "encoding 32FC1, expected 32FC2" in run_cli(tmp_path, capsys, bag)


def test_output_that_is_a_file(tmp_path, capsys):
    (tmp_path / "out").write_text("x")
    assert flow_bag(["eval", str(BAGS / "zoom"), "--output", str(tmp_path / "out"), *FAST]) == 1
    assert "exists and is not a folder" in capsys.readouterr().err
    assert (tmp_path / "out").read_text() == "x"


def test_failed_eval_keeps_previous_output(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "report.md").write_text("previous")
    with pytest.raises(BagError):
        run_eval(tmp_path / "nothing", out, [FlowConfig()], EvalOptions(progress=False))
    assert (out / "report.md").read_text() == "previous"


def test_bag_without_ground_truth(tmp_path):
    """A 'real recording': no GT topic; report has magnitude statistics close to the true speed."""
    frames, gts = frames_and_gt()
    bag = write_bag(tmp_path / "bag", frames, None, storage="sqlite3")
    out = tmp_path / "out"
    assert flow_bag(["eval", str(bag), "-o", str(out), "--png-frames", "all", *FAST]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["gt_topic"] is None and report["image_topic"] == "/cam/image"
    s = report["models"][0]["summary"]
    assert s["pairs"] == 2 and s["pairs_with_gt"] == 0 and s["aee_mean"] is None
    speed = float(np.linalg.norm(gts[0], axis=-1).mean())
    assert speed > 1.0 and s["magnitude_mean"] == pytest.approx(speed, rel=0.1)
    assert all(f["magnitude"]["p95"] >= f["magnitude"]["mean"] for f in report["models"][0]["frames"][1:])
    md = (out / "report.md").read_text()
    assert "| p95 | max |" in md and "AEE |" not in md.split("## Frames")[1]
    assert sorted(p.name for p in out.glob("*.png")) == ["frame_0001.png", "frame_0002.png", "per_frame.png"]


def test_bad_arguments_are_one_line(tmp_path, capsys):
    assert flow_bag(["eval", str(BAGS / "zoom"), "-o", str(tmp_path / "o"), "--model", "l3_xx"]) == 1
    assert flow_bag(["eval", str(BAGS / "zoom"), "-o", str(tmp_path / "o"), "--set", "alpha=-1"]) == 1
    assert flow_bag(["eval", str(BAGS / "zoom"), "-o", str(tmp_path / "o"), "--png-frames", "x"]) == 1
    lines = capsys.readouterr().err.strip().splitlines()
    assert len(lines) == 3 and "l3_xx" in lines[0] and "alpha" in lines[1] and "png-frames" in lines[2]
    assert not (tmp_path / "o").exists()


def test_unusable_image_is_skipped_like_the_node_does(tmp_path):
    """A malformed image (data shorter than step * height) is noted, not fatal; the next pair spans it and is
    not scored against the one-frame ground truth."""
    frames, gts = render_frames(SynthSpec(scene="translation", frames=4, size=(48, 40), seed=3))
    bag = tmp_path / "bag"
    with BagWriter(bag, "mcap") as w:
        w.add_topic("/cam/image", IMAGE)
        w.add_topic("/camera/flow_gt", IMAGE)
        for k, f in enumerate(frames):
            t = (k + 1) * 10**8
            fields = array_to_image_fields(f, "mono8")
            if k == 2:
                fields["data"] = fields["data"][:100]
            w.write("/cam/image", t, image_message(header(t, "cam"), fields))
            if k:
                w.write("/camera/flow_gt", t, image_message(header(t, "cam"),
                                                            array_to_image_fields(gts[k - 1], "32FC2")))
    out = tmp_path / "out"
    assert flow_bag(["eval", str(bag), "-o", str(out), *FAST]) == 0
    recs = json.loads((out / "report.json").read_text())["models"][0]["frames"]
    assert [r["aee"] is not None for r in recs] == [False, True, False, False]
    assert recs[2]["skipped"].startswith("image unusable: ") and "data has 100 bytes" in recs[2]["skipped"]
    assert recs[3]["previous_stamp_ns"] == 2 * 10**8 and "spans an unusable image" in recs[3]["note"]
    assert recs[1]["aee"] < 0.15


def test_eval_is_deterministic_and_shows_progress(tmp_path, capsys):
    """Same bag, same config: byte-identical flow messages; progress bar on stderr, summary on stdout;
    a ROS params file selects the model."""
    params = tmp_path / "p.yaml"
    params.write_text("flow_node:\n  ros__parameters:\n    model: l1_tv_l2\n    use_compressed: false\n")
    args = ["--preset", "realtime", "--set", "backend=numpy", "--params", str(params)]
    assert flow_bag(["eval", str(BAGS / "deformation"), "-o", str(tmp_path / "a"), *args]) == 0
    io = capsys.readouterr()
    assert "deformation: 100%" in io.err and "6/6" in io.err and "frame/s" in io.err  # tqdm's final state
    assert io.out.startswith("l1_tv_l2: 5 pairs, AEE ")
    assert flow_bag(["eval", str(BAGS / "deformation"), "-o", str(tmp_path / "b"), *args, "-q"]) == 0
    assert capsys.readouterr().err == ""

    def flows(folder: Path) -> list[bytes]:
        from rosbags.rosbag2 import Reader

        with Reader(folder / "bag") as reader:
            conns = [c for c in reader.connections if c.topic == "/flow_node/flow"]
            return [bytes(raw) for _, _, raw in reader.messages(connections=conns)]

    assert len(flows(tmp_path / "a")) == 5 and flows(tmp_path / "a") == flows(tmp_path / "b")


def test_flow_bag_without_rosbags_says_what_to_install() -> None:
    """An installed flow_bag on a system ROS without rosbags: one line naming the missing package, exit 1."""
    import subprocess
    import sys

    code = "import sys; sys.modules['rosbags'] = None; from flow_node.bag.cli import main; sys.exit(main(['--help']))"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 1 and proc.stdout == ""
    assert proc.stderr.count("\n") == 1 and "rosbags package is not installed" in proc.stderr
    assert "requirements-system-ros.txt" in proc.stderr
