"""The photometric stage hands back its own reliability judge (engine.photometric_stage): census
signatures for the census data term, grey values otherwise; the API only asks it (no branch on the mode)."""

from __future__ import annotations

import numpy as np
from synth import constant_flow, pair_from_flow, texture

from flow_node.core import census
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY
from flow_node.core.config import FlowConfig
from flow_node.core.engine import photometric_stage
from flow_node.core.photometric import reliability


def gamma_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured pair moving by (2.5, 1) px with frame 1 under gamma 2 (a tone change census is
    invariant to and grey values are not), and the flow (H, W, 2)."""
    h, w = 72, 96
    gt = constant_flow(h, w, 2.5, 1.0)
    i0, i1 = pair_from_flow(texture(h, w, seed=12), gt)
    return i0, (i1 * i1).astype(np.float32), gt


def test_the_census_stage_judges_signatures_and_the_grey_stage_grey_values() -> None:
    i0, i1, gt = gamma_pair()
    cfg = FlowConfig.preset("realtime")
    _, judged_census = photometric_stage(i0, i1, cfg.replace(photometric="census"), NUMPY)
    _, judged_grey = photometric_stage(i0, i1, cfg.replace(photometric="normalise"), NUMPY)
    assert judged_census.unexplained(gt) == census.reliability(*judged_census.frames, gt, NUMPY.warper.sample)
    assert judged_grey.unexplained(gt) == reliability(*judged_grey.frames, gt, NUMPY.warper.sample)
    # the right flow under gamma: explained by signatures, not by grey values
    assert judged_census.unexplained(gt) < 0.05 < 0.1 < judged_grey.unexplained(gt)
    assert judged_census.unexplained(np.zeros_like(gt)) > 0.5


def test_the_api_reports_the_stage_judges_figure() -> None:
    i0, i1, gt = gamma_pair()
    for mode in ("census", "normalise"):
        cfg = FlowConfig.preset("realtime").replace(photometric=mode, initialisation="none", backend="numpy")
        result = FlowEstimator(cfg).estimate(i0, i1)
        _, judged = photometric_stage(i0, i1, cfg, NUMPY)
        assert result.frames is not None
        assert np.array_equal(result.frames[0], judged.frames[0])
        assert result.unexplained == judged.unexplained(result.flow), mode
