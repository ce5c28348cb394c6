"""The numba fusion stage (numba_fusion.py) against the numpy reference (fusion.fuse,
initialise.forward_backward_consistent), the oracle, on exactly rendered scenes with real occlusions,
several candidates and every option of the fusion.

The kernels sample bilinearly themselves, as OpenCV 5's remap does (the reference's sampling): with
OpenCV 5 the fused flow, the choice and the masks must equal the reference's bit for bit. OpenCV 4.x
snaps remap positions to 1/32 px (the Ubuntu 24.04 venv), so there the reference differs slightly: the
kernels' sampling is checked against an exact bilinear numpy reference everywhere, and the fusion's
outcome must agree on all but a few pixels.
"""

from __future__ import annotations

import cv2
import numba
import numpy as np
import pytest

from flow_node.bag.scenes import AffineMotion, Layer, Scene, Texture
from flow_node.core import FlowEstimator, numba_backend
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig
from flow_node.core.fusion import FINAL_MARGIN, cost_planes, fuse, level_planes, planes
from flow_node.core.initialise import forward_backward_consistent
from flow_node.core.numba_fusion import _rows_on, consistent_numba, fuse_numba, planes_numba, residual_kernel

W, H = 200, 160


def remap_is_exact() -> bool:
    """Whether this OpenCV's remap samples bilinearly at the exact position (OpenCV 5) rather than at the
    nearest 1/32 px (4.x): a ramp sampled at 1/128 px steps comes back exactly."""
    ramp = np.tile(np.arange(16, dtype=np.float32), (4, 1))
    xs = np.tile(np.float32(5) + np.arange(0, 1, 1 / 128, dtype=np.float32), (4, 1))
    return bool(np.array_equal(cv2.remap(ramp, xs, np.ones_like(xs), cv2.INTER_LINEAR)[0], xs[0]))


REMAP_EXACT = remap_is_exact()


def assert_same_fusion(ref: tuple[np.ndarray, np.ndarray], out: tuple[np.ndarray, np.ndarray]) -> None:
    """The numba fusion's (flow, choice) equals the reference's: bit for bit with OpenCV 5's exact remap;
    with 4.x's 1/32 px positions, the same choice on >= 99 % of the pixels and the same flow there."""
    (ref_flow, ref_choice), (flow, choice) = ref, out
    assert flow.dtype == np.float32 and flow.shape == ref_flow.shape and choice.shape == ref_choice.shape
    if REMAP_EXACT:
        assert np.array_equal(choice, ref_choice) and np.array_equal(flow, ref_flow)
        return
    same = choice == ref_choice
    assert same.mean() >= 0.99 and np.array_equal(flow[:, same], ref_flow[:, same])


def bilinear(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Exact bilinear samples of img (h, w, c) at (x, y) (inside the image), float64: the reference of the
    kernels' sampling, independent of OpenCV."""
    h, w = img.shape[:2]
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    x1, y1 = np.minimum(x0 + 1, w - 1), np.minimum(y0 + 1, h - 1)
    ax, ay = (x - x0)[..., None], (y - y0)[..., None]
    im = img.astype(np.float64)
    return ((1 - ay) * ((1 - ax) * im[y0, x0] + ax * im[y0, x1]) + ay * ((1 - ax) * im[y1, x0] + ax * im[y1, x1]))


def test_residual_kernel_samples_bilinearly(rows) -> None:
    """The kernel's masked residual against an exact bilinear numpy reference (to float32 round-off),
    with a flow that leaves the image in places (mask 0 there)."""
    i0, i1, truth = jump_scene()
    flow = truth + np.random.default_rng(2).normal(0.0, 2.0, truth.shape).astype(np.float32)
    flow[0, :, :10] -= np.float32(20.0)
    s0, s1 = planes(i0), planes(i1)
    out = np.empty((H, W, 2), np.float32)
    with _rows_on(H, W):
        residual_kernel(out, s0, s1, flow)
    x = np.arange(W, dtype=np.float32)[None] + flow[0]
    y = np.arange(H, dtype=np.float32)[:, None] + flow[1]
    inside = (x >= 0) & (x <= W - 1) & (y >= 0) & (y <= H - 1)
    assert 0.05 < 1 - inside.mean() < 0.5
    ref = np.abs(bilinear(s1, x[inside], y[inside]) - s0[inside]).sum(axis=-1)
    assert np.array_equal(out[..., 1], inside.astype(np.float32)) and np.all(out[~inside, 0] == 0)
    np.testing.assert_allclose(out[inside, 0], ref, rtol=0, atol=1e-5)


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
    out = consistent_numba(forward, backward)
    assert np.array_equal(out, ref) if REMAP_EXACT else (out == ref).mean() > 0.99


@pytest.fixture(params=["serial", "parallel"])
def rows(request, monkeypatch: pytest.MonkeyPatch) -> str:
    """Both ways the kernels run their rows: serial (small levels) and in parallel (the threshold the
    kernels read, numba_backend.PARALLEL_MIN_PIXELS, patched down to this test's small frames)."""
    if request.param == "parallel":
        monkeypatch.setattr(numba_backend, "PARALLEL_MIN_PIXELS", 0)
        assert numba_backend.threads() > 1 or numba.config.NUMBA_NUM_THREADS == 1
    return request.param


@pytest.mark.parametrize("count", [2, 3])
@pytest.mark.parametrize("margin,only_consistent,propagate", [(1.3, False, True), (FINAL_MARGIN, True, True),
                                                              (1.0, False, False), (2.0, True, False)])
@pytest.mark.parametrize("photometric", ["normalise", "census"])
def test_fusion_equals_the_reference(count, margin, only_consistent, propagate, photometric, rows) -> None:
    """Grey-value cost planes (3) and census signatures (8: two groups of fusion.REMAP_CHANNELS)."""
    i0, i1, truth = jump_scene()
    cands, masks = candidates(truth, count)
    cands, masks = cands[:count], masks[:count]
    planes_of = cost_planes(photometric)
    ref = fuse(i0, i1, cands, masks, margin, only_consistent, propagate, planes_of=planes_of)
    assert len(np.unique(ref[1])) == count  # every candidate wins somewhere: the choice is exercised
    assert_same_fusion(ref, fuse_numba(i0, i1, cands, masks, margin, only_consistent, propagate, planes_of=planes_of))


AGREE = 1e-5  # the numba kernels' agreement with the numpy reference (float32 rounding; the rules' ~1e-5)


@pytest.mark.parametrize("eps", [0.0, 0.03, 0.2])
def test_cost_planes_match_the_reference(eps, rows) -> None:
    """The numba backend's cost planes (numba_fusion.planes_numba: the census term's factor kernel,
    numba_census.factor_kernel) match fusion.level_planes to float32 rounding (the kernel multiplies the differences
    by GAIN / (RMS + EPS), the reference divides by RMS + EPS, then multiplies by GAIN: the last bit of ~40 % of the
    values differs): the census signature (8 planes; EPS the default or a level's floor above it) of a textured
    frame, a flat one (RMS 0: EPS alone), and frames of one row, one column and 2 x 3 px (neighbours clamped on every
    side); the grey-value planes are OpenCV's in both backends, bit for bit."""
    i0, _, _ = jump_scene()
    flat = np.full((9, 7), 0.4, np.float32)
    for img in (i0, flat, i0[:1], i0[:, :1], i0[:2, :3]):
        out = planes_numba(img, "census", eps)
        assert out.shape == img.shape + (8,) and out.dtype == np.float32
        np.testing.assert_allclose(out, level_planes(img, "census", eps), rtol=0, atol=AGREE)
    assert np.abs(planes_numba(i0, "census", eps)).max() > 0.05  # not trivially zero
    assert np.array_equal(planes_numba(i0, "normalise", eps), level_planes(i0, "normalise", eps))


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize("margin,only_consistent,propagate", [(1.3, False, True), (FINAL_MARGIN, True, True),
                                                              (1.0, False, False)])
def test_fusion_on_the_kernel_s_census_planes_chooses_as_the_reference(seed, margin, only_consistent, propagate,
                                                                         rows) -> None:
    """The numba fusion on the numba census planes chooses as the numpy reference on its own planes (the planes'
    last bits do not move a box mean across a margin here): the jump scene's candidates, every option."""
    i0, i1, truth = jump_scene()
    cands, masks = candidates(truth, seed)
    ref = fuse(i0, i1, cands, masks, margin, only_consistent, propagate, planes_of=cost_planes("census"))
    assert len(np.unique(ref[1])) == 3  # every candidate wins somewhere: the choice is exercised
    stacks = (planes_numba(i0, "census"), planes_numba(i1, "census"))
    assert not np.array_equal(stacks[0], level_planes(i0, "census"))  # the kernel's rounding, not the reference's
    assert_same_fusion(ref, fuse_numba(i0, i1, cands, masks, margin, only_consistent, propagate, stacks=stacks))


def test_fusion_without_masks_and_with_undecided_pixels_equals_the_reference(rows) -> None:
    """No forward-backward masks, and a candidate that leaves the image in a wide stripe (no support: those
    pixels are undecided and continue their decided neighbours' flow)."""
    i0, i1, truth = jump_scene()
    left = truth.copy()
    left[0, :, :60] = -100.0
    out = truth.copy()
    out[0, :, :60] = -90.0
    ref = fuse(i0, i1, [left, out])
    assert ref[1].any()
    assert_same_fusion(ref, fuse_numba(i0, i1, [left, out]))


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


@pytest.mark.parametrize("photometric", ["normalise", "census"])
def test_engine_with_the_numba_fusion_equals_the_numpy_fusion(photometric) -> None:
    """A 40 px pan (DIS fused on two levels, forward-backward checked): the numba backend with its own
    fusion and cost planes and with the numpy reference's gives the same flow (bit for bit with OpenCV 5's remap),
    with grey values and with census signatures as the cost."""
    rng = np.random.default_rng(4)
    pan = Layer(Texture.random(rng, fmin=1 / 100), AffineMotion((119.5, 89.5), (40.0, 12.0)))
    scene = Scene("pan", (240, 180), (pan,))
    i0, i1 = grey(scene.render(0)), grey(scene.render(1))
    cfg = FlowConfig.preset("realtime").replace(backend="numba", photometric=photometric)
    est = FlowEstimator(cfg)
    res = est.estimate_grey(i0, i1)
    assert res.stats.init == "dis_ultrafast" and res.stats.start_level > 0
    backend = select_backend("numba")
    mixed = FlowEstimator(cfg, backend=backend._replace(fuse=fuse, consistent=forward_backward_consistent,
                                                        cost_planes=level_planes))
    ref = mixed.estimate_grey(i0, i1).flow
    if REMAP_EXACT:
        assert np.array_equal(ref, res.flow)
    else:  # 1/32 px remap positions move a few fusion choices, and the refinement carries them on (94 %)
        assert np.mean(np.hypot(*np.moveaxis(ref - res.flow, -1, 0)) < 0.01) > 0.9
