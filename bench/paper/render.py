"""An exact second-frame renderer for the paper protocol: frame 1 read as samples of a band-limited image.

The paper synthesises frame 2 by cubic interpolation of frame 1. That makes the pair exact only for an
image model nobody estimates with: an estimator whose own warp differs from that cubic (the engine's is a
prefiltered cubic B-spline, flow_node/core/warping.py) sees the renderer's interpolation error as a
residual and turns it into flow error. This renderer instead defines the continuous frame 1 as the unique
band-limited function whose half-sample-symmetric extension (the DCT-II image model: the image mirrored
about its borders, so no wrap-around edge) has the given samples, and evaluates that function at the
sub-pixel positions the flow asks for. It shares no kernel with the engine.

Evaluation. The spectrum of the mirrored image is zero-padded to ``UPSAMPLE`` times the sampling rate
(separably, rows then column blocks), which gives the band-limited function exactly on a grid of pitch
1/UPSAMPLE px. Between those dense samples a degree-5 Lagrange polynomial (6 x 6 taps) interpolates; at
pitch 1/8 the highest representable frequency (pi per px) is pi/8 per dense sample, where degree-5
Lagrange interpolation is accurate to ~1e-5 of the amplitude (test/test_paper_render.py checks it against
the analytic value of DCT basis images at random positions).
"""

from __future__ import annotations

import numpy as np

UPSAMPLE = 8  # dense grid pitch 1/UPSAMPLE px
TAPS = 6  # Lagrange nodes per axis (degree TAPS - 1)
MARGIN = 4  # px of mirrored border kept around the image on the dense grid (sample positions may leave it)
_COLUMN_BLOCK = 256  # dense columns transformed at once in the second pass (bounds the memory)


def _upsample_axis(a: np.ndarray, up: int, lo: int, hi: int) -> np.ndarray:
    """Band-limited upsampling of ``a`` along its last axis (N samples, half-sample-symmetric extension):
    the values at positions j/up px for dense indices j in [lo, hi) (any integers; periodic in 2N px)."""
    n = a.shape[-1]
    ext = np.concatenate([a, a[..., ::-1]], axis=-1).astype(np.float64)
    spec = np.fft.rfft(ext, axis=-1)  # bin n (Nyquist) is 0 for a symmetric extension: no split needed
    dense = np.fft.irfft(spec, n=2 * n * up, axis=-1) * up
    idx = np.arange(lo, hi) % (2 * n * up)
    return dense[..., idx]


def dense_grid(img: np.ndarray, up: int = UPSAMPLE, margin: int = MARGIN) -> np.ndarray:
    """The band-limited image on a grid of pitch 1/up px covering [-margin, size - 1 + margin] px on both
    axes (float32; dense index (i, j) is position (i/up - margin, j/up - margin))."""
    h, w = img.shape
    lo = -margin * up
    rows = _upsample_axis(img, up, lo, (w - 1 + margin) * up + 1)  # (h, W')
    out = np.empty(((h - 1 + 2 * margin) * up + 1, rows.shape[1]), np.float32)
    for c in range(0, rows.shape[1], _COLUMN_BLOCK):
        block = rows[:, c:c + _COLUMN_BLOCK].T  # (cols, h): transform along the original y axis
        out[:, c:c + _COLUMN_BLOCK] = _upsample_axis(block, up, lo, (h - 1 + margin) * up + 1).T
    return out


def _lagrange(t: np.ndarray, taps: int) -> tuple[np.ndarray, np.ndarray]:
    """First node index and the (taps, N) weights of Lagrange interpolation at dense positions ``t``."""
    first = np.floor(t).astype(np.int64) - (taps // 2 - 1)
    s = t - first  # position relative to the first node, in [taps/2 - 1, taps/2)
    weights = np.ones((taps,) + t.shape)
    for k in range(taps):
        for m in range(taps):
            if m != k:
                weights[k] *= (s - m) / (k - m)
    return first, weights


def sample(grid: np.ndarray, x: np.ndarray, y: np.ndarray, up: int = UPSAMPLE, margin: int = MARGIN,
           taps: int = TAPS) -> np.ndarray:
    """The band-limited image (its dense grid from :func:`dense_grid`) at positions (x, y) px, float64.

    Positions must lie within ``margin - 1`` px of the image (else ValueError)."""
    tx = (np.asarray(x, np.float64) + margin) * up
    ty = (np.asarray(y, np.float64) + margin) * up
    fx, wx = _lagrange(tx, taps)
    fy, wy = _lagrange(ty, taps)
    if fx.min() < 0 or fy.min() < 0 or fx.max() + taps > grid.shape[1] or fy.max() + taps > grid.shape[0]:
        raise ValueError("sample position outside the rendered margin")
    out = np.zeros(tx.shape)
    for i in range(taps):
        row = np.zeros(tx.shape)
        for j in range(taps):
            row += wx[j] * grid[fy + i, fx + j]
        out += wy[i] * row
    return out


def render(img: np.ndarray, x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """``img`` (H, W) read as a band-limited image and evaluated at positions (x, y) px (float32)."""
    return sample(dense_grid(img), x, y).astype(np.float32)
