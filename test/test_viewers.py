"""The viewer configurations shipped in share/flow_node/config: installed by setup.py, parse, and show the
input image, ~/flow_color, ~/magnitude, ~/motion/moving_mask and ~/motion/divergence (and, in Foxglove,
/diagnostics, the dominant motion and motion detected) under the node's real names."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from flow_node.bag.results import NODE_NAMESPACE
from flow_node.bag.synth import FRAME_ID, IMAGE_TOPIC

ROOT = Path(__file__).resolve().parent.parent
IMAGES = {"input": IMAGE_TOPIC, "color": f"{NODE_NAMESPACE}/flow_color", "magnitude": f"{NODE_NAMESPACE}/magnitude",
          "mask": f"{NODE_NAMESPACE}/motion/moving_mask", "divergence": f"{NODE_NAMESPACE}/motion/divergence"}


@pytest.fixture(scope="module")
def share(tmp_path_factory) -> Path:
    """setup.py's data files installed into a temporary prefix, as colcon/pip install them."""
    prefix = tmp_path_factory.mktemp("prefix")
    subprocess.run([sys.executable, "setup.py", "-q", "install_data", "--install-dir", str(prefix)], cwd=ROOT,
                   check=True, capture_output=True)
    return prefix / "share" / "flow_node" / "config"


def panel_ids(tree) -> list[str]:
    """Panel ids in a Foxglove mosaic layout tree (a panel id, or {first, second, direction, ...})."""
    if isinstance(tree, str):
        return [tree]
    return panel_ids(tree["first"]) + panel_ids(tree["second"])


def test_foxglove_layout(share):
    layout = json.loads((share / "flow_node.foxglove.json").read_text())
    panels = layout["configById"]
    assert sorted(panel_ids(layout["layout"])) == sorted(panels)  # every panel placed, none dangling
    by_type: dict[str, list[dict]] = {}
    for pid, cfg in panels.items():
        by_type.setdefault(pid.split("!")[0], []).append(cfg)
    assert sorted(c["imageMode"]["imageTopic"] for c in by_type["Image"]) == sorted(IMAGES.values())
    assert [c["topicToRender"] for c in by_type["DiagnosticSummary"]] == ["/diagnostics"]
    (status,) = by_type["DiagnosticStatusPanel"]
    assert status["topicToRender"] == "/diagnostics"
    assert (status["selectedName"], status["selectedHardwareId"]) == ("flow_node: optical flow", FRAME_ID)
    (divergence,) = [c["imageMode"] for c in by_type["Image"] if c["imageMode"]["imageTopic"] == IMAGES["divergence"]]
    assert divergence["minValue"] == -divergence["maxValue"] < 0  # 1/frame, 0 in the middle of the colour map
    (plot,) = by_type["Plot"]  # the dominant motion's image translation, px/s, on the frames' stamps
    assert [p["value"] for p in plot["paths"]] == [f"{NODE_NAMESPACE}/motion/dominant.twist.linear.{a}" for a in "xy"]
    assert all(p["timestampMethod"] == "headerStamp" for p in plot["paths"])
    (indicator,) = by_type["Indicator"]
    assert indicator["path"] == f"{NODE_NAMESPACE}/motion/detected.data"
    assert [(r["operator"], r["rawValue"]) for r in indicator["rules"]] == [("=", "true")]


def test_rviz_config(share):
    text = (share / "flow_node.rviz").read_text()
    rviz = yaml.safe_load(text)
    displays = rviz["Visualization Manager"]["Displays"]
    assert {d["Class"] for d in displays} == {"rviz_default_plugins/Image"}
    topics = {d["Topic"]["Value"]: d for d in displays}
    assert sorted(topics) == sorted(IMAGES.values())
    assert all(d["Enabled"] and d["Topic"]["Depth"] == 1 for d in displays)
    # The camera publishes best effort (sensor data), the node's outputs are reliable: both must match.
    assert topics[IMAGES["input"]]["Topic"]["Reliability Policy"] == "Best Effort"
    magnitude = topics[IMAGES["magnitude"]]
    assert not magnitude["Normalize Range"] and magnitude["Max Value"] > magnitude["Min Value"] == 0
    divergence = topics[IMAGES["divergence"]]  # 1/frame, fixed and symmetric: mid-grey is no expansion
    assert not divergence["Normalize Range"] and divergence["Min Value"] == -divergence["Max Value"] < 0
    assert rviz["Visualization Manager"]["Global Options"]["Fixed Frame"] == FRAME_ID
    assert "share/flow_node/config/flow_node.rviz" in text  # the usage line names the installed path
