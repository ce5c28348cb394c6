"""The edge weight g of the TV term in one compiled kernel: :func:`edge_weight_numba`, the numba backend's
edges.edge_weight (the OpenCV / numpy reference, docs/engine.md "Edge-weighted TV").

The reference makes ~12 OpenCV / numpy calls a pyramid level, and numpy's power runs per element in libm; at
fastest's sizes (a bag's 64 x 48 level, Middlebury's 292 x 194) that was 3-5 % of the preset's time (task
edgecost). Here one call does it in four passes over the rows, each vectorised along a row: the Gaussian along
rows, along columns, the central differences' magnitude with its column sums (the mean s), and the weight. The
power is repeated multiplication for an integer b (the presets' 3), and the exp is :func:`exp_parts` (a polynomial
and the exponent's bits: libm's expf is one element at a time). Each row loop indexes its arrays at plain ``j``
(row slices, not offsets or clamped indices per pixel: those kept LLVM from vectorising the loops, 3-5x slower).
The values match the reference to a few float32 ulps, not bit for bit: the blur sums in another order, x^3 rounds
twice, the exp is another approximation (test_edge_tv).
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numba import njit
from numba.extending import register_jitable

from .edges import EDGE_SIGMA, TINY
from .numba_kernels import FASTMATH
from .workspace import scratch

_JIT = dict(fastmath=FASTMATH, cache=True, error_model="numpy", nogil=True)  # the solver's flags
# the kernel's parts: compiled into it, not dispatchers of their own (a cached dispatcher costs a fresh process's
# import 1-2 ms on a loaded machine, docs/engine.md "Compiled kernels"); exp_parts is callable from Python too
_INLINE = dict(fastmath=FASTMATH, error_model="numpy")
_F32 = np.float32
_ONE = _F32(1.0)
_LOG2E = _F32(1.4426950408889634)
_LN2_HI = _F32(0.693359375)  # ln 2 in two parts (Cody-Waite): k * _LN2_HI is exact for k < 2^10
_LN2_LO = _F32(-2.12194440e-4)
EXP_MIN = -87.0  # exp_parts' least argument: 2^-126 (float32's least normal number) is e^-87.3
RADIUS = 4  # the kernel's Gaussian: OpenCV's 9 taps for sigma 1 (EDGE_SIGMA)


def gaussian_taps(sigma: float) -> np.ndarray:
    """The 1-D Gaussian cv2.GaussianBlur(sigma) uses on a float32 image, float32: OpenCV's size for it
    (round(8 sigma + 1), odd) and its kernel."""
    size = int(round(sigma * 8 + 1)) | 1
    return cv2.getGaussianKernel(size, sigma, cv2.CV_32F).ravel().astype(_F32)


TAPS = gaussian_taps(EDGE_SIGMA)  # 2 RADIUS + 1 of them (test_numba_edges)
_HALF = tuple(_F32(t) for t in TAPS[RADIUS:])  # centre, then the taps at distance 1 .. RADIUS (symmetric)


@register_jitable(**_INLINE)
def exp_parts(y, lo):  # noqa: ANN001, ANN201
    """exp(max(y, lo)) for lo >= EXP_MIN, y <= 0, as (p, e): exp = p * 2^-k with e = (127 - k) << 23 the bits of
    the float32 2^-k (the caller reads them as a float32). t = -k ln 2 + r, |r| <= ln 2 / 2, p = exp(r) by its
    Taylor series to r^7 (truncation < 6e-9 relative): within ~2 ulp of libm's expf. Arithmetic only, so a pixel
    loop of it vectorises."""
    t = max(y, lo)
    k = np.floor(-t * _LOG2E + np.float32(0.5))  # np.floor keeps float32 (math.floor: an int)
    r = (t + k * _LN2_HI) + k * _LN2_LO
    p = _ONE + r * (_ONE + r * (np.float32(1 / 2) + r * (np.float32(1 / 6) + r * (np.float32(1 / 24) + r * (
        np.float32(1 / 120) + r * (np.float32(1 / 720) + r * np.float32(1 / 5040)))))))
    return p, (np.int32(127) - np.int32(k)) << np.int32(23)


@register_jitable(**_INLINE)
def _blur_rows(img, c0, c1, c2, c3, c4, out, pad):  # noqa: ANN001, ANN201
    """The 9-tap symmetric Gaussian (centre c0, c1 .. c4 at distance 1 .. 4) along each row of ``img`` into
    ``out``, ends replicated (``pad``: W + 8 scratch)."""
    h, w = img.shape
    for i in range(h):
        src = img[i]
        for j in range(RADIUS):
            pad[j] = src[0]
            pad[w + RADIUS + j] = src[w - 1]
        mid = pad[RADIUS:RADIUS + w]
        for j in range(w):
            mid[j] = src[j]
        s0, s1, s2, s3, s4 = pad[0:w], pad[1:1 + w], pad[2:2 + w], pad[3:3 + w], pad[4:4 + w]
        s5, s6, s7, s8 = pad[5:5 + w], pad[6:6 + w], pad[7:7 + w], pad[8:8 + w]
        o = out[i]
        for j in range(w):
            o[j] = (c0 * s4[j] + c1 * (s3[j] + s5[j]) + c2 * (s2[j] + s6[j]) + c3 * (s1[j] + s7[j])
                    + c4 * (s0[j] + s8[j]))


@register_jitable(**_INLINE)
def _blur_columns(img, c0, c1, c2, c3, c4, out):  # noqa: ANN001, ANN201
    """:func:`_blur_rows` along the columns (rows clamped to the image: its ends replicated)."""
    h, w = img.shape
    last = h - 1
    for i in range(h):
        r0, r1, r2, r3 = img[max(i - 4, 0)], img[max(i - 3, 0)], img[max(i - 2, 0)], img[max(i - 1, 0)]
        r4 = img[i]
        r5, r6, r7, r8 = img[min(i + 1, last)], img[min(i + 2, last)], img[min(i + 3, last)], img[min(i + 4, last)]
        o = out[i]
        for j in range(w):
            o[j] = (c0 * r4[j] + c1 * (r3[j] + r5[j]) + c2 * (r2[j] + r6[j]) + c3 * (r1[j] + r7[j])
                    + c4 * (r0[j] + r8[j]))


@register_jitable(**_INLINE)
def _gradient_magnitude(img, out, colsum):  # noqa: ANN001, ANN201
    """|grad img| by central differences halved (cv2.Sobel ksize 1, scale 0.5), ends replicated, into ``out``;
    ``colsum`` (W,) float64 gets each column's sum of it."""
    h, w = img.shape
    half = np.float32(0.5)
    colsum[:] = 0.0
    for i in range(h):
        up, row, dn, o = img[max(i - 1, 0)], img[i], img[min(i + 1, h - 1)], out[i]
        left, right, up1, dn1, o1 = row[:w - 2], row[2:], up[1:w - 1], dn[1:w - 1], o[1:w - 1]
        for j in range(w - 2):  # the interior columns
            gx = half * (right[j] - left[j])
            gy = half * (dn1[j] - up1[j])
            o1[j] = math.sqrt(gx * gx + gy * gy)
        for j in (0, w - 1):  # the first and last (the same one for a 1 px wide image)
            gx = half * (row[min(j + 1, w - 1)] - row[max(j - 1, 0)])
            gy = half * (dn[j] - up[j])
            o[j] = math.sqrt(gx * gx + gy * gy)
        for j in range(w):
            colsum[j] += o[j]


@njit(**_JIT)
def edge_weight_kernel(img, c0, c1, c2, c3, c4, a, power, b, lo, floor, out, tmp, pad, colsum, bits):  # noqa: ANN001, ANN201
    """edges.edge_weight of ``img`` (H, W) into ``out`` (H, W): the Gaussian (:func:`_blur_rows`' taps), |grad|,
    its mean s, g = max(floor, exp(-a (|grad| / s)^b)); ``power`` b as an integer >= 0 (repeated multiplication)
    or -1 (math.pow with ``b``); ``lo`` = ln(floor), at least EXP_MIN (:func:`exp_parts`). Scratch: ``tmp``
    (H, W), ``pad`` (W + 8), ``colsum`` (W,) float64, ``bits`` (W,) int32."""
    h, w = img.shape
    _blur_rows(img, c0, c1, c2, c3, c4, tmp, pad)
    _blur_columns(tmp, c0, c1, c2, c3, c4, out)
    _gradient_magnitude(out, tmp, colsum)
    scale = 0.0
    for j in range(w):
        scale += colsum[j]
    scale /= h * w
    if scale <= TINY:  # a constant level
        out[:] = _ONE
        return
    s, na = np.float32(scale), -a
    scale2 = bits.view(np.float32)
    for i in range(h):
        x, o = tmp[i], out[i]
        for j in range(w):
            x[j] = x[j] / s
        if power >= 0:
            for j in range(w):
                o[j] = _ONE
            for _ in range(power):
                for j in range(w):
                    o[j] *= x[j]
        else:
            for j in range(w):
                o[j] = math.pow(x[j], b)
        for j in range(w):
            o[j], bits[j] = exp_parts(na * o[j], lo)
        for j in range(w):
            o[j] = max(floor, o[j] * scale2[j])


def edge_weight_numba(i0: np.ndarray, a: float, b: float, floor: float, out: np.ndarray | None = None) -> np.ndarray:
    """edges.edge_weight with :func:`edge_weight_kernel`: g (H, W) float32 of a level's frame 0 ``i0``, into
    ``out`` (float32 C-contiguous (H, W), not ``i0``) or a new array. Within a few float32 ulps of the
    reference."""
    img = np.ascontiguousarray(i0, dtype=_F32)
    h, w = img.shape
    if out is None:
        out = np.empty((h, w), _F32)
    power = int(b) if float(b).is_integer() else -1
    edge_weight_kernel(img, *_HALF, _F32(a), power, _F32(b), _F32(max(math.log(floor), EXP_MIN)), _F32(floor), out,
                       scratch("edges.tmp", (h, w)), scratch("edges.pad", (w + 2 * RADIUS,)),
                       scratch("edges.colsum", (w,), np.float64), scratch("edges.bits", (w,), np.int32))
    return out
