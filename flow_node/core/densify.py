"""Dense flow from scattered or partial flow: an edge-aware interpolation in the spirit of EpicFlow
(Revaud et al. 2015: motion edges are image edges), in a simple fast form of our own.

1. **Push-pull** normalised convolution fills every pixel from the known ones: known values and their
   weight are averaged down a Gaussian pyramid (``cv2.pyrDown``) until every coarse pixel has support, then
   each finer level keeps its own estimate where it has enough support and takes the coarser one elsewhere.
2. **Edge-aware smoothing** with a guided filter (He et al. 2010) steered by frame 0, so the filled flow
   changes where the image has edges, not halfway between two seeds.

Flows are channel-first (2, H, W) px; images (H, W) float32.
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

# blend(weight (h, w), weighted [(h, w)], coarse [(h, w)]) -> [(h, w)]: blend_level or a backend's kernel
Blend = Callable[[np.ndarray, list[np.ndarray], list[np.ndarray]], list[np.ndarray]]

GUIDE_RADIUS = 8  # px, guided filter window radius at full resolution
GUIDE_EPS = 1e-3  # guided filter regularisation (intensity^2): edges with contrast above ~0.03 are kept


def blend_level(weight: np.ndarray, weighted: list[np.ndarray], coarse: list[np.ndarray]) -> list[np.ndarray]:
    """One step of :func:`push_pull`'s pull phase on a level: each channel's own estimate (``weighted`` / its
    ``weight`` (h, w)) where the level has a quarter of full weight or more, the coarser level's (``coarse``,
    pyrUp'd to (h, w)) elsewhere, blended linearly in between. float32 (h, w) per channel. The numpy reference
    (numba_temporal.blend_level_numba: the same values in one kernel)."""
    keep = np.clip(weight * 4.0, 0.0, 1.0)  # support of a quarter of full weight or more: own estimate
    own = [c / np.maximum(weight, 1e-12) for c in weighted]
    return [(keep * o + (1.0 - keep) * u).astype(np.float32) for o, u in zip(own, coarse, strict=True)]


def push_pull(values: np.ndarray, weight: np.ndarray, blend: Blend = blend_level) -> np.ndarray:
    """Fill (2, H, W) ``values`` known where ``weight`` (H, W) > 0 (weight = confidence, e.g. 1) into a
    dense (2, H, W) float32 field; known pixels keep (almost) their values. All-zero weight gives zeros.
    ``blend``: :func:`blend_level` or a backend's kernel (the same values)."""
    if not np.any(weight > 0):
        return np.zeros(values.shape, np.float32)
    w = weight.astype(np.float32)
    vw = [np.ascontiguousarray(values[k] * w, dtype=np.float32) for k in range(2)]
    levels = [(w, vw)]
    while min(levels[-1][0].shape) > 2 and np.any(levels[-1][0] <= 1e-6):
        lw, lvw = levels[-1]
        levels.append((cv2.pyrDown(lw), [cv2.pyrDown(c) for c in lvw]))
    lw, lvw = levels[-1]
    safe = np.maximum(lw, 1e-12)
    est = [np.where(lw > 1e-6, c / safe, c.sum() / max(lw.sum(), 1e-12)).astype(np.float32) for c in lvw]
    for lw, lvw in reversed(levels[:-1]):
        h, w_ = lw.shape
        est = blend(lw, lvw, [cv2.pyrUp(e, dstsize=(w_, h)) for e in est])
    return np.stack(est)


def guided_filter(guide: np.ndarray, src: np.ndarray, radius: int, eps: float) -> np.ndarray:
    """Guided filter of each channel of ``src`` (C, H, W) by the grey ``guide`` (H, W): the output is
    locally an affine function of the guide, so it follows the guide's edges. Returns float32 (C, H, W)."""
    k = (2 * radius + 1, 2 * radius + 1)

    def box(x: np.ndarray) -> np.ndarray:
        return cv2.boxFilter(x, cv2.CV_32F, k, borderType=cv2.BORDER_REFLECT)

    g = guide.astype(np.float32)
    mean_g = box(g)
    var_g = box(g * g) - mean_g * mean_g
    out = np.empty(src.shape, np.float32)
    for ch, dst in zip(src, out, strict=True):
        p = ch.astype(np.float32)
        mean_p = box(p)
        a = (box(g * p) - mean_g * mean_p) / (var_g + eps)
        b = mean_p - a * mean_g
        dst[...] = box(a) * g + box(b)
    return out


def densify(guide: np.ndarray, values: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """Edge-aware dense flow (2, H, W) from partial flow ``values`` (2, H, W) with ``weight`` (H, W)."""
    filled = push_pull(values, weight)
    radius = max(2, round(GUIDE_RADIUS * max(guide.shape) / 640))
    return guided_filter(guide, filled, radius, GUIDE_EPS)


def splat_points(shape: tuple[int, int], points: np.ndarray, flows: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Scatter flows (N, 2) at points (N, 2) (x, y px) into a (2, H, W) field and its (H, W) weight (1 where
    a point landed; the mean where several did)."""
    h, w = shape
    xs = np.clip(np.rint(points[:, 0]).astype(np.int64), 0, w - 1)
    ys = np.clip(np.rint(points[:, 1]).astype(np.int64), 0, h - 1)
    idx = ys * w + xs
    count = np.bincount(idx, minlength=h * w).astype(np.float32)
    out = np.zeros((2, h * w), np.float32)
    for k in range(2):
        out[k] = np.bincount(idx, weights=flows[:, k], minlength=h * w)
    weight = (count > 0).astype(np.float32)
    out /= np.maximum(count, 1.0)
    return out.reshape(2, h, w), weight.reshape(h, w)


def forward_targets(flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Where each point of frame t-1's grid lands on frame t's grid under a flow (2, H, W): the flat indices
    of the targets (rounded x + f(x), half to even) and of the source pixel that wins each (the fastest where
    several land on one pixel -- the nearer surface, for a camera that translates; the first in raster order
    among equally fast ones). Points landing outside the grid have no target."""
    h, w = flow.shape[1:]
    ys, xs = np.mgrid[0:h, 0:w]
    tx = np.rint(xs + flow[0]).astype(np.int64)
    ty = np.rint(ys + flow[1]).astype(np.int64)
    ok = (tx >= 0) & (tx < w) & (ty >= 0) & (ty < h)
    mag = (flow[0] ** 2 + flow[1] ** 2)[ok]
    target = (ty * w + tx)[ok]
    src = np.flatnonzero(ok.reshape(-1))
    order = np.lexsort((-mag, target))  # per target, fastest first
    first = np.ones(order.size, bool)
    first[1:] = target[order][1:] != target[order][:-1]
    pick = order[first]
    return target[pick], src[pick]


def forward_propagate(flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Carry a flow (2, H, W) on frame t-1's grid forward to frame t's grid under constant velocity: the
    point x moves to x + f(x) and keeps moving by f(x) (:func:`forward_targets`). Returns the partial flow on
    the new grid (2, H, W) and its weight (H, W): 0 where nothing landed (disocclusions, image border)."""
    h, w = flow.shape[1:]
    target, src = forward_targets(flow)
    out = np.zeros((2, h * w), np.float32)
    weight = np.zeros(h * w, np.float32)
    for k in range(2):
        out[k, target] = flow[k].reshape(-1)[src]
    weight[target] = 1.0
    return out.reshape(2, h, w), weight.reshape(h, w)


def splat_forward(flow: np.ndarray, carried: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The numpy reference of the splat: ``flow`` (2, h, w) px and the ``carried`` fields (C, h, w) moved to
    the targets of densify.forward_targets (each point to round(x + f(x)), the fastest winning): the flow
    (2, h, w), the carried fields (C, h, w), both 0 where nothing landed, and the weight (h, w), 1 where
    something did. float32."""
    h, w = flow.shape[1:]
    target, src = forward_targets(flow)
    out = np.zeros((2 + carried.shape[0], h * w), np.float32)
    out[:, target] = np.concatenate([flow, carried]).reshape(out.shape[0], -1)[:, src]
    weight = np.zeros(h * w, np.float32)
    weight[target] = 1.0
    out = out.reshape(-1, h, w)
    return out[:2], out[2:], weight.reshape(h, w)
