"""numba kernels of the census data term (census.py, the numpy reference and test oracle).

:func:`factor_kernel` computes the factor GAIN / (RMS + EPS) that turns an image's neighbour differences into
its soft census signature, and the signatures: frame 0's once per level (:func:`level_signature_numba`), and on
request interleaved (the fusion's cost, :func:`census_planes_numba`);
:func:`census_kernel` one warp's quadratic form in one pass over the level (census.census_form): frame 1's channels
sampled at x + v0 (a value-only warp, numba_warp.sample_row), both frames' signatures and the form, row by row, the
warped rows and the rows of P = F0 + F1 and D = F1 - F0 kept in per-thread rings (cache-resident) instead of
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

from .census import OFFSETS, OFFSETS_DX, OFFSETS_DY, CensusParams, contrast_stride
from .numba_backend import LINEARISE_PARALLEL_MIN_PIXELS, row_base, threads
from .numba_kernels import FASTMATH
from .numba_sort import median_f32
from .numba_warp import sample_row
from .warping import KERNEL_CODES
from .workspace import scratch

# the solver's fastmath flags, not fastmath=True: with reassoc/arcp the census kernels computed other last bits when
# compiled in a process than when read from numba's cache (a new install's first process got census flows 2e-3 px
# away from every later process's; test_cold_start.test_kernels_compute_the_same_compiled_or_cached)
_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)
_ROWS = dict(_JIT, _nrt=False)
_F32 = np.float32
_K = len(OFFSETS)


def _offset_arrays(radius: int) -> tuple[np.ndarray, np.ndarray]:
    """The signature's neighbour offsets at distance ``radius`` (census.offsets) as (dy, dx) int64 arrays (K)."""
    return (OFFSETS_DY, OFFSETS_DX) if radius == 1 else (OFFSETS_DY * radius, OFFSETS_DX * radius)


def _make_diff_span(edge: bool):  # noqa: ANN202
    """out[k, i, j] = img[r, j + off] - img[rc, j] and ss[j] += out[k, i, j]^2 for j0 <= j < j1; with ``edge`` one
    neighbour value, img[r, off], for every pixel (the columns whose neighbour is clamped to the row's end).
    ``edge`` is a compile-time constant: one source, two kernels (:data:`_diff_span`, :data:`_diff_edge`), each
    as fast as its loop written out (the factor kernel's time within 1-2 %;
    git show 4983857:bench/results/census_cost/onesig/summary.md; a run-time select of the column was 15 %
    slower). Whole arrays and indices, no views (task censlarge, :func:`_census_rows`)."""

    def diff_span(img, r, rc, off, j0, j1, out, k, i, ss):  # noqa: ANN001, ANN202
        for j in range(j0, j1):
            c = np.uint64(j)  # unsigned column indices: numba wraps a signed index around (+ W where < 0), a
            # select that kept this loop (j + off, off < 0) from being vectorised (1.4x slower at 640 px)
            d = (img[r, off] if edge else img[r, np.uint64(j + off)]) - img[rc, c]
            out[k, i, c] = d
            ss[c] += d * d

    diff_span.__name__ = diff_span.__qualname__ = "diff_edge" if edge else "diff_span"
    return njit(**_ROWS)(diff_span)


_diff_span, _diff_edge = _make_diff_span(False), _make_diff_span(True)


@njit(**_ROWS)
def _neighbour_differences(img, ru, rc, rd, dy, dx, out, i, ss):  # noqa: ANN001, ANN201
    """The K neighbour differences of the row ``rc`` of img (., W), whose neighbour rows are ``ru`` and ``rd``
    (rows y - r and y + r for offsets (dy, dx) of distance r, clamped to the image: edge values), into the rows
    out[k, i] (k < K) of out (K, ., W), column neighbours clamped to the row; and their sum of squares added to
    ss (W). Channel by channel over whole rows (unit stride, so that the loops vectorise)."""
    w = img.shape[1]
    k_n = dy.shape[0]
    for k in range(k_n):
        r = ru if dy[k] < 0 else (rd if dy[k] > 0 else rc)
        d = dx[k]
        m = min(abs(d), w)  # the columns whose neighbour is clamped to the row's end
        if d == 0:
            _diff_span(img, r, rc, 0, 0, w, out, k, i, ss)
        elif d > 0:  # the last d columns' neighbour is the last column
            _diff_span(img, r, rc, m, 0, w - m, out, k, i, ss)
            _diff_edge(img, r, rc, w - 1, w - m, w, out, k, i, ss)
        else:
            _diff_span(img, r, rc, -m, m, w, out, k, i, ss)
            _diff_edge(img, r, rc, 0, 0, m, out, k, i, ss)


@njit(**_ROWS)
def _differences(img, ru, rc, rd, dy, dx, gain, eps, out, i, ss):  # noqa: ANN001, ANN201
    """:func:`_neighbour_differences` and into ss (W) the factor that makes them the signature,
    GAIN / (RMS + EPS) (census.signature)."""
    k_n = dy.shape[0]
    ss[:] = 0.0
    _neighbour_differences(img, ru, rc, rd, dy, dx, out, i, ss)
    inv_k = _F32(1.0) / _F32(k_n)  # float32 throughout (ss / k_n, an int, promoted the row to float64)
    for j in range(img.shape[1]):
        ss[j] = gain / (math.sqrt(ss[j] * inv_k) + eps)


@njit(**_JIT)
def _factor_image_row(img, rc, dy, dx, rad, gain, eps, out, planes, sigs):  # noqa: ANN001, ANN201
    """Row rc of :func:`factor_kernel`."""
    h, w = img.shape
    k_n = dy.shape[0]
    ru, rd = max(rc - rad, 0), min(rc + rad, h - 1)
    if sigs is not None:
        _differences(img, ru, rc, rd, dy, dx, gain, eps, sigs, rc, out[rc])
        for k in range(k_n):  # the same product as the planes' below
            for j in range(w):
                sigs[k, rc, j] = sigs[k, rc, j] * out[rc, j]
    else:
        tmp = np.empty((k_n, 1, w), np.float32)
        _differences(img, ru, rc, rd, dy, dx, gain, eps, tmp, 0, out[rc])
        if planes is not None:
            for j in range(w):
                for k in range(k_n):
                    planes[rc, j, k] = tmp[k, 0, j] * out[rc, j]


@njit(parallel=True, **_JIT)
def factor_kernel(img, dy, dx, rad, gain, eps, out, planes, sigs, parallel):  # noqa: ANN001, ANN201
    """The factor GAIN / (RMS + EPS) of img (H, W) into out (H, W) (:func:`_differences`) for the offsets (dy, dx)
    at distance ``rad``, neighbours clamped to the image (edge values), and the signature -- the neighbour
    differences times the factor; census.signature to float32 rounding -- into sigs (K, H, W) unless ``sigs`` is
    None (a compile-time case; a census level's, :func:`census_kernel` reads them), else into planes (H, W, K),
    interleaved, unless ``planes`` is None (a compile-time case; fusion.census_planes). Row by row
    (:func:`_factor_image_row`), in parallel when ``parallel`` (:func:`factor_parallel`; each row the same
    arithmetic either way)."""
    if parallel:
        for i in prange(img.shape[0]):
            _factor_image_row(img, np.int64(i), dy, dx, rad, gain, eps, out, planes, sigs)  # (prange's index is
            # unsigned: mixed with rad, float64)
    else:
        for i in range(img.shape[0]):
            _factor_image_row(img, i, dy, dx, rad, gain, eps, out, planes, sigs)


def factor_parallel(shape: tuple[int, ...]) -> bool:
    """Whether :func:`factor_kernel` runs the rows of an image of ``shape`` (H, W) in parallel: from
    LINEARISE_PARALLEL_MIN_PIXELS pixels on, as :func:`census_form_numba` does (a level's signatures cost about
    one linearisation); on smaller levels a parallel region's start and join cost more than the rows' work
    (task s320c: frame 0's signatures at 160 x 120 ~56 us serial, 32 us wall but ~2 x 32 us CPU on two threads,
    and under load a worker that is not running holds the region up)."""
    return shape[0] * shape[1] >= LINEARISE_PARALLEL_MIN_PIXELS and threads() > 1


@njit(**_ROWS)
def _factor_row(warped, c, sm, s0, sp, rad, gain, eps, ss, zero):  # noqa: ANN001, ANN201
    """The factor GAIN / (RMS + EPS) of channel c's warped row in slot s0 into ss (W), from its K = 8 neighbour
    differences (census.OFFSETS at distance rad, in their order) in the rows of slots sm, s0, sp (rad rows above,
    at, below), each padded with rad edge values on either side (:func:`_pad_row`), in one loop over the row: the
    float32 operations of :func:`_differences` (the sum of squares in OFFSETS' order, each square fused onto the
    sum so far by FASTMATH's contraction, as its K row loops computed it), without its K clamped row loops and row
    of differences stored and read back (:func:`_pair_diff` takes the differences again; task s320c: the warped
    signatures 86 -> 50 us a 160 x 120 level). ``zero`` is 0.0, passed in from Python so that the compiler
    cannot fold it: it makes the first square a rounded sum of its own (else the first two squares would be one
    fused sum, another last bit on 2-3 % of the pixels)."""
    inv_k = _F32(1.0) / _F32(_K)
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


@njit(inline="always", **_ROWS)
def _put(f0, q, rr, j, d, fac, pair, diff, sq):  # noqa: ANN001, ANN201
    """P and D of channel q at column j from the warped frame's neighbour difference d and its factor fac
    (:func:`_pair_diff`)."""
    a, b = f0[q, rr, j], d * fac
    pair[q, sq, j + 1] = a + b
    diff[q, sq, j] = b - a


@njit(**_ROWS)
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


@njit(inline="always", **_ROWS)
def _slot(dy, sm, s0, sp):  # noqa: ANN001, ANN201
    """The ring slot of the warped row at vertical offset dy: sm above, s0 at, sp below."""
    return sm if dy < 0 else (sp if dy > 0 else s0)


@njit(**_ROWS)
def _pad_row(warped, c, s, rad, w):  # noqa: ANN001, ANN201
    """The rad columns on either side of the warped row warped[c, s] (rad + W + rad long, the row from column
    rad) set to its edge values: what census.shifted's edge padding reads there."""
    for p in range(rad):
        warped[c, s, p] = warped[c, s, rad]
        warped[c, s, rad + w + p] = warped[c, s, rad + w - 1]


@njit(inline="always", **_ROWS)
def _sums4(pair, diff, q, su, sc, sd, j, d2, robust):  # noqa: ANN001, ANN201
    """The sums over four channels q .. q + 3 at column j, from P = F0 + F1 (``pair``, ring slots su, sc, sd: rows
    i - 1, i, i + 1, border-mirrored, column x at x + 1) at the pixel's left/right/up/down neighbours and
    D = F1 - F0 (``diff``, slot sc) at the pixel: with a channel's unscaled gradient ax = P(x + 1) - P(x - 1),
    ay = P(y + 1) - P(y - 1) (sums of both frames' central differences), the residual D at v0 and the weight wk,
    the sums of wk (ax ax, ax ay, ay ay, ax D, ay D)."""
    one = _F32(1.0)
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


@njit(inline="always", **_ROWS)
def _finish(out, i, j, ry, flow, keep, sk, s0, s1, s2, s3, s4):  # noqa: ANN001, ANN201
    """Pixel (i, j) of the form out (5, H, W) from its sums over the channels s0 .. s4 (:func:`_sums4`): the
    gradients' scales (x: 1/4, the mean of two central differences; y: ``ry``, 1/4 or 0 on the first and last
    rows) and the pixel's weight keep[sk, j], and the linearisation point flow (2, H, W): with rho_k(v) =
    a_k . (v - v0) + r0_k, g = sum_k w_k a_k r0_k - T v0 (census.signature_form's sum of w_k c_k a_k,
    c_k = r0_k - a_k . v0)."""
    q = _F32(0.25)
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
    return njit(**_ROWS)(form_row)


_form_row_first, _form_row_add, _form_row_last = (_make_form_row(*f) for f in ((True, False), (False, False),
                                                                                 (False, True)))


@njit(**_ROWS)
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


@njit(**_ROWS)
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
            _pair_diff(f0, c * k_n + k, rr, warped, c, (_slot(dy[k], sm, s0, sp), _slot(dy[k + 1], sm, s0, sp),
                                                         _slot(dy[k + 2], sm, s0, sp), _slot(dy[k + 3], sm, s0, sp)),
                       (rad + dx[k], rad + dx[k + 1], rad + dx[k + 2], rad + dx[k + 3]), s0, rad, ss, pair, diff, sq)


@njit(**_ROWS)
def _form_rows(out, i, pair, diff, keep, sk, flow, d2, robust):  # noqa: ANN001, ANN201
    """Row i of the form out (5, H, W) from the rings' rows i - 1, i, i + 1 and the row's weight keep[sk] (W)
    (:func:`_census_rows`)."""
    h = out.shape[1]
    su, sc, sd = (i + 2) % 3, (i + 3) % 3, (i + 4) % 3
    ry = _F32(0.25) if 0 < i < h - 1 else _F32(0.0)
    n = pair.shape[0]
    for q in range(0, n, 4):  # C K channels: K = 8, four per pass
        if q == 0:
            _form_row_first(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)
        elif q + 4 < n:
            _form_row_add(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)
        else:
            _form_row_last(pair, diff, q, su, sc, sd, out, i, d2, robust, ry, flow, keep, sk)


@njit(**_JIT)
def _ring_ends(t, n_c, m, w):  # noqa: ANN001, ANN201
    """Where each of :func:`_ring_views`' rings ends in ``rings`` (the layout's one definition; the last is the
    length :func:`ring_floats` allocates)."""
    q = n_c * _K
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


@njit(**_JIT)
def _ring_views(rings, t, n_c, m, w):  # noqa: ANN001, ANN201
    """:func:`census_kernel`'s per-thread rings for T = ``t`` threads, C = ``n_c`` channels, M = ``m`` warped rows,
    W = ``w`` columns, cut in this order from ``rings`` (1-D float32, :func:`ring_floats` long): warped
    (T, C, M, W + M - 1: rad = (M - 1) / 2 edge values on either side), keep (T, M, W), pair (T, C K, 3, W + 2),
    diff (T, C K, 3, W), ss (T, W) and the warp's row scratch taps (T, 9, W). One array argument instead of six:
    each array argument costs ~0.25 us of numba's dispatch per call (task fastcens)."""
    q = n_c * _K
    o1, o2, o3, o4, o5, o6 = _ring_ends(t, n_c, m, w)
    return (rings[:o1].reshape((t, n_c, m, w + m - 1)), rings[o1:o2].reshape((t, m, w)),
            rings[o2:o3].reshape((t, q, 3, w + 2)), rings[o3:o4].reshape((t, q, 3, w)),
            rings[o4:o5].reshape((t, w)), rings[o5:o6].reshape((t, 9, w)))


@njit(parallel=True, **_JIT)
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


def factor_numba(img: np.ndarray, params: CensusParams, out: np.ndarray | None = None,
                 sigs: np.ndarray | None = None) -> np.ndarray:
    """GAIN / (RMS + EPS) of an image (H, W) with :func:`factor_kernel`: (H, W) float32 (into ``out`` when
    given); census.signature = the neighbour differences (census.shifted) times it, which go into ``sigs``
    (K, H, W) float32 C-contiguous when given."""
    src = np.ascontiguousarray(img, dtype=_F32)
    out = np.empty(src.shape, _F32) if out is None else out
    factor_kernel(src, *_offset_arrays(params.radius), params.radius, _F32(params.gain), _F32(params.eps), out, None,
                  sigs, factor_parallel(src.shape))
    return out


def census_planes_numba(img: np.ndarray, params: CensusParams) -> np.ndarray:
    """fusion.census_planes with :func:`factor_kernel`: an image's (H, W) soft census signature, interleaved
    (H, W, K) float32 (census.signature's to float32 rounding)."""
    src = np.ascontiguousarray(img, dtype=_F32)
    out = np.empty(src.shape + (_K,), _F32)
    factor_kernel(src, *_offset_arrays(params.radius), params.radius, _F32(params.gain), _F32(params.eps),
                  np.empty(src.shape, _F32), out, None, factor_parallel(src.shape))
    return out


def level_signature_numba(frames: np.ndarray, params: CensusParams) -> tuple[np.ndarray, None]:
    """census.level_signature for the kernel: frame 0's signatures on one level of an image (H, W) or a channel
    stack (C, H, W), (C K, H, W) float32 (census.level_signature's f0 to float32 rounding; :func:`factor_numba`),
    and None (the gradients are taken inside :func:`census_kernel`, which reads f0's neighbours anyway). Taken
    once per level, not per warp: on fastest's small levels (73 x 48 .. 320 x 240) taking them in every warp made
    its kernel 1.1-1.35x slower per call (issue 25, task censreg; docs/engine.md, "The census data term"). The
    kernel once read the differences and the factor and multiplied them per warp; the level now holds the product
    (the same float32 product, so the same forms bit for bit; one plane less to read per warp; task fastcens).
    Into the calling thread's scratch array (workspace.py; as the grey path's level arrays, refine.grey_problem):
    valid until this thread's next level signature of that shape, i.e. for the level's warps."""
    stack = frames if frames.ndim == 3 else frames[None]
    n, h, w = stack.shape
    out = scratch("census.f0", (_K * n, h, w))
    factor = scratch("census.factor", (h, w))
    for c in range(n):
        factor_numba(stack[c], params, out=factor, sigs=out[c * _K:(c + 1) * _K])
    return out, None


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
    out = np.empty((5, h, w), _F32) if out is None else out
    census_kernel(np.ascontiguousarray(f0, dtype=_F32), np.ascontiguousarray(coefs, dtype=_F32),
                  np.ascontiguousarray(frames, dtype=_F32), np.ascontiguousarray(v0, dtype=_F32),
                  KERNEL_CODES[kernel], *_offset_arrays(params.radius), _F32(params.gain), _F32(params.eps), robust,
                  _F32(params.delta), _F32(1.0 / n_c), out, rings,
                  row_base(w), blocks, _F32(0.0))
    return out


@njit(cache=True, error_model="numpy", nogil=True)
def contrast_kernel(frames, dy, dx, st, ny, nx):  # noqa: ANN001, ANN201
    """census.median_contrast of frames (C, H, W) on the grid of pixels (1 + st i, 1 + st j), i < ny, j < nx:
    s(x) with the reference's float32 operations in its order (no fastmath: no contraction of sq + d d), and
    np.median's value (the middle one, or the float32 mean of the middle two), the largest over channels -- the
    same value bit for bit. A grid row at a time, neighbour by neighbour (the same sum per pixel, in the same
    order; the row loops vectorise where st is 1: 2-3x faster than pixel by pixel, task censlarge)."""
    n_c = frames.shape[0]
    k_n = dy.shape[0]
    values = np.empty(ny * nx, np.float32)
    best = _F32(-1.0)
    for c in range(n_c):
        for i in range(ny):
            y = 1 + st * i
            sq = values[i * nx:(i + 1) * nx]  # the row's sums, then its s(x)
            sq[:] = _F32(0.0)
            for k in range(k_n):
                yk, xk = y + dy[k], 1 + dx[k]
                for j in range(nx):  # unsigned column indices (numba_census's module doc: signed ones wrap around)
                    d = frames[c, yk, np.uint64(xk + st * j)] - frames[c, y, np.uint64(1 + st * j)]
                    sq[j] += d * d
            for j in range(nx):
                sq[j] = math.sqrt(sq[j] / _F32(k_n))
        best = max(best, median_f32(values))  # np.median's value
    return best


def median_contrast_numba(frames: np.ndarray) -> float:
    """census.median_contrast with :func:`contrast_kernel`: the same value bit for bit."""
    h, w = frames.shape[1:]
    if h < 3 or w < 3:
        return 0.0
    st = contrast_stride(h, w)
    return float(contrast_kernel(np.ascontiguousarray(frames, dtype=_F32), OFFSETS_DY, OFFSETS_DX, st,
                                 len(range(1, h - 1, st)), len(range(1, w - 1, st))))
