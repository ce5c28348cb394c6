"""numba kernels of the census data term (census.py, the numpy reference and test oracle).

:func:`factor_kernel` computes the factor GAIN / (RMS + EPS) that turns an image's neighbour differences into
its soft census signature (frame 0's, once per level: the level's signatures are that plane and the K
neighbour differences, :func:`level_signature_numba`), and on request the signature planes (the fusion's cost,
:func:`census_planes_numba`);
:func:`census_kernel` one warp's quadratic form in one pass over the level (census.census_form): frame 1's channels
sampled at x + v0 (a value-only warp, numba_warp.sample_row), both frames' signatures and the form, row by row, the
warped rows and the rows of P = F0 + F1 and D = F1 - F0 kept in per-thread rings (cache-resident) instead of
level-sized arrays (the judge's kernel, census.reliability, is numba_judge's). Grey and colour input are the
same kernel (C = 1 or 3 channels of K signatures each), and so are the neighbours at distance 1 and 2
(CensusParams.radius: the warped rows' ring holds 2 radius + 1 rows; the reliability figure compares the 3 x 3
signature either way). Rows run as whole-row loops (1-D views of C-contiguous arrays, so they vectorise). The same
quantities as the reference, the form's sums rearranged (:func:`_form_finish`): equal to float32 rounding
(test_census, 1e-5 of the form's largest value).

Importing this module raises ImportError when numba is not installed (backends.py then uses numpy).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numba import get_thread_id, njit, prange

from .census import OFFSETS, OFFSETS_DX, OFFSETS_DY, CensusParams, contrast_stride
from .numba_backend import LINEARISE_PARALLEL_MIN_PIXELS, row_scratch, threads
from .numba_kernels import FASTMATH
from .numba_warp import sample_row
from .warping import KERNEL_CODES
from .workspace import scratch

# the solver's fastmath flags, not fastmath=True: with reassoc/arcp the census kernels computed other last bits when
# compiled in a process than when read from numba's cache (a new install's first process got census flows 2e-3 px
# away from every later process's; test_cold_start.test_kernels_compute_the_same_compiled_or_cached)
_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)
_F32 = np.float32
_K = len(OFFSETS)


def _offset_arrays(radius: int) -> tuple[np.ndarray, np.ndarray]:
    """The signature's neighbour offsets at distance ``radius`` (census.offsets) as (dy, dx) int64 arrays (K)."""
    return (OFFSETS_DY, OFFSETS_DX) if radius == 1 else (OFFSETS_DY * radius, OFFSETS_DX * radius)


def _make_diff_row(edge: bool):  # noqa: ANN202
    """dst = neighbour - centre and ss += dst^2 over one row (1-D views; vectorises); with ``edge`` one neighbour
    value, neighbour[0], for every pixel (the columns whose neighbour is clamped to the row's end). ``edge`` is a
    compile-time constant: one source, two kernels (:data:`_diff_row`, :data:`_diff_edge`), each as fast as its
    loop written out (the factor kernel's time within 1-2 %;
    git show 4983857:bench/results/census_cost/onesig/summary.md)."""

    def diff_row(neighbour, centre, dst, ss):  # noqa: ANN001, ANN202
        for j in range(dst.shape[0]):
            d = (neighbour[0] if edge else neighbour[j]) - centre[j]  # (neighbour[0 if edge else j]: 15 % slower)
            dst[j] = d
            ss[j] += d * d

    diff_row.__name__ = diff_row.__qualname__ = "diff_edge" if edge else "diff_row"
    return njit(**_JIT)(diff_row)


_diff_row, _diff_edge = _make_diff_row(False), _make_diff_row(True)


@njit(**_JIT)
def _neighbour_differences(up, centre, down, dy, dx, out, i, ss):  # noqa: ANN001, ANN201
    """The K neighbour differences of one image row ``centre`` (W), whose neighbour rows are ``up`` and ``down``
    (rows y - r and y + r for offsets (dy, dx) of distance r, clamped to the image: edge values), into the rows
    out[k, i] (k < K) of out (K, ., W), column neighbours clamped to the row; and their sum of squares added to
    ss (W). Channel by channel over whole rows (1-D views of C-contiguous arrays,
    so that the loops vectorise)."""
    w = centre.shape[0]
    k_n = dy.shape[0]
    for k in range(k_n):
        src = up if dy[k] < 0 else (down if dy[k] > 0 else centre)
        dst = out[k, i]
        d = dx[k]
        m = min(abs(d), w)  # the columns whose neighbour is clamped to the row's end
        if d == 0:
            _diff_row(src, centre, dst, ss)
        elif d > 0:  # the last d columns' neighbour is the last column
            _diff_row(src[m:], centre[:w - m], dst[:w - m], ss[:w - m])
            _diff_edge(src[w - 1:], centre[w - m:], dst[w - m:], ss[w - m:])
        else:
            _diff_row(src[:w - m], centre[m:], dst[m:], ss[m:])
            _diff_edge(src[:1], centre[:m], dst[:m], ss[:m])


@njit(**_JIT)
def _differences(up, centre, down, dy, dx, gain, eps, out, i, ss):  # noqa: ANN001, ANN201
    """:func:`_neighbour_differences` and into ss (W) the factor that makes them the signature,
    GAIN / (RMS + EPS) (census.signature)."""
    k_n = dy.shape[0]
    ss[:] = 0.0
    _neighbour_differences(up, centre, down, dy, dx, out, i, ss)
    inv_k = _F32(1.0) / _F32(k_n)  # float32 throughout (ss / k_n, an int, promoted the row to float64)
    for j in range(centre.shape[0]):
        ss[j] = gain / (math.sqrt(ss[j] * inv_k) + eps)


@njit(parallel=True, **_JIT)
def factor_kernel(img, dy, dx, rad, gain, eps, out, planes, diffs):  # noqa: ANN001, ANN201
    """The factor GAIN / (RMS + EPS) of img (H, W) into out (H, W) (:func:`_differences`) for the offsets (dy, dx)
    at distance ``rad``, neighbours clamped to the image (edge values); unless ``diffs`` is None (a compile-time
    case), the neighbour differences themselves into diffs (K, H, W) (a census level's, :func:`census_kernel`
    reads them); unless ``planes`` is None (a compile-time case), also the signature -- the differences times
    the factor, as :func:`census_kernel` forms it; census.signature to float32 rounding -- into planes (H, W, K),
    interleaved (fusion.census_planes; read only when ``diffs`` is None). Rows in parallel."""
    h, w = img.shape
    k_n = dy.shape[0]
    for i in prange(h):
        up, centre, down = img[max(i - rad, 0)], img[i], img[min(i + rad, h - 1)]
        if diffs is not None:
            _differences(up, centre, down, dy, dx, gain, eps, diffs, i, out[i])
        else:
            tmp = np.empty((k_n, 1, w), np.float32)
            _differences(up, centre, down, dy, dx, gain, eps, tmp, 0, out[i])
            if planes is not None:
                for j in range(w):
                    for k in range(k_n):
                        planes[i, j, k] = tmp[k, 0, j] * out[i, j]


@njit(**_JIT)
def _pair_row(d0, s0, d, ss, p, r):  # noqa: ANN001, ANN201
    """With F0 = d0 s0 (frame 0's neighbour differences times its factor, :func:`factor_kernel`) and F1 = d ss
    (the warped frame's, :func:`_differences`) over one row (1-D views, W): p[1:W + 1] = F0 + F1 and
    r = F1 - F0; p's ends mirror its columns 1 and W - 2 (p[0] = P(1), p[W + 1] = P(W - 2); both P(0) when
    W == 1), so that P(x + 1) - P(x - 1) is 0 on the border columns."""
    w = r.shape[0]
    for j in range(w):
        a, b = d0[j] * s0[j], d[j] * ss[j]
        p[j + 1] = a + b
        r[j] = b - a
    p[0] = p[min(2, w)]
    p[w + 1] = p[max(w - 1, 1)]


def _make_form_row(first: bool):  # noqa: ANN202
    """The sums of four channels along one row segment (1-D views; vectorises; four per pass: the sums are
    loaded and stored a quarter as often as one per pass), from P = F0 + F1 at the pixels' left/right/up/down
    neighbours and D = F1 - F0 at the pixels (p, e, x, y: the four channels): with a channel's unscaled gradient
    ax = P(x + 1) - P(x - 1), ay = P(y + 1) - P(y - 1) (sums of both frames' central differences), the residual
    D at v0 and the weight wk, s0..s4 += wk (ax ax, ax ay, ay ay, ax D, ay D) of each (``first``: s0..s4 = the
    sums, the row's first pass; no zeroing pass). ``first`` is a compile-time constant: one source, two kernels
    (:data:`_form_row_first`, :data:`_form_row_add`). :func:`_form_finish` turns the sums over the channels into
    the form."""

    def form_row(pl, pr, pu, pd, pc, el, er, eu, ed, ec, xl, xr, xu, xd, xc, yl, yr, yu, yd, yc,  # noqa: ANN001, ANN202
                 s0, s1, s2, s3, s4, d2, robust):
        one = _F32(1.0)
        for j in range(s0.shape[0]):
            ax, ay, r0 = pr[j] - pl[j], pd[j] - pu[j], pc[j]
            bx, by, r1 = er[j] - el[j], ed[j] - eu[j], ec[j]
            cx, cy, r2 = xr[j] - xl[j], xd[j] - xu[j], xc[j]
            dx, dy, r3 = yr[j] - yl[j], yd[j] - yu[j], yc[j]
            wa = one / math.sqrt(r0 * r0 + d2) if robust else one
            wb = one / math.sqrt(r1 * r1 + d2) if robust else one
            wc = one / math.sqrt(r2 * r2 + d2) if robust else one
            wd = one / math.sqrt(r3 * r3 + d2) if robust else one
            wax, way, wbx, wby = wa * ax, wa * ay, wb * bx, wb * by
            wcx, wcy, wdx, wdy = wc * cx, wc * cy, wd * dx, wd * dy
            t0 = (wax * ax + wbx * bx) + (wcx * cx + wdx * dx)
            t1 = (wax * ay + wbx * by) + (wcx * cy + wdx * dy)
            t2 = (way * ay + wby * by) + (wcy * cy + wdy * dy)
            t3 = (wax * r0 + wbx * r1) + (wcx * r2 + wdx * r3)
            t4 = (way * r0 + wby * r1) + (wcy * r2 + wdy * r3)
            if first:
                s0[j], s1[j], s2[j], s3[j], s4[j] = t0, t1, t2, t3, t4
            else:
                s0[j] += t0
                s1[j] += t1
                s2[j] += t2
                s3[j] += t3
                s4[j] += t4

    form_row.__name__ = form_row.__qualname__ = "form_row_first" if first else "form_row_add"
    return njit(**_JIT)(form_row)


_form_row_first, _form_row_add = _make_form_row(True), _make_form_row(False)


@njit(**_JIT)
def _form_finish(out, i, ry, vx, vy, keep):  # noqa: ANN001, ANN201
    """Row i of out (5, H, W) from the channels' sums of :func:`_make_form_row` in place: the gradients' scales
    (x: 1/4, the mean of two central differences; y: ``ry``, 1/4 or 0 on the first and last rows) and the
    pixel's weight ``keep`` (W), and the linearisation point: with rho_k(v) = a_k . (v - v0) + r0_k,
    g = sum_k w_k a_k r0_k - T v0 (census.signature_form's sum of w_k c_k a_k, c_k = r0_k - a_k . v0)."""
    o0, o1, o2, o3, o4 = out[0, i], out[1, i], out[2, i], out[3, i], out[4, i]
    q = _F32(0.25)
    for j in range(o0.shape[0]):
        t11 = keep[j] * q * q * o0[j]
        t12 = keep[j] * q * ry * o1[j]
        t22 = keep[j] * ry * ry * o2[j]
        o0[j] = t11
        o1[j] = t12
        o2[j] = t22
        o3[j] = keep[j] * q * o3[j] - t11 * vx[j] - t12 * vy[j]
        o4[j] = keep[j] * ry * o4[j] - t12 * vx[j] - t22 * vy[j]


@njit(**_JIT)
def _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out, r0, r1,  # noqa: ANN001, ANN201
                 warped, keep, pair, diff, temp, ss, taps, base):
    """Rows r0 .. r1 - 1 of :func:`census_kernel`, with one thread's rings: warped (C, M, W) and keep (M, W)
    hold rows of frame 1 warped and its weight, row r in slot r mod M (M = 2 rad + 1, rad the offsets'
    distance: 3 rows for the 3 x 3 neighbours, 5 for the ring at distance 2); pair (C K, 3, W + 2) and diff
    (C K, 3, W) rows of P = F0 + F1 (border-mirrored: :func:`_pair_row`) and D = F1 - F0 (F1 the warped frame's
    signatures), row r in slot r mod 3; temp (K, 1, W) and ss (W) one channel's neighbour differences in the
    warped frame and its factor (:func:`_differences`). Row r of the rings stands for the image row clamped to
    0 .. H - 1 (so the signature of the first and last rows sees edge values, as census.signature), and output
    row i needs signature rows i - 1 .. i + 1, those warped rows i - 1 - rad .. i + 1 + rad: each block warps
    its rows and 1 + rad on either side, each once. (The rings' rows -1 and H are read for the first and last
    rows' y-gradient, whose weight is 0.) Each step's work is its own function (:func:`_pair_rows`,
    :func:`_form_rows`): written inline here the same code ran ~25 % slower."""
    h = f0.shape[1]
    m = warped.shape[1]
    rad = (m - 1) // 2
    for r in range(r0 - 1 - rad, r1 + 1 + rad):  # warp row r, the signatures of row r - rad, output row r - rad - 1
        s = (r + 2 * m) % m
        sample_row(coefs, frames, flow, min(max(r, 0), h - 1), kernel, weight, warped, s, keep[s], taps, base)
        rr = r - rad
        if rr >= r0 - 1:  # the signatures of row rr (warped rows rr - rad, rr, rr + rad) into diff, then P and D
            _pair_rows(f0, min(max(rr, 0), h - 1), warped, (rr - rad + 2 * m) % m, (rr + 2 * m) % m, s,
                       (rr + 3) % 3, dy, dx, gain, eps, pair, diff, temp, ss)
        if rr - 1 >= r0:  # output row i: signature rows i - 1, i, i + 1 are in the ring
            _form_rows(out, rr - 1, pair, diff, keep[(rr - 1 + 2 * m) % m], flow, d2, robust)


@njit(**_JIT)
def _pair_rows(f0, rr, warped, sm, s0, sp, sq, dy, dx, gain, eps, pair, diff, temp, ss):  # noqa: ANN001, ANN201
    """P and D of one row (image row rr) into ring slot sq of pair and diff, from the warped rows in slots sm,
    s0, sp (rad rows above, at, rad below) and frame 0's level f0 ((1 + K) C, H, W): its channels' factors and
    neighbour differences (:func:`level_signature_numba`) (:func:`_census_rows`)."""
    k_n = dy.shape[0]
    n_c = warped.shape[0]
    for c in range(n_c):
        _differences(warped[c, sm], warped[c, s0], warped[c, sp], dy, dx, gain, eps, temp, 0, ss)
        for k in range(k_n):
            q = c * k_n + k
            _pair_row(f0[n_c + q, rr], f0[c, rr], temp[k, 0], ss, pair[q, sq], diff[q, sq])


@njit(**_JIT)
def _form_rows(out, i, pair, diff, keep, flow, d2, robust):  # noqa: ANN001, ANN201
    """Row i of the form out (5, H, W) from the rings' rows i - 1, i, i + 1 and the row's weight keep (W)
    (:func:`_census_rows`)."""
    h = out.shape[1]
    su, sc, sd = (i + 2) % 3, (i + 3) % 3, (i + 4) % 3
    ry = _F32(0.25) if 0 < i < h - 1 else _F32(0.0)
    w = diff.shape[2]
    o0, o1, o2, o3, o4 = out[0, i], out[1, i], out[2, i], out[3, i], out[4, i]
    for q in range(0, pair.shape[0], 4):  # C K channels: K = 8, four per pass
        p, e, x, y = pair[q], pair[q + 1], pair[q + 2], pair[q + 3]  # rows (W + 2), border-mirrored: x - 1 at
        rows = (p[sc, :w], p[sc, 2:], p[su, 1:w + 1], p[sd, 1:w + 1], diff[q, sc],  # [:w], x + 1 at [2:]
                e[sc, :w], e[sc, 2:], e[su, 1:w + 1], e[sd, 1:w + 1], diff[q + 1, sc],
                x[sc, :w], x[sc, 2:], x[su, 1:w + 1], x[sd, 1:w + 1], diff[q + 2, sc],
                y[sc, :w], y[sc, 2:], y[su, 1:w + 1], y[sd, 1:w + 1], diff[q + 3, sc], o0, o1, o2, o3, o4, d2, robust)
        if q == 0:
            _form_row_first(*rows)
        else:
            _form_row_add(*rows)
    _form_finish(out, i, ry, flow[0, i], flow[1, i], keep)


@njit(parallel=True, **_JIT)
def census_kernel(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, delta, weight, out,  # noqa: ANN001, ANN201
                  warped, keep, pair, diff, temp, ss, taps, base, blocks):
    """census.census_form in one pass: out (5, H, W) from frame 0's level f0 ((1 + K) C, H, W) (its channels'
    factors and neighbour differences, :func:`level_signature_numba`), frame 1's interpolation coefficients
    ``coefs`` and channels ``frames`` (C, H, W) and the flow v0 (2, H, W); each pixel's weight ``weight`` (1 / C)
    inside, 0 where x + v0 leaves the image; the signatures' offsets (dy, dx) at distance rad, the warped rings'
    M = 2 rad + 1 rows. The rows in ``blocks`` contiguous blocks, in parallel when more than one
    (:func:`_census_rows`; per-thread rings warped (T, C, M, W), keep (T, M, W), pair (T, C K, 3, W + 2),
    diff (T, C K, 3, W), temp (T, K, 1, W), ss (T, W) and the warp's row scratch taps (T, 9, W), base (T, 2, W)
    int32)."""
    h = f0.shape[1]
    d2 = delta * delta
    if blocks > 1:
        for b in prange(blocks):
            t = get_thread_id()
            _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out,
                         b * h // blocks, (b + 1) * h // blocks, warped[t], keep[t], pair[t], diff[t], temp[t], ss[t],
                         taps[t], base[t])
    else:
        _census_rows(f0, coefs, frames, flow, kernel, dy, dx, gain, eps, robust, d2, weight, out, 0, h,
                     warped[0], keep[0], pair[0], diff[0], temp[0], ss[0], taps[0], base[0])


def factor_numba(img: np.ndarray, params: CensusParams, out: np.ndarray | None = None,
                 diffs: np.ndarray | None = None) -> np.ndarray:
    """GAIN / (RMS + EPS) of an image (H, W) with :func:`factor_kernel`: (H, W) float32 (into ``out`` when
    given); census.signature = the neighbour differences (census.shifted) times it, which go into ``diffs``
    (K, H, W) float32 C-contiguous when given."""
    src = np.ascontiguousarray(img, dtype=_F32)
    out = np.empty(src.shape, _F32) if out is None else out
    factor_kernel(src, *_offset_arrays(params.radius), params.radius, _F32(params.gain), _F32(params.eps), out, None,
                  diffs)
    return out


def census_planes_numba(img: np.ndarray, params: CensusParams) -> np.ndarray:
    """fusion.census_planes with :func:`factor_kernel`: an image's (H, W) soft census signature, interleaved
    (H, W, K) float32 (census.signature's to float32 rounding)."""
    src = np.ascontiguousarray(img, dtype=_F32)
    out = np.empty(src.shape + (_K,), _F32)
    factor_kernel(src, *_offset_arrays(params.radius), params.radius, _F32(params.gain), _F32(params.eps),
                  np.empty(src.shape, _F32), out, None)
    return out


def level_signature_numba(frames: np.ndarray, params: CensusParams) -> tuple[np.ndarray, None]:
    """census.level_signature for the kernel: frame 0's signatures on one level of an image (H, W) or a channel
    stack (C, H, W) as the level ((1 + K) C, H, W) -- the channels' factors, then their K neighbour differences
    each (:func:`factor_numba`) -- and None (the gradients are taken inside :func:`census_kernel`, which reads
    f0's neighbours anyway). :func:`census_kernel` scales the differences by the factor (the signatures as
    census.signature computes them, value for value; :func:`level_signatures` expands them, for checks). The
    differences are taken once per level, not per warp: on fastest's small levels (73 x 48 .. 320 x 240) taking
    them in every warp made its kernel 1.1-1.35x slower per call (issue 25, task censreg; docs/engine.md, "The
    census data term"). Into the calling thread's scratch array (workspace.py; as the grey path's level arrays,
    refine.grey_problem): valid until this thread's next level signature of that shape, i.e. for the level's
    warps."""
    stack = frames if frames.ndim == 3 else frames[None]
    n, h, w = stack.shape
    out = scratch("census.f0", ((1 + _K) * n, h, w))
    for c in range(n):
        factor_numba(stack[c], params, out=out[c], diffs=out[n + c * _K:n + (c + 1) * _K])
    return out, None


def level_signatures(level: np.ndarray) -> np.ndarray:
    """The signatures (C K, H, W) that a level of :func:`level_signature_numba` ((1 + K) C, H, W) stands for:
    each channel's K neighbour differences times its factor, as :func:`census_kernel` forms them (numpy; for
    checks)."""
    n = level.shape[0] // (1 + _K)
    return np.concatenate([level[n + c * _K:n + (c + 1) * _K] * level[c] for c in range(n)]).astype(np.float32)


def census_form_numba(f0: np.ndarray, g0: None, coefs: np.ndarray, frames: np.ndarray, v0: np.ndarray, kernel: str,
                      robust: bool, params: CensusParams, out: np.ndarray | None = None) -> np.ndarray:
    """census.census_form with :func:`census_kernel`: the quadratic form (5, H, W) of one warp, f0 frame 0's level
    ((1 + K) C, H, W) (:func:`level_signature_numba`). The rings are the
    calling thread's scratch arrays (workspace.py); the rows run in one block per thread on levels of
    LINEARISE_PARALLEL_MIN_PIXELS or more (else in one); the form itself is fresh (a Bregman step reuses the
    last warp's), or ``out`` (5, H, W) float32 C-contiguous when given."""
    n_c, h, w = frames.shape
    t = threads()
    blocks = min(t, h) if t > 1 and h * w >= LINEARISE_PARALLEL_MIN_PIXELS else 1
    n, q = numba.config.NUMBA_NUM_THREADS, n_c * _K  # per-thread rings: get_thread_id's range
    m = 2 * params.radius + 1  # warped rows per ring (_census_rows)
    rings = (scratch("census.warped", (n, n_c, m, w)), scratch("census.keep", (n, m, w)),
             scratch("census.pair", (n, q, 3, w + 2)), scratch("census.diff", (n, q, 3, w)),
             scratch("census.temp", (n, _K, 1, w)), scratch("census.ss", (n, w)), *row_scratch(w))
    out = np.empty((5, h, w), _F32) if out is None else out
    census_kernel(np.ascontiguousarray(f0, dtype=_F32), np.ascontiguousarray(coefs, dtype=_F32),
                  np.ascontiguousarray(frames, dtype=_F32), np.ascontiguousarray(v0, dtype=_F32),
                  KERNEL_CODES[kernel], *_offset_arrays(params.radius), _F32(params.gain), _F32(params.eps), robust,
                  _F32(params.delta),
                  _F32(1.0 / n_c), out, *rings, blocks)
    return out


@njit(cache=True, error_model="numpy", nogil=True)
def contrast_kernel(frames, dy, dx, st, ny, nx):  # noqa: ANN001, ANN201
    """census.median_contrast of frames (C, H, W) on the grid of pixels (1 + st i, 1 + st j), i < ny, j < nx:
    s(x) with the reference's float32 operations in its order (no fastmath: no contraction of sq + d d), and
    np.median's value (the middle one, or the float32 mean of the middle two), the largest over channels -- the
    same value bit for bit."""
    n_c = frames.shape[0]
    k_n = dy.shape[0]
    n = ny * nx
    values = np.empty(n, np.float32)
    best = _F32(-1.0)
    for c in range(n_c):
        for i in range(ny):
            y = 1 + st * i
            for j in range(nx):
                x = 1 + st * j
                centre = frames[c, y, x]
                sq = _F32(0.0)
                for k in range(k_n):
                    d = frames[c, y + dy[k], x + dx[k]] - centre
                    sq += d * d
                values[i * nx + j] = math.sqrt(sq / _F32(k_n))
        part = np.partition(values, n // 2)  # as np.median: the middle value, or the float32 mean of the middle two
        mid = part[n // 2] if n % 2 else (part[:n // 2].max() + part[n // 2]) / _F32(2.0)
        best = max(best, mid)
    return best


def median_contrast_numba(frames: np.ndarray) -> float:
    """census.median_contrast with :func:`contrast_kernel`: the same value bit for bit."""
    h, w = frames.shape[1:]
    if h < 3 or w < 3:
        return 0.0
    st = contrast_stride(h, w)
    return float(contrast_kernel(np.ascontiguousarray(frames, dtype=_F32), OFFSETS_DY, OFFSETS_DX, st,
                                 len(range(1, h - 1, st)), len(range(1, w - 1, st))))
