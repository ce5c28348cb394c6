"""The photometric stage: bit depth and exposure invariance, no false exposure correction, and the
reliability figure that tells a matching flow from garbage. Pairs are rendered exactly (test/synth.py)."""

from __future__ import annotations

import numpy as np
import pytest
from synth import constant_flow, interior, pair_from_flow, rotation_flow, texture

from flow_node import FlowConfig, FlowEstimator, aee
from flow_node.core.backends import select_backend
from flow_node.core.census import reliability
from flow_node.core.numba_judge import reliability_numba
from flow_node.core.numba_sort import median_f32, sorted_sample_numba
from flow_node.core.photometric import (
    UNRELIABLE,
    exposure_change,
    line_fit,
    preprocess,
    reliability_stride,
    sorted_sample,
)

H, W = 60, 80
GT = constant_flow(H, W, 1.2, -0.7) + rotation_flow(H, W, 1.5)
CFG = FlowConfig(levels=3, warps=3, iterations=40, backend="numba")


def quantised(img: np.ndarray, bits: int, container: type = np.uint8) -> np.ndarray:
    """img in [0, 1] as n-bit content (values up to 2^bits - 1) in a uint8 or uint16 container."""
    return np.clip(np.rint(img * (2**bits - 1)), 0, 2**bits - 1).astype(container)


@pytest.fixture(scope="module")
def pair() -> tuple[np.ndarray, np.ndarray]:
    i0, i1 = pair_from_flow(texture(H, W, 11), GT)
    return np.clip(i0, 0, 1), np.clip(i1, 0, 1)


def flow_error(est: FlowEstimator, f0: np.ndarray, f1: np.ndarray) -> float:
    return aee(interior(est.estimate(f0, f1).flow), interior(GT))


def test_bit_depth_does_not_change_the_result(pair) -> None:
    """10-bit content in mono16 (values up to 1023 of 65535): normalised, within 10 % of 8 bit; without the
    stage the weights act on 1/64 of the contrast and the flow is far off."""
    i0, i1 = pair
    est = FlowEstimator(CFG)
    e8 = flow_error(est, quantised(i0, 8), quantised(i1, 8))
    e10 = flow_error(est, quantised(i0, 10, np.uint16), quantised(i1, 10, np.uint16))
    assert e8 < 0.05 and e10 < 1.1 * e8
    est.config = CFG.replace(photometric="none")
    assert flow_error(est, quantised(i0, 10, np.uint16), quantised(i1, 10, np.uint16)) > 3 * e8


# AEE with an exposure change over AEE without, per mode: the local modes are invariant by construction;
# normalise detects the change from the frames' percentiles and then normalises the pair locally (its global
# fit alone left a ~1 % gain error: 6x the AEE on this 60x80 pair; the local normalisation costs ~1.8x here
# against the unchanged pair's global one, 1.1-1.25x on the suite's 320x240 pairs)
RATIO = {"normalise": 2.0, "local_contrast": 1.3, "structure_texture": 1.3}


@pytest.mark.parametrize("mode", sorted(RATIO))
@pytest.mark.parametrize("gain,offset", [(1.25, -0.02), (0.8, 0.04)])
def test_exposure_change_is_not_motion(pair, mode: str, gain: float, offset: float) -> None:
    i0, i1 = pair
    est = FlowEstimator(CFG.replace(photometric=mode, alpha=0.1))
    same = flow_error(est, quantised(i0, 8), quantised(i1, 8))
    changed = quantised(np.clip(i1 * gain + offset, 0, 1), 8)
    result = est.estimate(quantised(i0, 8), changed)
    assert aee(interior(result.flow), interior(GT)) < RATIO[mode] * same + 0.005
    assert result.unexplained < 0.1
    est.config = CFG.replace(photometric="none")
    garbage = est.estimate(quantised(i0, 8), changed)
    assert aee(interior(garbage.flow), interior(GT)) > 5 * same
    # the garbage stands out: 1.4-1.9 px off, 0.25-0.32 unexplained by census signatures (the judge of every data
    # term; the grey-value judge read 0.52-0.72 here: on a smooth texture a shift changes a 3 x 3 signature less
    # than the grey values, the price of a judge no tone curve fools, docs/engine.md "The judge")
    assert garbage.unexplained > max(0.2, 20 * result.unexplained)


def test_unchanged_pairs_are_not_exposure_corrected(pair) -> None:
    """Content differences (motion at the border) move the percentiles a little; that is no exposure change."""
    for seed in range(6):
        i0, i1 = pair_from_flow(texture(40, 48, seed), constant_flow(40, 48, 2.5, 1.5))
        assert exposure_change(sorted_sample(i0), sorted_sample(i1)) == (1.0, 0.0)
    i0, i1 = pair
    gain, offset = exposure_change(sorted_sample(i0), sorted_sample(np.clip(1.25 * i1 - 0.02, 0, 1)))
    assert gain == pytest.approx(0.8, abs=0.02) and offset == pytest.approx(0.016, abs=0.01)


@pytest.mark.parametrize("backend", ["numpy", "numba"])
def test_reliability_tells_matching_flow_from_garbage(pair, backend: str) -> None:
    reliability = select_backend(backend).reliability
    p0, p1 = preprocess(*pair, "normalise")
    assert reliability(p0, p1, GT) < 0.05
    assert reliability(p0, p1, -GT) > UNRELIABLE  # wrong sign
    assert reliability(p0, p1, np.zeros_like(GT)) > UNRELIABLE
    other = preprocess(pair[0], np.clip(texture(H, W, 12).image, 0, 1), "normalise")
    assert reliability(*other, np.zeros_like(GT)) > UNRELIABLE  # two unrelated frames
    assert reliability(p0, p1, np.full_like(GT, 1e3)) == 1.0  # everything leaves the frame


def test_normalise_maps_the_robust_range_of_the_pair(pair) -> None:
    i0, i1 = pair
    hot = i1.copy()
    hot[:2, :2] = 50.0  # a few hot pixels do not set the scale
    for a, b in (preprocess(i0, i1, "normalise"), preprocess(0.1 * i0 + 0.3, 0.1 * hot + 0.3, "normalise")):
        lo, hi = np.mean([np.percentile(a, (2, 98)), np.percentile(b, (2, 98))], axis=0)
        assert lo == pytest.approx(0.0, abs=0.02) and hi == pytest.approx(1.0, abs=0.02)
    assert np.array_equal(preprocess(i0, i1, "none")[0], i0)


def test_line_fit_is_the_least_squares_line() -> None:
    """The closed-form fit of exposure_change against numpy's least squares (np.polyfit degree 1)."""
    rng = np.random.default_rng(8)
    x = np.sort(rng.random(19))
    y = 1.3 * x - 0.05 + 0.01 * rng.standard_normal(19)
    assert np.allclose(line_fit(x, y), np.polyfit(x, y, 1), rtol=0, atol=1e-12)


def test_numba_sorted_sample_is_numpys(pair) -> None:
    """The radix sort (numba_sort.py) gives np.sort's array: 8-bit content (many equal values), continuous
    values of either sign with -0.0, 0.0 and infinities, a small frame sampled whole, odd sizes; and the
    numba backend's photometric stage uses it."""
    rng = np.random.default_rng(12)
    signed = rng.standard_normal((241, 322)).astype(np.float32) * np.float32(3.0)
    signed[0, :6] = np.array([-0.0, 0.0, np.inf, -np.inf, 1e-40, -1e-40], np.float32)  # incl. subnormals
    for img in (pair[0], quantised(pair[1], 8).astype(np.float32) / np.float32(255.0), signed,
                signed[:10, :11], signed[1:, 3:]):
        ref = sorted_sample(img)
        got = sorted_sample_numba(img)
        assert got.dtype == ref.dtype == np.float32 and got.shape == ref.shape
        np.testing.assert_array_equal(got, ref)
    assert select_backend("numba").sample(pair[0]).tolist() == sorted_sample(pair[0]).tolist()


def test_numba_median_is_numpys_bit_for_bit() -> None:
    """numba_sort.median_f32 (the radix select behind the census noise estimate and the level contrast): np.median's
    float32 value exactly, for odd and even sizes from 1 to ~30,000, on uniform, quantised (many ties), constant,
    all-zero, two-valued, wide-exponent and signed values."""
    rng = np.random.default_rng(21)
    for n in [*range(1, 40), 255, 256, 1344, 4524, 4525, 29000]:
        two = np.full(n, 0.3, np.float32)
        two[: n // 3] = 0.1
        for v in (rng.random(n), np.round(rng.random(n) * 5) / 7, np.zeros(n), np.full(n, 0.7), two,
                  rng.standard_normal(n) * 10.0 ** rng.integers(-30, 30, n), rng.standard_normal(n)):
            v = v.astype(np.float32)
            want = np.float32(np.median(v))
            assert np.float32(median_f32(v.copy())).view(np.uint32) == want.view(np.uint32), (n, v[:4])


def test_reliability_on_a_large_frame_samples_coarser_but_reads_the_same() -> None:
    """A VGA frame is sampled at a coarser stride than 2 (reliability_stride), and the unexplained fraction
    stays what stride 2 gives, for flows from good to garbage (the node's WARN threshold sits in between)."""
    h, w = 480, 640
    flow0 = constant_flow(h, w, 1.2, -0.7) + rotation_flow(h, w, 1.5)
    p0, p1 = preprocess(*(np.clip(f, 0, 1) for f in pair_from_flow(texture(h, w, 5), flow0)), "normalise")
    assert reliability_stride(h, w) > 2 and reliability_stride(H, W) == 2
    rng = np.random.default_rng(3)
    for noise in (0.0, 0.4, 1.0, 3.0):
        flow = (flow0 + noise * rng.standard_normal(flow0.shape)).astype(np.float32)
        fine = reliability(p0, p1, flow, samples=h * w)  # the grid at stride 2 everywhere
        fine_numba = reliability_numba(p0, p1, flow, samples=h * w)
        coarse, coarse_numba = reliability(p0, p1, flow), reliability_numba(p0, p1, flow)
        assert abs(coarse - fine) < 0.01 and abs(coarse_numba - fine_numba) < 0.01, (noise, fine, coarse)
        # fewer samples (a stream's result check, FlowConfig.stream_check_samples): a coarser stride, the
        # numba count equal to the reference's on the same grid
        sparse = reliability(p0, p1, flow, samples=5000)  # ~1,250 signatures (every second point each way)
        assert sparse == pytest.approx(reliability_numba(p0, p1, flow, samples=5000), abs=2e-3)
        assert abs(sparse - fine) < 0.03, (noise, fine, sparse)  # binomial sd at 0.7 and 1,250: 0.013
    assert reliability_stride(h, w, 5000) == 8 and reliability_stride(h, w, h * w) == 2
