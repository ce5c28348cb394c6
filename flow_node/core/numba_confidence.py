"""The confidence of a flow with numba kernels: :func:`confidence_numba`, the numba backend's ``confidence``
(the reference and test oracle is confidence.confidence).

The reference chains a dozen whole-image passes with temporaries (the sampling maps, an OpenCV remap of
frame 1's (h, w, 3) planes, their difference summed over the last axis, the gradient magnitude, two box
means, the division, the mask); here one pass writes, per pixel, the residual (frame 1's planes sampled
bilinearly as OpenCV's remap samples them: inside as in numba_fusion, outside the image at the clamped
position, as BORDER_REPLICATE does) and the gradient magnitude of frame 0 side by side, one OpenCV box
filter averages both, and one pass turns them into the confidence (0 where x + f leaves the image). The
planes (I, dI/dx, dI/dy) and the box filter stay OpenCV's. Same result as the reference up to float32
rounding (test_confidence_numba.py). Rows run in parallel on images of numba_backend.PARALLEL_MIN_PIXELS or
more.
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit, prange

from . import numba_backend as nb
from .confidence import CONFIDENCE_SCALE_PX, CONFIDENCE_WINDOW
from .workspace import scratch

_F32 = np.float32
# fastmath: every value is finite here (the engine's flow is checked finite, the frames are in [0, 1])
_JIT = dict(cache=True, fastmath=True, error_model="numpy", nogil=True)
_EPS = _F32(1e-3)  # confidence.confidence: the gradient floor of the division


@njit(**_JIT)
def _planes_row(out, img, i):  # noqa: ANN001, ANN202
    """Row i of fusion.planes(img) into ``out`` (h, w, 3): I, dI/dx, dI/dy as 3x3 Sobel / 8 with the
    border replicated (fusion._grad)."""
    h, w = img.shape
    up, down = max(i - 1, 0), min(i + 1, h - 1)
    eighth = _F32(0.125)
    for j in range(w):
        left, right = max(j - 1, 0), min(j + 1, w - 1)
        dx = (img[up, right] - img[up, left]) + _F32(2) * (img[i, right] - img[i, left]) \
            + (img[down, right] - img[down, left])
        dy = (img[down, left] - img[up, left]) + _F32(2) * (img[down, j] - img[up, j]) \
            + (img[down, right] - img[up, right])
        out[i, j, 0] = img[i, j]
        out[i, j, 1] = dx * eighth
        out[i, j, 2] = dy * eighth


@njit(**_JIT)
def _terms_row(out, s0, s1, flat1, flow, i):  # noqa: ANN001, ANN202
    """Row i of the two box inputs, interleaved: out[..., 0] = |I1(x + f) - I0(x)|_1 over the 3 planes of
    s0, s1 (h, w, 3), I1 sampled bilinearly at x + f clamped into the image (fusion.warp_residual's remap
    with BORDER_REPLICATE; ``flat1`` is s1 flat, read at offsets computed once per pixel); out[..., 1] =
    |dI0/dx| + |dI0/dy|. ``flow`` (h, w, 2)."""
    h, w = s0.shape[0], s0.shape[1]
    right, bottom = _F32(w - 1), _F32(h - 1)
    y_row = _F32(i)
    for j in range(w):
        x = min(max(_F32(j) + flow[i, j, 0], _F32(0)), right)
        y = min(max(y_row + flow[i, j, 1], _F32(0)), bottom)
        xa, ya = int(x), int(y)  # x, y >= 0: truncation is floor
        ax, ay = x - _F32(xa), y - _F32(ya)
        o00 = 3 * (ya * w + xa)
        o01 = o00 + (3 if xa < w - 1 else 0)  # the far taps clamped (their weight is 0 there)
        step = 3 * w if ya < h - 1 else 0
        o10, o11 = o00 + step, o01 + step
        r = _F32(0)
        for c in range(3):
            top = flat1[o00 + c] + ax * (flat1[o01 + c] - flat1[o00 + c])
            bottom_row = flat1[o10 + c] + ax * (flat1[o11 + c] - flat1[o10 + c])
            r += abs(top + ay * (bottom_row - top) - s0[i, j, c])
        out[i, j, 0] = r
        out[i, j, 1] = abs(s0[i, j, 1]) + abs(s0[i, j, 2])


@njit(**_JIT)
def _confidence_row(conf, boxed, flow, inv_scale, i):  # noqa: ANN001, ANN202
    """Row i of the confidence 1 / (1 + e^2), e = box(residual) / (box(gradient) + 1e-3) / scale (as
    g^2 / (g^2 + r^2): one division), and 0 where x + f leaves the image (operators.warp_maps' test)."""
    h, w = conf.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    y_row = _F32(i)
    for j in range(w):
        x, y = _F32(j) + flow[i, j, 0], y_row + flow[i, j, 1]
        g = boxed[i, j, 1] + _EPS
        r = boxed[i, j, 0] * inv_scale
        c = g * g / (g * g + r * r)
        conf[i, j] = c if (x >= 0) & (x <= right) & (y >= 0) & (y <= bottom) else _F32(0)


# One driver per row function, written out (not built by a factory: numba_fusion says why).
@njit(parallel=True, **_JIT)
def planes_kernel(out, img):  # noqa: ANN001, ANN201
    """:func:`_planes_row` over every row of ``out``."""
    for i in prange(out.shape[0]):
        _planes_row(out, img, i)


@njit(parallel=True, **_JIT)
def terms_kernel(out, s0, s1, flow):  # noqa: ANN001, ANN201
    """:func:`_terms_row` over every row of ``out``."""
    flat1 = s1.reshape(-1)
    for i in prange(out.shape[0]):
        _terms_row(out, s0, s1, flat1, flow, i)


@njit(parallel=True, **_JIT)
def confidence_kernel(conf, boxed, flow, inv_scale):  # noqa: ANN001, ANN201
    """:func:`_confidence_row` over every row of ``conf``."""
    for i in prange(conf.shape[0]):
        _confidence_row(conf, boxed, flow, inv_scale, i)


def confidence_numba(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """confidence.confidence with the kernels above: same arguments (frames (H, W), flow (H, W, 2)), same
    result up to float32 rounding; float32 (H, W) in [0, 1]."""
    flow = np.ascontiguousarray(flow, dtype=_F32)
    h, w = flow.shape[:2]
    # the temporaries are the calling thread's scratch (fresh ~1 MB arrays cost page faults every frame)
    s0, s1 = scratch("confidence_s0", (h, w, 3)), scratch("confidence_s1", (h, w, 3))
    boxed = scratch("confidence_boxed", (h, w, 2))
    conf = np.empty((h, w), _F32)
    with nb.thread_count(nb.threads() if h * w >= nb.LINEARISE_PARALLEL_MIN_PIXELS else 1):
        planes_kernel(s0, np.ascontiguousarray(i0, dtype=_F32))
        planes_kernel(s1, np.ascontiguousarray(i1, dtype=_F32))
        terms_kernel(boxed, s0, s1, flow)
        cv2.boxFilter(boxed, -1, (CONFIDENCE_WINDOW, CONFIDENCE_WINDOW), dst=boxed, borderType=cv2.BORDER_REFLECT)
        confidence_kernel(conf, boxed, flow, _F32(1.0 / CONFIDENCE_SCALE_PX))
    return conf
