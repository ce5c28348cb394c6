"""bench.suite.stream_costs: the stage timers wrap the stream stage's real calls and are removed afterwards."""

from __future__ import annotations

import numpy as np
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


def test_census_stages_timed() -> None:
    """stream_fast (census signatures): the census term's level setup and forms are timed inside the refinement."""
    stages = stream_costs.measure("fast=stream_fast", (96, 72), 1)["stages"]
    parts = stages["  census level setup"] + stages["  census forms"] + stages["  solver iterations"]
    assert stages["  census level setup"] > 0 and stages["  census forms"] > 0 and stages["  linearisation"] == 0
    assert parts <= stages["refinement"] * 1.001



def test_cpu_counts_the_predicted_frames_of_a_pan() -> None:
    """bench.suite.stream_costs --cpu: every pair of a report pan after the first is predicted and timed."""
    from bench.suite.sequences import sequences

    frames = len(next(iter(sequences("report", (96, 72), ("pan",)))).frames)
    best, median, n = stream_costs.cpu_per_frame("lite=stream_lite", (96, 72), "pan", 1)
    assert n == frames - 2  # the first frame starts the stream, the first pair is solved in full
    assert 0 < best <= median * 1.001  # one pass: the per-frame minima are that pass's times


@pytest.mark.parametrize("kind", ["shake", "wave", "shear"])
def test_heldout_sequences_are_exact(kind: str) -> None:
    """The stream regime's held-out motions (bench.suite.sequences, split ``heldout``): frame t + 1 sampled at
    x + gt(x) is frame t (the rendering before noise and quantisation), at every pair the sequence scores."""
    from bench.suite.sequences import HELDOUT_KINDS, grey, scene_of, sequences

    size = (64, 48)
    scene = scene_of(kind, size, np.random.default_rng(5))
    for t in (1, 7):
        back = scene.render(t + 1, scene.pixel_grid() + scene.ground_truth(t + 1)) @ np.array([0.299, 0.587, 0.114])
        np.testing.assert_allclose(back, grey(scene, t), atol=1e-9)
    names = [s.name for s in sequences("heldout", size, frames=3)]
    assert names == [f"s{7000 + k}_{HELDOUT_KINDS[k % 3]}" for k in range(6)]
