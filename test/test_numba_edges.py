"""The edge weight's compiled kernel (numba_edges.py) against its reference, edges.edge_weight (OpenCV and numpy):
the same g to a few float32 ulps on every size and setting, its exp to ~1 ulp, its Gaussian OpenCV's."""

from __future__ import annotations

import cv2
import numpy as np
import pytest
from numba import njit
from synth import texture

from flow_node import FlowConfig
from flow_node.core.backends import NUMPY, select_backend
from flow_node.core.edges import EDGE_SIGMA, edge_weight, level_edge_weight
from flow_node.core.numba_edges import EXP_MIN, RADIUS, TAPS, edge_weight_numba, exp_parts

AGREE = 1e-5  # the numba kernels' agreement with the numpy reference (docs/engine.md, "Compiled kernels")


def frame(h: int, w: int, seed: int = 5) -> np.ndarray:
    """A texture with a bright rectangle: strong edges, so g spans its range."""
    img = texture(max(h, 8), max(w, 8), seed=seed).image.astype(np.float32)[:h, :w].copy()
    img[h // 4:3 * h // 4, w // 3:2 * w // 3] += 0.5
    return img


def exact(img: np.ndarray, a: float, b: float, floor: float) -> np.ndarray:
    """edges.edge_weight's formula in float64 (OpenCV's Gaussian and differences on a float64 image)."""
    smooth = cv2.GaussianBlur(img.astype(np.float64), (0, 0), EDGE_SIGMA, borderType=cv2.BORDER_REPLICATE)
    gx, gy = (cv2.Sobel(smooth, cv2.CV_64F, dx, 1 - dx, ksize=1, scale=0.5, borderType=cv2.BORDER_REPLICATE)
              for dx in (1, 0))
    mag = np.hypot(gx, gy)
    return np.ones_like(mag) if mag.mean() <= 1e-12 else np.maximum(floor, np.exp(-a * (mag / mag.mean()) ** b))


@pytest.mark.parametrize("shape", [(1, 1), (1, 9), (7, 1), (2, 3), (5, 5), (6, 8), (40, 56), (97, 146)])
@pytest.mark.parametrize("a, b, floor", [(0.05, 3.0, 0.6), (1.0, 1.0, 0.1), (2.0, 2.5, 0.05), (100.0, 4.0, 0.01),
                                         (0.5, 0.1, 1.0)])
def test_the_kernel_is_the_reference(shape: tuple[int, int], a: float, b: float, floor: float) -> None:
    """Both are float32 roundings of one formula: the kernel is about as close to its float64 value as the
    reference is (they differ by |grad| / s's rounding times g's slope a b x^(b-1) g: up to 1.6e-5 with a = 100,
    b = 4, the fields' steepest), and within AGREE of the reference where g is not that steep."""
    img = frame(*shape)
    ref = edge_weight(img, a, b, floor)
    got = edge_weight_numba(img, a, b, floor)
    assert got.dtype == np.float32 and got.shape == shape
    truth = exact(img, a, b, floor)
    assert np.abs(got - truth).max() <= 2.0 * np.abs(ref - truth).max() + 2e-6
    if a * b <= 10:
        np.testing.assert_allclose(got, ref, rtol=0, atol=AGREE)
    assert got.min() >= np.float32(floor) and got.max() <= 1.0
    if floor < 1.0 and min(shape) >= 5:
        assert got.min() < 0.99  # the edges are weighted: not a vacuous agreement of ones


def test_a_constant_level_and_the_contrast() -> None:
    flat = np.full((12, 20), 0.4, np.float32)
    assert np.all(edge_weight_numba(flat, 2.0, 1.0, 0.1) == 1.0)  # nothing to weight, as the reference
    img = frame(40, 56)
    np.testing.assert_allclose(edge_weight_numba(0.2 * img + 0.3, 2.0, 1.0, 0.05),
                               edge_weight_numba(img, 2.0, 1.0, 0.05), atol=AGREE)


def test_into_a_given_array_and_from_any_layout() -> None:
    img = frame(40, 56)
    out = np.full((40, 56), -1.0, np.float32)
    for weight in (edge_weight, edge_weight_numba):
        assert weight(img, 0.05, 3.0, 0.6, out=out) is out
        np.testing.assert_allclose(out, edge_weight(img, 0.05, 3.0, 0.6), atol=AGREE)
        out.fill(-1.0)
    wide = np.asfortranarray(img.astype(np.float64))  # another dtype and layout: converted
    np.testing.assert_allclose(edge_weight_numba(wide, 0.05, 3.0, 0.6), edge_weight(img, 0.05, 3.0, 0.6), atol=AGREE)


@njit(cache=False)
def _exp(y: np.ndarray, lo: np.float32, out: np.ndarray, bits: np.ndarray) -> None:
    scale = bits.view(np.float32)
    for i in range(y.size):
        out[i], bits[0] = exp_parts(y[i], lo)
        out[i] *= scale[0]


def test_the_exp_is_libm_s_to_an_ulp_or_two() -> None:
    y = np.linspace(EXP_MIN, 0.0, 200_001).astype(np.float32)
    out = np.empty_like(y)
    _exp(y, np.float32(EXP_MIN), out, np.zeros(1, np.int32))
    np.testing.assert_allclose(out, np.exp(y.astype(np.float64)), rtol=2.5e-7, atol=0)
    _exp(y, np.float32(np.log(0.6)), out, np.zeros(1, np.int32))  # clamped below at lo
    assert np.all(out >= np.float32(0.6) * (1 - 2.5e-7)) and out[-1] == 1.0


def test_the_gaussian_is_opencv_s() -> None:
    impulse = np.zeros((21, 21), np.float32)
    impulse[10, 10] = 1.0
    blurred = cv2.GaussianBlur(impulse, (0, 0), EDGE_SIGMA, borderType=cv2.BORDER_REPLICATE)
    r = TAPS.size // 2
    assert r == RADIUS  # the kernel is written for this many taps
    np.testing.assert_allclose(blurred[10 - r:11 + r, 10 - r:11 + r], np.outer(TAPS, TAPS), rtol=1e-6, atol=1e-9)
    assert blurred[10, 10 - r - 1] == 0.0  # nothing beyond the taps


def test_the_numba_backend_computes_g_with_the_kernel() -> None:
    backend = select_backend("numba").resolved()
    assert backend.edge_weight is edge_weight_numba and NUMPY.edge_weight is edge_weight
    img = frame(40, 56)
    cfg = FlowConfig(tv_edge_weight=0.05)
    ref = level_edge_weight(img, cfg, 1).copy()  # the level's scratch array: the next call writes it again
    got = level_edge_weight(img, cfg, 1, None, backend.edge_weight)
    np.testing.assert_allclose(got, ref, atol=AGREE)
    assert not np.array_equal(got, ref)  # the kernel's values, not the reference's
    assert got is level_edge_weight(img, cfg, 1)  # one array per level shape and thread, not fresh pages a level
