"""The weighted median after a warp in compiled kernels: :func:`weighted_median_numba`, the numba backend's
wmedian.weighted_median (the numpy reference, docs/engine.md "Weighted median"); the same values.

The plain median stays OpenCV's vectorised filter. :func:`_flagged` finds the pixels whose 3 x 3 window holds two
motions in one pass over the rows (the column and row extrema along a row at plain indices, which LLVM vectorises;
numba_edges), :func:`_weighted` weighs BLOCK of them side by side: each window's neighbour k of the block's pixels
in a row ``[k, p]``, so the weights (the occlusion state from the flow's central differences at the neighbour, the
grey-value similarity), a sorting network on the (value, weight) pairs (:func:`sorting_network`: 140 compare-exchanges
for a 5 x 5 window, against 625 comparisons of every value with every other) and the cumulative weight run along p,
vectorised, with no branch. The
weights are integers (wmedian.QUANTUM), so each pixel's sums are exact in any order: the reference's values.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np
from numba import njit

from .wmedian import QUANTUM, RANGE_WINDOW, median_filter, spatial_weights
from .workspace import scratch

BLOCK = 64  # pixels the kernel weighs side by side
_JIT = dict(cache=True, error_model="numpy", nogil=True)  # no fastmath: the reference's float64 arithmetic
assert RANGE_WINDOW == 3  # _flagged's window


@lru_cache(maxsize=4)
def sorting_network(n: int) -> np.ndarray:
    """Batcher's odd-even merge sort of n values: (m, 2) int64 compare-exchange pairs (i < j: the smaller value to
    i), the network of the next power of two without the comparators that touch a slot >= n (those only meet the
    padding's +inf, which never moves a value)."""
    size = 1 << max(n - 1, 0).bit_length()
    pairs: list[tuple[int, int]] = []

    def merge(lo: int, hi: int, r: int) -> None:
        step = 2 * r
        if step < hi - lo:
            merge(lo, hi, step)
            merge(lo + r, hi, step)
            pairs.extend((i, i + r) for i in range(lo + r, hi - r, step))
        else:
            pairs.append((lo, lo + r))

    def sort(lo: int, hi: int) -> None:
        if hi > lo:
            mid = (lo + hi) // 2
            sort(lo, mid)
            sort(mid + 1, hi)
            merge(lo, hi, 1)

    sort(0, size - 1)
    network = np.array([p for p in pairs if p[1] < n], np.int64).reshape(-1, 2)
    network.flags.writeable = False
    return network


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
def _weighted(v, guide, ys, xs, r, spatial, inv, inv_d, pairs, out):  # noqa: ANN001, ANN202
    """The weighted median of each component at pixels (ys, xs) into ``out`` (2, H, W) (wmedian.weighted_median);
    ``inv`` = 1 / sigma_i^2, ``inv_d`` = 1 / sigma_d^2 (0: no occlusion state); ``pairs``: :func:`sorting_network`
    of the window's size."""
    h, w = guide.shape
    n = (2 * r + 1) * (2 * r + 1)
    vals = np.zeros((2, n, BLOCK), np.float32)  # a last block's unused columns: zeros (ignored)
    dif = np.zeros((n, BLOCK))
    div = np.zeros((n, BLOCK))
    wq = np.empty((n, BLOCK), np.int32)
    work_v = np.empty((n, BLOCK), np.float32)
    work_q = np.empty((n, BLOCK), np.int32)
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
            sv, sw = work_v, work_q  # the window sorted by value, its weights along (a sorting network)
            sv[:] = vals[c]
            sw[:] = wq
            for t in range(pairs.shape[0]):
                vi, vj, qi, qj = sv[pairs[t, 0]], sv[pairs[t, 1]], sw[pairs[t, 0]], sw[pairs[t, 1]]
                for p in range(BLOCK):
                    a, b, qa, qb = vi[p], vj[p], qi[p], qj[p]
                    swap = a > b
                    vi[p], vj[p] = (b, a) if swap else (a, b)
                    qi[p], qj[p] = (qb, qa) if swap else (qa, qb)
            below[:] = 0
            best[:] = inf
            for k in range(n):  # the least value whose weight of values <= it reaches half the total
                vk, qk = sv[k], sw[k]
                for p in range(BLOCK):
                    below[p] += qk[p]
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
                  sorting_network(window * window), out)
    return out
