"""The photometric stage's sorted sample with a numba kernel: :func:`sorted_sample_numba`
(photometric.sorted_sample), the numba backend's ``sample`` field; the census initialisation's mid-ranks of a
frame, :func:`ranks_numba` (initialise.equalised), its ``ranks`` field; and a frame's white-noise estimate for the
census noise floor, :func:`noise_sigma_numba` (census_noise.noise_sigma), its ``noise`` field -- with
:func:`median_f32`, np.median of float32 values (numba_census.contrast_kernel's too).

np.sort takes ~18 ns an element here (0.6 ms for the 34,000 samples of a 640x480 frame, twice a pair); an LSD
radix sort on the floats' bit patterns -- mapped to unsigned keys that order as the floats do -- takes three
counting passes of 11 bits. A sorted array of numbers is one array whichever way it was sorted, so the result
equals np.sort's (test_photometric.py); only -0.0 and 0.0, equal as numbers, may come in another order. The
frames are finite (api.to_grey), so there is no NaN to place.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from .census_noise import IMMERKAER, KERNEL_NORM, MAD_TO_STD, noise_grid
from .initialise import RANK_LEVELS
from .photometric import subsample

_BITS = 11
_ROUND = np.float32(2**23)
_DIGITS = 1 << _BITS
_SIGN = np.uint32(0x80000000)
_ALL = np.uint32(0xFFFFFFFF)


@njit(cache=True, error_model="numpy", nogil=True, inline="always")
def _key(b):  # noqa: ANN001, ANN202
    """A float32's bit pattern b (uint32) as an unsigned key that orders as the floats do: a negative float's bits
    all flipped, another's sign bit set."""
    return b ^ _ALL if b & _SIGN else b | _SIGN


@njit(cache=True, error_model="numpy", nogil=True, inline="always")
def _unkey(k):  # noqa: ANN001, ANN202
    """The float32 bit pattern of a :func:`_key`."""
    return k ^ _SIGN if k & _SIGN else k ^ _ALL


@njit(cache=True, error_model="numpy", nogil=True)
def radix_sort_kernel(values, out):  # noqa: ANN001, ANN201
    """out (n,) float32 = values (n,) float32 (finite, C-contiguous) in ascending order."""
    n = values.size
    bits = values.view(np.uint32)
    keys = np.empty(n, np.uint32)
    tmp = np.empty(n, np.uint32)
    for k in range(n):
        keys[k] = _key(bits[k])
    counts = np.empty(_DIGITS, np.int64)
    for shift in (0, _BITS, 2 * _BITS):
        counts[:] = 0
        for k in range(n):
            counts[(keys[k] >> shift) & (_DIGITS - 1)] += 1
        total = 0
        for d in range(_DIGITS):
            c = counts[d]
            counts[d] = total
            total += c
        for k in range(n):
            d = (keys[k] >> shift) & (_DIGITS - 1)
            tmp[counts[d]] = keys[k]
            counts[d] += 1
        keys, tmp = tmp, keys
    out_bits = out.view(np.uint32)
    for k in range(n):
        out_bits[k] = _unkey(keys[k])


def sorted_sample_numba(img: np.ndarray) -> np.ndarray:
    """photometric.sorted_sample with :func:`radix_sort_kernel`: the subsample of img (H, W), sorted, flat
    float32."""
    sample = np.ascontiguousarray(subsample(img), dtype=np.float32).ravel()
    out = np.empty_like(sample)
    radix_sort_kernel(sample, out)
    return out


@njit(cache=True, error_model="numpy", nogil=True)
def ranks_kernel(img, levels, out):  # noqa: ANN001, ANN201
    """initialise.equalised into out (n,) float32 from img (n,) float32 (finite, C-contiguous) on ``levels`` grey
    levels: each pixel quantised (rounded half to even, clipped) and counted in one pass, the levels' mid-ranks
    (float64, then float32) and a look-up in a second. The reference's arithmetic in its order (no fastmath):
    equal to it bit for bit."""
    n = img.size
    top = np.float32(levels - 1)
    q = np.empty(n, np.uint16)
    counts = np.zeros(levels, np.int64)
    for k in range(n):  # clipped first, then rounded: the same level (the bounds are whole); + and - 2^23 rounds
        v = min(max(img[k] * top, np.float32(0)), top)  # a float32 in [0, 2^22] half to even, as np.rint
        q[k] = np.uint16((v + _ROUND) - _ROUND)
    for k in range(n):
        counts[q[k]] += 1
    table = np.empty(levels, np.float32)
    inv = 1.0 / n
    total = 0
    for d in range(levels):
        total += counts[d]
        table[d] = np.float32((np.float64(total) - 0.5 * counts[d]) * inv)
    for k in range(n):
        out[k] = table[q[k]]


def ranks_numba(img: np.ndarray) -> np.ndarray:
    """initialise.equalised with :func:`ranks_kernel`: (H, W) float32 -> (H, W) float32, the same bits."""
    src = np.ascontiguousarray(img, dtype=np.float32)
    out = np.empty(src.shape, np.float32)
    ranks_kernel(src.reshape(-1), RANK_LEVELS, out.reshape(-1))
    return out


@njit(cache=True, error_model="numpy", nogil=True)
def _kth_key(keys, k, work, counts):  # noqa: ANN001, ANN201
    """The k-th smallest (0-based) of keys (n,) uint32 by an MSD radix select: per digit (11, 11 and 10 bits from
    the top) the candidates' digits counted, the k-th's digit found, and only the candidates with it kept (into
    ``work`` (n,) uint32; ``counts`` (2048,) int64 scratch). Three counting passes over ever fewer candidates,
    where a partition (numba's np.partition) took ~8 ns an element."""
    src, m = keys, keys.size
    result = np.uint32(0)
    for shift, width in ((21, 11), (10, 11), (0, 10)):
        mask = (1 << width) - 1
        counts[:mask + 1] = 0
        for t in range(m):
            counts[(src[t] >> shift) & mask] += 1
        d, below = 0, 0
        while below + counts[d] <= k:
            below += counts[d]
            d += 1
        k -= below
        result |= np.uint32(d << shift)
        kept = 0
        for t in range(m):
            if (src[t] >> shift) & mask == d:
                work[kept] = src[t]
                kept += 1
        src, m = work, kept
    return result


@njit(cache=True, error_model="numpy", nogil=True)
def median_f32(values):  # noqa: ANN001, ANN201
    """np.median of float32 values (n,), n > 0, finite: the middle value, or the float32 mean of the middle two --
    np.median's value bit for bit (a selection finds the same order statistic however it runs; only a -0.0 and a
    0.0 both in the middle might come in the other order, as with np.partition; the callers' values are >= +0).
    By :func:`_kth_key` on the floats' :func:`_key`: 2.4-3x faster than
    numba's np.partition on 4,500-30,000 values (the noise estimate's and the level contrast's), 1.4x on 1,300."""
    n = values.size
    bits = values.view(np.uint32)
    keys = np.empty(n, np.uint32)
    for t in range(n):
        keys[t] = _key(bits[t])
    work = np.empty(n, np.uint32)
    counts = np.empty(2048, np.int64)
    k = n // 2
    hi = _kth_key(keys, k, work, counts)
    lo = hi
    if n % 2 == 0:  # the (k - 1)-th: the largest key below hi if k keys are below it, else hi itself
        below, top = 0, np.uint32(0)
        for t in range(n):
            if keys[t] < hi:
                below += 1
                top = max(top, keys[t])
        lo = top if below == k else hi
    pair = np.empty(2, np.uint32)
    pair[0], pair[1] = _unkey(lo), _unkey(hi)
    v = pair.view(np.float32)
    return v[1] if n % 2 else (v[0] + v[1]) / np.float32(2.0)


@njit(cache=True, error_model="numpy", nogil=True)
def noise_kernel(img, s, ny, nx):  # noqa: ANN001, ANN201
    """The median of |I * N| (census_noise.IMMERKAER, a compile-time constant) over the pixels
    (1 + s i, 1 + s j), i < ny, j < nx, of img (H, W) float32: the reference's float32 operations in its order (the
    nine taps' sum from zero, row by row of N; no fastmath), so the same value bit for bit."""
    values = np.empty(ny * nx, np.float32)
    for i in range(ny):
        y = 1 + s * i
        for j in range(nx):
            x = 1 + s * j
            r = np.float32(0.0)
            for a in range(3):
                for b in range(3):
                    r = r + np.float32(IMMERKAER[a][b]) * img[y + a - 1, x + b - 1]
            values[i * nx + j] = abs(r)
    return median_f32(values)


def noise_sigma_numba(img: np.ndarray) -> float:
    """census_noise.noise_sigma with :func:`noise_kernel`: the same value bit for bit, ~10x faster."""
    grid = noise_grid(*img.shape)
    if grid is None:
        return 0.0
    med = np.float32(noise_kernel(np.ascontiguousarray(img, dtype=np.float32), *grid))
    return float(MAD_TO_STD * med / KERNEL_NORM)  # as the reference: float32 (NumPy 2's scalar rules), then float
