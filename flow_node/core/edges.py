"""The image-driven weight of the TV regulariser (docs/engine.md, "Edge-weighted TV"): TV_g(v) = sum_x g(x) |grad v(x)|
with g = max(g_min, exp(-a (|grad I0_s| / s)^b)) (Wedel et al. 2009, "structure- and motion-adaptive
regularization"; Werlberger et al. 2009), I0_s a pyramid level's frame 0 smoothed, s the mean of |grad I0_s| on the
level. Dividing by s makes g the same for the image times any gain, so the census term's invariance to contrast is
not undone by the regulariser. In the primal-dual iteration g only changes the dual projection: y's ball has
radius g(x) instead of 1 (models.project_dual_tv), step sizes unchanged (g <= 1 does not enlarge ||K||).
"""

from __future__ import annotations

from collections.abc import Callable

import cv2
import numpy as np

from .config import FlowConfig
from .workspace import scratch

EDGE_SIGMA = 1.0  # px: the Gaussian that smooths a level's frame 0 before its gradient (noise must not read as edges)
TINY = 1e-12  # a level whose mean gradient is at most this is constant: g = 1
MASK_REACH = 2  # px around an invalid pixel of frame 0 that keep plain TV (:func:`unweighted_near_invalid`)


def edge_weight(i0: np.ndarray, a: float, b: float, floor: float, out: np.ndarray | None = None) -> np.ndarray:
    """g (H, W) float32 in [floor, 1] of a level's frame 0 ``i0`` (H, W): exp(-a (|grad I0_s| / s)^b) floored,
    I0_s = i0 smoothed by a Gaussian of EDGE_SIGMA, grad its central differences (border replicated),
    s = mean |grad I0_s| over the level. A constant level (s = 0) gives g = 1 everywhere. Into ``out`` (float32
    (H, W)) where given. The reference (OpenCV and numpy); the numba backend's is numba_edges.edge_weight_numba."""
    img = np.ascontiguousarray(i0, dtype=np.float32)
    smooth = cv2.GaussianBlur(img, (0, 0), EDGE_SIGMA, borderType=cv2.BORDER_REPLICATE)
    g = cv2.Sobel(smooth, cv2.CV_32F, 1, 0, ksize=1, scale=0.5, borderType=cv2.BORDER_REPLICATE)
    gy = cv2.Sobel(smooth, cv2.CV_32F, 0, 1, ksize=1, scale=0.5, borderType=cv2.BORDER_REPLICATE)
    # in place from here, g holding |grad|, then the weight: a level's temporaries of a few hundred kB are fresh
    # pages each (glibc's mmap threshold) where an executable has not set process.keep_freed_memory
    np.multiply(g, g, out=g)
    np.multiply(gy, gy, out=gy)
    np.sqrt(np.add(g, gy, out=g), out=g)
    scale = float(np.mean(g, dtype=np.float64))
    if scale <= TINY:
        g.fill(1.0)  # floor <= 1: g = 1 below
    else:
        np.power(np.divide(g, np.float32(scale), out=g), np.float32(b), out=g)
        np.exp(np.multiply(g, np.float32(-a), out=g), out=g)
    return np.maximum(g, np.float32(floor), out=g if out is None else out)


# what computes g: edge_weight(i0, a, b, floor, out) -> out (or a new array); a backend's (backends.Backend.edge_weight)
EdgeWeight = Callable[..., np.ndarray]


def level_edge_weight(i0: np.ndarray, cfg: FlowConfig, level: int = 0, valid0: np.ndarray | None = None,
                      weight: EdgeWeight = edge_weight) -> np.ndarray | None:
    """:func:`edge_weight` (or a backend's ``weight``) of pyramid level ``level``'s frame 0 with ``cfg``'s
    tv_edge_weight / tv_edge_power / tv_edge_floor; None when tv_edge_weight is 0 or ``level`` is finer than
    ``cfg.tv_edge_min_level`` (plain TV: the solvers take the unit ball, bit for bit today's flows). Without
    ``valid0`` g is the calling thread's scratch array of the level's shape (workspace.py: valid until the next
    level of that shape asks for it; a fresh one each level was fresh pages each, ~50 us at 292 x 194)."""
    if cfg.tv_edge_weight <= 0.0 or level < cfg.tv_edge_min_level:
        return None
    g = weight(i0, cfg.tv_edge_weight, cfg.tv_edge_power, cfg.tv_edge_floor, out=scratch("edges.g", i0.shape))
    return g if valid0 is None else unweighted_near_invalid(g, valid0)


def unweighted_near_invalid(g: np.ndarray, valid0: np.ndarray) -> np.ndarray:
    """g raised to 1 - v where v is frame 0's validity ``valid0`` (H, W) in [0, 1] (validity.py) eroded by
    MASK_REACH px: pixels without a data term get their flow from the regulariser alone, so their TV stays the
    plain one (an invalid area is filled smoothly, validity.fill_invalid, and the border of that fill reads as an
    edge). -> float32 (H, W)."""
    size = 2 * MASK_REACH + 1
    near = cv2.erode(np.ascontiguousarray(valid0, dtype=np.float32), np.ones((size, size), np.uint8),
                     borderType=cv2.BORDER_REPLICATE)
    return np.maximum(g, 1.0 - near).astype(np.float32, copy=False)
