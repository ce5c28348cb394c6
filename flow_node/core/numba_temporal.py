"""The stream stage's forward splat with a numba kernel: :func:`splat_numba` (densify.splat_forward), the
numba backend's ``splat`` field; and its hole fill's pull steps in one kernel per channel: :func:`push_pull_numba`
(densify.push_pull), the ``fill`` field.

The reference (densify.forward_targets) sorts every landing pixel by (target, -speed) and keeps the first of
each target; here one serial pass over the source pixels in raster order keeps, per target, the fastest so
far (a strictly faster one replaces it), which is the same choice -- ties go to the earliest source pixel, as
the reference's stable sort gives them. The rounding of the target (half to even) and the float32 speed are
the reference's, so the results are equal bit for bit (test_temporal.py). A z-buffer is a race in parallel:
the pass stays serial (~1 ms at 640x480; the stream splats on its start level, often half size).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .densify import push_pull

_F32 = np.float32


@njit(cache=True, error_model="numpy", nogil=True)
def splat_kernel(flow, carried, out, out_carried, weight, best):  # noqa: ANN001, ANN201
    """Forward splat of ``flow`` (2, h, w) float32 and the ``carried`` fields (C, h, w) along it: out
    (2, h, w), out_carried (C, h, w) and weight (h, w), zero-initialised, get the fastest landing pixel's
    values and 1 at every target round(x + f(x)) inside the grid; ``best`` (h, w) float32 scratch, -1."""
    h, w = flow.shape[1], flow.shape[2]
    for i in range(h):
        for j in range(w):
            u, v = flow[0, i, j], flow[1, i, j]
            tx = np.int64(np.rint(np.float64(j) + np.float64(u)))
            ty = np.int64(np.rint(np.float64(i) + np.float64(v)))
            if tx < 0 or tx >= w or ty < 0 or ty >= h:
                continue
            mag = u * u + v * v
            if mag > best[ty, tx]:
                best[ty, tx] = mag
                out[0, ty, tx] = u
                out[1, ty, tx] = v
                for c in range(carried.shape[0]):
                    out_carried[c, ty, tx] = carried[c, i, j]
                weight[ty, tx] = _F32(1.0)


def splat_numba(flow: np.ndarray, carried: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """densify.splat_forward with :func:`splat_kernel`: (flow (2, h, w), carried (C, h, w), weight (h, w))."""
    f = np.ascontiguousarray(flow, dtype=_F32)
    c = np.ascontiguousarray(carried, dtype=_F32)
    h, w = f.shape[1:]
    out, out_carried = np.zeros((2, h, w), _F32), np.zeros(c.shape, _F32)
    weight = np.zeros((h, w), _F32)
    splat_kernel(f, c, out, out_carried, weight, np.full((h, w), -1.0, _F32))
    return out, out_carried, weight


@njit(cache=True, error_model="numpy", nogil=True)  # no fastmath: the reference's float32 roundings, no fused ops
def blend_kernel(weight, weighted, coarse, out):  # noqa: ANN001, ANN201
    """densify.blend_level for one channel in one pass: out (h, w) = keep * (weighted / max(weight, 1e-12)) +
    (1 - keep) * coarse with keep = clip(4 weight, 0, 1); all (h, w) float32, weight >= 0."""
    four, one, zero, tiny = _F32(4.0), _F32(1.0), _F32(0.0), _F32(1e-12)
    for i in range(weight.shape[0]):
        for j in range(weight.shape[1]):
            lw = weight[i, j]
            keep = min(max(lw * four, zero), one)
            out[i, j] = keep * (weighted[i, j] / max(lw, tiny)) + (one - keep) * coarse[i, j]


def blend_level_numba(weight: np.ndarray, weighted: list[np.ndarray], coarse: list[np.ndarray]) -> list[np.ndarray]:
    """densify.blend_level with :func:`blend_kernel` per channel (the same values bit for bit)."""
    w = np.ascontiguousarray(weight, dtype=_F32)
    out = []
    for c, u in zip(weighted, coarse, strict=True):
        out.append(np.empty(w.shape, _F32))
        blend_kernel(w, np.ascontiguousarray(c, dtype=_F32), np.ascontiguousarray(u, dtype=_F32), out[-1])
    return out


def push_pull_numba(values: np.ndarray, weight: np.ndarray) -> np.ndarray:
    """densify.push_pull with :func:`blend_level_numba` for its pull steps (the numba backend's ``fill``): the
    same field bit for bit, without the reference's ten numpy calls per level (~45 us per stream frame at
    320x240, on the 80x60 start level)."""
    return push_pull(values, weight, blend_level_numba)
