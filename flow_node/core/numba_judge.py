"""The judge's numba kernel: census.reliability (the numpy reference and test oracle), the unexplained fraction of
every data term's flow (engine.Judged; docs/engine.md, "The judge"). Its own module, apart from numba_census: every
solve calls it, and a grey-value solve does not load the census data term's kernels (backends.Deferred).

Importing this module raises ImportError when numba is not installed (backends.py then uses numpy).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from .census import CENSUS, OFFSETS_DX, OFFSETS_DY, OUTLIER, SAMPLE_SPACING, CensusParams
from .numba_kernels import FASTMATH
from .numba_warp import cubic_weights4, tap_indices, tap_sum
from .photometric import reliability_stride

_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)  # numba_census's flags
_F32 = np.float32


@njit(**_JIT)
def _normalised_residual(d1, d0, eps):  # noqa: ANN001, ANN201
    """mean_k |d1_k / (RMS(d1) + eps) - d0_k / (RMS(d0) + eps)| of two pixels' K neighbour differences (K)."""
    k_n = d1.shape[0]
    s1, s0 = _F32(0.0), _F32(0.0)
    for k in range(k_n):
        s1 += d1[k] * d1[k]
        s0 += d0[k] * d0[k]
    n1 = _F32(1.0) / (math.sqrt(s1 / k_n) + eps)
    n0 = _F32(1.0) / (math.sqrt(s0 / k_n) + eps)
    total = _F32(0.0)
    for k in range(k_n):
        total += abs(d1[k] * n1 - d0[k] * n0)
    return total / k_n


@njit(**_JIT)
def unexplained_kernel(i0, i1, flow, stride, dy, dx, eps, outlier):  # noqa: ANN001, ANN201
    """census.reliability's counts: over every ``stride``-th pixel of i0 (H, W) whose x + flow (flow (H, W, 2))
    lies at least one pixel inside, how many there are and how many have a mean signature residual above
    ``outlier`` -> (inside, unexplained). I1 (1, H, W) is sampled (Keys) at x + flow and its K neighbours
    (dy, dx): one position's fraction, so one set of tap weights for all of them."""
    h, w = i0.shape
    k_n = dy.shape[0]
    d1, d0 = np.empty(k_n, np.float32), np.empty(k_n, np.float32)
    inside, bad = 0, 0
    for i in range(0, h, stride):
        for j in range(0, w, stride):
            mx, my = np.float32(j) + flow[i, j, 0], np.float32(i) + flow[i, j, 1]
            if not (mx >= 1 and mx <= w - 2 and my >= 1 and my <= h - 2):  # (NaN: not inside either)
                continue
            xi, yi = np.int64(mx), np.int64(my)  # mx, my >= 1: truncation is the floor
            wx = cubic_weights4(mx - np.float32(xi), 0)
            wy = cubic_weights4(my - np.float32(yi), 0)
            centre = tap_sum(i1, 0, wx, wy, tap_indices(xi, w), tap_indices(yi, h))
            for k in range(k_n):
                d1[k] = tap_sum(i1, 0, wx, wy, tap_indices(xi + dx[k], w), tap_indices(yi + dy[k], h)) - centre
                d0[k] = i0[min(max(i + dy[k], 0), h - 1), min(max(j + dx[k], 0), w - 1)] - i0[i, j]
            inside += 1
            bad += _normalised_residual(d1, d0, eps) > outlier
    return inside, bad


def reliability_numba(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, params: CensusParams = CENSUS, *,
                      samples: int | None = None) -> float:
    """census.reliability with :func:`unexplained_kernel` (same samples, threshold and stride; the tap weights of
    a sample's 9 positions from its own fraction, which the reference recomputes from each position)."""
    h, w = i0.shape
    stride = SAMPLE_SPACING * reliability_stride(h, w, samples)
    inside, bad = unexplained_kernel(np.ascontiguousarray(i0, dtype=_F32), np.ascontiguousarray(i1, dtype=_F32)[None],
                                     np.ascontiguousarray(flow, dtype=_F32), stride, OFFSETS_DY, OFFSETS_DX,
                                     _F32(params.eps), _F32(OUTLIER))
    return bad / inside if inside else 1.0
