"""The weighted median after a warp in compiled kernels: :func:`weighted_median_numba`, the numba backend's
wmedian.weighted_median (the numpy reference, docs/engine.md "Weighted median"); the same values.

The plain median stays OpenCV's vectorised filter. :func:`_flagged` finds the pixels whose 3 x 3 window holds two
motions in one pass over the rows (the column and row extrema along a row at plain indices, which LLVM vectorises;
numba_edges), :func:`_weighted` weighs BLOCK of them side by side: each window's neighbour k of the block's pixels
in a row ``[k, p]``, so the weights (the occlusion state from the flow's central differences at the neighbour, the
grey-value similarity) and the comparisons of the median run along p, vectorised, with no sort and no branch. The
weights are integers (wmedian.QUANTUM), so each pixel's sums are exact in any order: the reference's values.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .wmedian import QUANTUM, RANGE_WINDOW, median_filter, spatial_weights
from .workspace import scratch

BLOCK = 64  # pixels the kernel weighs side by side
_JIT = dict(cache=True, error_model="numpy", nogil=True)  # no fastmath: the reference's float64 arithmetic
assert RANGE_WINDOW == 3  # _flagged's window


@njit(**_JIT)
def _flagged(v, tau, ys, xs, lo, hi):  # noqa: ANN001, ANN202
    """The pixels where a flow component's range over the 3 x 3 window (border replicated) exceeds ``tau``
    (wmedian.window_range > tau, the range in float32) into ``ys``, ``xs`` in row-major order; their count.
    ``lo``, ``hi``: (2, W + 2) scratch."""
    h, w = v.shape[1:]
    count = 0
    for i in range(h):
        iu, idn = max(i - 1, 0), min(i + 1, h - 1)
        for c in range(2):
            up, mid, dn = v[c, iu], v[c, i], v[c, idn]
            lc, hc = lo[c, 1:w + 1], hi[c, 1:w + 1]
            for j in range(w):  # column extrema
                lc[j] = min(min(up[j], mid[j]), dn[j])
                hc[j] = max(max(up[j], mid[j]), dn[j])
            lo[c, 0], hi[c, 0], lo[c, w + 1], hi[c, w + 1] = lc[0], hc[0], lc[w - 1], hc[w - 1]
        l0, l1, h0, h1 = lo[0], lo[1], hi[0], hi[1]
        for j in range(w):
            r0 = max(max(h0[j], h0[j + 1]), h0[j + 2]) - min(min(l0[j], l0[j + 1]), l0[j + 2])
            r1 = max(max(h1[j], h1[j + 1]), h1[j + 2]) - min(min(l1[j], l1[j + 1]), l1[j + 2])
            if np.float64(max(r0, r1)) > tau:
                ys[count], xs[count] = i, j
                count += 1
    return count


@njit(**_JIT)
def _weighted(v, guide, ys, xs, r, spatial, inv, inv_d, out):  # noqa: ANN001, ANN202
    """The weighted median of each component at pixels (ys, xs) into ``out`` (2, H, W) (wmedian.weighted_median);
    ``inv`` = 1 / sigma_i^2, ``inv_d`` = 1 / sigma_d^2 (0: no occlusion state)."""
    h, w = guide.shape
    n = (2 * r + 1) * (2 * r + 1)
    vals = np.zeros((2, n, BLOCK), np.float32)  # a last block's unused columns: zeros (ignored)
    dif = np.zeros((n, BLOCK))
    div = np.zeros((n, BLOCK))
    wq = np.empty((n, BLOCK), np.int32)
    total = np.empty(BLOCK, np.int32)
    below = np.empty(BLOCK, np.int32)
    best = np.empty(BLOCK, np.float32)
    inf = np.float32(np.inf)
    for start in range(0, ys.size, BLOCK):
        cnt = min(BLOCK, ys.size - start)
        for p in range(cnt):  # gather the windows
            y, x = ys[start + p], xs[start + p]
            g = np.float64(guide[y, x])
            k = 0
            for dy in range(-r, r + 1):
                yy = min(max(y + dy, 0), h - 1)
                yu, yd = max(yy - 1, 0), min(yy + 1, h - 1)
                for dx in range(-r, r + 1):
                    xx = min(max(x + dx, 0), w - 1)
                    xl, xr = max(xx - 1, 0), min(xx + 1, w - 1)
                    dif[k, p] = np.float64(guide[yy, xx]) - g
                    div[k, p] = 0.5 * (np.float64(v[0, yy, xr]) - np.float64(v[0, yy, xl])) + \
                        0.5 * (np.float64(v[1, yd, xx]) - np.float64(v[1, yu, xx]))
                    vals[0, k, p] = v[0, yy, xx]
                    vals[1, k, p] = v[1, yy, xx]
                    k += 1
        total[:] = 0
        for k in range(n):  # row slices: loops along p at plain indices vectorise (numba_edges)
            sk, dk, ck, qk = spatial[k], dif[k], div[k], wq[k]
            for p in range(BLOCK):
                d = min(ck[p], 0.0)
                o = 1.0 / (1.0 + (d * d) * inv_d)
                qk[p] = np.int32(math.floor(sk / (1.0 + (dk[p] * dk[p]) * inv) * o * QUANTUM)) + np.int32(1)
                total[p] += qk[p]
        for c in range(2):
            best[:] = inf
            for k in range(n):  # the least value whose weight of values <= it reaches half the total
                below[:] = 0
                vk = vals[c, k]
                for j in range(n):
                    vj, qj = vals[c, j], wq[j]
                    for p in range(BLOCK):
                        below[p] += qj[p] if vj[p] <= vk[p] else np.int32(0)
                for p in range(BLOCK):
                    best[p] = min(best[p], vk[p] if np.int32(2) * below[p] >= total[p] else inf)
            for p in range(cnt):
                out[c, ys[start + p], xs[start + p]] = best[p]


def weighted_median_numba(v: np.ndarray, i0: np.ndarray, size: int, sigma_i: float, sigma_d: float, tau: float,
                          window: int = 0) -> np.ndarray:
    """wmedian.weighted_median (same arguments, same values)."""
    out = median_filter(v, size)
    if sigma_i <= 0.0:
        return out
    h, w = i0.shape
    ys, xs = scratch("wmedian.ys", (h * w,), np.int64), scratch("wmedian.xs", (h * w,), np.int64)
    count = _flagged(v, float(tau), ys, xs, scratch("wmedian.lo", (2, w + 2)), scratch("wmedian.hi", (2, w + 2)))
    if count:
        inv_d = 1.0 / (sigma_d * sigma_d) if sigma_d > 0.0 else 0.0
        window = window or size
        _weighted(v, i0, ys[:count], xs[:count], window // 2, spatial_weights(window), 1.0 / (sigma_i * sigma_i), inv_d,
                  out)
    return out
