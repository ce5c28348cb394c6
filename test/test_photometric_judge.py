"""The photometric stage hands back the pair a flow is judged on (engine.photometric_stage), and every data term
is judged by census signatures (census.reliability through the backend): a right flow under a tone curve is
explained, a grey-value flow the tone curve bent is not. The API only asks the judge (no branch on the mode)."""

from __future__ import annotations

import numpy as np
from synth import constant_flow, pair_from_flow, texture

from flow_node.core import census
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY
from flow_node.core.config import FlowConfig
from flow_node.core.engine import photometric_stage
from flow_node.core.metrics import aee
from flow_node.core.photometric import UNRELIABLE


def gamma_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured pair moving by (2.5, 1) px with frame 1 under gamma 2 (a tone change census is
    invariant to and grey values are not), and the flow (H, W, 2)."""
    h, w = 72, 96
    gt = constant_flow(h, w, 2.5, 1.0)
    i0, i1 = pair_from_flow(texture(h, w, seed=12), gt)
    return i0, (i1 * i1).astype(np.float32), gt


def test_every_data_term_is_judged_on_census_signatures() -> None:
    i0, i1, gt = gamma_pair()
    cfg = FlowConfig.preset("realtime")
    for mode in ("census", "normalise", "local_contrast"):
        _, judged = photometric_stage(i0, i1, cfg.replace(photometric=mode), NUMPY)
        assert judged.unexplained(gt) == census.reliability(*judged.frames, gt, NUMPY.warper.sample), mode
        # the right flow under gamma is explained, a zero flow is not
        assert judged.unexplained(gt) < 0.05 and judged.unexplained(np.zeros_like(gt)) > 0.5, mode


def test_a_grey_value_flow_bent_by_a_tone_change_reads_unexplained() -> None:
    """Under gamma 2 and an illumination ramp (0.7 to 1.3 across the frame) the grey-value term fits intensities,
    not motion: its flow is ~8 px off and the judge says so (0.77), while the census term's right flow reads
    explained (0.007). (The grey-value judge this replaced read such flows as explained on about half of the
    suite's held-out family pairs: docs/engine.md, "The judge".)"""
    i0, i1, gt = gamma_pair()
    i1 = np.clip(i1 * np.linspace(0.7, 1.3, i1.shape[1], dtype=np.float32)[None, :], 0, 1)
    base = FlowConfig.preset("realtime").replace(initialisation="none", backend="numpy")
    grey = FlowEstimator(base.replace(photometric="normalise")).estimate(i0, i1)
    right = FlowEstimator(base.replace(photometric="census")).estimate(i0, i1)
    assert aee(grey.flow, gt) > 2.0 > 0.1 > aee(right.flow, gt)
    assert grey.unexplained > UNRELIABLE > 0.05 > right.unexplained


def test_the_api_reports_the_stage_judges_figure() -> None:
    i0, i1, gt = gamma_pair()
    for mode in ("census", "normalise"):
        cfg = FlowConfig.preset("realtime").replace(photometric=mode, initialisation="none", backend="numpy")
        result = FlowEstimator(cfg).estimate(i0, i1)
        _, judged = photometric_stage(i0, i1, cfg, NUMPY)
        assert result.frames is not None
        assert np.array_equal(result.frames[0], judged.frames[0])
        assert result.unexplained == judged.unexplained(result.flow), mode
