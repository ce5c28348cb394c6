"""FlowConfig.stream_finest_level (task litefull): a stream's predicted pairs solved on a coarser pyramid level
than its full solves (single pairs, first frames, cuts, fallbacks), which keep finest_level; the previous state
reaches the stream's level through temporal.predict's resize. The default (-1) is the stream as before."""

from __future__ import annotations

import numpy as np
import pytest
from test_temporal import aee, frames, pan

from flow_node.core import FlowConfig, FlowEstimator, temporal
from flow_node.core.config import ConfigError
from flow_node.core.pyramid import noise_gain
from flow_node.core.temporal import FULL, PREDICTED, Prior, stream_finest, stream_schedule

# stream_lite's fields with its single pairs at half size and its predicted pairs at quarter size
CAND = dict(finest_level=1, stream_finest_level=2)
SIZE = (320, 240)


def stream(est: FlowEstimator, seq: list[np.ndarray], seen: bool = True) -> list:
    """estimate_next over ``seq`` (the first pair without a prior), each pair's prior the previous result."""
    out = [est.estimate_next(seq[0], seq[1], None)]
    for t in range(2, len(seq)):
        p = out[-1]
        out.append(est.estimate_next(seq[t - 1], seq[t], Prior(p.state, p.unexplained,
                                                               seen=p.seen if seen else None)))
    return out


def old_schedule(cfg: FlowConfig) -> FlowConfig:
    """stream_schedule as it was before the field (main c48fba9): the reference the default must equal."""
    levels = min(cfg.levels, cfg.finest_level + max(cfg.stream_levels, 1))
    return cfg.replace(warps=cfg.stream_warps, iterations=cfg.stream_iterations,
                       finest_warps=cfg.stream_finest_warps, finest_iterations=cfg.stream_finest_iterations,
                       census_iterations=0, census_finest_iterations=0, census_finest_warps=0,
                       levels=levels, alpha=cfg.stream_alpha or cfg.alpha,
                       census_alpha=0.0 if cfg.stream_alpha else cfg.census_alpha)


@pytest.mark.parametrize("preset", ["stream_fast", "stream_lite"])
def test_the_default_is_the_stream_as_before(preset: str) -> None:
    """-1: the schedule is the former one field for field, the photometric stage's noise gain (now taken from the
    schedule) the full config's, and setting the field to finest_level itself changes no flow, bit for bit."""
    cfg = FlowConfig.preset(preset)
    assert cfg.stream_finest_level == FlowConfig().stream_finest_level == -1
    assert stream_finest(cfg) == cfg.finest_level
    assert stream_schedule(cfg) == old_schedule(cfg)
    for shape in ((240, 320), (480, 640), (96, 128), (20, 24)):
        assert noise_gain(shape, stream_schedule(cfg)) == noise_gain(shape, cfg)
    seq = frames(pan(2, size=SIZE), 4)
    a = stream(FlowEstimator(cfg.replace(backend="numpy")), seq)
    b = stream(FlowEstimator(cfg.replace(backend="numpy", stream_finest_level=cfg.finest_level)), seq)
    assert [r.stats.stream for r in a] == ["", PREDICTED, PREDICTED]
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.flow, y.flow)
        np.testing.assert_array_equal(x.state.v, y.state.v)


def test_predicted_pairs_refine_on_the_stream_level_and_full_solves_on_finest_level() -> None:
    """stream_lite at finest_level 1 with stream_finest_level 2 on 320x240: the first pair is solved in full on
    level 1 (160x120) over the whole pyramid; the predicted pairs refine only level 2 (80x60), one warp of 34,
    from the previous state resized there (the first from level 1's state, then from level 2's); every flow is
    full size and accurate."""
    cfg = FlowConfig.preset("stream_lite").replace(backend="numpy", **CAND)
    scene = pan(1, size=SIZE)
    seq = frames(scene, 5)
    out = stream(FlowEstimator(cfg), seq)
    first, predicted = out[0], out[1:]
    assert first.stats.stream == "" and first.state.v.shape == (2, 120, 160)
    assert first.stats.iterations[0] == 0 and first.stats.iterations[1] > 0 and len(first.stats.shapes) > 3
    for k, res in enumerate(predicted, start=2):
        assert res.stats.stream == PREDICTED
        assert res.state.v.shape == (2, 60, 80) and res.flow.shape == (240, 320, 2)
        assert res.stats.start_level == 2 and len(res.stats.shapes) == 3  # the pyramid stops at the stream level
        assert res.stats.iterations == [0, 0, cfg.stream_warps * cfg.stream_iterations]
        assert aee(res.flow, scene.ground_truth(k)) < 0.15, aee(res.flow, scene.ground_truth(k))


def test_predicted_pairs_are_stream_lites_and_single_pairs_are_solved_at_half_size() -> None:
    """From the same prior state the candidate's predicted pair is today's stream_lite's (quarter size), bit for
    bit -- the schedule and the photometric stage's noise gain are the same --; its single pair is stream_lite's
    fields at finest_level 1 (task litesc's "fl1"). The frames span ~15 8-bit grey levels: coarse steps after
    level 1's noise gain, fine ones after level 2's (photometric.affine_normalised), so a stage that took the
    full solve's gain would change the predicted pair."""
    lite = FlowConfig.preset("stream_lite").replace(backend="numpy")
    cand = lite.replace(**CAND)
    seq = [np.round((0.45 + 0.06 * f) * 255).astype(np.float32) / 255 for f in frames(pan(4, size=SIZE), 4)]
    est_lite, est_cand = FlowEstimator(lite), FlowEstimator(cand)
    prev = stream(est_lite, seq[:3])[-1]
    assert prev.stats.stream == PREDICTED
    for seen in (None, prev.seen):
        a = est_lite.estimate_next(seq[2], seq[3], Prior(prev.state, prev.unexplained, seen=seen))
        b = est_cand.estimate_next(seq[2], seq[3], Prior(prev.state, prev.unexplained, seen=seen))
        assert a.stats.stream == b.stats.stream == PREDICTED
        np.testing.assert_array_equal(a.flow, b.flow)
    fl1 = FlowEstimator(lite.replace(finest_level=1)).estimate_grey(seq[0], seq[1])
    single = est_cand.estimate_grey(seq[0], seq[1])
    np.testing.assert_array_equal(single.flow, fl1.flow)
    assert single.stats.iterations == fl1.stats.iterations


def test_a_cut_after_coarser_predictions_is_the_single_pair_solve() -> None:
    """A scene cut after predicted pairs on level 2 is solved in full on level 1, and its flow is the single-pair
    solve's bit for bit (the pyramid the full solve builds is its own, not the cut stream pyramid)."""
    cfg = FlowConfig.preset("stream_lite").replace(backend="numpy", **CAND)
    seq, cut = frames(pan(1, size=SIZE), 4), frames(pan(7, (-1.5, 0.5), size=SIZE), 1)[0]
    est = FlowEstimator(cfg)
    prev = stream(est, seq)[-1]
    assert prev.stats.stream == PREDICTED and prev.state.v.shape == (2, 60, 80)
    res = est.estimate_next(seq[3], cut, Prior(prev.state, prev.unexplained, seen=prev.seen))
    assert res.stats.stream.startswith(FULL) and res.state.v.shape == (2, 120, 160)
    single = est.estimate_grey(seq[3], cut)
    np.testing.assert_array_equal(res.flow, single.flow)
    assert res.stats.iterations == single.stats.iterations


def test_numpy_and_numba_agree_on_a_coarser_stream() -> None:
    """The same stream through both backends: the same decisions and levels, flows to float32 round-off (the
    kernels' own tests hold them to ~1e-5 each; a solve compounds them over medians and warps)."""
    cfg = FlowConfig.preset("stream_lite").replace(**CAND)
    seq = frames(pan(5, size=SIZE), 4)
    ref = stream(FlowEstimator(cfg.replace(backend="numpy")), seq)
    fast = stream(FlowEstimator(cfg.replace(backend="numba")), seq)
    assert [r.backend for r in ref + fast] == ["numpy"] * 3 + ["numba"] * 3
    for a, b in zip(ref, fast, strict=True):
        assert a.stats.stream == b.stats.stream and a.stats.iterations == b.stats.iterations
        assert a.state.v.shape == b.state.v.shape
        diff = np.abs(a.flow - b.flow)
        assert diff.mean() < 1e-4 and diff.max() < 1e-2, (diff.mean(), diff.max())


@pytest.mark.parametrize("fields", [dict(finest_level=2, stream_finest_level=1),
                                    dict(finest_level=1, stream_finest_level=0),
                                    dict(levels=3, stream_finest_level=3),
                                    dict(stream_finest_level=-2)])
def test_invalid_stream_finest_levels_raise(fields: dict) -> None:
    with pytest.raises(ConfigError, match="stream_finest_level"):
        FlowConfig.preset("stream_lite").replace(**fields)


def test_a_stream_level_beyond_a_small_pyramid_is_clamped() -> None:
    """On frames too small for the stream level (min_size), the schedule's finest level clamps to the coarsest
    level the pyramid has, as finest_level does: the stream still runs and returns full-size flows."""
    cfg = FlowConfig.preset("stream_lite").replace(backend="numpy", finest_level=1, stream_finest_level=4)
    seq = frames(pan(3, size=(64, 48)), 3)
    out = stream(FlowEstimator(cfg), seq)
    assert all(r.flow.shape == (48, 64, 2) for r in out)
    assert temporal.stream_schedule(cfg).finest_level == 4
