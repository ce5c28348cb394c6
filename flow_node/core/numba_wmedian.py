"""The weighted median after a warp in compiled kernels: :func:`weighted_median_numba`, the numba backend's
wmedian.weighted_median (the numpy reference, docs/engine.md "Weighted median"); the same values.

The plain median stays OpenCV's vectorised filter. One kernel (:func:`_kernel`) then runs over the rows: each row's
3 x 3 ranges (:func:`_row_range`: the column and row extrema along the row at plain indices, which LLVM vectorises;
numba_edges) find the pixels whose window holds two motions, and BLOCK of them are weighed side by side
(:func:`_weigh_block`): each window's neighbour k of the block's pixels in a row ``[k, p]``, so the weights (the
occlusion state from the flow's central differences at the neighbour, the grey-value similarity), a sorting network
on the (value, weight) pairs (:func:`sorting_network`: 140 compare-exchanges for a 5 x 5 window, against 625
comparisons of every value with every other) and the cumulative weight run along p, vectorised, with no branch. The
weights are integers (wmedian.QUANTUM), so each pixel's sums are exact in any order: the reference's values. With
more than one thread bound (the estimator's ``threads``) the threads take the image's stripes of STRIPE rows in turn
(pixels to weigh cluster along motion boundaries: contiguous halves would leave one thread most of them); each pixel's
value does not depend on which thread or block weighs it (task wmfast).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numba
import numpy as np
from numba import get_thread_id, njit, prange

from .numba_backend import threads
from .wmedian import QUANTUM, RANGE_WINDOW, median_filter, spatial_weights
from .workspace import scratch

BLOCK = 64  # pixels the kernel weighs side by side
STRIPE = 4  # rows: the threads take turns by stripes (the flagged pixels cluster along motion boundaries)
PARALLEL_MIN_PIXELS = 20_000  # levels below this run serially (a parallel region's start costs more than it saves)
_JIT = dict(cache=True, error_model="numpy", nogil=True)  # no fastmath: the reference's float64 arithmetic
assert RANGE_WINDOW == 3  # _row_range's window


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
def _row_range(v, i, lo, hi, span):  # noqa: ANN001, ANN202
    """Row ``i``'s larger flow-component range over the 3 x 3 window (border replicated; wmedian.window_range, in
    float32) into ``span`` (W,): the column extrema along the row at plain indices, then the row extrema
    (vectorised; numba_edges). ``lo``, ``hi``: (2, W + 2) scratch."""
    h, w = v.shape[1:]
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
        span[j] = max(r0, r1)


@njit(inline="always", **_JIT)
def _gather(v, guide, y, x, r, p, dif, div, vals):  # noqa: ANN001, ANN202
    """Column ``p`` of the block: pixel (y, x)'s window, neighbour k in row k -- the grey-value difference to the
    pixel (float64), the flow's divergence by central differences at the neighbour (border replicated) and both
    flow components. Windows whose neighbours' neighbours lie inside the image skip the clamps."""
    h, w = guide.shape
    g = np.float64(guide[y, x])
    clamp = not (r < y < h - 1 - r and r < x < w - 1 - r)
    k = 0
    for dy in range(-r, r + 1):
        yy, yu, yd = y + dy, y + dy - 1, y + dy + 1
        if clamp:
            yy = min(max(yy, 0), h - 1)
            yu, yd = max(yy - 1, 0), min(yy + 1, h - 1)
        for dx in range(-r, r + 1):
            xx, xl, xr = x + dx, x + dx - 1, x + dx + 1
            if clamp:
                xx = min(max(xx, 0), w - 1)
                xl, xr = max(xx - 1, 0), min(xx + 1, w - 1)
            dif[k, p] = np.float64(guide[yy, xx]) - g
            div[k, p] = 0.5 * (np.float64(v[0, yy, xr]) - np.float64(v[0, yy, xl])) + \
                0.5 * (np.float64(v[1, yd, xx]) - np.float64(v[1, yu, xx]))
            vals[0, k, p] = v[0, yy, xx]
            vals[1, k, p] = v[1, yy, xx]
            k += 1


@njit(inline="always", **_JIT)
def _weigh_block(ys, xs, cnt, spatial, inv, inv_d, pairs, out, dif, div, vals, wq, work_q, total, below,  # noqa: ANN001, ANN202
                 best):
    """The weighted median of each component at the block's ``cnt`` pixels (ys, xs) into ``out`` (2, H, W)
    (wmedian.weighted_median): their windows gathered by :func:`_gather` into dif, div (n, BLOCK) and vals (2, n,
    BLOCK), which is sorted in place; ``inv`` = 1 / sigma_i^2, ``inv_d`` = 1 / sigma_d^2 (0: no occlusion state);
    ``pairs``: :func:`sorting_network` of the window's size. The columns past ``cnt`` (finite: a former block's
    windows, or zeros) are weighed and ignored."""
    n = dif.shape[0]
    inf = np.float32(np.inf)
    total[:] = 0
    for k in range(n):  # row slices: loops along p at plain indices vectorise (numba_edges)
        sk, dk, ck, qk = spatial[k], dif[k], div[k], wq[k]
        for p in range(BLOCK):
            d = min(ck[p], 0.0)
            o = 1.0 / (1.0 + (d * d) * inv_d)
            qk[p] = np.int32(math.floor(sk / (1.0 + (dk[p] * dk[p]) * inv) * o * QUANTUM)) + np.int32(1)
            total[p] += qk[p]
    for c in range(2):
        sv, sw = vals[c], work_q  # the window sorted by value in place, a copy of its weights along (a sorting network)
        for k in range(n):
            wk, qk = sw[k], wq[k]
            for p in range(BLOCK):
                wk[p] = qk[p]
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
            out[c, ys[p], xs[p]] = best[p]


@njit(**_JIT)
def _stripes(v, guide, tau, r, spatial, inv, inv_d, pairs, out, first, step, rows):  # noqa: ANN001, ANN202
    """The weighted median where a component's 3 x 3 range exceeds ``tau``, on the rows of stripes ``first``,
    ``first + step``, ... (STRIPE rows each): each row's ranges (:func:`_row_range`), its flagged pixels
    collected; each BLOCK of them gathered (:func:`_gather`) and weighed (:func:`_weigh_block`), the last, partial
    one at the end (its unused columns zeroed). ``rows``: (5, W + 2) float32 scratch of this call's thread. The
    block's arrays are local (a few kB; as arguments, which might alias, the loops along p ran ~5 % slower)."""
    h, w = guide.shape
    n = spatial.shape[0]
    lo, hi, span = rows[0:2], rows[2:4], rows[4]
    ys = np.empty(BLOCK, np.int64)
    xs = np.empty(BLOCK, np.int64)
    vals = np.empty((2, n, BLOCK), np.float32)
    dif = np.empty((n, BLOCK))
    div = np.empty((n, BLOCK))
    wq = np.empty((n, BLOCK), np.int32)
    work_q = np.empty((n, BLOCK), np.int32)
    total = np.empty(BLOCK, np.int32)
    below = np.empty(BLOCK, np.int32)
    best = np.empty(BLOCK, np.float32)
    cnt = 0
    for s in range(first, (h + STRIPE - 1) // STRIPE, step):
        for i in range(s * STRIPE, min((s + 1) * STRIPE, h)):
            _row_range(v, i, lo, hi, span)
            for j in range(w):
                if np.float64(span[j]) > tau:
                    ys[cnt], xs[cnt] = i, j
                    cnt += 1
                    if cnt == BLOCK:
                        for p in range(BLOCK):
                            _gather(v, guide, ys[p], xs[p], r, p, dif, div, vals)
                        _weigh_block(ys, xs, cnt, spatial, inv, inv_d, pairs, out, dif, div, vals, wq, work_q, total,
                                     below, best)
                        cnt = 0
    if cnt:
        for p in range(cnt):
            _gather(v, guide, ys[p], xs[p], r, p, dif, div, vals)
        for k in range(n):
            for p in range(cnt, BLOCK):
                dif[k, p] = div[k, p] = 0.0
                vals[0, k, p] = vals[1, k, p] = 0.0
        _weigh_block(ys, xs, cnt, spatial, inv, inv_d, pairs, out, dif, div, vals, wq, work_q, total, below, best)


@njit(parallel=True, **_JIT)
def _kernel(v, guide, tau, r, spatial, inv, inv_d, pairs, out, rows, slots):  # noqa: ANN001, ANN202
    """:func:`_stripes` over the whole image: ``slots`` > 1 interleaved sets of stripes in parallel (each on its
    thread's rows of ``rows`` (T, 5, W + 2), indexed by get_thread_id), else one serially."""
    if slots > 1:
        for b in prange(slots):
            _stripes(v, guide, tau, r, spatial, inv, inv_d, pairs, out, b, slots, rows[get_thread_id()])
    else:
        _stripes(v, guide, tau, r, spatial, inv, inv_d, pairs, out, 0, 1, rows[0])


def weighted_median_numba(v: np.ndarray, i0: np.ndarray, size: int, sigma_i: float, sigma_d: float, tau: float,
                          window: int = 0) -> np.ndarray:
    """wmedian.weighted_median (same arguments, same values): the plain median (OpenCV's), then one kernel
    (:func:`_kernel`) finds the pixels to weigh and weighs them, on the calling thread's numba threads
    (numba_backend.threads) on levels of PARALLEL_MIN_PIXELS or more, else serially."""
    out = median_filter(v, size)
    if sigma_i <= 0.0:
        return out
    h, w = i0.shape
    window = window or size
    inv_d = 1.0 / (sigma_d * sigma_d) if sigma_d > 0.0 else 0.0
    rows = scratch("wmedian.rows", (numba.config.NUMBA_NUM_THREADS, 5, w + 2))  # get_thread_id's range
    _kernel(np.ascontiguousarray(v), np.ascontiguousarray(i0), float(tau), window // 2, spatial_weights(window),
            1.0 / (sigma_i * sigma_i), inv_d, sorting_network(window * window), out, rows,
            threads() if h * w >= PARALLEL_MIN_PIXELS else 1)
    return out
