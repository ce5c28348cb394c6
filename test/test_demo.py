"""`make demo` end to end: bag -> play -> live node (a child process) -> flow over DDS, equal to eval."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

from flow_node.demo import DemoOptions, run_demo

pytestmark = [pytest.mark.ros, pytest.mark.slow]  # rclpy over DDS, node processes; seconds each

ROOT = Path(__file__).resolve().parent.parent


def node_processes() -> list[str]:
    """Node processes of this checkout's interpreter (the demo starts its node with it): another checkout's
    node on the same machine is none of this test's business."""
    out = subprocess.run(["ps", "-eo", "pid,args"], capture_output=True, text=True).stdout
    return [line for line in out.splitlines()
            if "flow_node.ros.node" in line and sys.executable in line and str(os.getpid()) not in line]


def test_live_node_matches_eval(tmp_path):
    """Every pair comes back over DDS; the live flow equals flow_bag eval's within 1e-5 px; AEE vs GT small."""
    before = node_processes()
    result = run_demo(DemoOptions(out_dir=tmp_path, rate=0.5))
    assert result.node_exit == 0  # SIGINT -> clean shutdown
    assert node_processes() == before  # nothing left running
    assert len(result.rows) == 9 and result.received == 9
    for row in result.rows:
        assert row.max_diff is not None and row.max_diff <= 1e-5
        assert row.aee is not None and row.aee < 0.3 and abs(row.aee - row.eval_aee) < 1e-5
        assert 0.0 < row.latency < 2.0
    assert result.diagnostics["model"] == "l1_tv" and result.diagnostics["backend"] == "numpy"
    assert result.diagnostics["frames published"] == "9"
    assert "node.log" in os.listdir(tmp_path)


def test_demo_command(tmp_path):
    """`python -m flow_node.demo` (what `make demo` runs): exit 0, table, summary, PNGs, in well under a minute."""
    proc = subprocess.run([sys.executable, "-m", "flow_node.demo", "--out", str(tmp_path / "demo_out")],
                          capture_output=True, text=True, timeout=120, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert lines[1].split() == ["frame", "AEE", "px", "AE", "deg", "latency", "ms", "eval", "AEE", "|live-eval|"]
    assert any(line.startswith("summary: 9/9 frame pairs received over DDS") for line in lines)
    assert sorted(p.name for p in (tmp_path / "demo_out").glob("flow_*.png")) == [f"flow_{k:04d}.png"
                                                                                 for k in range(1, 10)]
