"""The numba fusion stage (numba_fusion.py) against the numpy reference (fusion.fuse,
initialise.forward_backward_consistent), the oracle: same remap and box means, same float32 arithmetic,
so the fused flow, the choice and the consistency masks must be equal bit for bit -- on exactly rendered
scenes with real occlusions, several candidates and every option of the fusion.
"""

from __future__ import annotations

import numba
import numpy as np
import pytest

from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowEstimator, numba_backend
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig
from flow_node.core.fusion import FINAL_MARGIN, fuse
from flow_node.core.initialise import forward_backward_consistent
from flow_node.core.numba_fusion import consistent_numba, fuse_numba

W, H = 200, 160


def grey(rgb: np.ndarray) -> np.ndarray:
    return (rgb @ np.array([0.299, 0.587, 0.114])).astype(np.float32)


def jump_scene(jump: float = 60.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A textured box jumping ``jump`` px right over a textured, still background, rendered exactly:
    (i0, i1, true flow (2, H, W)). The background the box covers in frame 1 is occluded."""
    rng = np.random.default_rng(11)
    back = Layer(Texture.random(rng, fmin=1 / 60, fmax=1 / 8), AffineMotion(((W - 1) / 2, (H - 1) / 2)))
    box = Layer(Texture.random(rng, fmax=1 / 6), AffineMotion((50.0, 80.0), (jump, 0.0)),
                (50.0, 80.0, 20.0, 20.0, "box"))
    scene = Scene("jump", (W, H), (back, box))
    return grey(scene.render(0)), grey(scene.render(1)), np.moveaxis(scene.ground_truth(1).astype(np.float32), -1, 0)


def candidates(truth: np.ndarray, seed: int) -> tuple[list[np.ndarray], list[np.ndarray | None]]:
    """A reference that lost the box, the truth with noise and wrong patches, and a constant shift; the
    last two with forward-backward masks from backward flows that agree in places only."""
    rng = np.random.default_rng(seed)
    reference = truth.copy()
    reference[:, 60:100, 30:71] = 0.0
    noisy = truth + rng.normal(0.0, 0.3, truth.shape).astype(np.float32)
    noisy[:, 10:40, 120:180] += np.float32(25.0)  # wrong patch
    noisy[1, 60:100, 90:131] = -55.0  # the occluded background sent onto other content
    shifted = np.full_like(truth, 3.0)
    masks: list[np.ndarray | None] = [None]
    for cand in (noisy, shifted):
        backward = -cand + rng.normal(0.0, 0.8, truth.shape).astype(np.float32)
        masks.append(forward_backward_consistent(cand, backward))
    return [reference, noisy, shifted], masks


@pytest.mark.parametrize("seed", [0, 1])
def test_consistency_check_equals_the_reference(seed, rows) -> None:
    _, _, truth = jump_scene()
    rng = np.random.default_rng(seed)
    forward = truth + rng.normal(0.0, 1.0, truth.shape).astype(np.float32)
    forward[:, :8] -= np.float32(30.0)  # leaves the image on the left
    backward = -truth + rng.normal(0.0, 1.0, truth.shape).astype(np.float32)
    ref = forward_backward_consistent(forward, backward)
    assert 0.1 < ref.mean() < 0.9  # both outcomes occur
    assert np.array_equal(consistent_numba(forward, backward), ref)


@pytest.fixture(params=["serial", "parallel"])
def rows(request, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both ways the kernels run their rows: serial (small levels) and in parallel (the threshold the
    kernels read, numba_backend.PARALLEL_MIN_PIXELS, patched down to this test's small frames)."""
    if request.param == "parallel":
        monkeypatch.setattr(numba_backend, "PARALLEL_MIN_PIXELS", 0)
        numba_backend.set_threads(0)
        assert numba_backend.threads() > 1 or numba.config.NUMBA_NUM_THREADS == 1
    return request.param


@pytest.mark.parametrize("count", [2, 3])
@pytest.mark.parametrize("margin,only_consistent,propagate", [(1.3, False, True), (FINAL_MARGIN, True, True),
                                                              (1.0, False, False), (2.0, True, False)])
def test_fusion_equals_the_reference(count, margin, only_consistent, propagate, rows) -> None:
    i0, i1, truth = jump_scene()
    cands, masks = candidates(truth, count)
    cands, masks = cands[:count], masks[:count]
    ref_flow, ref_choice = fuse(i0, i1, cands, masks, margin, only_consistent, propagate)
    flow, choice = fuse_numba(i0, i1, cands, masks, margin, only_consistent, propagate)
    assert len(np.unique(ref_choice)) == count  # every candidate wins somewhere: the choice is exercised
    assert flow.dtype == np.float32 and flow.shape == ref_flow.shape
    assert np.array_equal(choice, ref_choice) and np.array_equal(flow, ref_flow)


def test_fusion_without_masks_and_with_undecided_pixels_equals_the_reference(rows) -> None:
    """No forward-backward masks, and a candidate that leaves the image in a wide stripe (no support: those
    pixels are undecided and continue their decided neighbours' flow)."""
    i0, i1, truth = jump_scene()
    left = truth.copy()
    left[0, :, :60] = -100.0
    out = truth.copy()
    out[0, :, :60] = -90.0
    ref_flow, ref_choice = fuse(i0, i1, [left, out])
    flow, choice = fuse_numba(i0, i1, [left, out])
    assert np.array_equal(choice, ref_choice) and np.array_equal(flow, ref_flow)


def test_numba_fusion_keeps_the_background_where_it_is_occluded() -> None:
    """The behaviour the reference's test asserts (test_core_large.py), on the numba stage: where the box
    covers the background in frame 1, the candidate's wrong vectors fail the check and the fused flow is
    the background's own (zero); on the box, which the reference lost, the candidate wins."""
    i0, i1, truth = jump_scene()
    reference = truth.copy()
    reference[:, 60:101, 30:71] = 0.0
    candidate = truth.copy()
    candidate[1, 60:101, 90:131] = -55.0
    backward = np.zeros_like(truth)
    backward[0, 60:101, 90:131] = -60.0
    ok = consistent_numba(candidate, backward)
    fused, choice = fuse_numba(i0, i1, [reference, candidate], [None, ok])
    err = np.hypot(*(fused - truth))
    assert err[62:99, 92:129].max() == 0.0
    assert err[62:99, 32:69].max() == 0.0 and np.all(choice[62:99, 32:69] == 1)


def test_engine_with_the_numba_fusion_equals_the_numpy_fusion() -> None:
    """A 40 px pan (DIS fused on two levels, forward-backward checked): the numba backend with its own
    fusion and with the numpy reference's gives the same flow bit for bit."""
    rng = np.random.default_rng(4)
    pan = Layer(Texture.random(rng, fmin=1 / 100), AffineMotion((119.5, 89.5), (40.0, 12.0)))
    scene = Scene("pan", (240, 180), (pan,))
    i0, i1 = grey(scene.render(0)), grey(scene.render(1))
    cfg = FlowConfig.preset("realtime").replace(backend="numba")
    est = FlowEstimator(cfg)
    res = est.estimate_grey(i0, i1)
    assert res.stats.init == "dis_ultrafast" and res.stats.start_level > 0
    backend = select_backend("numba")
    est._backend = backend._replace(fuse=fuse, consistent=forward_backward_consistent)
    assert np.array_equal(est.estimate_grey(i0, i1).flow, res.flow)
