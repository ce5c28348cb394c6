"""The census stage's noise-adaptive presmoothing (FlowConfig.census_noise_smooth; photometric.noise_blur,
engine.photometric_stage; task noisesm): the blur rule, its gain against the noise floor's exact one, a clean pair
untouched bit for bit, and a smooth noisy pair whose flow gets better."""

from __future__ import annotations

import math

import numpy as np
import pytest
from synth import texture

from flow_node.core.api import FlowEstimator
from flow_node.core.backends import NUMPY
from flow_node.core.census import CENSUS
from flow_node.core.census_noise import difference_noise_gains
from flow_node.core.config import FlowConfig
from flow_node.core.engine import photometric_stage
from flow_node.core.photometric import NOISE_BLUR_STEP, QUANT_SIGMA, difference_gain, noise_blur

REALTIME = FlowConfig.preset("realtime").replace(threads=1)


def quantised(img: np.ndarray) -> np.ndarray:
    """img in [0, 1] to 8 bit and back, float32."""
    return (np.clip(np.rint(img * 255.0), 0, 255) / 255.0).astype(np.float32)


def noisy_pair(sigma: float, cell: int = 8, seed: int = 3, h: int = 96, w: int = 128
               ) -> tuple[np.ndarray, np.ndarray]:
    """A smooth 8-bit texture moved 1 px to the right, both frames with Gaussian noise of ``sigma`` grey levels."""
    tex = texture(h, w + 1, seed=seed, cell=cell).image
    rng = np.random.default_rng(5)
    return (quantised(tex[:, 1:] + rng.normal(0.0, sigma / 255.0, (h, w))),
            quantised(tex[:, :-1] + rng.normal(0.0, sigma / 255.0, (h, w))))


@pytest.mark.parametrize("blur", [0.5, 1.0, 1.7, 3.0])
@pytest.mark.parametrize("lag", [1, 2])
def test_the_blur_gain_is_the_noise_floor_s(blur: float, lag: int) -> None:
    """difference_gain (1-D kernel sums, interior) against census_noise's exact impulse responses on one level
    (a reflected border on a 600 x 800 frame: within 0.5 %)."""
    exact = difference_noise_gains([(600, 800)], [], blur, (lag,))[lag][0]
    assert difference_gain(blur, lag) == pytest.approx(exact, rel=5e-3)
    assert difference_gain(0.0, lag) == 1.0


@pytest.mark.parametrize("lag", [1, 2])
def test_the_rule_takes_the_least_blur_that_brings_the_noise_below_the_fraction(lag: int) -> None:
    eps, fraction = CENSUS.eps, 2.0
    assert noise_blur(0.01, 0.0, eps, lag) == 0.0  # off
    assert noise_blur(fraction * eps / math.sqrt(2.0) * 0.99, fraction, eps, lag) == 0.0  # already below: none
    blurs = [noise_blur(s, fraction, eps, lag) for s in (0.015, 0.02, 0.03, 0.05)]
    assert all(b > 0 for b in blurs) and blurs == sorted(blurs) and blurs[0] < blurs[-1]
    for sigma, b in zip((0.015, 0.02, 0.03, 0.05), blurs, strict=True):
        assert sigma * math.sqrt(2.0) * difference_gain(b, lag) <= fraction * eps
        less = round(b - NOISE_BLUR_STEP, 6)
        assert less <= 0 or sigma * math.sqrt(2.0) * difference_gain(less, lag) > fraction * eps


def test_a_clean_pair_is_not_touched() -> None:
    """An 8-bit textured pair whose noise is below the rule's threshold: the same stage and flow, bit for bit."""
    tex = texture(72, 97, seed=8).image
    f0, f1 = quantised(tex[:, 1:]), quantised(tex[:, :-1])
    cfg = REALTIME.replace(census_noise_smooth=2.0)
    _, judged = photometric_stage(f0, f1, cfg, NUMPY)
    assert judged.noise is not None and judged.noise.base_blur is None
    flows = [FlowEstimator(cfg.replace(census_noise_smooth=c)).estimate(f0, f1).flow for c in (0.0, 2.0)]
    np.testing.assert_array_equal(*flows)


def test_a_smooth_noisy_pair_is_blurred_and_its_flow_gets_better() -> None:
    """A smooth texture under noise of 6 grey levels: both frames blurred alike (above the quantisation's
    presmoothing), the noise floor's gains for that blur, and the flow closer to the true 1 px shift (measured:
    AEE 0.102 -> 0.088 with fraction 2)."""
    f0, f1 = noisy_pair(6.0)
    cfg = REALTIME.replace(census_noise_smooth=2.0)
    (s0, s1), judged = photometric_stage(f0, f1, cfg, NUMPY)
    off, judged0 = photometric_stage(f0, f1, REALTIME, NUMPY)
    noise = judged.noise
    assert noise is not None and noise.base_blur == judged0.noise.blur and noise.blur > max(noise.base_blur, 0.0)
    assert noise.blur == noise_blur(noise.sigma, 2.0, CENSUS.eps, cfg.census_finest_radius)
    assert noise.sigma == judged0.noise.sigma  # measured before any blur, as without the rule
    assert judged.keys == (None, None)  # a stream does not reuse frames whose blur depends on the pair's noise
    assert noise.base_blur in (0.0, QUANT_SIGMA)
    for a, b in ((s0, off[0]), (s1, off[1])):
        assert np.std(np.diff(a, axis=1)) < 0.8 * np.std(np.diff(b, axis=1))  # blurred further, both frames

    def aee(c: float) -> float:
        flow = FlowEstimator(REALTIME.replace(census_noise_smooth=c)).estimate(f0, f1).flow
        return float(np.hypot(flow[..., 0] - 1.0, flow[..., 1])[8:-8, 8:-8].mean())

    assert aee(2.0) < 0.92 * aee(0.0)
