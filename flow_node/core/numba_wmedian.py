"""The weighted median after a warp in compiled kernels: :func:`weighted_median_numba`, the numba backend's
wmedian.weighted_median (the numpy reference, docs/engine.md "Weighted median").

The plain median and the windows' range (which pixels get weights) stay OpenCV's vectorised calls, shared with
the reference; the occlusion state is one pass over the level, the weighted median a loop over the pixels whose
window holds two motions: the window's weights, then per flow component an insertion sort of (value, weight)
pairs (stable: ties keep the window's row-major order) and the cumulative weight up to half the total. Float64
sums in the sorted order like the reference, so the values match it (an exp differing by an ulp could flip a
pick whose cumulative weight lies within ~1e-16 of half the total; test_wmedian).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .wmedian import QUANTUM, median_filter, spatial_weights
from .workspace import scratch

_JIT = dict(cache=True, error_model="numpy", nogil=True)  # no fastmath: the reference's float64 arithmetic


@njit(**_JIT)
def _prepare(v, tau, inv, occ, ys, xs):  # noqa: ANN001, ANN202
    """One pass over the level: wmedian.occlusion_weight into ``occ`` (H, W) float64 (``inv`` = 1 / (2 sigma_d^2),
    0: ones) and the pixels whose 3 x 3 window (border replicated) has a flow component's range over ``tau``
    (wmedian.window_range with RANGE_WINDOW 3) into ``ys``, ``xs`` in row-major order; returns their count."""
    h, w = occ.shape
    count = 0
    for i in range(h):
        iu, idn = max(i - 1, 0), min(i + 1, h - 1)
        for j in range(w):
            jl, jr = max(j - 1, 0), min(j + 1, w - 1)
            if inv > 0.0:
                div = 0.5 * (np.float64(v[0, i, jr]) - np.float64(v[0, i, jl])) + \
                    0.5 * (np.float64(v[1, idn, j]) - np.float64(v[1, iu, j]))
                occ[i, j] = math.exp(-(div * div) * inv) if div < 0.0 else 1.0
            else:
                occ[i, j] = 1.0
            over = False
            for c in range(2):
                lo = hi = v[c, i, j]
                for a in (iu, i, idn):
                    for b in (jl, j, jr):
                        lo, hi = min(lo, v[c, a, b]), max(hi, v[c, a, b])
                over = over or np.float64(hi - lo) > tau  # the float32 range, as the reference's
            if over:
                ys[count], xs[count] = i, j
                count += 1
    return count


@njit(**_JIT)
def _weighted(v, guide, occ, ys, xs, r, spatial, inv, out):  # noqa: ANN001, ANN202
    """The weighted median of each component at pixels (ys, xs) into ``out`` (2, H, W) (wmedian.weighted_median);
    ``inv`` = 1 / sigma_i^2. Integer weights, so each pixel's sums are exact in any order: the loops over the
    window vectorise (no sort, no branches)."""
    h, w = guide.shape
    n = (2 * r + 1) * (2 * r + 1)
    wq = np.empty(n, np.int32)
    vals = np.empty(n, np.float32)
    iy = np.empty(n, np.int64)
    ix = np.empty(n, np.int64)
    gk = np.empty(n, np.float32)
    ok = np.empty(n)
    for m in range(ys.size):
        y, x = ys[m], xs[m]
        g = np.float64(guide[y, x])
        k = 0
        for dy in range(-r, r + 1):
            yy = min(max(y + dy, 0), h - 1)
            for dx in range(-r, r + 1):
                iy[k], ix[k] = yy, min(max(x + dx, 0), w - 1)
                k += 1
        for k in range(n):
            gk[k] = guide[iy[k], ix[k]]
            ok[k] = occ[iy[k], ix[k]]
        total = 0
        for k in range(n):
            d = np.float64(gk[k]) - g
            q = np.int32(math.floor(spatial[k] / (1.0 + (d * d) * inv) * ok[k] * QUANTUM)) + 1
            wq[k] = q
            total += q
        for c in range(2):
            for k in range(n):
                vals[k] = v[c, iy[k], ix[k]]
            best = np.float32(np.inf)
            for k in range(n):  # the least value whose weight of values <= it reaches half the total
                below = 0
                vk = vals[k]
                for j in range(n):
                    below += wq[j] if vals[j] <= vk else 0
                if 2 * below >= total and vk < best:
                    best = vk
            out[c, y, x] = best


def weighted_median_numba(v: np.ndarray, i0: np.ndarray, size: int, sigma_i: float, sigma_d: float,
                          tau: float) -> np.ndarray:
    """wmedian.weighted_median (same arguments, same values)."""
    out = median_filter(v, size)
    if sigma_i <= 0.0:
        return out
    h, w = i0.shape
    occ = scratch("wmedian.occ", (h, w), np.float64)
    ys, xs = scratch("wmedian.ys", (h * w,), np.int64), scratch("wmedian.xs", (h * w,), np.int64)
    count = _prepare(v, float(tau), 1.0 / (2.0 * sigma_d * sigma_d) if sigma_d > 0.0 else 0.0, occ, ys, xs)
    if count:
        _weighted(v, i0, occ, ys[:count], xs[:count], size // 2, spatial_weights(size),
                  1.0 / (sigma_i * sigma_i), out)
    return out
