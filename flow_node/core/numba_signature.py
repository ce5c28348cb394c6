"""numba kernels of the census term's level signatures (census.py, the numpy reference and test oracle): split from
numba_census.py (task s320c), which re-exports them and holds the per-warp form kernel.

:func:`factor_kernel` computes the factor GAIN / (RMS + EPS) that turns an image's neighbour differences into
its soft census signature, and the signatures: frame 0's once per level (:func:`level_signature_numba`), and on
request interleaved (the fusion's cost, :func:`census_planes_numba`); :func:`contrast_kernel` a level's median
contrast (census.median_contrast). Rows run as whole-row loops over C-contiguous arrays (unit stride, so they
vectorise), the helpers taking the whole arrays and row indices, not row views (numba_census's module doc). The
constants and flags here are numba_census's too.

Importing this module raises ImportError when numba is not installed (backends.py then uses numpy).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .census import OFFSETS, OFFSETS_DX, OFFSETS_DY, CensusParams, contrast_stride
from .numba_backend import LINEARISE_PARALLEL_MIN_PIXELS, threads
from .numba_kernels import FASTMATH
from .numba_sort import median_f32
from .workspace import scratch

# the solver's fastmath flags, not fastmath=True: with reassoc/arcp the census kernels computed other last bits when
# compiled in a process than when read from numba's cache (a new install's first process got census flows 2e-3 px
# away from every later process's; test_cold_start.test_kernels_compute_the_same_compiled_or_cached)
JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)
ROWS = dict(JIT, _nrt=False)
F32 = np.float32
K = len(OFFSETS)


def offset_arrays(radius: int) -> tuple[np.ndarray, np.ndarray]:
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
    return njit(**ROWS)(diff_span)


_diff_span, _diff_edge = _make_diff_span(False), _make_diff_span(True)


@njit(inline="always", **ROWS)
def neighbour_row(dy, above, at, below):  # noqa: ANN001, ANN201
    """The row (an index or a ring slot) that holds the neighbours at vertical offset dy: ``above`` for dy < 0,
    ``below`` for dy > 0, else ``at`` (here and numba_census._pair_rows)."""
    return above if dy < 0 else (below if dy > 0 else at)


@njit(**ROWS)
def _neighbour_differences(img, ru, rc, rd, dy, dx, out, i, ss):  # noqa: ANN001, ANN201
    """The K neighbour differences of the row ``rc`` of img (., W), whose neighbour rows are ``ru`` and ``rd``
    (rows y - r and y + r for offsets (dy, dx) of distance r, clamped to the image: edge values), into the rows
    out[k, i] (k < K) of out (K, ., W), column neighbours clamped to the row; and their sum of squares added to
    ss (W). Channel by channel over whole rows (unit stride, so that the loops vectorise)."""
    w = img.shape[1]
    k_n = dy.shape[0]
    for k in range(k_n):
        r = neighbour_row(dy[k], ru, rc, rd)
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


@njit(**ROWS)
def _differences(img, ru, rc, rd, dy, dx, gain, eps, out, i, ss):  # noqa: ANN001, ANN201
    """:func:`_neighbour_differences` and into ss (W) the factor that makes them the signature,
    GAIN / (RMS + EPS) (census.signature)."""
    k_n = dy.shape[0]
    ss[:] = 0.0
    _neighbour_differences(img, ru, rc, rd, dy, dx, out, i, ss)
    inv_k = F32(1.0) / F32(k_n)  # float32 throughout (ss / k_n, an int, promoted the row to float64)
    for j in range(img.shape[1]):
        ss[j] = gain / (math.sqrt(ss[j] * inv_k) + eps)


@njit(**JIT)
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


@njit(parallel=True, **JIT)
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


def factor_numba(img: np.ndarray, params: CensusParams, out: np.ndarray | None = None,
                 sigs: np.ndarray | None = None) -> np.ndarray:
    """GAIN / (RMS + EPS) of an image (H, W) with :func:`factor_kernel`: (H, W) float32 (into ``out`` when
    given); census.signature = the neighbour differences (census.shifted) times it, which go into ``sigs``
    (K, H, W) float32 C-contiguous when given."""
    src = np.ascontiguousarray(img, dtype=F32)
    out = np.empty(src.shape, F32) if out is None else out
    factor_kernel(src, *offset_arrays(params.radius), params.radius, F32(params.gain), F32(params.eps), out, None,
                  sigs, factor_parallel(src.shape))
    return out


def census_planes_numba(img: np.ndarray, params: CensusParams) -> np.ndarray:
    """fusion.census_planes with :func:`factor_kernel`: an image's (H, W) soft census signature, interleaved
    (H, W, K) float32 (census.signature's to float32 rounding)."""
    src = np.ascontiguousarray(img, dtype=F32)
    out = np.empty(src.shape + (K,), F32)
    factor_kernel(src, *offset_arrays(params.radius), params.radius, F32(params.gain), F32(params.eps),
                  np.empty(src.shape, F32), out, None, factor_parallel(src.shape))
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
    out = scratch("census.f0", (K * n, h, w))
    factor = scratch("census.factor", (h, w))
    for c in range(n):
        factor_numba(stack[c], params, out=factor, sigs=out[c * K:(c + 1) * K])
    return out, None


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
    best = F32(-1.0)
    for c in range(n_c):
        for i in range(ny):
            y = 1 + st * i
            sq = values[i * nx:(i + 1) * nx]  # the row's sums, then its s(x)
            sq[:] = F32(0.0)
            for k in range(k_n):
                yk, xk = y + dy[k], 1 + dx[k]
                for j in range(nx):  # unsigned column indices (numba_census's module doc: signed ones wrap around)
                    d = frames[c, yk, np.uint64(xk + st * j)] - frames[c, y, np.uint64(1 + st * j)]
                    sq[j] += d * d
            for j in range(nx):
                sq[j] = math.sqrt(sq[j] / F32(k_n))
        best = max(best, median_f32(values))  # np.median's value
    return best


def median_contrast_numba(frames: np.ndarray) -> float:
    """census.median_contrast with :func:`contrast_kernel`: the same value bit for bit."""
    h, w = frames.shape[1:]
    if h < 3 or w < 3:
        return 0.0
    st = contrast_stride(h, w)
    return float(contrast_kernel(np.ascontiguousarray(frames, dtype=F32), OFFSETS_DY, OFFSETS_DX, st,
                                 len(range(1, h - 1, st)), len(range(1, w - 1, st))))
