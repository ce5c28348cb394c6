"""The fusion stage with numba kernels: :func:`fuse_numba` (fusion.fuse), :func:`consistent_numba`
(initialise.forward_backward_consistent) and :func:`planes_numba` (fusion.level_planes), the numba backend's fields.

The numpy references chain a dozen whole-image passes with temporaries per candidate (maps, an OpenCV
remap of the (h, w, 3) planes, masks, the difference summed over its last axis, a (K, h, w) stack of
costs, argmin, take_along_axis, the label look-ups of fill_undecided); here each is one pass: the masked
residual of a candidate (sampling frame 1 itself), the choice over all candidates, the undecided pixels'
choice and the gather of the fused flow; the forward-backward check is one pass too. The box means
(cv2.boxFilter) and the distance transform stay OpenCV's. The bilinear sample is computed as OpenCV 5's
remap computes it (two lerps along x, one along y, each a fused multiply-add) and the rest of the
arithmetic is the references' float32 in the same order, so with OpenCV 5 the results equal the
references' bit for bit; OpenCV 4.x snaps remap positions to 1/32 px, so there the references differ
slightly and these kernels are the exact ones (test_fusion_numba.py). The census cost planes are the census
term's signature kernel's (numba_census.factor_kernel): the reference's to float32 rounding, which moved no fusion
choice on the large set (docs/engine.md, round onesig). Rows run in parallel on levels of
numba_backend.PARALLEL_MIN_PIXELS or more.
"""

from __future__ import annotations

from contextlib import AbstractContextManager

import cv2
import numpy as np
from numba import njit, prange

from . import numba_backend as nb
from .fusion import (
    CONSISTENT_COST,
    FUSION_MARGIN,
    FUSION_WINDOW,
    PROPAGATE_INCONSISTENT,
    REMAP_CHANNELS,
    CostPlanes,
    cost_census,
    planes,
)
from .initialise import FB_TOLERANCE_PX
from .photometric import compares_signatures

_F32 = np.float32
# no fastmath: the costs are inf where no data decides, and fastmath may assume there is no inf
_JIT = dict(cache=True, error_model="numpy", nogil=True)
_JIT_CONTRACT = dict(_JIT, fastmath={"contract"})  # a + t (b - a) as one fused multiply-add, like OpenCV
_MIN_SUPPORT = _F32(0.05)  # fusion.data_cost: a box with less inside support than this has no cost
_TINY = _F32(1e-6)
_NO_LABELS, _NO_NEAR = np.zeros((1, 1), np.int32), np.zeros(1, np.int64)  # settle_kernel's dummies (no fill)


@njit(**_JIT_CONTRACT)
def _lerp(a, b, t):  # noqa: ANN001, ANN202
    """a + t (b - a), contracted to one fused multiply-add where the CPU has it (as OpenCV's remap does)."""
    return a + t * (b - a)


@njit(**_JIT)
def _bilinear_taps(x, y, h, w):  # noqa: ANN001, ANN202
    """Columns, rows and fractions of a bilinear sample at (x, y) inside an (h, w) image (the far taps
    clamped to the last column / row, where their weight is 0 or the position is the last pixel)."""
    x0, y0 = min(np.int64(x), w - 1), min(np.int64(y), h - 1)  # x, y >= 0: truncation is floor
    return x0, min(x0 + 1, w - 1), x - _F32(x0), y0, min(y0 + 1, h - 1), y - _F32(y0)


@njit(**_JIT)
def _residual_row(out, s0, s1, flow, i):  # noqa: ANN001, ANN202
    """Row i of fusion.data_cost's two box inputs for the candidate ``flow`` (2, h, w), interleaved:
    out[..., 0] = |S1(x + f) - S0(x)|_1 over the P cost planes of s0, s1 (h, w, P; fusion.cost_planes) where
    x + f stays inside the image, else 0; out[..., 1] = that inside mask (1 / 0). S1 is sampled bilinearly
    (fusion.warp_residual: OpenCV's remap, which OpenCV 5 computes exactly so: per plane two lerps along x,
    one along y), and the planes are summed in groups of fusion.REMAP_CHANNELS as the reference sums them."""
    h, w, n = s0.shape[0], s0.shape[1], s0.shape[2]
    right, bottom = _F32(w - 1), _F32(h - 1)
    y_row = _F32(i)
    for j in range(w):
        x, y = _F32(j) + flow[0, i, j], y_row + flow[1, i, j]
        if x >= 0 and x <= right and y >= 0 and y <= bottom:
            xa, xb, ax, ya, yb, ay = _bilinear_taps(x, y, h, w)
            r = _F32(0)
            for g in range(0, n, REMAP_CHANNELS):
                part = _F32(0)
                for c in range(g, min(g + REMAP_CHANNELS, n)):
                    top = _lerp(s1[ya, xa, c], s1[ya, xb, c], ax)
                    part += abs(_lerp(top, _lerp(s1[yb, xa, c], s1[yb, xb, c], ax), ay) - s0[i, j, c])
                r += part
            out[i, j, 0] = r
            out[i, j, 1] = 1
        else:
            out[i, j, 0] = 0
            out[i, j, 1] = 0


@njit(**_JIT)
def _choose_row(choice, undecided, boxed, ok, checked, options, margin, consistent_cost, i):  # noqa: ANN001, ANN202
    """Row i of fusion.fuse's choice: per pixel the candidate of least cost (boxed (K, h, w, 2): box means
    of the masked residual and of the mask; the reference's cost times ``margin``; a ``checked``
    candidate's cost times ``consistent_cost`` where ``ok`` (K, h, w), or inf where not ``ok`` with
    options[0] (only_consistent)), first on ties; ``undecided`` where every cost is inf, or (options[1],
    propagate) the winner is checked and not ok. Returns the row's count of undecided pixels."""
    k_n, w = boxed.shape[0], boxed.shape[2]
    only_consistent, propagate = options[0], options[1]
    inf = _F32(np.inf)
    count = 0
    for j in range(w):
        best = inf
        pick = 0
        for k in range(k_n):
            support = boxed[k, i, j, 1]
            cost = inf if support < _MIN_SUPPORT else boxed[k, i, j, 0] / max(support, _TINY)
            if k == 0:
                cost *= margin
            if checked[k]:
                if only_consistent:
                    if not ok[k, i, j]:
                        cost = inf
                elif ok[k, i, j]:
                    cost *= consistent_cost
            if k == 0 or cost < best:
                best = cost
                pick = k
        choice[i, j] = pick
        lost = best == inf or (propagate and checked[pick] and not ok[pick, i, j])
        undecided[i, j] = lost
        count += lost
    return count


@njit(**_JIT)
def _near_row(labels, undecided, near, i):  # noqa: ANN001, ANN202
    """Row i of the label -> decided pixel table of fusion.fill_undecided (each decided pixel has its own
    label, so rows write disjoint entries)."""
    w = labels.shape[1]
    for j in range(w):
        if not undecided[i, j]:
            near[labels[i, j]] = i * w + j


@njit(**_JIT)
def _fill_row(choice, undecided, labels, near, stack, flat_choice, flat_stack, i):  # noqa: ANN001, ANN202
    """Row i of fusion.fill_undecided, in place on ``choice``: an undecided pixel takes the candidate of
    stack (K, 2, h, w) nearest to the flow its nearest decided pixel (flat index ``near[labels]``, read
    through the flat views of choice and stack) chose (decided pixels are only read, undecided ones only
    written: rows are independent)."""
    k_n, w = stack.shape[0], choice.shape[1]
    for j in range(w):
        if not undecided[i, j]:
            continue
        src = near[labels[i, j]]
        kc = flat_choice[src]
        t0, t1 = flat_stack[kc, 0, src], flat_stack[kc, 1, src]
        best = _F32(np.inf)
        pick = 0
        for k in range(k_n):
            d0, d1 = stack[k, 0, i, j] - t0, stack[k, 1, i, j] - t1
            d = d0 * d0 + d1 * d1
            if k == 0 or d < best:
                best = d
                pick = k
        choice[i, j] = pick


@njit(**_JIT)
def _gather_row(choice, stack, out, i):  # noqa: ANN001, ANN202
    """Row i of the fused flow: out[c, i, j] = stack[choice[i, j], c, i, j]."""
    for j in range(choice.shape[1]):
        k = choice[i, j]
        out[0, i, j] = stack[k, 0, i, j]
        out[1, i, j] = stack[k, 1, i, j]


@njit(**_JIT)
def _consistent_row(out, forward, backward, tolerance, i):  # noqa: ANN001, ANN202
    """Row i of initialise.forward_backward_consistent: out = inside & |f + b(x + f)|^2 < tol^2, tol =
    tolerance + 5 % of |f| (float32 as the reference), b sampled bilinearly like :func:`_residual_row`."""
    h, w = forward.shape[1], forward.shape[2]
    right, bottom = _F32(w - 1), _F32(h - 1)
    five = _F32(0.05)
    for j in range(w):
        f0, f1 = forward[0, i, j], forward[1, i, j]
        x, y = _F32(j) + f0, _F32(i) + f1
        if not (x >= 0 and x <= right and y >= 0 and y <= bottom):
            out[i, j] = False
            continue
        xa, xb, ax, ya, yb, ay = _bilinear_taps(x, y, h, w)
        bu = _lerp(_lerp(backward[0, ya, xa], backward[0, ya, xb], ax),
                   _lerp(backward[0, yb, xa], backward[0, yb, xb], ax), ay)
        bv = _lerp(_lerp(backward[1, ya, xa], backward[1, ya, xb], ax),
                   _lerp(backward[1, yb, xa], backward[1, yb, xb], ax), ay)
        e0, e1 = f0 + bu, f1 + bv
        tol = tolerance + five * np.sqrt(f0 * f0 + f1 * f1)
        out[i, j] = e0 * e0 + e1 * e1 < tol * tol


# The kernels: each runs one row function above over every row, in parallel on the calling thread's numba
# threads (one thread on small levels: :func:`_rows_on`). Written out one by one, not built by a factory
# around the row function: numba keys a closure's cache entry by its pickled cell contents, and a pickled
# dispatcher carries a random per-process id, so such drivers were compiled again in every process.
@njit(parallel=True, **_JIT)
def residual_kernel(out, s0, s1, flow):  # noqa: ANN001, ANN201
    """:func:`_residual_row` over every row of ``out``."""
    for i in prange(out.shape[0]):
        _residual_row(out, s0, s1, flow, i)


@njit(parallel=True, **_JIT)
def choose_kernel(choice, undecided, boxed, ok, checked, options, margin, consistent_cost):  # noqa: ANN001, ANN201
    """:func:`_choose_row` over every row of ``choice``; returns the count of undecided pixels."""
    lost = 0
    for i in prange(choice.shape[0]):
        lost += _choose_row(choice, undecided, boxed, ok, checked, options, margin, consistent_cost, i)
    return lost


# Parfor fusion off: the near table must be complete (every row) before any row is filled from it.
@njit(parallel={"fusion": False}, **_JIT)
def settle_kernel(choice, undecided, labels, near, stack, flat_choice, flat_stack, fill, out):  # noqa: ANN001, ANN201
    """The fused flow ``out`` (2, h, w): with ``fill``, the undecided pixels' choice first
    (fusion.fill_undecided: :func:`_near_row` over every row, then :func:`_fill_row`), then the gather
    (:func:`_gather_row`); a row's fill and gather in one pass (its gather reads only that row's choice,
    which its fill has settled). Without ``fill`` labels and near are dummies, not read. One kernel, not
    three: a fresh process reads one kernel from numba's cache, not three (docs/engine.md)."""
    if fill:
        for i in prange(labels.shape[0]):
            _near_row(labels, undecided, near, i)
    for i in prange(choice.shape[0]):
        if fill:
            _fill_row(choice, undecided, labels, near, stack, flat_choice, flat_stack, i)
        _gather_row(choice, stack, out, i)


@njit(parallel=True, **_JIT)
def consistent_kernel(out, forward, backward, tolerance):  # noqa: ANN001, ANN201
    """:func:`_consistent_row` over every row of ``out``."""
    for i in prange(out.shape[0]):
        _consistent_row(out, forward, backward, tolerance, i)


def planes_numba(img: np.ndarray, photometric: str, eps: float = 0.0) -> np.ndarray:
    """fusion.level_planes for the numba backend: (h, w) -> (h, w, P) float32. A census data term's signature is
    numba_census.census_planes_numba's (the census term's own factor kernel: census.signature's to float32 rounding;
    imported on the first census call, as backends.Deferred imports numba_census); the grey-value planes are
    OpenCV's in either backend."""
    if not compares_signatures(photometric):
        return planes(img)
    from .numba_census import census_planes_numba

    with _rows_on(*img.shape):
        return census_planes_numba(img, cost_census(eps))


def _rows_on(h: int, w: int) -> AbstractContextManager[int]:
    """The threads the kernels run an (h, w) level's rows on: the calling thread's numba threads from
    numba_backend.PARALLEL_MIN_PIXELS pixels, one below (thread start-up dominates on small levels)."""
    return nb.threads_for(h * w, nb.PARALLEL_MIN_PIXELS)


def consistent_numba(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """initialise.forward_backward_consistent with the kernel above (same result with OpenCV 5)."""
    forward = np.ascontiguousarray(forward, dtype=_F32)
    out = np.empty(forward.shape[1:], np.bool_)
    with _rows_on(*out.shape):
        consistent_kernel(out, forward, np.ascontiguousarray(backward, dtype=_F32), _F32(FB_TOLERANCE_PX))
    return out


def fuse_numba(i0: np.ndarray, i1: np.ndarray, candidates: list[np.ndarray],
               consistent: list[np.ndarray | None] | None = None, margin: float = FUSION_MARGIN,
               only_consistent: bool = False, propagate: bool = PROPAGATE_INCONSISTENT,
               planes_of: CostPlanes = planes, stacks: tuple[np.ndarray, np.ndarray] | None = None
               ) -> tuple[np.ndarray, np.ndarray]:
    """fusion.fuse with the kernels above: same arguments, same result (with OpenCV 5)."""
    stack = np.stack([np.asarray(c, dtype=_F32) for c in candidates])
    s0, s1 = stacks if stacks is not None else (planes_of(i0), planes_of(i1))
    with _rows_on(*stack.shape[2:]):
        return _fuse(s0, s1, stack, consistent, margin, only_consistent, propagate)


def _fuse(s0: np.ndarray, s1: np.ndarray, stack: np.ndarray, consistent: list[np.ndarray | None] | None,
          margin: float, only_consistent: bool, propagate: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`fuse_numba` on the cost planes s0, s1 (h, w, P) and the candidates' stack (K, 2, h, w)."""
    k_n, h, w = stack.shape[0], stack.shape[2], stack.shape[3]
    boxed = np.empty((k_n, h, w, 2), _F32)
    for k in range(k_n):  # the masked residual, then its box means in place (OpenCV's filters allow it)
        residual_kernel(boxed[k], s0, s1, stack[k])
        cv2.boxFilter(boxed[k], -1, (FUSION_WINDOW, FUSION_WINDOW), dst=boxed[k], borderType=cv2.BORDER_REFLECT)
    checks = list(consistent or []) + [None] * (k_n - len(consistent or []))
    checked = np.array([c is not None for c in checks], np.bool_)
    ok = np.zeros((k_n, h, w) if checked.any() else (k_n, 1, 1), np.bool_)  # read only where checked
    for k, c in enumerate(checks):
        if c is not None:
            ok[k] = c
    choice = np.empty((h, w), np.int64)
    undecided = np.empty((h, w), np.bool_)
    options = np.array([only_consistent, propagate], np.bool_)
    lost = choose_kernel(choice, undecided, boxed, ok, checked, options, _F32(margin), _F32(CONSISTENT_COST))
    fill = 0 < lost < h * w
    labels, near = _NO_LABELS, _NO_NEAR
    if fill:
        _, labels = cv2.distanceTransformWithLabels(undecided.view(np.uint8), cv2.DIST_L2, 5,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
        near = np.zeros(int(labels.max()) + 1, np.int64)
    fused = np.empty((2, h, w), _F32)
    settle_kernel(choice, undecided, labels, near, stack, choice.reshape(-1), stack.reshape(k_n, 2, -1), fill, fused)
    return fused, choice
