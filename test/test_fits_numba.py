"""The derived motion outputs' compiled fits (flow_node.pipeline.numba_fits) against the numpy reference
(motion.fit_model, expansion.region_fits), the oracle: exact flows with a moving block, random flows with
garbage and zero confidence, and rendered pairs through the realtime engine; the parameters to 1e-9 (the same
arithmetic up to summation order), the same inliers and the same mask; failures (no support) alike; the moving
mask's deviating pixels (numba_fits.deviating_numba against motion.deviating_pixels) and the dominant motion's
robust start (numba_fits.similarity_start_numba against motion.similarity_start) and its inlier samples
(numba_fits.sample_inliers_numba against motion.sample_inliers) bit for bit; and the wiring:
MotionAnalysis.of takes the stream's backend's fits."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from test_pipeline_motion import ONES, homography_flow, similarity_flow, with_block

from flow_node.bag.motion_scenes import motion_scene
from flow_node.bag.scenes import render_grey_pair
from flow_node.core import FlowConfig, FlowEstimator
from flow_node.core.confidence import confidence as flow_confidence
from flow_node.pipeline.derived import NUMPY_FITS, MotionAnalysis, fits_for
from flow_node.pipeline.expansion import region_fits, region_ttc
from flow_node.pipeline.motion import (
    MaskThreshold,
    SampleFrame,
    apply_homography,
    deviating_pixels,
    dominant_motion,
    fit_model,
    moving_mask,
    sample_inliers,
    similarity_start,
)
from flow_node.pipeline.numba_fits import (
    deviating_numba,
    fit_model_numba,
    region_fits_numba,
    sample_inliers_numba,
    similarity_start_numba,
)
from flow_node.pipeline.robust import SAMPLES, sample_flow, sample_step

TOL = 1e-9  # parameters: the reference's arithmetic, summed in another order (the target is ~1e-5)


def assert_same_dominant(flow: np.ndarray, conf: np.ndarray) -> None:
    for samples in (SAMPLES, 300, 64):  # the start's grids: its slopes' pair distances and its candidates vary
        assert_same_start(flow, conf, samples)
    ref, out = (dominant_motion(flow, conf, fit=f, start=s, inliers=i) for f, s, i in (
        (fit_model, similarity_start, sample_inliers), (fit_model_numba, similarity_start_numba, sample_inliers_numba)))
    assert (ref is None) == (out is None)
    if ref is None:
        return
    assert_same_inliers(flow, conf, np.array(ref.homography))
    np.testing.assert_allclose(np.array(out.homography), np.array(ref.homography), rtol=0, atol=TOL)
    for name in ("tx", "ty", "rotation_deg", "scale", "residual_px"):
        assert getattr(out, name) == pytest.approx(getattr(ref, name), rel=0, abs=TOL), name
    assert out.inlier_share == ref.inlier_share and out.samples == ref.samples  # the same inliers
    mask = moving_mask(flow, conf, ref)
    assert np.array_equal(moving_mask(flow, conf, out), mask)
    assert np.array_equal(moving_mask(flow, conf, ref, deviating=deviating_numba), mask)  # the mask's kernel
    assert_same_deviating(flow, np.asarray(ref.homography, np.float32))


def assert_same_start(flow: np.ndarray, conf: np.ndarray, samples: int = SAMPLES) -> None:
    """The compiled start equals the reference's bit for bit (the same selections and arithmetic), also with
    few or no confident samples (robust.START_CONFIDENCE)."""
    for c in (conf, np.where(conf > 0.7, conf, 0.0), np.minimum(conf, 0.4)):
        frame = SampleFrame(sample_flow(flow, c, sample_step(flow.shape, samples)), flow.shape[:2])
        ref, out = similarity_start(frame), similarity_start_numba(frame)
        assert out.dtype == np.float64 and out.shape == (4,)
        np.testing.assert_array_equal(out, ref)


def assert_same_inliers(flow: np.ndarray, conf: np.ndarray, hp: np.ndarray) -> None:
    """The compiled inlier samples equal the reference's bit for bit, with the default threshold and others,
    also with the samples' flow placed on the threshold to the ulp."""
    s = sample_flow(flow, conf, sample_step(flow.shape, SAMPLES))
    pu, pv = apply_homography(hp, s.x, s.y)
    angle = np.random.default_rng(0).uniform(0, 2 * np.pi, s.x.shape)
    for t in (MaskThreshold(), MaskThreshold(abs_px=0.01, rel=0.0), MaskThreshold(abs_px=3.0, rel=1.5)):
        limit = t.abs_px + t.rel * np.sqrt(pu * pu + pv * pv)
        for samples in (s, *(replace(s, u=pu + f * limit * np.cos(angle), v=pv + f * limit * np.sin(angle))
                             for f in (1.0 - 1e-15, 1.0, 1.0 + 1e-15))):
            ref = sample_inliers(hp, samples, t)
            assert ref.dtype == np.bool_ and ref.shape == s.x.shape
            np.testing.assert_array_equal(sample_inliers_numba(hp, samples, t), ref)


def assert_same_deviating(flow: np.ndarray, hm: np.ndarray, threshold: MaskThreshold | None = None) -> None:
    """The kernel's deviating pixels equal the reference's bit for bit (with the default and a zero-rel and
    a large threshold too, unless ``threshold`` is given)."""
    for t in (threshold,) if threshold is not None else (MaskThreshold(), MaskThreshold(abs_px=0.01, rel=0.0),
                                                         MaskThreshold(abs_px=3.0, rel=1.5)):
        args = (hm, np.float32(t.abs_px), np.float32(t.rel))
        with np.errstate(divide="ignore", invalid="ignore", over="ignore"):  # a horizon inside, huge values
            ref = deviating_pixels(flow, *args)
        out = deviating_numba(flow, *args)
        assert out.dtype == np.bool_ and out.shape == flow.shape[:2]
        assert np.array_equal(out, ref), f"{int(np.sum(out != ref))} pixels differ"


def assert_same_regions(flow: np.ndarray, conf: np.ndarray) -> None:
    ref, out = (region_ttc(flow, conf, 0.1, fit=f) for f in (region_fits, region_fits_numba))
    for field in ("divergence", "expansion", "ttc_frames"):
        a, b = ref.grid(field), out.grid(field)
        assert np.array_equal(np.isnan(a), np.isnan(b)) and np.array_equal(np.isinf(a), np.isinf(b)), field
        finite = np.isfinite(a)
        np.testing.assert_allclose(b[finite], a[finite], rtol=1e-7 if field == "ttc_frames" else 0, atol=TOL)


@pytest.mark.parametrize("flow", [
    with_block(similarity_flow(1.3, -0.6, 0.0, 1.0)), with_block(similarity_flow(0.4, 0.2, -2.0, 1.02)),
    with_block(similarity_flow(-0.8, 1.1, 0.7, 0.985), (-3.0, 0.5)),
    with_block(homography_flow(np.array([[1.01, 0.002, 0.5], [-0.003, 0.99, -0.7], [2e-5, -1e-5, 1.0]]))),
], ids=["pan", "rotation-zoom", "contraction", "homography"])
def test_exact_flows_with_a_block(flow: np.ndarray) -> None:
    assert_same_dominant(flow, ONES)
    assert_same_regions(flow, ONES)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_random_flows_garbage_and_zero_confidence(seed: int) -> None:
    rng = np.random.default_rng(seed)
    flow = with_block(similarity_flow(0.5, -0.3, 1.0, 1.01), (4.0, -2.0))
    garbage = rng.random(ONES.shape) < 0.15
    flow[garbage] = rng.normal(0.0, 5.0, (int(garbage.sum()), 2)).astype(np.float32)
    conf = rng.random(ONES.shape).astype(np.float32)
    conf[:, :40] = 0.0  # a quarter of the image (one column of TTC regions) without support
    assert_same_dominant(flow, conf)
    assert_same_regions(flow, conf)


def test_no_support_fails_alike() -> None:
    flow = similarity_flow(1.0, 0.0, 0.0, 1.0)
    zero = np.zeros_like(ONES)
    assert_same_dominant(flow, zero)  # both None
    assert_same_regions(flow, zero)  # every region NaN in both
    frame_conf = np.zeros(16)
    from flow_node.pipeline.motion import SampleFrame  # the kernels' direct input
    from flow_node.pipeline.robust import sample_flow
    s = sample_flow(flow[:16, :16], np.ones((16, 16), np.float32), 4)
    frame = SampleFrame(s, (16, 16))
    for model, start in (("similarity", np.zeros(4)), ("homography", np.array([1, 0, 0, 0, 1, 0, 0, 0.0]))):
        assert fit_model(model, frame, start, frame_conf, 0) is None
        assert fit_model_numba(model, frame, start, frame_conf, 0) is None


@pytest.mark.parametrize("kind, share, seed", [("pan", 0.2, 3), ("rotation", 0.3, 4), ("approach", 0.0, 5),
                                               ("zoom", 0.1, 6)])
def test_rendered_pairs_through_realtime(kind: str, share: float, seed: int) -> None:
    est = FlowEstimator(FlowConfig.preset("realtime"))
    scene, _ = motion_scene(kind, (192, 144), np.random.default_rng(seed), share, objects=1)
    i0, i1, _ = render_grey_pair(scene)
    res = est.estimate(i0.astype(np.float32), i1.astype(np.float32))
    conf = flow_confidence(*res.frames, res.flow)
    assert_same_dominant(res.flow, conf)
    assert_same_regions(res.flow, conf)


def test_analysis_takes_the_backends_fits() -> None:
    from flow_node.pipeline.stream import FlowStream, StreamSettings

    assert fits_for("numpy") is NUMPY_FITS and fits_for("numba").name == "numba"
    for backend in ("numpy", "numba"):
        stream = FlowStream(StreamSettings(config=FlowConfig.preset("realtime").replace(backend=backend)))
        scene, _ = motion_scene("pan", (96, 72), np.random.default_rng(1), 0.2, objects=1)
        i0, i1, _ = render_grey_pair(scene)
        assert stream.process((255 * i0).astype(np.uint8), 0) is None
        out = stream.process((255 * i1).astype(np.uint8), 100_000_000)
        assert out is not None and out.backend == backend
        a = MotionAnalysis.of(out)
        assert a.fits.name == backend
        assert a.fits.model is (fit_model if backend == "numpy" else fit_model_numba)
        assert a.fits.deviating is (deviating_pixels if backend == "numpy" else deviating_numba)
        assert a.fits.start is (similarity_start if backend == "numpy" else similarity_start_numba)
        assert a.fits.inliers is (sample_inliers if backend == "numpy" else sample_inliers_numba)


def test_warm_fits_compiles_the_kernels() -> None:
    from flow_node.pipeline import numba_fits
    from flow_node.pipeline.derived import warm_fits

    assert warm_fits(NUMPY_FITS) >= 0.0
    warm_fits(fits_for("numba"))  # what the node's warm-up and flow_bag eval --motion run before the first frame
    assert numba_fits.compiled()


def test_deviating_pixels_bit_for_bit_at_the_edges() -> None:
    """The mask's kernel on what could round differently: deviations within an ulp of the threshold, zero
    flow and an identity, a homography whose horizon crosses the image (den 0, inf and NaN), a 1 x 1 and a
    one-row image, a strided float64 flow (the wrapper's conversion), huge values."""
    rng = np.random.default_rng(7)
    hm = np.array([[1.01, 0.002, 0.5], [-0.003, 0.99, -0.7], [2e-5, -1e-5, 1.0]], np.float32)
    predicted = homography_flow(hm.astype(np.float64))
    t = MaskThreshold()
    limit = np.float32(t.abs_px) + np.float32(t.rel) * np.sqrt((predicted ** 2).sum(-1), dtype=np.float32)
    angle = rng.uniform(0, 2 * np.pi, predicted.shape[:2])
    for factor in (1.0 - 1e-7, 1.0, 1.0 + 1e-7):  # on the threshold, to the ulp
        ring = np.stack([np.cos(angle), np.sin(angle)], -1) * (factor * limit)[..., None]
        assert_same_deviating((predicted + ring).astype(np.float32), hm, t)
    eye = np.eye(3, dtype=np.float32)
    assert_same_deviating(np.zeros_like(predicted), eye)
    assert_same_deviating(np.full_like(predicted, 0.5), eye)  # exactly abs_px: not beyond it
    horizon = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.01, 0.02, -1.5]], np.float32)  # den 0 inside
    assert_same_deviating(rng.normal(0, 3, predicted.shape).astype(np.float32), horizon)
    assert_same_deviating(np.full((1, 1, 2), 0.7, np.float32), eye)
    assert_same_deviating(rng.normal(0, 1, (1, 37, 2)).astype(np.float32), hm)
    strided = rng.normal(0, 2, (60, 2 * predicted.shape[1], 2))[:, ::2]  # float64, not contiguous
    assert_same_deviating(strided, hm)
    assert_same_deviating(np.full_like(predicted, 1e30), hm)


def test_start_bit_for_bit_in_the_medoids_edge_cases() -> None:
    """The start's medoid where the reference's np.nan_to_num decides: a kept candidate without a kept
    reference (its median NaN -> inf), candidates not kept (inf -> the largest float), ties (the first)."""
    from flow_node.pipeline.robust import START_CANDIDATES, START_CONFIDENCE, medoid_spread

    rng = np.random.default_rng(11)
    flow = rng.normal(0.0, 2.0, ONES.shape + (2,)).astype(np.float32)
    step = sample_step(flow.shape, SAMPLES)
    o = step // 2
    ny, nx = len(range(o, flow.shape[0], step)), len(range(o, flow.shape[1], step))
    idx, ref = medoid_spread(ny * nx, START_CANDIDATES)
    lonely = [int(i) for i in idx if i not in set(ref.tolist())]
    assert lonely  # a candidate that is no reference
    for kept in ([lonely[0]], [lonely[0], int(idx[0])], [int(i) for i in ref[:3]], [int(idx[2]), int(idx[5])]):
        conf = np.zeros(ONES.shape, np.float32)
        ys, xs = np.unravel_index(kept, (ny, nx))
        conf[o + step * ys, o + step * xs] = START_CONFIDENCE
        frame = SampleFrame(sample_flow(flow, conf, step), flow.shape[:2])
        np.testing.assert_array_equal(similarity_start_numba(frame), similarity_start(frame))
    same = np.zeros_like(flow) + np.float32(0.25)  # every distance 0: ties everywhere
    frame = SampleFrame(sample_flow(same, ONES, step), flow.shape[:2])
    np.testing.assert_array_equal(similarity_start_numba(frame), similarity_start(frame))
