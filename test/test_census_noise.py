"""The census signature's noise floor and symmetric presmoothing (issue 25, low light; core/census_noise.py,
photometric.normalise_frames): the noise estimate, its analytic carry down the pyramid, the numpy and numba
forms with the raised EPS, and that grey-value flows and clean census pairs are unchanged."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from synth import isoluminant_pair, texture

from flow_node.core.api import FlowEstimator
from flow_node.core.census import CENSUS
from flow_node.core.census_noise import (
    PairNoise,
    channel_noise,
    comb_period,
    difference_noise_gains,
    noise_sigma,
    pair_noise,
)
from flow_node.core.colour import channel_maps, normalise_channel_pair
from flow_node.core.config import FlowConfig
from flow_node.core.numba_sort import noise_sigma_numba
from flow_node.core.photometric import (
    QUANT_SIGMA,
    STEP_REF,
    affine_normalised,
    frame_maps,
    quantiles,
    quantisation_step,
    sorted_sample,
    stage,
)
from flow_node.core.pyramid import antialias_steps, build_pyramid, make_pyramid, pyramid_shapes, step_sigmas
from flow_node.core.refine import level_census

CENSUS_RT = FlowConfig.preset("realtime").replace(photometric="census")


def quantised(img: np.ndarray) -> np.ndarray:
    """img in [0, 1] to 8 bit and back, float32."""
    return (np.clip(np.rint(img * 255.0), 0, 255) / 255.0).astype(np.float32)


def low_light_pair(h: int = 96, w: int = 128, gain: float = 0.4, sigma: float = 4.0, seed: int = 2
                   ) -> tuple[np.ndarray, np.ndarray]:
    """An 8-bit texture pair (a 1 px shift) with frame 2 darkened by ``gain`` plus Gaussian noise of ``sigma``
    grey levels (of 255), as the suite's low_light family does."""
    tex = texture(h, w + 1, seed=seed).image
    rng = np.random.default_rng(seed)
    f0 = quantised(tex[:, 1:])
    f1 = quantised(gain * tex[:, :-1] + rng.normal(0.0, sigma / 255.0, (h, w)))
    return f0, f1


def test_noise_sigma_reads_white_noise_and_not_a_smooth_texture() -> None:
    tex = texture(240, 320, seed=1).image.astype(np.float32)
    noise = np.random.default_rng(0).normal(0.0, 0.02, tex.shape).astype(np.float32)
    assert noise_sigma(tex + noise) == pytest.approx(0.02, rel=0.1)
    assert noise_sigma(quantised(tex)) < 0.002  # 8-bit quantisation of a smooth texture: ~1/255 / sqrt(12) at most
    assert noise_sigma(np.zeros((2, 9), np.float32)) == 0.0


@pytest.mark.parametrize("shape", [(1, 1), (2, 9), (3, 3), (5, 7), (16, 17), (17, 16), (18, 40), (240, 320),
                                   (375, 1242)])
def test_noise_sigma_numba_is_the_reference_bit_for_bit(shape: tuple[int, int]) -> None:
    """numba_sort.noise_sigma_numba (the numba backend's ``noise``): noise_sigma's value exactly, on noise,
    quantised noise (ties in the median), a flat frame and a noisy ramp; both the stride-1 and stride-4 grids,
    odd and even sample counts."""
    rng = np.random.default_rng(shape[0] * 1000 + shape[1])
    ramp = np.linspace(0.0, 1.0, shape[1], dtype=np.float32)[None] + 0.01 * rng.standard_normal(shape)
    for img in (rng.random(shape), np.round(rng.random(shape) * 255) / 255, np.zeros(shape), ramp):
        img = img.astype(np.float32)
        assert noise_sigma_numba(img) == noise_sigma(img)


@pytest.mark.parametrize(("cfg", "blur"), [(CENSUS_RT, 0.0), (CENSUS_RT, QUANT_SIGMA),
                                           (CENSUS_RT.replace(census_antialias=-1, scale_factor=0.8, levels=8), 0.0),
                                           (FlowConfig.preset("fastest").replace(photometric="census"), 0.0)],
                         ids=["realtime", "realtime-presmoothed", "every-step-0.8", "fastest"])
@pytest.mark.parametrize("lag", [1, 2])
def test_the_carried_noise_matches_the_pyramid_of_white_noise(cfg: FlowConfig, blur: float, lag: int) -> None:
    """The analytic gain of white noise's differences ``lag`` px apart per level (difference_noise_gains) is
    what the pyramid's own levels of a white-noise image (presmoothed by ``blur`` first) measure, within sampling
    error."""
    noise = np.random.default_rng(3).normal(0.0, 1.0, (240, 320)).astype(np.float32)
    if blur:
        noise = cv2.GaussianBlur(noise, (0, 0), blur, borderType=cv2.BORDER_REFLECT)
    shapes = pyramid_shapes(noise.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
    steps = antialias_steps(cfg, len(shapes))
    gains = difference_noise_gains(shapes, step_sigmas(len(shapes) - 1, cfg.scale_factor, steps), blur, (lag,))[lag]
    assert gains[0] == pytest.approx(1.0) if not blur else gains[0] < (0.3 if lag == 1 else 0.6)
    for level, gain in zip(build_pyramid(noise, shapes, cfg.scale_factor, steps), gains, strict=True):
        inner = level[2:-2, 2:-2].astype(np.float64)
        dx, dy = inner[:, lag:] - inner[:, :-lag], inner[lag:] - inner[:-lag]
        rms = np.sqrt(0.5 * (np.mean(dx ** 2) + np.mean(dy ** 2)))
        assert rms / np.sqrt(2.0) == pytest.approx(gain, rel=0.06), level.shape
    assert gains[-1] < 0.25  # and it falls: the coarse levels' EPS floor is far below the input's
    if blur and lag == 2:  # presmoothed noise differs more between far pixels than between neighbours
        assert gains[0] > 1.5 * difference_noise_gains(shapes, step_sigmas(len(shapes) - 1, cfg.scale_factor, steps),
                                                       blur)[1][0]


# the floor reaching the form (numpy and numba): test_census_schedule.test_census_problem_uses_the_level_eps


def _dense_gains(shapes: list[tuple[int, int]], sigmas: tuple[float, ...], blur: float, lag: int) -> tuple[float, ...]:
    """difference_noise_gains as it was built before: per axis, the whole n_0 x n_0 impulse matrix at once,
    through the pyramid's blurs (OpenCV's kernel size for float input) and bilinear resampling."""
    def blurred(m: np.ndarray, sigma: float, border: int) -> np.ndarray:
        kernel = cv2.getGaussianKernel(int(round(sigma * 4 * 2 + 1)) | 1, sigma, cv2.CV_32F)
        return cv2.sepFilter2D(m, cv2.CV_32F, kernel, np.ones((1, 1), np.float32), borderType=border)

    def axis(lengths: list[int]) -> tuple[list[float], list[float]]:
        m = np.eye(lengths[0], dtype=np.float32)
        if blur > 0:
            m = blurred(m, blur, cv2.BORDER_REFLECT)
        var, dvar = [], []
        for level, n in enumerate(lengths):
            if level:
                m = blurred(m, sigmas[level - 1], cv2.BORDER_REPLICATE)
                m = cv2.resize(m, (n, m.shape[0]), interpolation=cv2.INTER_LINEAR)
            inner = (m[:, 2:-2] if n > 8 else m).astype(np.float64)
            var.append(float(np.mean(np.sum(inner ** 2, axis=0))))
            diff = inner[:, lag:] - inner[:, :-lag]
            dvar.append(float(np.mean(np.sum(diff * diff, axis=0))) if diff.size else 0.0)
        return var, dvar

    (vy, dy), (vx, dx) = axis([s[0] for s in shapes]), axis([s[1] for s in shapes])
    return tuple(float(np.sqrt((dx[k] * vy[k] + vx[k] * dy[k]) / 4.0)) for k in range(len(shapes)))


@pytest.mark.parametrize("size", [(375, 1242), (129, 300), (13, 5)])
@pytest.mark.parametrize("blur,lag", [(0.0, 1), (1.0, 2)])
def test_the_gains_built_in_blocks_are_the_dense_matrix_s(size: tuple[int, int], blur: float, lag: int) -> None:
    """census_noise builds its impulse responses GAIN_ROWS input pixels at a time (a fresh process's first call
    paid ~0.1 s for the whole matrix at 1242 px); the gains are the dense matrix's to float32 rounding (OpenCV's
    float32 filters round a block of rows differently here and there: ~4e-9 relative on a 129 px axis's deepest
    levels), with a partial last block and axes under one block."""
    shapes = [size]
    while min(shapes[-1]) > 4:
        shapes.append((int(round(shapes[-1][0] * 0.5)), int(round(shapes[-1][1] * 0.5))))
    sigmas = tuple([1.4] * (len(shapes) - 1))
    dense = _dense_gains(shapes, sigmas, blur, lag)
    np.testing.assert_allclose(difference_noise_gains(shapes, sigmas, blur, (lag,))[lag], dense, rtol=1e-7, atol=0.0)


@pytest.mark.parametrize("preset,size", [("fastest", (375, 1242)), ("realtime", (388, 584)), ("realtime", (240, 320))])
@pytest.mark.parametrize("blur,lag", [(0.0, 1), (0.0, 2), (1.0, 1)])
def test_the_gains_of_impulses_combed_into_rows_are_the_dense_matrix_s(preset: str, size: tuple[int, int], blur: float,
                                                                    lag: int) -> None:
    """On a preset's pyramid (a few levels) every row carries several impulses, comb_period apart (fewer rows:
    ~3x faster at 1242 px), and the gains are still the dense matrix's: no two impulses' responses or differences
    meet on any level, also when both lags take one pass (the larger lag's period). The period is a bound, ~1.6x
    the reach measured of one impulse's response: a third of it lets them meet here (some gains then read low), a
    quarter everywhere."""
    cfg = FlowConfig.preset(preset)
    shapes = pyramid_shapes(size, cfg.levels, cfg.scale_factor, cfg.min_size)
    for steps in (0, len(shapes) - 1):  # plain steps; every step anti-aliased (wider kernels)
        sigmas = tuple(step_sigmas(len(shapes) - 1, cfg.scale_factor, steps))
        assert comb_period(tuple(s[1] for s in shapes), sigmas, blur, lag) < size[1]  # some rows hold two or more
        dense = _dense_gains(shapes, sigmas, blur, lag)
        for lags in ((lag,), (1, 2)):  # alone, and in one pass with the other lag (the pyramid's call, radius 2)
            gains = difference_noise_gains(shapes, sigmas, blur, lags)[lag]
            np.testing.assert_allclose(gains, dense, rtol=1e-7, atol=0.0)


def test_low_light_gets_the_pair_eps_and_both_frames_presmoothed() -> None:
    """Frame 2 at gain 0.4 plus noise: its 8-bit step is coarse against its range, so both frames are
    presmoothed (not frame 2 alone), and the pair's EPS floor, from frame 2's noise, is above EPS on the
    finest level and used for both frames."""
    f0, f1 = low_light_pair()
    s0, s1 = sorted_sample(f0), sorted_sample(f1)
    rels = [quantisation_step(s) / float(np.subtract(*quantiles(s, (98.0, 2.0)))) for s in (s0, s1)]
    assert rels[0] < STEP_REF < rels[1]
    (n0, n1), judged = stage(f0, f1, "census")
    assert judged[0] is n0 and judged[1] is n1
    for img, s, n in ((f0, s0, n0), (f1, s1, n1)):
        lo, hi = quantiles(s, (2.0, 98.0))
        step = quantisation_step(s)
        np.testing.assert_array_equal(n, affine_normalised(img, lo, hi, step, 1.0, QUANT_SIGMA))
        assert np.abs(n - affine_normalised(img, lo, hi, step, 1.0, 0.0)).max() > 1e-3
    noise = pair_noise((f0, f1), frame_maps((s0, s1)), 1.0, (n0, n1))
    assert noise.blur == QUANT_SIGMA
    # measured before the blur: frame 2's noise, 4 / 255 over its own range, contrast-shrunk by STEP_REF / rel
    span1 = float(np.subtract(*quantiles(s1, (98.0, 2.0))))
    assert noise.sigma == pytest.approx(4.0 / 255.0 / span1 * STEP_REF / rels[1], rel=0.15)
    assert noise_sigma(n1) < 0.3 * noise.sigma  # the blurred frame reads as far less noisy than it is
    cfg = CENSUS_RT.replace(census_noise_k=2.0, census_finest_radius=1)  # the 3 x 3 signature; the ring below
    pyr = make_pyramid(n0, n1, cfg, noise=noise)
    assert pyr.census_eps is not None
    gains = difference_noise_gains(pyr.shapes, step_sigmas(len(pyr.shapes) - 1, 0.5, 3), QUANT_SIGMA)[1]
    assert pyr.census_eps == pytest.approx([2.0 * noise.sigma * g for g in gains])
    assert pyr.census_eps[0] > CENSUS.eps
    assert all(a > b for a, b in zip(pyr.census_eps, pyr.census_eps[1:], strict=False))
    assert level_census(cfg, pyr.shapes[0][1], pyr.eps_floor(0)).eps == pyr.census_eps[0]
    # the engine hands the stage's noise to the pyramid: the same floor (both frames use it, refine.census_problem)
    assert make_pyramid(n0, n1, cfg, noise=PairNoise(noise.sigma, QUANT_SIGMA)).census_eps == pyr.census_eps
    assert pyr.census_eps_far is None and pyr.eps_floor(0, 2) == 0.0
    far = make_pyramid(n0, n1, cfg.replace(census_finest_radius=2), noise=PairNoise(noise.sigma, QUANT_SIGMA))
    # the 3 x 3 floors unchanged, to the float32 rounding of another comb: both lags' gains take one pass then
    assert far.census_eps == pytest.approx(pyr.census_eps, rel=1e-7, abs=0.0)
    gains2 = difference_noise_gains(pyr.shapes, step_sigmas(len(pyr.shapes) - 1, 0.5, 3), QUANT_SIGMA, (2,))[2]
    assert far.census_eps_far == pytest.approx([2.0 * noise.sigma * g for g in gains2])
    assert far.eps_floor(0, 2) > 1.5 * far.eps_floor(0)  # presmoothed: far differences carry more noise


def test_a_clean_pair_without_coarse_quantisation_is_not_presmoothed() -> None:
    tex = quantised(texture(64, 80, seed=4).image)
    (n0, n1), _ = stage(tex, tex, "census")
    s = sorted_sample(tex)
    lo, hi = quantiles(s, (2.0, 98.0))
    np.testing.assert_array_equal(n0, affine_normalised(tex, lo, hi, quantisation_step(s), 1.0, 0.0))


@pytest.mark.parametrize("preset", ["realtime", "fastest"])
def test_grey_value_flows_do_not_see_the_noise_floor(preset: str) -> None:
    f0, f1 = low_light_pair(64, 80)
    cfg = FlowConfig.preset(preset).replace(threads=1, photometric="normalise")  # (the grey-value term, said)
    assert make_pyramid(f0, f1, cfg.replace(census_noise_k=3.0)).census_eps is None
    flows = [FlowEstimator(cfg.replace(census_noise_k=k)).estimate(f0, f1).flow for k in (0.0, 3.0)]
    np.testing.assert_array_equal(*flows)


def test_a_clean_census_pair_keeps_its_flow_at_the_default_k() -> None:
    """An 8-bit textured pair whose noise (quantisation) times the default K is below EPS: the census flow is
    the one without the floor, bit for bit."""
    tex = texture(72, 97, seed=8).image
    f0, f1 = quantised(tex[:, 1:]), quantised(tex[:, :-1])
    cfg = CENSUS_RT.replace(threads=1)
    k = FlowConfig().census_noise_k
    assert k > 0
    (n0, n1), _ = stage(f0, f1, "census")
    assert k * max(noise_sigma(n0), noise_sigma(n1)) < CENSUS.eps
    flows = [FlowEstimator(cfg.replace(census_noise_k=kk)).estimate(f0, f1).flow for kk in (0.0, k)]
    np.testing.assert_array_equal(*flows)
    noisy = [FlowEstimator(cfg.replace(census_noise_k=kk)).estimate(*low_light_pair(72, 96)).flow for kk in (0.0, k)]
    assert np.abs(noisy[0] - noisy[1]).max() > 1e-3  # where the noise is above EPS / K, K does change the flow


def test_fastest_floors_the_eps_at_two_sigma() -> None:
    """fastest's noise floor K is 2 (task lownoise), the other general presets' and stream_fast's the default 3: on a
    noisy pair fastest's EPS floors are 2/3 of the default K's, level by level, and its flow is the one of K 2."""
    fastest = FlowConfig.preset("fastest").replace(threads=1)
    assert fastest.census_noise_k == 2.0
    default = FlowConfig().census_noise_k
    assert default == 3.0
    for name in ("quality", "balanced", "realtime", "stream_fast"):
        assert FlowConfig.preset(name).census_noise_k == default
    f0, f1 = low_light_pair(144, 192)  # fastest solves at half size: levels narrower than 50 px take the coarse EPS
    (n0, n1), _ = stage(f0, f1, "census")
    noise = PairNoise(max(noise_sigma(n0), noise_sigma(n1)))
    two, three = (make_pyramid(n0, n1, fastest.replace(census_noise_k=k), noise=noise).census_eps for k in (2.0, 3.0))
    assert two == pytest.approx([2.0 / 3.0 * e for e in three], rel=1e-6)
    flows = [FlowEstimator(cfg).estimate(f0, f1).flow for cfg in (fastest, fastest.replace(census_noise_k=2.0),
                                                                  fastest.replace(census_noise_k=default))]
    np.testing.assert_array_equal(flows[0], flows[1])
    assert np.abs(flows[0] - flows[2]).max() > 1e-3


def test_colour_channels_measure_their_own_noise() -> None:
    """With colour channels the floor comes from the channels the signatures are taken on: an 8-bit isoluminant
    pair's normalised luma is mostly quantisation noise, its R and G channels are clean textures."""
    c0, c1, _ = isoluminant_pair(3, 96, 128)
    planes = [np.moveaxis(quantised(c), -1, 0) for c in (c0, c1)]
    grey = [(0.299 * p[0] + 0.587 * p[1] + 0.114 * p[2]).astype(np.float32) for p in planes]  # the luma of 8-bit RGB
    (g0, g1), _ = stage(*grey, "census")
    luma = pair_noise((grey[0], grey[1]), frame_maps((sorted_sample(grey[0]), sorted_sample(grey[1]))), 1.0, (g0, g1))
    maps = channel_maps(*planes)
    colour = channel_noise((planes[0], planes[1]), maps, 1.0, normalise_channel_pair(*planes, maps=maps))
    assert luma.sigma > 2.0 * CENSUS.eps  # the luma would damp every signature
    assert 2.0 * colour.sigma < CENSUS.eps
