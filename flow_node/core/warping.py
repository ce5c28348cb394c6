"""Sampling an image at sub-pixel positions (the warp of frame 1), numpy reference.

The warp of the coarse-to-fine scheme (paper, "Large Displacements") samples frame 1 and its gradient at
x + v0(x). Its kernel decides the flow's accuracy: the data term reads the sampled intensity as the
truth, so an interpolation that is biased at sub-pixel phases becomes flow error directly (the L1 data
term passes it through at full strength). The kernel must therefore reproduce linear ramps exactly.

Kernels (``KERNELS``), separable, four taps per axis at offsets -1, 0, 1, 2 of floor(x):

* ``bspline`` (the default): the cubic B-spline evaluated on prefiltered coefficients
  (:func:`bspline_prefilter`): interpolating, fourth-order accurate, reproduces cubics; one recursive
  filter pass per image and axis more. On exactly rendered pairs it gives 2-5x lower AEE than ``keys``
  for the L1 models (docs/engine.md, "Warping").
* ``keys``: Keys' cubic convolution with a = -1/2 (Catmull-Rom). Interpolating, third-order accurate,
  reproduces polynomials of degree <= 2. (OpenCV's INTER_CUBIC uses a = -3/4, which does not reproduce a
  ramp: at phase t it is off by up to 0.047 px; OpenCV 4.x also rounds positions to 1/32 px.)

Taps beyond the border read the mirror image (whole-sample symmetric, the boundary the prefilter
assumes, so the B-spline interpolates up to the last pixel); positions outside the image are masked out
(:func:`flow_node.core.operators.warp_maps`). The numba kernel (numba_warp.warp_kernel) implements the
same arithmetic and matches this reference to ~1e-6 (test_warping.py).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import NamedTuple

import numpy as np

KERNELS = ("bspline", "keys")
KERNEL_CODES = {"keys": 0, "bspline": 1}
KEYS_A = -0.5
BSPLINE_POLE = float(np.sqrt(3.0) - 2.0)  # z of the cubic B-spline's direct transform (Unser 1999)
HORIZON = 30  # terms of the mirrored causal start sum: |z|**30 ~ 1e-17

# sample(coef, map_x, map_y, kernel) -> sampled image; prefilter(img) -> B-spline coefficients
Sample = Callable[[np.ndarray, np.ndarray, np.ndarray, str], np.ndarray]
Prefilter = Callable[[np.ndarray], np.ndarray]


def cubic_weights(t: np.ndarray, kernel: str) -> np.ndarray:
    """Weights of the taps at offsets -1, 0, 1, 2 for fractional positions t in [0, 1). -> (4, ...)."""
    d = np.stack([1.0 + t, t, 1.0 - t, 2.0 - t])  # distances |x - tap|
    if kernel == "keys":
        a = KEYS_A
        near = ((a + 2.0) * d - (a + 3.0)) * d * d + 1.0
        far = ((a * d - 5.0 * a) * d + 8.0 * a) * d - 4.0 * a
    else:
        near = (0.5 * d - 1.0) * d * d + 2.0 / 3.0
        far = (2.0 - d) ** 3 / 6.0
    return np.where(d <= 1.0, near, far).astype(np.float32)


def bspline_prefilter(img: np.ndarray) -> np.ndarray:
    """Cubic B-spline coefficients c of img (..., H, W) so that the B-spline through c interpolates img.

    The direct transform per axis: a causal and an anticausal first-order recursion with pole
    z = sqrt(3) - 2 and gain 6, mirror-symmetric boundary (Unser, "Splines", IEEE SPM 1999). float32."""
    out = img.astype(np.float64, copy=True)
    for axis in (-1, -2):
        out = np.moveaxis(_prefilter_last_axis(np.moveaxis(out, axis, -1)), -1, axis)
    return out.astype(np.float32)


def _prefilter_last_axis(s: np.ndarray) -> np.ndarray:
    """One-axis B-spline direct transform along the last axis (float64, a new array)."""
    z = BSPLINE_POLE
    n = s.shape[-1]
    c = 6.0 * s  # the gain (1 - z)(1 - 1/z) = 6
    if n == 1:
        return s.copy()
    horizon = min(n, HORIZON)
    powers = z ** np.arange(horizon)
    c[..., 0] = c[..., :horizon] @ powers
    for k in range(1, n):
        c[..., k] += z * c[..., k - 1]
    c[..., n - 1] = (z / (z * z - 1.0)) * (c[..., n - 1] + z * c[..., n - 2])
    for k in range(n - 2, -1, -1):
        c[..., k] = z * (c[..., k + 1] - c[..., k])
    return c


class Warper(NamedTuple):
    """A backend's two warp functions: ``sample`` (:func:`sample_coefficients`) and ``prefilter``
    (:func:`bspline_prefilter`). :meth:`coefficients` once per image, then ``sample`` per warp."""

    sample: Sample
    prefilter: Prefilter

    def coefficients(self, img: np.ndarray, kernel: str) -> np.ndarray:
        """What ``sample`` interpolates for ``kernel``: the B-spline coefficients of img, or img (Keys)."""
        return self.prefilter(img) if kernel == "bspline" else np.asarray(img, dtype=np.float32)

    def warp(self, img: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, kernel: str = "bspline") -> np.ndarray:
        """The ``kernel``'s interpolant of img (H, W) or (C, H, W) sampled at (map_x, map_y) (each (h, w), px),
        border mirrored. float32, shape (h, w) or (C, h, w)."""
        return self.sample(self.coefficients(img, kernel), map_x, map_y, kernel)


def mirror_index(i: np.ndarray, n: int) -> np.ndarray:
    """Tap index i reflected about the first and last sample (-1 -> 1, n -> n - 2), then clamped to [0, n-1]:
    the whole-sample symmetric extension the B-spline prefilter assumes."""
    i = np.where(i < 0, -i, i)
    i = np.where(i > n - 1, 2 * (n - 1) - i, i)
    return np.clip(i, 0, n - 1)


def sample_coefficients(coef: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, kernel: str) -> np.ndarray:
    """sum over the 4 x 4 taps around each position of weight * coef (coef (..., H, W)), mirrored taps:
    coef sampled at (map_x, map_y) (each (h, w), px) -> float32 (..., h, w)."""
    h, w = coef.shape[-2:]
    mx = map_x.astype(np.float32)
    my = map_y.astype(np.float32)
    x0, y0 = np.floor(mx), np.floor(my)
    wx, wy = cubic_weights(mx - x0, kernel), cubic_weights(my - y0, kernel)
    xi, yi = x0.astype(np.int64), y0.astype(np.int64)
    out = np.zeros(coef.shape[:-2] + mx.shape, dtype=np.float32)
    for ky in range(4):
        rows = mirror_index(yi + ky - 1, h)
        for kx in range(4):
            cols = mirror_index(xi + kx - 1, w)
            out += (wy[ky] * wx[kx]) * coef[..., rows, cols]
    return out


NUMPY_WARPER = Warper(sample_coefficients, bspline_prefilter)
warp = NUMPY_WARPER.warp
