"""numba kernels of the warp: the cubic sample (warping.sample_coefficients), the B-spline prefilter
(warping.bspline_prefilter) and the whole linearisation of one warp (operators.linearise) in one pass.

Same arithmetic as the numpy references (the oracles, test_warping.py / test_numba_backend.py). A sample
position's taps and weights are computed once (:func:`taps`) and shared by every channel sampled there
(:func:`tap_sum`): the linearisation samples I1 and both components of its gradient at x + v0 with the
same 4 x 4 taps, forms a and c, and masks the pixels whose target leaves the image -- one kernel over the
level instead of a dozen numpy passes and temporaries. Within a row it first computes every pixel's tap
weights (vectorised), then gathers; away from the border a tap row is four adjacent samples, so only
pixels near the border pay for mirrored indices.
"""

from __future__ import annotations

import numpy as np
from numba import get_thread_id, njit, prange

from .numba_kernels import _ONE

_JIT = dict(fastmath=True, cache=True, error_model="numpy", nogil=True)

_HALF = np.float32(0.5)


@njit(**_JIT)
def cubic_weights4(t, kernel):  # noqa: ANN001, ANN201
    """Tap weights at offsets -1, 0, 1, 2 for the fraction t (warping.cubic_weights): kernel 0 = Keys
    a = -1/2, 1 = cubic B-spline."""
    s = _ONE - t
    if kernel == 0:  # Keys a = -1/2 written per tap (the same polynomials, expanded)
        h = _HALF
        return (h * t * (-s * s), _ONE + t * t * (np.float32(1.5) * t - np.float32(2.5)),
                _ONE + s * s * (np.float32(1.5) * s - np.float32(2.5)), h * s * (-t * t))
    sixth = np.float32(1.0 / 6.0)
    return (sixth * s * s * s, np.float32(2.0 / 3.0) - t * t * (_ONE - _HALF * t),
            np.float32(2.0 / 3.0) - s * s * (_ONE - _HALF * s), sixth * t * t * t)


@njit(**_JIT)
def _floor(x):  # noqa: ANN001, ANN201
    """floor of a float32 as an int64, without math.floor's float64 round trip."""
    i = np.int64(x)
    return i - 1 if x < i else i


@njit(**_JIT)
def _mirror(i, n):  # noqa: ANN001, ANN201
    """warping.mirror_index for one index."""
    i = -i if i < 0 else i
    i = 2 * (n - 1) - i if i > n - 1 else i
    return min(max(i, 0), n - 1)


@njit(**_JIT)
def tap_indices(i0, n):  # noqa: ANN001, ANN201
    """The four tap indices i0 - 1 .. i0 + 2, mirrored at the borders (interior: no reflection)."""
    if i0 >= 1 and i0 + 2 < n:
        return i0 - 1, i0, i0 + 1, i0 + 2
    return _mirror(i0 - 1, n), _mirror(i0, n), _mirror(i0 + 1, n), _mirror(i0 + 2, n)


@njit(**_JIT)
def taps(mx, my, h, w, kernel):  # noqa: ANN001, ANN201
    """Weights and indices of the 4 x 4 taps around (mx, my) in an (h, w) image: (wx, wy, cols, rows)."""
    xi, yi = _floor(mx), _floor(my)
    return (cubic_weights4(mx - np.float32(xi), kernel), cubic_weights4(my - np.float32(yi), kernel),
            tap_indices(xi, w), tap_indices(yi, h))


@njit(**_JIT)
def tap_sum(img, ch, wx, wy, cols, rows):  # noqa: ANN001, ANN201
    """sum of weight * img[ch] over the taps of :func:`taps` (rows outer, as warping.sample_coefficients).
    The indices (never negative: mirrored or interior) are read as unsigned, so that numba emits no
    negative-index wraparound per load (48 selects per linearised pixel; the sums are the same, 25-35 %
    less time in the gathers)."""
    c0, c1, c2, c3 = np.uint64(cols[0]), np.uint64(cols[1]), np.uint64(cols[2]), np.uint64(cols[3])
    r0, r1, r2, r3 = np.uint64(rows[0]), np.uint64(rows[1]), np.uint64(rows[2]), np.uint64(rows[3])
    ch = np.uint64(ch)
    wx0, wx1, wx2, wx3 = wx
    wy0, wy1, wy2, wy3 = wy
    return (wy0 * (wx0 * img[ch, r0, c0] + wx1 * img[ch, r0, c1] + wx2 * img[ch, r0, c2] + wx3 * img[ch, r0, c3])
            + wy1 * (wx0 * img[ch, r1, c0] + wx1 * img[ch, r1, c1] + wx2 * img[ch, r1, c2] + wx3 * img[ch, r1, c3])
            + wy2 * (wx0 * img[ch, r2, c0] + wx1 * img[ch, r2, c1] + wx2 * img[ch, r2, c2] + wx3 * img[ch, r2, c3])
            + wy3 * (wx0 * img[ch, r3, c0] + wx1 * img[ch, r3, c1] + wx2 * img[ch, r3, c2] + wx3 * img[ch, r3, c3]))


@njit(**_JIT)
def _warp_row(img, map_x, map_y, kernel, out, i):  # noqa: ANN001, ANN201
    """Row i of :func:`warp_kernel`."""
    h, w = img.shape[1], img.shape[2]
    for j in range(map_x.shape[1]):
        wx, wy, cols, rows = taps(map_x[i, j], map_y[i, j], h, w, kernel)
        for ch in range(img.shape[0]):
            out[ch, i, j] = tap_sum(img, ch, wx, wy, cols, rows)


@njit(parallel=True, **_JIT)
def warp_kernel(img, map_x, map_y, kernel, out, parallel):  # noqa: ANN001, ANN201
    """out[c, i, j] = separable cubic sample of img[c] (C, H, W) at (map_x, map_y)[i, j], mirrored taps;
    rows in parallel when ``parallel`` (else serial: cheaper on small levels)."""
    if parallel:
        for i in prange(map_x.shape[0]):
            _warp_row(img, map_x, map_y, kernel, out, i)
    else:
        for i in range(map_x.shape[0]):
            _warp_row(img, map_x, map_y, kernel, out, i)


@njit(**_JIT)
def row_taps(flow, i, h, w, kernel, scratch, base):  # noqa: ANN001, ANN201
    """The first pass over row i of a warp by ``flow`` (2, H, W) in an (h, w) image: each pixel's tap weights
    (x: scratch[0:4], y: scratch[4:8]) and inside mask (scratch[8]: 1 where x + flow stays inside the image,
    else 0) into ``scratch`` (9, W), the floor of its position into ``base`` (2, W) (0 outside). No gathers,
    no branches: vectorised. Then :func:`row_block` and :func:`tap_sum` per pixel."""
    right, bottom = np.float32(w - 1), np.float32(h - 1)
    zero = np.float32(0.0)
    for j in range(flow.shape[2]):
        mx, my = np.float32(j) + flow[0, i, j], np.float32(i) + flow[1, i, j]
        inside = mx >= 0 and mx <= right and my >= 0 and my <= bottom
        mx = mx if inside else zero  # outside (or NaN): a harmless position, masked below
        my = my if inside else zero
        xi, yi = np.int64(mx), np.int64(my)  # mx, my >= 0: truncation is the floor
        wx0, wx1, wx2, wx3 = cubic_weights4(mx - np.float32(xi), kernel)
        wy0, wy1, wy2, wy3 = cubic_weights4(my - np.float32(yi), kernel)
        scratch[0, j], scratch[1, j], scratch[2, j], scratch[3, j] = wx0, wx1, wx2, wx3
        scratch[4, j], scratch[5, j], scratch[6, j], scratch[7, j] = wy0, wy1, wy2, wy3
        scratch[8, j] = _ONE if inside else zero
        base[0, j], base[1, j] = xi, yi


@njit(inline="always", **_JIT)
def row_block(scratch, base, j, h, w):  # noqa: ANN001, ANN201
    """Pixel j's taps from :func:`row_taps`' row scratch: (wx, wy, cols, rows) for :func:`tap_sum` -- adjacent,
    unmirrored taps wherever the 4 x 4 block lies inside the image (one test for both axes), mirrored ones near
    the border."""
    wx = (scratch[0, j], scratch[1, j], scratch[2, j], scratch[3, j])
    wy = (scratch[4, j], scratch[5, j], scratch[6, j], scratch[7, j])
    xi, yi = np.int64(base[0, j]), np.int64(base[1, j])
    if xi >= 1 and xi + 2 < w and yi >= 1 and yi + 2 < h:  # interior: one branch for both axes
        return wx, wy, (xi - 1, xi, xi + 1, xi + 2), (yi - 1, yi, yi + 1, yi + 2)
    return wx, wy, tap_indices(xi, w), tap_indices(yi, h)


@njit(**_JIT)
def _linearise_row(i0, src, g0, flow, kernel, interpolated, a, c, i, scratch, base):  # noqa: ANN001, ANN201
    """Row i of :func:`linearise_kernel`, in two passes over the row: :func:`row_taps`, then the gathers
    (:func:`tap_sum`) of the pixels inside."""
    h, w = i0.shape
    zero = np.float32(0.0)
    ig = min(np.int64(i), g0.shape[1] - 1)  # g0 is a (2, 1, W) zero row when not ``interpolated``
    row_taps(flow, i, h, w, kernel, scratch, base)
    for j in range(w):
        if scratch[8, j] == zero:  # target outside: no data term
            a[0, i, j] = 0
            a[1, i, j] = 0
            c[i, j] = 0
            continue
        wx, wy, cols, rows = row_block(scratch, base, j, h, w)
        i1w = tap_sum(src, 0, wx, wy, cols, rows)
        a0 = tap_sum(src, 1, wx, wy, cols, rows)
        a1 = tap_sum(src, 2, wx, wy, cols, rows)
        if interpolated:
            a0 = _HALF * (g0[0, ig, j] + a0)
            a1 = _HALF * (g0[1, ig, j] + a1)
        a[0, i, j] = a0
        a[1, i, j] = a1
        c[i, j] = i1w - i0[i, j] - a0 * flow[0, i, j] - a1 * flow[1, i, j]


@njit(_nrt=False, **_JIT)  # no reference counts: a view per channel and row (task fastcens)
def sample_row(coefs, frames, flow, i, kernel, weight, out, slot, col, keep, scratch, base):  # noqa: ANN001, ANN201
    """Row i of every channel of frame 1 sampled at x + flow (census.warped_frames): out[:, slot, col:col + W] of
    out (C, ., >= col + W) from the interpolation coefficients ``coefs`` (C, H, W), where x + flow leaves the image
    the channels of ``frames`` (C, H, W) themselves; keep (W) = ``weight`` inside, 0 outside. ``scratch`` (9, W),
    ``base`` (2, W): row scratch of :func:`row_taps`. Channel by channel over the row (1-D views: 1.7x faster
    than the channels inside the pixel loop)."""
    h, w = coefs.shape[1], coefs.shape[2]
    zero = np.float32(0.0)
    row_taps(flow, i, h, w, kernel, scratch, base)
    for ch in range(coefs.shape[0]):
        dst, src = out[ch, slot], frames[ch, i]
        for j in range(w):
            if scratch[8, j] == zero:
                dst[col + j] = src[j]
            else:
                wx, wy, cols, rows = row_block(scratch, base, j, h, w)
                dst[col + j] = tap_sum(coefs, ch, wx, wy, cols, rows)
    for j in range(w):
        keep[j] = weight * scratch[8, j]


@njit(parallel=True, **_JIT)
def linearise_kernel(i0, src, g0, flow, kernel, interpolated, a, c, scratch, base, parallel):  # noqa: ANN001, ANN201
    """operators.linearise in one pass: a (2, H, W) and c (H, W) of the data term linearised around flow
    (2, H, W), from i0 (H, W), the warp source src (3, H, W) = coefficients of [I1, dI1/dx, dI1/dy] and,
    when ``interpolated``, frame 0's gradient g0 (2, H, W) (else a (2, 1, W) zero row, not read: its row index
    is clamped, numba_kernels.py says why). ``scratch`` (threads,
    9, W) float32 and ``base`` (threads, 2, W) int32 are per-thread row scratch. Rows in parallel when
    ``parallel``."""
    if parallel:
        for i in prange(i0.shape[0]):
            t = get_thread_id()
            _linearise_row(i0, src, g0, flow, kernel, interpolated, a, c, i, scratch[t], base[t])
    else:
        for i in range(i0.shape[0]):
            _linearise_row(i0, src, g0, flow, kernel, interpolated, a, c, i, scratch[0], base[0])


@njit(cache=True, error_model="numpy", nogil=True)  # no fastmath: (b - a) * 0.5 exactly as numpy rounds it
def gradient_kernel(img, central, out):  # noqa: ANN001, ANN201
    """operators.image_gradient of an image (H, W) into out (2, H, W) in one pass: the central difference
    (I(x+1) - I(x-1)) * 0.5 (``central``) or the forward one I(x+1) - I(x), along x (out[0]) and y (out[1]),
    zero on the border entries the reference leaves zero."""
    h, w = img.shape
    half = np.float32(0.5)
    zero = np.float32(0.0)
    for i in range(h):
        gx, gy = out[0, i], out[1, i]
        if central:
            gx[0] = zero
            for j in range(1, w - 1):
                gx[j] = (img[i, j + 1] - img[i, j - 1]) * half
            gx[w - 1] = zero
            if i == 0 or i == h - 1:
                gy[:] = zero
            else:
                for j in range(w):
                    gy[j] = (img[i + 1, j] - img[i - 1, j]) * half
        else:
            for j in range(w - 1):
                gx[j] = img[i, j + 1] - img[i, j]
            gx[w - 1] = zero
            if i == h - 1:
                gy[:] = zero
            else:
                for j in range(w):
                    gy[j] = img[i + 1, j] - img[i, j]


@njit(**_JIT)
def bspline_columns(img, pole, horizon):  # noqa: ANN001, ANN201
    """In place: the B-spline direct transform of every column of each plane of img (N, H, W), run over
    whole rows (unit stride: one strided line per column misses the cache on every element). The recursion
    of warping.bspline_prefilter (causal, then anti-causal, mirrored start); the carried row is read back as
    float32."""
    n, h, w = img.shape
    if h == 1:
        return
    z = np.float32(pole)
    six = np.float32(6.0)
    end = np.float32(pole / (pole * pole - 1.0))
    acc = np.empty(w, np.float64)
    for p in range(n):
        plane = img[p]
        acc[:] = 0.0
        zk = 1.0
        for k in range(horizon):  # mirrored causal start
            for j in range(w):
                acc[j] += zk * 6.0 * plane[k, j]
            zk *= pole
        for j in range(w):
            plane[0, j] = acc[j]
        for k in range(1, h):
            for j in range(w):
                plane[k, j] = six * plane[k, j] + z * plane[k - 1, j]
        for j in range(w):
            plane[h - 1, j] = end * (plane[h - 1, j] + z * plane[h - 2, j])
        for k in range(h - 2, -1, -1):
            for j in range(w):
                plane[k, j] = z * (plane[k + 1, j] - plane[k, j])
