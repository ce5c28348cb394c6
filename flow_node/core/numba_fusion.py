"""The fusion stage with numba kernels: :func:`fuse_numba` (fusion.fuse) and :func:`consistent_numba`
(initialise.forward_backward_consistent), the numba backend's fields.

The numpy references chain a dozen whole-image passes with temporaries per candidate (maps, masks, an
(h, w, 3) difference summed over its last axis, a (K, h, w) stack of costs, argmin, take_along_axis, the
label look-ups of fill_undecided); here each is one pass: the masked residual of a candidate, the choice
over all candidates, the undecided pixels' choice and the gather of the fused flow. The sampling
(cv2.remap), the box means (cv2.boxFilter) and the distance transform stay OpenCV's and the arithmetic is
the references' float32 in the same order, so the results equal theirs bit for bit (test_fusion_numba.py).
"""

from __future__ import annotations

import cv2
import numba
import numpy as np
from numba import njit, prange

from . import numba_backend as nb

from .fusion import CONSISTENT_COST, FUSION_MARGIN, FUSION_WINDOW, PROPAGATE_INCONSISTENT, planes
from .initialise import FB_TOLERANCE_PX

_F32 = np.float32
# no fastmath: the costs are inf where no data decides, and fastmath may assume there is no inf
_JIT = dict(cache=True, error_model="numpy", nogil=True)
_MIN_SUPPORT = _F32(0.05)  # fusion.data_cost: a box with less inside support than this has no cost
_TINY = _F32(1e-6)


@njit(**_JIT)
def _maps_row(map_x, map_y, flow, _d, _e, _f, _g, _h, i):  # noqa: ANN001, ANN202
    """Row i of operators.warp_maps' maps: x + u, y + v (float32) of flow (2, h, w)."""
    y = _F32(i)
    for j in range(flow.shape[2]):
        map_x[i, j] = _F32(j) + flow[0, i, j]
        map_y[i, j] = y + flow[1, i, j]
    return 0


@njit(**_JIT)
def _residual_row(out, s0, w1, map_x, map_y, _f, _g, _h, i):  # noqa: ANN001, ANN202
    """Row i of fusion.data_cost's two box inputs, interleaved: out[..., 0] = |w1 - s0|_1 over the 3
    planes where the map stays inside the image, else 0; out[..., 1] = that inside mask (1 / 0)."""
    h, w = map_x.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    for j in range(w):
        x, y = map_x[i, j], map_y[i, j]
        if x >= 0 and x <= right and y >= 0 and y <= bottom:
            out[i, j, 0] = (abs(w1[i, j, 0] - s0[i, j, 0]) + abs(w1[i, j, 1] - s0[i, j, 1])
                            + abs(w1[i, j, 2] - s0[i, j, 2]))
            out[i, j, 1] = 1
        else:
            out[i, j, 0] = 0
            out[i, j, 1] = 0
    return 0


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
def _near_row(labels, undecided, near, _d, _e, _f, _g, _h, i):  # noqa: ANN001, ANN202
    """Row i of the label -> decided pixel table of fusion.fill_undecided (each decided pixel has its own
    label, so rows write disjoint entries)."""
    w = labels.shape[1]
    for j in range(w):
        if not undecided[i, j]:
            near[labels[i, j]] = i * w + j
    return 0


@njit(**_JIT)
def _fill_row(choice, undecided, labels, near, stack, _f, _g, _h, i):  # noqa: ANN001, ANN202
    """Row i of fusion.fill_undecided, in place on ``choice``: an undecided pixel takes the candidate of
    stack (K, 2, h, w) nearest to the flow its nearest decided pixel (``near[labels]``) chose (decided
    pixels are only read, undecided ones only written: rows are independent)."""
    k_n, w = stack.shape[0], choice.shape[1]
    for j in range(w):
        if not undecided[i, j]:
            continue
        src = near[labels[i, j]]
        si, sj = src // w, src % w
        kc = choice[si, sj]
        t0, t1 = stack[kc, 0, si, sj], stack[kc, 1, si, sj]
        best = _F32(np.inf)
        pick = 0
        for k in range(k_n):
            d0, d1 = stack[k, 0, i, j] - t0, stack[k, 1, i, j] - t1
            d = d0 * d0 + d1 * d1
            if k == 0 or d < best:
                best = d
                pick = k
        choice[i, j] = pick
    return 0


@njit(**_JIT)
def _gather_row(choice, stack, out, _d, _e, _f, _g, _h, i):  # noqa: ANN001, ANN202
    """Row i of the fused flow: out[c, i, j] = stack[choice[i, j], c, i, j]."""
    for j in range(choice.shape[1]):
        k = choice[i, j]
        out[0, i, j] = stack[k, 0, i, j]
        out[1, i, j] = stack[k, 1, i, j]
    return 0


@njit(**_JIT)
def _consistent_row(out, forward, bu, bv, map_x, map_y, tolerance, _h, i):  # noqa: ANN001, ANN202
    """Row i of initialise.forward_backward_consistent after its remaps: out = inside & |f + b(x + f)|^2 <
    tol^2, tol = tolerance + 5 % of |f| (float32 as the reference)."""
    h, w = map_x.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    five = _F32(0.05)
    for j in range(w):
        x, y = map_x[i, j], map_y[i, j]
        f0, f1 = forward[0, i, j], forward[1, i, j]
        e0, e1 = f0 + bu[i, j], f1 + bv[i, j]
        tol = tolerance + five * np.sqrt(f0 * f0 + f1 * f1)
        out[i, j] = (x >= 0 and x <= right and y >= 0 and y <= bottom) and e0 * e0 + e1 * e1 < tol * tol
    return 0


@njit(parallel=True, **_JIT)
def maps_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_maps_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _maps_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _maps_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def residual_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_residual_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _residual_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _residual_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def choose_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_choose_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _choose_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _choose_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def near_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_near_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _near_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _near_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def fill_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_fill_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _fill_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _fill_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def gather_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_gather_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _gather_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _gather_row(a, b, c, d, e, f, g, h, i)
    return total


@njit(parallel=True, **_JIT)
def consistent_kernel(a, b, c, d, e, f, g, h, parallel):  # noqa: ANN001, ANN201
    """:func:`_consistent_row` over every row (in parallel when ``parallel``); the rows' returns summed."""
    total = 0
    if parallel:
        for i in prange(a.shape[0]):
            total += _consistent_row(a, b, c, d, e, f, g, h, i)
    else:
        for i in range(a.shape[0]):
            total += _consistent_row(a, b, c, d, e, f, g, h, i)
    return total


_NONE = np.zeros(1, np.uint8)  # filler for a kernel's unused arguments


def _parallel(h: int, w: int) -> bool:
    numba.set_num_threads(nb.threads())
    return nb.threads() > 1 and h * w >= nb.PARALLEL_MIN_PIXELS


def _maps(flow: np.ndarray, parallel: bool) -> tuple[np.ndarray, np.ndarray]:
    h, w = flow.shape[1:]
    map_x, map_y = np.empty((h, w), _F32), np.empty((h, w), _F32)
    maps_kernel(map_x, map_y, flow, _NONE, _NONE, _NONE, _NONE, _NONE, parallel)
    return map_x, map_y


def consistent_numba(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """initialise.forward_backward_consistent with the kernels above (same remap, same result)."""
    forward = np.ascontiguousarray(forward, dtype=_F32)
    parallel = _parallel(*forward.shape[1:])
    map_x, map_y = _maps(forward, parallel)
    bu, bv = (cv2.remap(np.ascontiguousarray(b, dtype=_F32), map_x, map_y, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE) for b in backward)
    out = np.empty(map_x.shape, np.bool_)
    consistent_kernel(out, forward, bu, bv, map_x, map_y, _F32(FB_TOLERANCE_PX), _NONE, parallel)
    return out


def fuse_numba(i0: np.ndarray, i1: np.ndarray, candidates: list[np.ndarray],
               consistent: list[np.ndarray | None] | None = None, margin: float = FUSION_MARGIN,
               only_consistent: bool = False, propagate: bool = PROPAGATE_INCONSISTENT
               ) -> tuple[np.ndarray, np.ndarray]:
    """fusion.fuse with the kernels above: same arguments, same result."""
    s0, s1 = planes(i0), planes(i1)
    stack = np.stack([np.asarray(c, dtype=_F32) for c in candidates])
    k_n, h, w = stack.shape[0], stack.shape[2], stack.shape[3]
    parallel = _parallel(h, w)
    boxed = np.empty((k_n, h, w, 2), _F32)
    masked = np.empty((h, w, 2), _F32)
    for k in range(k_n):
        map_x, map_y = _maps(stack[k], parallel)
        w1 = cv2.remap(s1, map_x, map_y, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        residual_kernel(masked, s0, w1, map_x, map_y, _NONE, _NONE, _NONE, parallel)
        cv2.boxFilter(masked, -1, (FUSION_WINDOW, FUSION_WINDOW), dst=boxed[k], borderType=cv2.BORDER_REFLECT)
    checks = list(consistent or []) + [None] * (k_n - len(consistent or []))
    checked = np.array([c is not None for c in checks], np.bool_)
    ok = np.zeros((k_n, h, w), np.bool_)
    for k, c in enumerate(checks):
        if c is not None:
            ok[k] = c
    choice = np.empty((h, w), np.int64)
    undecided = np.empty((h, w), np.bool_)
    options = np.array([only_consistent, propagate], np.bool_)
    lost = choose_kernel(choice, undecided, boxed, ok, checked, options, _F32(margin), _F32(CONSISTENT_COST),
                         parallel)
    if 0 < lost < h * w:
        _, labels = cv2.distanceTransformWithLabels(undecided.view(np.uint8), cv2.DIST_L2, 5,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
        near = np.zeros(int(labels.max()) + 1, np.int64)
        near_kernel(labels, undecided, near, _NONE, _NONE, _NONE, _NONE, _NONE, parallel)
        fill_kernel(choice, undecided, labels, near, stack, _NONE, _NONE, _NONE, parallel)
    fused = np.empty((2, h, w), _F32)
    gather_kernel(choice, stack, fused, _NONE, _NONE, _NONE, _NONE, _NONE, parallel)
    return fused, choice
