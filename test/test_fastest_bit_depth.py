"""The ``fastest`` preset (half-size solve, finest_level 1) on 10-16-bit content: the flow must not get
worse than on the same scene at 8 bit (issue 11: "10/12/16-bit content within 10 % of the 8-bit AEE").

Before the fix, 8-bit content was presmoothed by the photometric stage's quantisation path (its step is
coarse against the texture's range) and 10-16 bit was not; on the half-size level the weak pyramid blur
then let a fine texture alias, and the higher bit depth gave ~1.5x the 8-bit AEE. Pairs are rendered
exactly (flow_node.bag.scenes: the texture evaluated at exactly transformed coordinates)."""

from __future__ import annotations

import numpy as np
import pytest

from flow_node import FlowConfig, FlowEstimator, aee
from flow_node.bag.scenes import BandTexture, Layer, Scene, fine_motion, render_grey_pair
from flow_node.core.pyramid import build_pyramid, make_pyramid, noise_gain, pyramid_shapes

SIZE = (320, 240)  # the half-size level must be large enough to hold the texture's coarser octaves


def fine_pair(seed: int, kind: str, fmax: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A band-limited texture (1/10 .. fmax cycles/px) under a sub-pixel-to-3-px ``kind`` motion, float64."""
    rng = np.random.default_rng(seed)
    tex = BandTexture.band(rng, 1 / 10, fmax)
    return render_grey_pair(Scene("fine", SIZE, (Layer(tex, fine_motion(kind, SIZE, rng)),)))


def quantised(img: np.ndarray, bits: int) -> np.ndarray:
    """[0, 1] -> n-bit content (up to 2^bits - 1): uint8 for 8 bit, else in a uint16 container (mono16)."""
    q = np.rint(np.clip(img, 0.0, 1.0) * (2**bits - 1))
    return q.astype(np.uint8 if bits == 8 else np.uint16)


@pytest.mark.parametrize("seed,kind", [(5, "rotation"), (2, "zoom")])
def test_fastest_is_not_worse_at_12_or_16_bit_than_at_8_bit(seed: int, kind: str) -> None:
    i0, i1, gt = fine_pair(seed, kind, 1 / 3)  # the finest band of the suite: period 3 px, aliases at half size
    est = FlowEstimator(FlowConfig.preset("fastest").replace(backend="numba"))
    err = {bits: aee(est.estimate(quantised(i0, bits), quantised(i1, bits)).flow, gt) for bits in (8, 12, 16)}
    assert err[8] < 0.08, err
    assert err[12] <= 1.1 * err[8] and err[16] <= 1.1 * err[8], err


def test_a_coarser_finest_level_is_anti_aliased() -> None:
    """A cosine of 0.4 cycles/px (above the half-size level's Nyquist limit of 0.25) must not survive to
    that level when it is the finest solved one (it would alias into a false pattern); with a full-resolution
    solve the pyramid keeps its weak blur (the finer levels correct what aliases on a coarse one)."""
    h, w = 96, 128
    x = np.arange(w, dtype=np.float32)[None, :].repeat(h, 0)
    img = (0.5 + 0.4 * np.cos(2 * np.pi * 0.4 * x)).astype(np.float32)
    shapes = pyramid_shapes((h, w), 3, 0.5, 16)
    weak, anti = build_pyramid(img, shapes, 0.5, 0), build_pyramid(img, shapes, 0.5, len(shapes))
    inner = (slice(8, -8), slice(8, -8))
    assert np.std(weak[1][inner]) > 0.02  # the weak blur leaves an aliased pattern of ~0.05 amplitude
    assert np.std(anti[1][inner]) < 0.2 * np.std(weak[1][inner])
    # the engine's pyramids: anti-aliased for a half-size solve and for the census data term (which
    # normalises a faint aliased remnant up to full weight), weak for a full-resolution grey-value solve
    half, full = (FlowConfig.preset(p).replace(levels=3, photometric="normalise") for p in ("fastest", "realtime"))
    np.testing.assert_array_equal(make_pyramid(img, img, half).i0[1], anti[1])
    np.testing.assert_array_equal(make_pyramid(img, img, full).i0[1], weak[1])
    np.testing.assert_array_equal(make_pyramid(img, img, full.replace(photometric="census")).i0[1], anti[1])


def test_noise_gain_is_one_at_full_resolution_and_shrinks_with_the_blur() -> None:
    full = FlowConfig.preset("realtime")
    half = FlowConfig.preset("fastest")
    assert noise_gain((240, 320), full) == 1.0
    assert 0.1 < noise_gain((240, 320), half) < 0.3  # a Gaussian of 1.4 input px: 1 / (2 sqrt(pi) 1.4) = 0.20
    assert noise_gain((240, 320), half.replace(finest_level=2)) < noise_gain((240, 320), half)
