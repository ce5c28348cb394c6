"""numba kernels of the census data term (census.py, the numpy reference and test oracle).

The level signatures -- :func:`factor_kernel`, frame 0's signatures once per level (:func:`level_signature_numba`),
interleaved for the fusion (:func:`census_planes_numba`) -- and the level contrast (:func:`median_contrast_numba`)
are numba_signature's (split off in task s320c), re-exported here;
:func:`census_kernel` computes one warp's quadratic form in one pass over the level (census.census_form): frame 1's
channels sampled at x + v0 (a value-only warp, numba_warp.sample_row), both frames' signatures and the form, row
by row, the warped rows and the rows of P = F0 + F1 and D = F1 - F0 kept in per-thread rings (cache-resident) instead of
level-sized arrays (the judge's kernel, census.reliability, is numba_judge's). Grey and colour input are the
same kernel (C = 1 or 3 channels of K signatures each), and so are the neighbours at distance 1 and 2
(CensusParams.radius: the warped rows' ring holds 2 radius + 1 rows; the reliability figure compares the 3 x 3
signature either way). Rows run as whole-row loops over C-contiguous arrays (unit stride, so they vectorise), the
helpers taking the whole arrays and row / slot indices, not row views: every view numba makes is a reference count
taken and dropped (two atomic operations), and the ~90 views a row took cost ~2 us a row whatever its width -- on a
40-160 px level most of the kernel's time (task censlarge: 1.6-2.6x faster there, 1.2x at 640 px). The same
quantities as the reference, the form's sums rearranged (:func:`_finish`): equal to float32 rounding
(test_census, 1e-5 of the form's largest value).

Importing this module raises ImportError when numba is not installed (backends.py then uses numpy).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import get_thread_id, njit, prange

from .census import CensusParams
from .numba_backend import LINEARISE_PARALLEL_MIN_PIXELS, row_base, threads
from .numba_signature import F32, JIT, ROWS, K, neighbour_row, offset_arrays

# the level signatures and contrast, re-exported (numba_signature.py; backends.py and the tests take them from here)
from .numba_signature import census_planes_numba as census_planes_numba
from .numba_signature import contrast_kernel as contrast_kernel
from .numba_signature import factor_kernel as factor_kernel
from .numba_signature import factor_numba as factor_numba
from .numba_signature import level_signature_numba as level_signature_numba
from .numba_signature import median_contrast_numba as median_contrast_numba
from .numba_warp import sample_row
from .warping import KERNEL_CODES
from .workspace import scratch

# _form_rows works four channels a pass and finishes the form in the last pass: C K channels must be a multiple
# of four and at least eight (K = 8 by construction, census.OFFSETS); a change of K has to revisit it
if K % 4 or K < 8:
    raise RuntimeError(f"numba_census._form_rows needs K a multiple of 4 and >= 8, got K = {K}")


@njit(**ROWS)
def _factor_row(warped, c, sm, s0, sp, rad, gain, eps, ss, zero):  # noqa: ANN001, ANN201
    """The factor GAIN / (RMS + EPS) of channel c's warped row in slot s0 into ss (W), from its K = 8 neighbour
    differences (census.OFFSETS at distance rad, in their order) in the rows of slots sm, s0, sp (rad rows above,
    at, below), each padded with rad edge values on either side (:func:`_pad_row`), in one loop over the row: the
    float32 operations of numba_signature._differences (the sum of squares in OFFSETS' order, each square fused onto
    the sum so far by FASTMATH's contraction, as its K row loops computed it), without its K clamped row loops and
    row of differences stored and read back (:func:`_pair_diff` takes the differences again; task s320c: the warped
    signatures 86 -> 50 us a 160 x 120 level). ``zero`` is 0.0, passed in from Python so that the compiler
    cannot fold it: it makes the first square a rounded sum of its own (else the first two squares would be one
    fused sum, another last bit on 2-3 % of the pixels)."""
    inv_k = F32(1.0) / F32(K)
    for j in range(ss.shape[0]):
        x0, x1, x2 = np.uint64(j), np.uint64(j + rad), np.uint64(j + 2 * rad)
        e = warped[c, s0, x1]
        d0 = warped[c, sm, x0] - e
        d1 = warped[c, sm, x1] - e
        d2 = warped[c, sm, x2] - e
        d3 = warped[c, s0, x0] - e
        d4 = warped[c, s0, x2] - e
        d5 = warped[c, sp, x0] - e
        d6 = warped[c, sp, x1] - e
        d7 = warped[c, sp, x2] - e
        t = d0 * d0 + zero
        t += d1 * d1
        t += d2 * d2
        t += d3 * d3
        t += d4 * d4
        t += d5 * d5
        t += d6 * d6
        t += d7 * d7
        ss[j] = gain / (math.sqrt(t * inv_k) + eps)


@njit(inline="always", **ROWS)
def _put(f0, q, rr, j, d, fac, pair, diff, sq):  # noqa: ANN001, ANN201
    """P and D of channel q at column j from the warped frame's neighbour difference d and its factor fac
    (:func:`_pair_diff`)."""
    a, b = f0[q, rr, j], d * fac
    pair[q, sq, j + 1] = a + b
    diff[q, sq, j] = b - a


@njit(**ROWS)
def _pair_diff(f0, q, rr, warped, c, s, o, s0, rad, ss, pair, diff, sq):  # noqa: ANN001, ANN201
    """Channels q .. q + 3 (of channel c's signature) of one row (image row rr) into ring slot sq of pair and
    diff: with F0 = frame 0's signature f0[q, rr] (:func:`level_signature_numba`) and F1 = d ss (the warped
    frame's: d its neighbour difference -- the padded row in slot s[k] at column j + o[k] minus the row in slot
    s0 at j + rad, as :func:`_factor_row` took it -- and ss its factor), pair[q, sq, 1:W + 1] = F0 + F1 and
    diff[q, sq] = F1 - F0; the pair row's ends mirror its columns 1 and W - 2 (P(1) before, P(W - 2) after; both
    P(0) when W == 1), so that P(x + 1) - P(x - 1) is 0 on the border columns. Four channels a pass (one: 1.2x
    slower; all eight with the factor: not vectorised, 2.4x slower)."""
    w = diff.shape[2]
    sa, sb, sc, sd = s
    oa, ob, oc, od = o
    for j in range(w):
        e = warped[c, s0, np.uint64(j + rad)]
        fac = ss[j]
        _put(f0, q, rr, j, warped[c, sa, np.uint64(j + oa)] - e, fac, pair, diff, sq)
        _put(f0, q + 1, rr, j, warped[c, sb, np.uint64(j + ob)] - e, fac, pair, diff, sq)
        _put(f0, q + 2, rr, j, warped[c, sc, np.uint64(j + oc)] - e, fac, pair, diff, sq)
        _put(f0, q + 3, rr, j, warped[c, sd, np.uint64(j + od)] - e, fac, pair, diff, sq)
    for k in range(q, q + 4):
        pair[k, sq, 0] = pair[k, sq, min(2, w)]
        pair[k, sq, w + 1] = pair[k, sq, max(w - 1, 1)]


@njit(**ROWS)
def _pad_row(warped, c, s, rad, w):  # noqa: ANN001, ANN201
    """The rad columns on either side of the warped row warped[c, s] (rad + W + rad long, the row from column
    rad) set to its edge values: what census.shifted's edge padding reads there."""
    for p in range(rad):
        warped[c, s, p] = warped[c, s, rad]
        warped[c, s, rad + w + p] = warped[c, s, rad + w - 1]


@njit(inline="always", **ROWS)
def _sums4(pair, diff, q, su, sc, sd, j, d2, robust):  # noqa: ANN001, ANN201
    """The sums over four channels q .. q + 3 at column j, from P = F0 + F1 (``pair``, ring slots su, sc, sd: rows
    i - 1, i, i + 1, border-mirrored, column x at x + 1) at the pixel's left/right/up/down neighbours and
    D = F1 - F0 (``diff``, slot sc) at the pixel: with a channel's unscaled gradient ax = P(x + 1) - P(x - 1),
    ay = P(y + 1) - P(y - 1) (sums of both frames' central differences), the residual D at v0 and the weight wk,
    the sums of wk (ax ax, ax ay, ay ay, ax D, ay D)."""
    one = F32(1.0)
    ax, ay, r0 = pair[q, sc, j + 2] - pair[q, sc, j], pair[q, sd, j + 1] - pair[q, su, j + 1], diff[q, sc, j]
    bx, by, r1 = (pair[q + 1, sc, j + 2] - pair[q + 1, sc, j], pair[q + 1, sd, j + 1] - pair[q + 1, su, j + 1],
                  diff[q + 1, sc, j])
    cx, cy, r2 = (pair[q + 2, sc, j + 2] - pair[q + 2, sc, j], pair[q + 2, sd, j + 1] - pair[q + 2, su, j + 1],
                  diff[q + 2, sc, j])
    dx, dy, r3 = (pair[q + 3, sc, j + 2] - pair[q + 3, sc, j], pair[q + 3, sd, j + 1] - pair[q + 3, su, j + 1],
                  diff[q + 3, sc, j])
    wa = one / math.sqrt(r0 * r0 + d2) if robust else one
    wb = one / math.sqrt(r1 * r1 + d2) if robust else one
    wc = one / math.sqrt(r2 * r2 + d2) if robust else one
    wd = one / math.sqrt(r3 * r3 + d2) if robust else one
    wax, way, wbx, wby = wa * ax, wa * ay, wb * bx, wb * by
    wcx, wcy, wdx, wdy = wc * cx, wc * cy, wd * dx, wd * dy
    return ((wax * ax + wbx * bx) + (wcx * cx + wdx * dx), (wax * ay + wbx * by) + (wcx * cy + wdx * dy),
            (way * ay + wby * by) + (wcy * cy + wdy * dy), (wax * r0 + wbx * r1) + (wcx * r2 + wdx * r3),
            (way * r0 + wby * r1) + (wcy * r2 + wdy * r3))


@njit(inline="always", **ROWS)
def _finish(out, i, j, ry, flow, keep, sk, s0, s1, s2, s3, s4):  # noqa: ANN001, ANN201
    """Pixel (i, j) of the form out (5, H, W) from its sums over the channels s0 .. s4 (:func:`_sums4`): the
    gradients' scales (x: 1/4, the mean of two central differences; y: ``ry``, 1/4 or 0 on the first and last
    rows) and the pixel's weight keep[sk, j], and the linearisation point flow (2, H, W): with rho_k(v) =
    a_k . (v - v0) + r0_k, g = sum_k w_k a_k r0_k - T v0 (census.signature_form's sum of w_k c_k a_k,
    c_k = r0_k - a_k . v0)."""
    q = F32(0.25)
    t11 = keep[sk, j] * q * q * s0
    t12 = keep[sk, j] * q * ry * s1
    t22 = keep[sk, j] * ry * ry * s2
    out[0, i, j] = t11
    out[1, i, j] = t12
    out[2, i, j] = t22
    out[3, i, j] = keep[sk, j] * q * s3 - t11 * flow[0, i, j] - t12 * flow[1, i, j]
    out[4, i, j] = keep[sk, j] * ry * s4 - t12 * flow[0, i, j] - t22 * flow[1, i, j]


def _make_form_row(first: bool, last: bool):  # noqa: ANN202
    """One pass along row i of the form out (5, H, W) over channels q .. q + 3 (:func:`_sums4`; unit stride,
    vectorises; four per pass: the sums are loaded and stored a quarter as often as one per pass): ``first`` the
    row's first pass (out = the sums; no zeroing pass), ``last`` its last (out = :func:`_finish` of the sums so
    far plus these: not stored and read back, task s320c), else out += the sums. Compile-time constants: one
    source, three kernels (:data:`_form_row_first`, :data:`_form_row_add`, :data:`_form_row_last`). (All eight
    channels of a grey signature in one pass were 5.8x slower: too many rows for one vectorised loop.) Whole
    arrays and indices, no row views (task censlarge, :func:`_census_rows`)."""

    def form_row(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk):  # noqa: ANN001, ANN202
        for j in range(diff.shape[2]):
            t0, t1, t2, t3, t4 = _sums4(pair, diff, q, su, sc, sd, j, d2, robust)
            if first:
                out[0, i, j], out[1, i, j], out[2, i, j], out[3, i, j], out[4, i, j] = t0, t1, t2, t3, t4
            elif last:
                _finish(out, i, j, ry, flow, keep, sk, out[0, i, j] + t0, out[1, i, j] + t1, out[2, i, j] + t2,
                        out[3, i, j] + t3, out[4, i, j] + t4)
            else:
                out[0, i, j] += t0
                out[1, i, j] += t1
                out[2, i, j] += t2
                out[3, i, j] += t3
                out[4, i, j] += t4

    form_row.__name__ = form_row.__qualname__ = "form_row_" + ("first" if first else "last" if last else "add")
    return njit(**ROWS)(form_row)


_form_row_first, _form_row_add, _form_row_last = (_make_form_row(*f) for f in ((True, False), (False, False),
                                                                                 (False, True)))


@njit(**ROWS)
def _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out, r0, r1,  # noqa: ANN001, ANN201
                 warped, keep, pair, diff, ss, taps, base, zero):
    """Rows r0 .. r1 - 1 of :func:`census_kernel`, with one thread's rings: warped (C, M, W + 2 rad) and keep
    (M, W) hold rows of frame 1 warped (padded with rad edge values on either side: :func:`_pad_row`) and its
    weight, row r in slot r mod M (M = 2 rad + 1, rad the offsets' distance: 3 rows for the 3 x 3 neighbours, 5
    for the ring at distance 2); pair (C K, 3, W + 2) and diff (C K, 3, W) rows of P = F0 + F1
    (border-mirrored: :func:`_pair_diff`) and D = F1 - F0 (F1 the warped frame's signatures), row r in slot
    r mod 3; ss (W) one channel's factor in the warped frame (:func:`_factor_row`). Row r of the rings stands for
    the image row clamped to 0 .. H - 1 (so the signature of the first and last rows sees edge values, as
    census.signature), and output row i needs signature rows i - 1 .. i + 1, those warped rows
    i - 1 - rad .. i + 1 + rad: each block warps its rows and 1 + rad on either side, each once. (The rings' rows
    -1 and H are read for the first and last rows' y-gradient, whose weight is 0.) Each step's work is its own
    function (:func:`_pair_rows`, :func:`_form_rows`): written inline here the same code ran ~25 % slower."""
    h, w = f0.shape[1], f0.shape[2]
    m = warped.shape[1]
    rad = (m - 1) // 2
    for r in range(r0 - 1 - rad, r1 + 1 + rad):  # warp row r, the signatures of row r - rad, output row r - rad - 1
        s = (r + 2 * m) % m
        sample_row(coefs, frames, flow, min(max(r, 0), h - 1), kernel, weight, warped, s, rad, keep[s], taps, base)
        for c in range(warped.shape[0]):
            _pad_row(warped, c, s, rad, w)
        rr = r - rad
        if rr >= r0 - 1:  # the signatures of row rr (warped rows rr - rad, rr, rr + rad) into diff, then P and D
            _pair_rows(f0, min(max(rr, 0), h - 1), warped, (rr - rad + 2 * m) % m, (rr + 2 * m) % m, s,
                       (rr + 3) % 3, dy, dx, gain, eps, pair, diff, ss, zero)
        if rr - 1 >= r0:  # output row i: signature rows i - 1, i, i + 1 are in the ring
            _form_rows(out, rr - 1, pair, diff, keep, (rr - 1 + 2 * m) % m, flow, d2, robust)


@njit(**ROWS)
def _pair_rows(f0, rr, warped, sm, s0, sp, sq, dy, dx, gain, eps, pair, diff, ss, zero):  # noqa: ANN001, ANN201
    """P and D of one row (image row rr) into ring slot sq of pair and diff, from the warped rows in slots sm,
    s0, sp (rad rows above, at, rad below; padded) and frame 0's level f0 (C K, H, W): its channels' signatures
    (:func:`level_signature_numba`) (:func:`_census_rows`). Per channel the factor (:func:`_factor_row`), then
    the K neighbour differences (offsets dy, dx at distance rad) again with their products and sums, four at a
    time (:func:`_pair_diff`)."""
    k_n = dy.shape[0]
    rad = (warped.shape[1] - 1) // 2
    for c in range(warped.shape[0]):
        _factor_row(warped, c, sm, s0, sp, rad, gain, eps, ss, zero)
        for k in range(0, k_n, 4):
            slots = (neighbour_row(dy[k], sm, s0, sp), neighbour_row(dy[k + 1], sm, s0, sp),
                     neighbour_row(dy[k + 2], sm, s0, sp), neighbour_row(dy[k + 3], sm, s0, sp))
            cols = (rad + dx[k], rad + dx[k + 1], rad + dx[k + 2], rad + dx[k + 3])
            _pair_diff(f0, c * k_n + k, rr, warped, c, slots, cols, s0, rad, ss, pair, diff, sq)


@njit(**ROWS)
def _form_rows(out, i, pair, diff, keep, sk, flow, d2, robust):  # noqa: ANN001, ANN201
    """Row i of the form out (5, H, W) from the rings' rows i - 1, i, i + 1 and the row's weight keep[sk] (W)
    (:func:`_census_rows`)."""
    h = out.shape[1]
    su, sc, sd = (i + 2) % 3, (i + 3) % 3, (i + 4) % 3
    ry = F32(0.25) if 0 < i < h - 1 else F32(0.0)
    n = pair.shape[0]
    for q in range(0, n, 4):  # C K channels: K = 8, four per pass
        if q == 0:
            _form_row_first(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)
        elif q + 4 < n:
            _form_row_add(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)
        else:
            _form_row_last(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)


@njit(**JIT)
def _ring_ends(t, n_c, m, w):  # noqa: ANN001, ANN201
    """Where each of :func:`_ring_views`' rings ends in ``rings`` (the layout's one definition; the last is the
    length :func:`ring_floats` allocates)."""
    q = n_c * K
    o1 = t * n_c * m * (w + m - 1)
    o2 = o1 + t * m * w
    o3 = o2 + t * q * 3 * (w + 2)
    o4 = o3 + t * q * 3 * w
    o5 = o4 + t * w
    return o1, o2, o3, o4, o5, o5 + t * 9 * w


def ring_floats(threads: int, n_c: int, m: int, w: int) -> int:
    """The length of :func:`census_kernel`'s ``rings`` (float32) for ``threads`` threads, C ``n_c`` channels, M
    ``m`` warped rows and W ``w`` columns (:func:`_ring_views`)."""
    return int(_ring_ends.py_func(threads, n_c, m, w)[-1])  # plain Python: no kernel to compile or read


@njit(**JIT)
def _ring_views(rings, t, n_c, m, w):  # noqa: ANN001, ANN201
    """:func:`census_kernel`'s per-thread rings for T = ``t`` threads, C = ``n_c`` channels, M = ``m`` warped rows,
    W = ``w`` columns, cut in this order from ``rings`` (1-D float32, :func:`ring_floats` long): warped
    (T, C, M, W + M - 1: rad = (M - 1) / 2 edge values on either side), keep (T, M, W), pair (T, C K, 3, W + 2),
    diff (T, C K, 3, W), ss (T, W) and the warp's row scratch taps (T, 9, W). One array argument instead of six:
    each array argument costs ~0.25 us of numba's dispatch per call (task fastcens)."""
    q = n_c * K
    o1, o2, o3, o4, o5, o6 = _ring_ends(t, n_c, m, w)
    return (rings[:o1].reshape((t, n_c, m, w + m - 1)), rings[o1:o2].reshape((t, m, w)),
            rings[o2:o3].reshape((t, q, 3, w + 2)), rings[o3:o4].reshape((t, q, 3, w)),
            rings[o4:o5].reshape((t, w)), rings[o5:o6].reshape((t, 9, w)))


@njit(parallel=True, **JIT)
def census_kernel(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, delta, weight, out,  # noqa: ANN001, ANN201
                  rings, base, blocks, zero):
    """census.census_form in one pass: out (5, H, W) from frame 0's level f0 (C K, H, W) (its channels'
    signatures, :func:`level_signature_numba`), frame 1's interpolation coefficients
    ``coefs`` and channels ``frames`` (C, H, W) and the flow v0 (2, H, W); each pixel's weight ``weight`` (1 / C)
    inside, 0 where x + v0 leaves the image; the signatures' offsets (dy, dx) at distance rad (census.OFFSETS
    times rad, in that order: :func:`_factor_row`), the warped rings' M = 2 rad + 1 rows. The rows in ``blocks``
    contiguous blocks, in parallel when more than one (:func:`_census_rows`; per-thread rings cut from
    ``rings``, :func:`_ring_views`, for T = base.shape[0] threads, and the warp's row scratch base (T, 2, W)
    int32). ``zero``: 0.0, passed in so that the compiler cannot fold it (:func:`_factor_row`)."""
    n_c, h, w = frames.shape
    d2 = delta * delta
    t_n = base.shape[0]
    rad = 0
    for k in range(dy.shape[0]):
        rad = max(rad, abs(dy[k]))
    warped, keep, pair, diff, ss, taps = _ring_views(rings, t_n, n_c, 2 * rad + 1, w)
    if blocks > 1:
        for b in prange(blocks):
            t = get_thread_id()
            _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out,
                         b * h // blocks, (b + 1) * h // blocks, warped[t], keep[t], pair[t], diff[t], ss[t],
                         taps[t], base[t], zero)
    else:
        _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out, 0, h,
                     warped[0], keep[0], pair[0], diff[0], ss[0], taps[0], base[0], zero)


def census_form_numba(f0: np.ndarray, g0: None, coefs: np.ndarray, frames: np.ndarray, v0: np.ndarray, kernel: str,
                      robust: bool, params: CensusParams, out: np.ndarray | None = None) -> np.ndarray:
    """census.census_form with :func:`census_kernel`: the quadratic form (5, H, W) of one warp, f0 frame 0's level
    (C K, H, W) (:func:`level_signature_numba`). The rings are the
    calling thread's scratch arrays (workspace.py); the rows run in one block per thread on levels of
    LINEARISE_PARALLEL_MIN_PIXELS or more (else in one); the form itself is fresh (a Bregman step reuses the
    last warp's), or ``out`` (5, H, W) float32 C-contiguous when given."""
    n_c, h, w = frames.shape
    blocks = min(threads(), h) if h * w >= LINEARISE_PARALLEL_MIN_PIXELS else 1  # (threads() costs ~0.6 us)
    n = numba.config.NUMBA_NUM_THREADS  # per-thread rings: get_thread_id's range
    rings = scratch("census.rings", (ring_floats(n, n_c, 2 * params.radius + 1, w),))
    out = np.empty((5, h, w), F32) if out is None else out
    census_kernel(np.ascontiguousarray(f0, dtype=F32), np.ascontiguousarray(coefs, dtype=F32),
                  np.ascontiguousarray(frames, dtype=F32), np.ascontiguousarray(v0, dtype=F32),
                  KERNEL_CODES[kernel], *offset_arrays(params.radius), F32(params.gain), F32(params.eps), robust,
                  F32(params.delta), F32(1.0 / n_c), out, rings,
                  row_base(w), blocks, F32(0.0))
    return out
