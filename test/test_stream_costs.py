"""bench.suite.stream_costs: the stage timers wrap the stream stage's real calls and are removed afterwards."""

from __future__ import annotations

import pytest

pytest.importorskip("cv2")

from bench.suite import stream_costs  # noqa: E402


def test_stages_timed_and_restored() -> None:
    originals = [getattr(mod, name) for mod, name, _ in stream_costs.STAGES]
    res = stream_costs.measure("lite=stream_lite", (96, 72), 1)
    assert [getattr(mod, name) for mod, name, _ in stream_costs.STAGES] == originals
    assert res["predicted"] == res["pairs"] - 1  # every pair of the pan after the first is predicted
    stages = res["stages"]
    assert stages["refinement"] > 0 and stages["  solver iterations"] > 0 and stages["pyramid"] > 0
    top = sum(v for k, v in stages.items() if not k.startswith(" ") and k != "other")
    assert top <= res["frame_seconds"] * 1.001  # stages are parts of the frame's time
    assert res["frame_cpu_seconds"] > 0
    assert stages["  solver iterations"] + stages["  linearisation"] <= stages["refinement"] * 1.001

