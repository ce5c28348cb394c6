"""numba kernels of the 3-D engine's pyramid (core/volume.py): a volume resampled along each axis by the sparse
rows of volume.resample's matrices (the same arithmetic as the dense matrix product there, nonzeros only).
Kept apart from numba_volume.py, whose kernels are the primal-dual iteration and the linearisation."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
from numba import njit

_JIT = dict(fastmath=True, cache=True, error_model="numpy", nogil=True)
_ZERO = np.float32(0.0)


@njit(**_JIT)
def resample_axis(f, idx, wts, axis):  # noqa: ANN001, ANN201
    """f (M, Z, Y, X) resampled along ``axis`` (0 = z, 1 = y, 2 = x) by sparse rows: output o is
    sum_t wts[o, t] * f[..., idx[o, t], ...] (volume.resample's matrices, nonzeros only). float32."""
    m_, nz, ny, nx = f.shape
    n, taps = idx.shape
    if axis == 2:
        out = np.zeros((m_, nz, ny, n), np.float32)
        for m in range(m_):
            for k in range(nz):
                for i in range(ny):
                    for o in range(n):
                        acc = _ZERO
                        for t in range(taps):
                            acc += wts[o, t] * f[m, k, i, idx[o, t]]
                        out[m, k, i, o] = acc
    elif axis == 1:
        out = np.zeros((m_, nz, n, nx), np.float32)
        for m in range(m_):
            for k in range(nz):
                for o in range(n):
                    for t in range(taps):
                        w, r = wts[o, t], idx[o, t]
                        for j in range(nx):
                            out[m, k, o, j] += w * f[m, k, r, j]
    else:
        out = np.zeros((m_, n, ny, nx), np.float32)
        for m in range(m_):
            for o in range(n):
                for t in range(taps):
                    w, r = wts[o, t], idx[o, t]
                    for i in range(ny):
                        for j in range(nx):
                            out[m, o, i, j] += w * f[m, r, i, j]
    return out


def sparse_rows(matrix: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A resampling matrix (n_out, n_in) as (indices, weights) (n_out, taps) of each row's nonzeros (padded
    with weight 0)."""
    taps = max(1, int((matrix != 0).sum(axis=1).max()))
    idx = np.zeros((matrix.shape[0], taps), np.int64)
    wts = np.zeros((matrix.shape[0], taps), np.float32)
    for o, row in enumerate(matrix):
        nz = np.flatnonzero(row)
        idx[o, :len(nz)], wts[o, :len(nz)] = nz, row[nz]
    return idx, wts


def resample_numba(f: np.ndarray, shape: tuple[int, int, int], matrix: Callable[[int, int], np.ndarray]
                   ) -> np.ndarray:
    """volume.resample with :func:`resample_axis`: f (..., Z, Y, X) -> (..., *shape) float32."""
    lead = f.shape[:-3]
    out = np.ascontiguousarray(f, dtype=np.float32).reshape((-1,) + f.shape[-3:])
    for axis in (2, 1, 0):
        n_in, n_out = out.shape[axis + 1], shape[axis]
        if n_in != n_out:
            out = resample_axis(out, *sparse_rows(matrix(n_in, n_out)), axis)
    return out.reshape(lead + tuple(shape))
