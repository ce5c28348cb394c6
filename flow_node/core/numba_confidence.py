"""The confidence of a flow with numba kernels: :func:`confidence_numba`, the numba backend's ``confidence``
(the reference and test oracle is confidence.confidence).

The reference chains a dozen whole-image passes with temporaries (the sampling maps, an OpenCV remap of
frame 1's (h, w, 3) planes, their difference summed over the last axis, the gradient magnitude, two box
means, the division, the mask); here frame 1's planes are written once, then one pass writes, per pixel,
the residual (frame 0's planes computed in place, frame 1's sampled
bilinearly as OpenCV's remap samples them: inside as in numba_fusion, outside the image at the clamped
position, as BORDER_REPLICATE does) and the gradient magnitude of frame 0 side by side, one OpenCV box
filter averages both, and one pass turns them into the confidence (0 where x + f leaves the image). The
box filter stays OpenCV's. :func:`confidence_at_numba` computes the same at given pixels alone (the
derived motion outputs' samples): the box of each point summed from its 25 pixels' terms. Same result as
the reference up to float32 rounding (test_confidence_numba.py). Rows (points) run in parallel on images
of numba_backend.LINEARISE_PARALLEL_MIN_PIXELS or more (as many terms).
"""

from __future__ import annotations

import cv2
import numpy as np
from numba import njit, prange

from . import numba_backend as nb
from .confidence import CONFIDENCE_SCALE_PX, CONFIDENCE_WINDOW, Shared, check_points, check_where, kept
from .workspace import scratch

_F32 = np.float32
# fastmath: every value is finite here (the engine's flow is checked finite, the frames are in [0, 1])
_JIT = dict(cache=True, fastmath=True, error_model="numpy", nogil=True)
_EPS = _F32(1e-3)  # confidence.confidence: the gradient floor of the division
# confidence_at_numba: points whose boxes (25 px each) add up to at least this share of the image take the
# map near them (confidence_numba with ``where``: each pixel's terms once, frame 1's planes computed once)
# instead of every box summed from its own terms (measured: 972 points at 320x240 0.66 vs 0.70 ms, 1296
# 0.71 vs 0.92 ms; 1064 at 640x480 1.74 vs 0.80 ms)
AT_MAP_COVER = 0.25
_NONE = np.zeros((0, 0), np.bool_)  # the kernels' "no mask": every pixel


@njit(**_JIT)
def _plane_at(img, i, j):  # noqa: ANN001, ANN202
    """fusion.planes(img) at pixel (i, j): I, dI/dx, dI/dy as 3x3 Sobel / 8 with the border replicated
    (fusion._grad)."""
    h, w = img.shape
    up, down = max(i - 1, 0), min(i + 1, h - 1)
    left, right = max(j - 1, 0), min(j + 1, w - 1)
    dx = (img[up, right] - img[up, left]) + _F32(2) * (img[i, right] - img[i, left]) \
        + (img[down, right] - img[down, left])
    dy = (img[down, left] - img[up, left]) + _F32(2) * (img[down, j] - img[up, j]) \
        + (img[down, right] - img[up, right])
    return img[i, j], dx * _F32(0.125), dy * _F32(0.125)


@njit(**_JIT)
def _planes_row(out, img, i):  # noqa: ANN001, ANN202
    """Row i of fusion.planes(img) into ``out`` (h, w, 3) (:func:`_plane_at`)."""
    for j in range(img.shape[1]):
        out[i, j, 0], out[i, j, 1], out[i, j, 2] = _plane_at(img, i, j)


@njit(**_JIT)
def _terms_row(out, i0, s1, flat1, flow, need, i):  # noqa: ANN001, ANN202
    """Row i of the two box inputs, interleaved: out[..., 0] = |I1(x + f) - I0(x)|_1 over the 3 planes of
    frame i0 (h, w; its planes computed here, :func:`_plane_at`) and s1 (h, w, 3), I1 sampled bilinearly
    at x + f clamped into the image (fusion.warp_residual's remap
    with BORDER_REPLICATE; ``flat1`` is s1 flat, read at offsets computed once per pixel); out[..., 1] =
    |dI0/dx| + |dI0/dy|. ``flow`` (h, w, 2). ``need`` (h, w) bool: both 0 where it is False (an empty
    (0, 0) array: every pixel computed)."""
    h, w = i0.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    y_row = _F32(i)
    every = need.shape[0] == 0
    for j in range(w):
        if not (every or need[i, j]):
            out[i, j, 0] = out[i, j, 1] = _F32(0)
            continue
        p0 = _plane_at(i0, i, j)
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
            r += abs(top + ay * (bottom_row - top) - p0[c])
        out[i, j, 0] = r
        out[i, j, 1] = abs(p0[1]) + abs(p0[2])


@njit(**_JIT)
def _ratio(r_box, g_box, inv_scale):  # noqa: ANN001, ANN202
    """The confidence 1 / (1 + e^2) of box means r_box (residual) and g_box (gradient magnitude),
    e = r_box / (g_box + 1e-3) / scale, as g^2 / (g^2 + r^2): one division."""
    g = g_box + _EPS
    r = r_box * inv_scale
    return g * g / (g * g + r * r)


@njit(**_JIT)
def _inside(flow, i, j, right, bottom):  # noqa: ANN001, ANN202
    """Whether x + f of pixel (i, j) stays in the image [0, right] x [0, bottom] (operators.warp_maps' test)."""
    x, y = _F32(j) + flow[i, j, 0], _F32(i) + flow[i, j, 1]
    return (x >= 0) & (x <= right) & (y >= 0) & (y <= bottom)


@njit(**_JIT)
def _confidence_row(conf, boxed, flow, where, inv_scale, i):  # noqa: ANN001, ANN202
    """Row i of the confidence (:func:`_ratio` of the box means), 0 where x + f leaves the image and where
    ``where`` (h, w) bool is False (an empty (0, 0) array: nowhere)."""
    h, w = conf.shape
    right, bottom = _F32(w - 1), _F32(h - 1)
    every = where.shape[0] == 0
    for j in range(w):
        if (every or where[i, j]) and _inside(flow, i, j, right, bottom):
            conf[i, j] = _ratio(boxed[i, j, 0], boxed[i, j, 1], inv_scale)
        else:
            conf[i, j] = _F32(0)


@njit(**_JIT)
def _terms_at(i0, i1, flow, i, j):  # noqa: ANN001, ANN202
    """:func:`_terms_row`'s two values at pixel (i, j) alone, the planes of frames i0, i1 (h, w) computed
    at the taps (:func:`_plane_at`): the residual over the 3 planes and |dI0/dx| + |dI0/dy|."""
    h, w = i0.shape
    x = min(max(_F32(j) + flow[i, j, 0], _F32(0)), _F32(w - 1))
    y = min(max(_F32(i) + flow[i, j, 1], _F32(0)), _F32(h - 1))
    xa, ya = int(x), int(y)  # x, y >= 0: truncation is floor
    ax, ay = x - _F32(xa), y - _F32(ya)
    xb, yb = min(xa + 1, w - 1), min(ya + 1, h - 1)  # the far taps clamped (their weight is 0 there)
    p0 = _plane_at(i0, i, j)
    t00, t01, t10, t11 = _plane_at(i1, ya, xa), _plane_at(i1, ya, xb), _plane_at(i1, yb, xa), _plane_at(i1, yb, xb)
    r = _F32(0)
    for c in range(3):
        top = t00[c] + ax * (t01[c] - t00[c])
        bottom_row = t10[c] + ax * (t11[c] - t10[c])
        r += abs(top + ay * (bottom_row - top) - p0[c])
    return r, abs(p0[1]) + abs(p0[2])


@njit(**_JIT)
def _reflect(k, n):  # noqa: ANN001, ANN202
    """Index k folded into [0, n) as OpenCV's BORDER_REFLECT does (fedcba|abcdef|fedcba)."""
    if n == 1:
        return 0
    while k < 0 or k >= n:
        k = -k - 1 if k < 0 else 2 * n - k - 1
    return k


# One driver per row function, written out (not built by a factory: numba_fusion says why).
@njit(parallel=True, **_JIT)
def planes_kernel(out, img):  # noqa: ANN001, ANN201
    """:func:`_planes_row` over every row of ``out``."""
    for i in prange(out.shape[0]):
        _planes_row(out, img, i)


@njit(parallel=True, **_JIT)
def terms_kernel(out, i0, s1, flow, need):  # noqa: ANN001, ANN201
    """:func:`_terms_row` over every row of ``out``."""
    flat1 = s1.reshape(-1)
    for i in prange(out.shape[0]):
        _terms_row(out, i0, s1, flat1, flow, need, i)


@njit(parallel=True, **_JIT)
def confidence_kernel(conf, boxed, flow, where, inv_scale):  # noqa: ANN001, ANN201
    """:func:`_confidence_row` over every row of ``conf``."""
    for i in prange(conf.shape[0]):
        _confidence_row(conf, boxed, flow, where, inv_scale, i)


def confidence_numba(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, where: np.ndarray | None = None,
                     shared: Shared | None = None) -> np.ndarray:
    """confidence.confidence with the kernels above: same arguments (frames (H, W), flow (H, W, 2), ``where``
    (H, W) bool or None, ``shared``: frame 1's planes kept there for the pair's next call), same result up
    to float32 rounding; float32 (H, W) in [0, 1]. With ``where`` the residual terms are computed only
    within the box's reach of it (:func:`_box_means`) and the ratio only at ``where``: what the moving mask
    needs, about that share of the terms pass (the bulk of the cost)."""
    flow = np.ascontiguousarray(flow, dtype=_F32)
    h, w = flow.shape[:2]
    check_where((h, w), where)
    conf = np.empty((h, w), _F32)
    with nb.threads_for(h * w, nb.LINEARISE_PARALLEL_MIN_PIXELS):
        boxed = _box_means(i0, i1, flow, where, shared)
        confidence_kernel(conf, boxed, flow, _NONE if where is None else np.ascontiguousarray(where),
                          _F32(1.0 / CONFIDENCE_SCALE_PX))
    return conf


def _box_means(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, where: np.ndarray | None,
               shared: Shared | None) -> np.ndarray:
    """The CONFIDENCE_WINDOW box means of the residual and of the gradient magnitude (h, w, 2) float32 (the
    thread's scratch), right at least where ``where`` (H, W) bool is True (None: everywhere): the terms
    (:func:`terms_kernel`) computed only within the box's reach of it (its CONFIDENCE_WINDOW dilation; 0
    beyond, which no box of a ``where`` pixel reads, also where the border is reflected), the box filter on
    the rows of that reach (:func:`_band`). Frame 1's planes from ``shared`` when a call on the pair has
    computed them (else computed, and kept there); run under the caller's thread count."""
    h, w = flow.shape[:2]
    need = _NONE if where is None else cv2.dilate(where.view(np.uint8), np.ones(
        (CONFIDENCE_WINDOW, CONFIDENCE_WINDOW), np.uint8)).view(np.bool_)
    i1 = np.ascontiguousarray(i1, dtype=_F32)
    # the temporaries are the calling thread's scratch (fresh ~1 MB arrays cost page faults every frame), but
    # for planes kept in ``shared``, which a later call (on another pair) must not overwrite
    s1 = _planes(i1, scratch("confidence_s1", (h, w, 3))) if shared is None else \
        kept(shared, "numba.planes1", lambda: _planes(i1, np.empty((h, w, 3), _F32)))
    boxed = scratch("confidence_boxed", (h, w, 2))  # frame 0's planes are computed where they are used
    terms_kernel(boxed, np.ascontiguousarray(i0, dtype=_F32), s1, flow, need)
    band = boxed if where is None else boxed[_band(need)]  # where: the rows within the box's reach alone
    if band.size:
        cv2.boxFilter(band, -1, (CONFIDENCE_WINDOW, CONFIDENCE_WINDOW), dst=band, borderType=cv2.BORDER_REFLECT)
    return boxed


def _planes(img: np.ndarray, out: np.ndarray) -> np.ndarray:
    """fusion.planes of ``img`` (h, w) float32 into ``out`` (h, w, 3) (:func:`planes_kernel`); ``out``."""
    planes_kernel(out, img)
    return out


def _band(need: np.ndarray) -> slice:
    """The rows from the first to the last with a True in ``need`` (H, W) bool (none: an empty slice). The box
    filter on those rows alone gives every pixel whose whole box lies in ``need`` its value: its box's rows
    are in the band, and only rows beyond the band's ends are reflected differently."""
    rows = np.flatnonzero(need.any(axis=1))
    return slice(int(rows[0]), int(rows[-1]) + 1) if rows.size else slice(0, 0)


@njit(parallel=True, **_JIT)
def confidence_at_kernel(out, i0, i1, flow, ys, xs, inv_scale):  # noqa: ANN001, ANN201
    """The confidence at the points (ys[n], xs[n]) into ``out`` (n,): the CONFIDENCE_WINDOW box means of
    :func:`_terms_at` (borders reflected, as the box filter's), :func:`_ratio`, 0 where x + f leaves."""
    h, w = i0.shape
    half, area = CONFIDENCE_WINDOW // 2, _F32(CONFIDENCE_WINDOW * CONFIDENCE_WINDOW)
    right, bottom = _F32(w - 1), _F32(h - 1)
    for n in prange(ys.size):
        i, j = ys[n], xs[n]
        r_sum, g_sum = _F32(0), _F32(0)
        for di in range(-half, half + 1):
            q = _reflect(i + di, h)
            for dj in range(-half, half + 1):
                r, g = _terms_at(i0, i1, flow, q, _reflect(j + dj, w))
                r_sum += r
                g_sum += g
        c = _ratio(r_sum / area, g_sum / area, inv_scale)
        out[n] = c if _inside(flow, i, j, right, bottom) else _F32(0)


@njit(**_JIT)
def ratio_at_kernel(out, boxed, flow, ys, xs, inv_scale):  # noqa: ANN001, ANN201
    """:func:`_confidence_row`'s value at the points (ys[n], xs[n]) alone into ``out`` (n,): :func:`_ratio` of
    the box means ``boxed`` (h, w, 2) there, 0 where x + f leaves the image."""
    h, w = boxed.shape[:2]
    right, bottom = _F32(w - 1), _F32(h - 1)
    for n in range(ys.size):
        i, j = ys[n], xs[n]
        out[n] = _ratio(boxed[i, j, 0], boxed[i, j, 1], inv_scale) if _inside(flow, i, j, right, bottom) else _F32(0)


def confidence_at_numba(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, ys: np.ndarray, xs: np.ndarray,
                        shared: Shared | None = None) -> np.ndarray:
    """confidence.confidence_at with :func:`confidence_at_kernel`: the confidence at the pixels (ys, xs)
    (integer arrays of one shape, inside the image) alone, ~25 x 5 plane evaluations per point instead of
    whole-image passes, or, for points dense enough (AT_MAP_COVER), the box means near them
    (:func:`_box_means`, frame 1's planes kept in ``shared``) and the ratio at the points alone (the values
    of confidence_numba with ``where`` the points, bit for bit); float32 of ys' shape, the full map's values
    up to float32 rounding."""
    flow = np.ascontiguousarray(flow, dtype=_F32)
    h, w = flow.shape[:2]
    check_points((h, w), ys, xs)
    yi, xi = (np.ascontiguousarray(np.ravel(a), dtype=np.int64) for a in (ys, xs))
    work = yi.size * CONFIDENCE_WINDOW * CONFIDENCE_WINDOW
    out = np.empty(yi.size, _F32)
    if work >= AT_MAP_COVER * h * w:  # dense points: the map near them
        where = np.zeros((h, w), np.bool_)
        where[yi, xi] = True
        with nb.threads_for(h * w, nb.LINEARISE_PARALLEL_MIN_PIXELS):
            ratio_at_kernel(out, _box_means(i0, i1, flow, where, shared), flow, yi, xi, _F32(1.0 / CONFIDENCE_SCALE_PX))
        return out.reshape(np.shape(ys))
    with nb.threads_for(work, nb.LINEARISE_PARALLEL_MIN_PIXELS):
        confidence_at_kernel(out, np.ascontiguousarray(i0, dtype=_F32), np.ascontiguousarray(i1, dtype=_F32),
                             flow, yi, xi, _F32(1.0 / CONFIDENCE_SCALE_PX))
    return out.reshape(np.shape(ys))
