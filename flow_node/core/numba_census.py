"""numba kernels of the census data term (census.py, the numpy reference and test oracle).

:func:`signature_kernel` computes the soft census signature of an image; :func:`warped_kernel` recovers the
warped frame 1 from the grey-value linearisation (census.warped_frame); :func:`form_kernel` builds one
warp's quadratic form from frame 0's signature and the warped frame's (both gradients taken inside it);
:func:`colour_form_numba` the same over the stacked signatures of colour channels (colour.py).
Rows run in parallel (prange), each row's loops over whole rows (1-D views, so they vectorise). Same
float32 arithmetic as the reference up to the order of the sums (to ~1e-6 relative).

Importing this module raises ImportError when numba is not installed (backends.py then uses numpy).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from .census import OFFSETS, CensusParams
from .workspace import scratch

_JIT = dict(fastmath=True, cache=True, error_model="numpy", nogil=True)
_F32 = np.float32
_DY = np.array([d[0] for d in OFFSETS], np.int64)
_DX = np.array([d[1] for d in OFFSETS], np.int64)


@njit(**_JIT)
def _diff_row(neighbour, centre, dst, ss):  # noqa: ANN001, ANN201
    """dst = neighbour - centre and ss += dst^2 over one row (1-D views; vectorises)."""
    for j in range(dst.shape[0]):
        d = neighbour[j] - centre[j]
        dst[j] = d
        ss[j] += d * d


@njit(parallel=True, **_JIT)
def signature_kernel(img, dy, dx, gain, eps, out):  # noqa: ANN001, ANN201
    """census.signature of img (H, W) into out (K, H, W); neighbours clamped to the image (edge values).
    Row by row and channel by channel over whole rows (1-D views: the loops vectorise)."""
    h, w = img.shape
    k_n = dy.shape[0]
    for i in prange(h):
        ss = np.zeros(w, np.float32)
        centre = img[i]
        for k in range(k_n):
            src = img[min(max(i + dy[k], 0), h - 1)]
            dst = out[k, i]
            d = dx[k]
            if d == 0:
                _diff_row(src, centre, dst, ss)
            elif d > 0:  # the last column's neighbour is itself (clamped)
                _diff_row(src[d:], centre[:w - d], dst[:w - d], ss[:w - d])
                _diff_row(src[w - 1:], centre[w - d:], dst[w - d:], ss[w - d:])
            else:
                _diff_row(src[:w + d], centre[-d:], dst[-d:], ss[-d:])
                _diff_row(src[:1], centre[:-d], dst[:-d], ss[:-d])
        for j in range(w):
            ss[j] = gain / (math.sqrt(ss[j] / k_n) + eps)
        for k in range(k_n):
            dst = out[k, i]
            for j in range(w):
                dst[j] *= ss[j]


@njit(parallel=True, **_JIT)
def warped_kernel(i0, i1, a, c, v0, warped, keep):  # noqa: ANN001, ANN201
    """census.warped_frame into warped (H, W) float32 and keep (H, W) float32 (0 outside, else 1)."""
    h, w = i0.shape
    for i in prange(h):
        for j in range(w):
            out = a[0, i, j] == 0 and a[1, i, j] == 0 and c[i, j] == 0
            keep[i, j] = _F32(0.0) if out else _F32(1.0)
            warped[i, j] = i1[i, j] if out else c[i, j] + a[0, i, j] * v0[0, i, j] + a[1, i, j] * v0[1, i, j] + i0[i, j]


@njit(**_JIT)
def _form_row(f0c, f0l, f0r, f0u, f0d, f1c, f1l, f1r, f1u, f1d, vx, vy, keep, o0, o1, o2, o3, o4,  # noqa: ANN001, ANN201
              rx, ry, d2, robust):
    """One channel's contribution to the quadratic form along one row segment (1-D views of the signatures
    at the pixels (c) and their left/right/up/down neighbours; vectorises): the channel's gradient (rx, ry:
    1/4 for the mean of two central differences, 0 on the border), residual, weight and the five sums."""
    for j in range(o0.shape[0]):
        ax = rx * (f0r[j] - f0l[j] + f1r[j] - f1l[j])
        ay = ry * (f0d[j] - f0u[j] + f1d[j] - f1u[j])
        r0 = f1c[j] - f0c[j]
        cc = r0 - ax * vx[j] - ay * vy[j]
        wk = keep[j] / math.sqrt(r0 * r0 + d2) if robust else keep[j]
        wax = wk * ax
        way = wk * ay
        o0[j] += wax * ax
        o1[j] += wax * ay
        o2[j] += way * ay
        o3[j] += wax * cc
        o4[j] += way * cc


@njit(parallel=True, **_JIT)
def form_kernel(f0, f1, keep, v0, robust, delta, out):  # noqa: ANN001, ANN201
    """census.quadratic_form from frame 0's signature f0 (K, H, W) and the warped frame's f1 (K, H, W) (both
    gradients taken here: central differences, zero on the border), keep (H, W) (0 = no data term) and v0
    (2, H, W), into out (5, H, W). Row by row and channel by channel: the interior columns, then the two
    border columns (x-gradient 0) as a stride-(W-1) view."""
    k_n, h, w = f0.shape
    d2 = delta * delta
    quarter = _F32(0.25)
    zero = _F32(0.0)
    e = max(w - 1, 1)  # the border columns 0 and w - 1 (one column when w == 1)
    for i in prange(h):
        iu, idn = max(i - 1, 0), min(i + 1, h - 1)
        ry = quarter if 0 < i < h - 1 else zero
        out[:, i] = zero
        o0, o1, o2, o3, o4 = out[0, i], out[1, i], out[2, i], out[3, i], out[4, i]
        vx, vy, kp = v0[0, i], v0[1, i], keep[i]
        for k in range(k_n):
            a0, a1, u0, u1, d0, d1 = f0[k, i], f1[k, i], f0[k, iu], f1[k, iu], f0[k, idn], f1[k, idn]
            m = slice(1, w - 1)
            _form_row(a0[m], a0[:w - 2], a0[2:], u0[m], d0[m], a1[m], a1[:w - 2], a1[2:], u1[m], d1[m],
                      vx[m], vy[m], kp[m], o0[m], o1[m], o2[m], o3[m], o4[m], quarter, ry, d2, robust)
            b0, b1 = a0[::e], a1[::e]
            _form_row(b0, b0, b0, u0[::e], d0[::e], b1, b1, b1, u1[::e], d1[::e], vx[::e], vy[::e], kp[::e],
                      o0[::e], o1[::e], o2[::e], o3[::e], o4[::e], zero, ry, d2, robust)


def signature_numba(img: np.ndarray, params: CensusParams, out: np.ndarray | None = None) -> np.ndarray:
    """census.signature with the kernel: (H, W) -> (K, H, W) float32 (into ``out`` when given)."""
    src = np.ascontiguousarray(img, dtype=_F32)
    out = np.empty((len(OFFSETS),) + src.shape, _F32) if out is None else out
    signature_kernel(src, _DY, _DX, _F32(params.gain), _F32(params.eps), out)
    return out


def level_signature_numba(i0: np.ndarray, params: CensusParams) -> tuple[np.ndarray, None]:
    """Frame 0's signature (K, H, W) on one level (census.level_signature; its gradient is taken inside
    :func:`form_kernel`, which reads f0's neighbours anyway: None)."""
    return signature_numba(i0, params), None


def census_form_numba(i0: np.ndarray, i1: np.ndarray, f0: np.ndarray, g0: None, a: np.ndarray, c: np.ndarray,
                      v0: np.ndarray, robust: bool, params: CensusParams) -> np.ndarray:
    """census.census_form with the kernels: the quadratic form (5, H, W) of one warp. The warped frame, its
    mask and its signature are the calling thread's scratch arrays (workspace.py: every warp of every level
    needs them, and they are dead once the form is built); the form itself is fresh (a Bregman step reuses
    the last warp's)."""
    h, w = i0.shape
    warped, keep = scratch("census.warped", (h, w)), scratch("census.keep", (h, w))
    v0 = np.ascontiguousarray(v0, dtype=_F32)
    warped_kernel(np.ascontiguousarray(i0, dtype=_F32), np.ascontiguousarray(i1, dtype=_F32), a, c, v0, warped, keep)
    f1 = signature_numba(warped, params, out=scratch("census.f1", (len(OFFSETS), h, w)))
    out = np.empty((5, h, w), _F32)
    form_kernel(f0, f1, keep, v0, robust, _F32(params.delta), out)
    return out



def colour_form_numba(f0: np.ndarray, g0: None, warped: np.ndarray, outside: np.ndarray, v0: np.ndarray,
                      robust: bool, params: CensusParams) -> np.ndarray:
    """colour.colour_form with the kernels: the signature of each warped channel (C, H, W) into one stacked
    scratch array, the form kernel's per-pixel weight (1 / C inside, 0 ``outside``: the reference's mask and
    1 / C), then one form over all C x K channels (5, H, W)."""
    n, h, w = warped.shape
    k_n = len(OFFSETS)
    f1 = scratch("colour.f1", (n * k_n, h, w))
    for k in range(n):
        signature_numba(warped[k], params, out=f1[k * k_n:(k + 1) * k_n])
    weight = np.where(outside, _F32(0.0), _F32(1.0 / n)).astype(_F32)
    out = np.empty((5, h, w), _F32)
    form_kernel(np.ascontiguousarray(f0, dtype=_F32), f1, weight, np.ascontiguousarray(v0, dtype=_F32), robust,
                _F32(params.delta), out)
    return out
