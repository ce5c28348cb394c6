"""The weighted median filter of the flow after a warp (docs/engine.md, "Weighted median"): Sun, Roth and Black,
"Secrets of optical flow estimation and their principles" (CVPR 2010; IJCV 2014, "Classic+NL"), in a cheap form.

The plain median (:func:`median_filter`) gives every neighbour of a window the same say, so at a motion boundary
the majority motion of the window wins whichever surface the pixel lies on, and occluded pixels (whose data term
matches nothing) take whatever the solver left them. The weighted median gives neighbour y of pixel x the weight

    w(x, y) = exp(-|y - x|^2 / (2 SPATIAL_SIGMA^2)) / (1 + (I0(y) - I0(x))^2 / sigma_i^2) * o(y)

(I0 the level's grey frame 0, ``sigma_i`` = FlowConfig.median_weight_sigma) with the occlusion state
o(y) = 1 / (1 + min(div v(y), 0)^2 / sigma_d^2) (``sigma_d`` = FlowConfig.median_occlusion_sigma, 0: o = 1):
a pixel the flow compresses (negative divergence: the surface behind it is being covered) is likely occluded
(Sand & Teller; Sun et al.'s o(x) without the brightness residual, which a photometric change would fake). Its
neighbours on the same side of an image edge and not occluded decide its flow.

The weights only matter where the window holds more than one motion: where each flow component's range (max - min)
over the RANGE_WINDOW x RANGE_WINDOW window around a pixel is at most ``tau`` (FlowConfig.median_weight_range, px)
the plain median stands (3 x 3: a pixel 2 px from a straight boundary has its own side in the majority of a
5 x 5 window, so the plain median is right there; a 5 x 5 range weighted twice the pixels for ~5 % more gain on
tune real_exact). The weighted median costs per pixel what the plain one (OpenCV's vectorised filter) costs per
row, so only a pixel next to two motions pays for it. Borders are replicated like OpenCV's median.

This module is the numpy reference; numba_wmedian.weighted_median_numba is the numba backend's (same values).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache

import cv2
import numpy as np

SPATIAL_SIGMA = 7.0  # px: Sun et al.'s; over a 5 x 5 window a mild preference for the nearer neighbours
RANGE_WINDOW = 3  # px: the window whose flow range decides where the weights apply
QUANTUM = 2.0**20  # the weights in integer units of 1 / QUANTUM (plus one each: no window weighs nothing)


def median_filter(v: np.ndarray, size: int) -> np.ndarray:
    """Median of each flow component over size x size windows (OpenCV; size 3 or 5)."""
    out = np.empty_like(v)
    for ch, dst in zip(v, out, strict=True):
        cv2.medianBlur(np.ascontiguousarray(ch), size, dst=dst)
    return out


def window_range(v: np.ndarray, size: int) -> np.ndarray:
    """(H, W) float32: the larger of the flow components' ranges (max - min) over size x size windows (border
    replicated; OpenCV's dilate and erode)."""
    kernel = np.ones((size, size), np.uint8)
    spans = [cv2.dilate(ch, kernel, borderType=cv2.BORDER_REPLICATE)
             - cv2.erode(ch, kernel, borderType=cv2.BORDER_REPLICATE) for ch in (np.ascontiguousarray(c) for c in v)]
    return np.maximum(spans[0], spans[1])


def occlusion_weight(v: np.ndarray, sigma_d: float) -> np.ndarray:
    """o (H, W) float64 in (0, 1]: 1 / (1 + min(div v, 0)^2 / sigma_d^2), div by central differences with the
    border replicated; 1 everywhere for sigma_d <= 0."""
    h, w = v.shape[1:]
    if sigma_d <= 0.0:
        return np.ones((h, w))
    u, vv = v[0].astype(np.float64), v[1].astype(np.float64)
    xr, xl = np.minimum(np.arange(w) + 1, w - 1), np.maximum(np.arange(w) - 1, 0)
    yd, yu = np.minimum(np.arange(h) + 1, h - 1), np.maximum(np.arange(h) - 1, 0)
    div = 0.5 * (u[:, xr] - u[:, xl]) + 0.5 * (vv[yd] - vv[yu])
    d = np.minimum(div, 0.0)
    return 1.0 / (1.0 + (d * d) * (1.0 / (sigma_d * sigma_d)))


@lru_cache(maxsize=4)
def spatial_weights(size: int) -> np.ndarray:
    """The window's spatial factors, float64 (size * size,) in row-major order of (dy, dx)."""
    r = size // 2
    dy, dx = np.mgrid[-r:r + 1, -r:r + 1]
    weights = np.exp(-(dy * dy + dx * dx).ravel() / (2.0 * SPATIAL_SIGMA * SPATIAL_SIGMA))
    weights.flags.writeable = False  # cached
    return weights


def weighted_median(v: np.ndarray, i0: np.ndarray, size: int, sigma_i: float, sigma_d: float, tau: float,
                    window: int = 0) -> np.ndarray:
    """The flow ``v`` (2, H, W) float32 filtered: the plain median (:func:`median_filter`) where the range over the
    RANGE_WINDOW window is at most ``tau``, elsewhere the weighted median of each component over the window x window
    window (``window`` 0: ``size``) with the module's weights (``i0``: the level's frame 0, (H, W)). The weights are
    integers, q_k = floor(w_k QUANTUM) + 1 (exact sums in any order, so the numba kernel's values are the same);
    the weighted median of values x_k is the least x_k whose weight of values <= x_k is at least half the total."""
    out = median_filter(v, size)
    if sigma_i <= 0.0:
        return out
    ys, xs = np.nonzero(window_range(v, RANGE_WINDOW) > tau)
    if ys.size == 0:
        return out
    h, w = i0.shape
    window = window or size
    r = window // 2
    occ = occlusion_weight(v, sigma_d)
    guide = i0.astype(np.float64)
    offsets = [(dy, dx) for dy in range(-r, r + 1) for dx in range(-r, r + 1)]
    ny = np.stack([np.clip(ys + dy, 0, h - 1) for dy, _ in offsets])  # (n, m)
    nx = np.stack([np.clip(xs + dx, 0, w - 1) for _, dx in offsets])
    diff = guide[ny, nx] - guide[ys, xs][None]
    weights = spatial_weights(window)[:, None] / (1.0 + (diff * diff) * (1.0 / (sigma_i * sigma_i))) * occ[ny, nx]
    quanta = np.floor(weights * QUANTUM).astype(np.int64) + 1
    total = quanta.sum(axis=0)
    for c in range(2):
        values = v[c][ny, nx]  # (n, m)
        below = ((values[None] <= values[:, None]) * quanta[None]).sum(axis=1)  # (n, m): weight of values <= each
        out[c, ys, xs] = np.where(2 * below >= total, values, np.float32(np.inf)).min(axis=0)
    return out


# what filters a warp's flow: weighted_median(v, i0, size, sigma_i, sigma_d, tau) -> (2, H, W); a backend's
WeightedMedian = Callable[..., np.ndarray]
