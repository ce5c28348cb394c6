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
import numpy as np
from numba import njit

from .fusion import CONSISTENT_COST, FUSION_MARGIN, FUSION_WINDOW, PROPAGATE_INCONSISTENT, planes
from .initialise import FB_TOLERANCE_PX

_F32 = np.float32
# no fastmath: the costs are inf where no data decides, and fastmath may assume there is no inf
_JIT = dict(cache=True, error_model="numpy", nogil=True)
_MIN_SUPPORT = _F32(0.05)  # fusion.data_cost: a box with less inside support than this has no cost
_TINY = _F32(1e-6)


@njit(**_JIT)
def maps_kernel(flow, map_x, map_y):  # noqa: ANN001, ANN201
    """operators.warp_maps' maps: x + u, y + v (float32) of flow (2, h, w)."""
    for i in range(flow.shape[1]):
        y = _F32(i)
        for j in range(flow.shape[2]):
            map_x[i, j] = _F32(j) + flow[0, i, j]
            map_y[i, j] = y + flow[1, i, j]


@njit(**_JIT)
def residual_kernel(s0, w1, map_x, map_y, out):  # noqa: ANN001, ANN201
    """fusion.data_cost's two box inputs, interleaved: out[..., 0] = |w1 - s0|_1 over the 3 planes where
    the map stays inside the image, else 0; out[..., 1] = that inside mask (1 / 0). s0, w1 (h, w, 3)."""
    h, w = map_x.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    for i in range(h):
        for j in range(w):
            x, y = map_x[i, j], map_y[i, j]
            if x >= 0 and x <= right and y >= 0 and y <= bottom:
                out[i, j, 0] = (abs(w1[i, j, 0] - s0[i, j, 0]) + abs(w1[i, j, 1] - s0[i, j, 1])
                                + abs(w1[i, j, 2] - s0[i, j, 2]))
                out[i, j, 1] = 1
            else:
                out[i, j, 0] = 0
                out[i, j, 1] = 0


@njit(**_JIT)
def choose_kernel(boxed, margin, ok, checked, only_consistent, propagate, consistent_cost, choice,  # noqa: ANN001, ANN201
                  undecided):
    """fusion.fuse's choice: per pixel the candidate of least cost (boxed (K, h, w, 2): box means of the
    masked residual and of the mask; the reference's cost times ``margin``; a ``checked`` candidate's cost
    times ``consistent_cost`` where ``ok`` (K, h, w), or inf where not ``ok`` with ``only_consistent``),
    first on ties; ``undecided`` where every cost is inf, or (``propagate``) the winner is checked and not ok.
    Returns whether any pixel is undecided and whether all are."""
    k_n, h, w = boxed.shape[0], boxed.shape[1], boxed.shape[2]
    inf = _F32(np.inf)
    n_undecided = 0
    for i in range(h):
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
            n_undecided += lost
    return n_undecided > 0, n_undecided == h * w


@njit(**_JIT)
def fill_kernel(choice, undecided, labels, stack, near):  # noqa: ANN001, ANN201
    """fusion.fill_undecided after the distance transform, in place on ``choice``: an undecided pixel takes
    the candidate of stack (K, 2, h, w) nearest to the flow its nearest decided pixel chose (labels: the
    transform's per-pixel labels; near: scratch of labels.max() + 1 entries)."""
    k_n, h, w = stack.shape[0], choice.shape[0], choice.shape[1]
    for i in range(h):
        for j in range(w):
            if not undecided[i, j]:
                near[labels[i, j]] = i * w + j
    for i in range(h):
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


@njit(**_JIT)
def gather_kernel(stack, choice, out):  # noqa: ANN001, ANN201
    """out[c, i, j] = stack[choice[i, j], c, i, j]: the fused flow."""
    for i in range(choice.shape[0]):
        for j in range(choice.shape[1]):
            k = choice[i, j]
            out[0, i, j] = stack[k, 0, i, j]
            out[1, i, j] = stack[k, 1, i, j]


@njit(**_JIT)
def consistent_kernel(forward, bu, bv, map_x, map_y, tolerance, out):  # noqa: ANN001, ANN201
    """initialise.forward_backward_consistent after its remaps: out = inside & |f + b(x + f)|^2 < tol^2,
    tol = tolerance + 5 % of |f| (float32 as the reference)."""
    h, w = map_x.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    five = _F32(0.05)
    for i in range(h):
        for j in range(w):
            x, y = map_x[i, j], map_y[i, j]
            f0, f1 = forward[0, i, j], forward[1, i, j]
            e0, e1 = f0 + bu[i, j], f1 + bv[i, j]
            tol = tolerance + five * np.sqrt(f0 * f0 + f1 * f1)
            out[i, j] = (x >= 0 and x <= right and y >= 0 and y <= bottom) and e0 * e0 + e1 * e1 < tol * tol


def _maps(flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    h, w = flow.shape[1:]
    map_x, map_y = np.empty((h, w), _F32), np.empty((h, w), _F32)
    maps_kernel(flow, map_x, map_y)
    return map_x, map_y


def consistent_numba(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """initialise.forward_backward_consistent with the kernels above (same remap, same result)."""
    forward = np.ascontiguousarray(forward, dtype=_F32)
    map_x, map_y = _maps(forward)
    bu, bv = (cv2.remap(np.ascontiguousarray(b, dtype=_F32), map_x, map_y, cv2.INTER_LINEAR,
                        borderMode=cv2.BORDER_REPLICATE) for b in backward)
    out = np.empty(map_x.shape, np.bool_)
    consistent_kernel(forward, bu, bv, map_x, map_y, _F32(FB_TOLERANCE_PX), out)
    return out


def fuse_numba(i0: np.ndarray, i1: np.ndarray, candidates: list[np.ndarray],
               consistent: list[np.ndarray | None] | None = None, margin: float = FUSION_MARGIN,
               only_consistent: bool = False, propagate: bool = PROPAGATE_INCONSISTENT
               ) -> tuple[np.ndarray, np.ndarray]:
    """fusion.fuse with the kernels above: same arguments, same result."""
    s0, s1 = planes(i0), planes(i1)
    stack = np.stack([np.asarray(c, dtype=_F32) for c in candidates])
    k_n, h, w = stack.shape[0], stack.shape[2], stack.shape[3]
    boxed = np.empty((k_n, h, w, 2), _F32)
    masked = np.empty((h, w, 2), _F32)
    for k in range(k_n):
        map_x, map_y = _maps(stack[k])
        w1 = cv2.remap(s1, map_x, map_y, interpolation=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
        residual_kernel(s0, w1, map_x, map_y, masked)
        cv2.boxFilter(masked, -1, (FUSION_WINDOW, FUSION_WINDOW), dst=boxed[k], borderType=cv2.BORDER_REFLECT)
    checks = list(consistent or []) + [None] * (k_n - len(consistent or []))
    checked = np.array([c is not None for c in checks], np.bool_)
    ok = np.zeros((k_n, h, w), np.bool_)
    for k, c in enumerate(checks):
        if c is not None:
            ok[k] = c
    choice = np.empty((h, w), np.int64)
    undecided = np.empty((h, w), np.bool_)
    some, every = choose_kernel(boxed, _F32(margin), ok, checked, bool(only_consistent), bool(propagate),
                                _F32(CONSISTENT_COST), choice, undecided)
    if some and not every:
        _, labels = cv2.distanceTransformWithLabels(undecided.view(np.uint8), cv2.DIST_L2, 5,
                                                    labelType=cv2.DIST_LABEL_PIXEL)
        fill_kernel(choice, undecided, labels, stack, np.zeros(int(labels.max()) + 1, np.int64))
    fused = np.empty((2, h, w), _F32)
    gather_kernel(stack, choice, fused)
    return fused, choice
