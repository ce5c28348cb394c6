"""FlowConfig.census_saturation (issue 25, task softrank): the saturating ("soft-rank") census signature
F_k = GAIN TAU tanh(n_k / TAU), n_k = d_k / (s + EPS) (census.py's module doc), between the linear signature
(TAU -> infinity; TAU = 0 is off: it bit for bit) and the sign of d_k. The numba kernels against the numpy
reference with it on: test_census.test_numba_signature_and_form_match_numpy."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from synth import texture

from flow_node.core import census
from flow_node.core.api import FlowEstimator
from flow_node.core.census import CENSUS, CensusParams, normalised, signature
from flow_node.core.config import FlowConfig
from flow_node.core.numba_signature import tanh_f32
from flow_node.core.refine import level_census

H, W = 48, 64
RT = FlowConfig.preset("realtime").replace(threads=1)


def _image(seed: int) -> np.ndarray:
    return texture(H, W, seed=seed, cell=2).image


def _diffs(img: np.ndarray) -> np.ndarray:
    return np.stack([census.shifted(img, dy, dx) - img for dy, dx in census.OFFSETS])


def test_off_is_the_linear_signature_bit_for_bit_and_large_tau_approaches_it() -> None:
    img = _image(1)
    linear = (normalised(_diffs(img)) * np.float32(CENSUS.gain)).astype(np.float32)
    np.testing.assert_array_equal(signature(img), linear)
    np.testing.assert_array_equal(signature(img, replace(CENSUS, saturation=0.0)), linear)
    np.testing.assert_allclose(signature(img, replace(CENSUS, saturation=1e3)), linear, atol=1e-6)


def test_saturated_signature_is_bounded_odd_and_monotonic() -> None:
    img = _image(2)
    params = CensusParams(saturation=0.75)
    f = signature(img, params)
    n = normalised(_diffs(img))
    bound = params.gain * params.saturation
    assert np.abs(f).max() <= bound < params.gain * np.abs(n).max()  # saturated where |n| is large
    np.testing.assert_allclose(f, bound * np.tanh(n / params.saturation), atol=1e-7)
    order = np.argsort(n.ravel())
    assert np.all(np.diff(f.ravel()[order]) >= 0)  # a monotonic map of n: the ranks kept
    np.testing.assert_allclose(signature(-img, params), -f, atol=1e-7)
    np.testing.assert_allclose(signature(1.7 * img - 0.3, replace(params, eps=0.0)),
                               signature(img, replace(params, eps=0.0)), atol=1e-4)  # still gain / offset exact


def test_the_kernels_tanh_is_tanh_to_float32_precision() -> None:
    """numba_signature.tanh_f32 (a rational fit, vectorisable) against np.tanh in float64, over and beyond its
    clamp, and relative near 0 (the saturated signature of a small difference keeps its slope)."""
    njit_tanh = np.vectorize(tanh_f32)  # the jitted function called per element
    x = np.linspace(-12.0, 12.0, 24001).astype(np.float32)
    assert np.abs(njit_tanh(x) - np.tanh(x.astype(np.float64))).max() < 5e-7
    small = np.linspace(-1e-3, 1e-3, 2001).astype(np.float32)
    small = small[small != 0]
    assert (np.abs(njit_tanh(small) / np.tanh(small.astype(np.float64)) - 1)).max() < 5e-7


def test_saturation_moves_less_under_a_strong_tone_curve() -> None:
    """On a fine texture (each window spans much of the grey range) a strong gamma is not affine over the window:
    the linear signature moves with it; the saturated one, closer to the signs of the differences, less (relative
    to its own size)."""
    img = _image(3)
    curved = img ** np.float32(0.4)

    def moved(params: CensusParams) -> float:
        ref = signature(img, params)
        return float(np.abs(signature(curved, params) - ref).mean() / np.abs(ref).mean())

    linear, soft = moved(CENSUS), moved(CensusParams(saturation=0.5))
    assert soft < 0.85 * linear, (soft, linear)


def test_the_field_reaches_every_level_and_the_flow() -> None:
    assert FlowConfig().census_saturation == 0.0
    assert level_census(RT.replace(census_saturation=0.0), 128).saturation == 0.0
    cfg = RT.replace(census_saturation=1.5)
    for width, finest in ((20, False), (64, False), (128, True)):
        assert level_census(cfg, width, finest=finest).saturation == 1.5
    assert level_census(cfg, 128, eps_floor=0.05).saturation == 1.5  # with the noise floor
    i0 = _image(4)
    i1 = np.roll(i0, 1, axis=1)

    def flow(c: FlowConfig) -> np.ndarray:
        return FlowEstimator(c).estimate(i0, i1).flow

    on = flow(cfg)
    assert np.abs(on - flow(RT)).max() > 1e-4
    np.testing.assert_allclose(flow(cfg.replace(backend="numpy")), on, atol=2e-3)
