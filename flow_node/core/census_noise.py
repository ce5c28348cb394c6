"""The census signature's noise floor (issue 25, low light): EPS raised to the pair's noise level.

The census signature divides a pixel's 3 x 3 differences by their RMS s(x) plus EPS (census.py). Where the
frame is flat, s(x) is the noise's: with noise above EPS the signature of a flat area is noise at full
contrast, and two frames' signatures there disagree at random. Raising EPS to K times the noise std damps
exactly those pixels and leaves textured ones (s(x) >> EPS) normalised as before.

* The noise std is estimated ONCE per frame, at full resolution, on the normalised frame before any
  presmoothing (white noise there; :func:`pair_noise`): Immerkaer's (1996) estimator,
  1.4826 median |I * N| / |N|_2 with N = [[1, -2, 1], [-2, 4, -2], [1, -2, 1]] (zero on any linear ramp,
  |N|_2 = 6), on every :data:`NOISE_STRIDE`-th interior pixel in each direction (:func:`noise_sigma`).
* Both frames use one EPS, from the larger of their two estimates: the same contrast scale in both
  signatures (a per-frame EPS leaves a flat area full-contrast in the clean frame and damped in the noisy
  one, measured worse: git show 4983857:bench/results/census_cost/lowlight/summary.md).
* It is carried down the pyramid analytically, not re-estimated (a coarse level's texture reads as noise):
  every level is a fixed linear filter of the input (blur and bilinear resampling, separable), so white
  noise's neighbour differences on a level have a known RMS, computed from that filter
  (:func:`difference_noise_gains`, the photometric stage's presmoothing included: a white-noise estimator
  would read a blurred frame's noise as far smaller than it is). The floor on a level is K sigma times that
  gain, for the differences the level's signature takes (its neighbours at distance 1, or 2 on the finest level
  with census_finest_radius 2: a blurred frame's noise differs less between close pixels than between far ones).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from .photometric import FrameMap, FrameMaps, affine_normalised

NOISE_STRIDE = 4  # the estimate's median over every 4th interior pixel in each direction (1/16 of them)
MAD_TO_STD = 1.4826  # std of a Gaussian over its median absolute deviation
IMMERKAER = ((1, -2, 1), (-2, 4, -2), (1, -2, 1))  # the estimator's 3 x 3 kernel N (module doc)
KERNEL_NORM = 6.0  # |N|_2 of Immerkaer's kernel: the std of N * (white noise of std 1)
_PAD = 1  # the kernel's radius
GAIN_ROWS = 128  # _axis_gains builds its impulse responses this many input impulses at a time


def noise_grid(h: int, w: int) -> tuple[int, int, int] | None:
    """The pixels :func:`noise_sigma` reads on an (h, w) image: (stride s, rows ny, columns nx) of the grid
    (1 + s i, 1 + s j); None for an image smaller than 3 x 3."""
    if h < 3 or w < 3:
        return None
    s = NOISE_STRIDE if min(h, w) > 4 * NOISE_STRIDE else 1
    return s, len(range(_PAD, h - _PAD, s)), len(range(_PAD, w - _PAD, s))


def noise_sigma(img: np.ndarray) -> float:
    """Robust std of the white noise in img (H, W) float32, in img's units (Immerkaer's estimator, module
    doc), on every NOISE_STRIDE-th interior pixel (:func:`noise_grid`); 0 for an image smaller than 3 x 3. ~0.2 ms
    a 640x480 frame (numba: numba_sort.noise_sigma_numba, the same value bit for bit, ~0.02 ms)."""
    grid = noise_grid(*img.shape)
    if grid is None:
        return 0.0
    s, ny, nx = grid
    response = np.zeros((ny, nx), np.float32)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            y0, x0 = _PAD + dy, _PAD + dx
            view = img[y0:y0 + (ny - 1) * s + 1:s, x0:x0 + (nx - 1) * s + 1:s]
            response += np.float32(IMMERKAER[dy + 1][dx + 1]) * view
    return float(MAD_TO_STD * np.median(np.abs(response)) / KERNEL_NORM)


@dataclass(frozen=True)
class PairNoise:
    """A pair's noise for the census EPS floor: ``sigma``, the larger of both frames' white-noise std in
    normalised units (before presmoothing), and ``blur``, the presmoothing Gaussian (px; 0: none) both frames
    then got (photometric.normalise_frames); ``frames``: each frame's std where :func:`pair_noise` measured them
    (a stream hands frame 1's to its next pair: engine.Seen), else None."""

    sigma: float
    blur: float = 0.0
    frames: tuple[float, float] | None = None


def pair_noise(frames: tuple[np.ndarray, np.ndarray], maps: FrameMaps, noise_gain: float,
               solver_pair: tuple[np.ndarray, np.ndarray], sigma: Callable[[np.ndarray], float] = noise_sigma,
               sigma0: float | None = None) -> PairNoise:
    """The :class:`PairNoise` of the census stage's pair: ``frames`` (H, W) as they came, their ``maps``
    (photometric.frame_maps at the stage's ``noise_gain``: each frame's own map and the blur both got) and what the
    stage made of them (``solver_pair``). Where the stage did not presmooth, its pair is the normalised one and is
    measured as it is; where it did, the frames are mapped again without the blur (one affine map each) and
    measured, by ``sigma`` (:func:`noise_sigma` or a backend's: the same value). ``sigma0``: frame 0's std when
    known (a stream's previous pair measured it as its frame 1's, with the same photometric.frame_key:
    engine.Seen)."""
    (map0, map1), blur = maps

    def measured(k: int, frame_map: FrameMap) -> float:
        return sigma(affine_normalised(frames[k], *frame_map, noise_gain, 0.0) if blur > 0 else solver_pair[k])

    both = (measured(0, map0) if sigma0 is None else sigma0, measured(1, map1))
    return PairNoise(max(both), blur, both)


def channel_noise(raw: tuple[np.ndarray, np.ndarray], maps: Sequence[FrameMaps], noise_gain: float,
                  normalised: tuple[np.ndarray, np.ndarray], sigma: Callable[[np.ndarray], float] = noise_sigma
                  ) -> PairNoise:
    """The :class:`PairNoise` of colour channels (colour.py): both frames' channels (C, H, W) as they came
    (``raw``), each channel's maps (colour.channel_maps, the ones the colour stage normalised them by) and the
    channels as it normalised them (colour.normalise_channel_pair), measured channel by channel
    (:func:`pair_noise`, by ``sigma``); the largest sigma and blur over the channels (one EPS for the stacked
    signatures). The luma's noise would be wrong here: an isoluminant frame's normalised luma is mostly
    quantisation noise."""
    noises = [pair_noise((r0, r1), m, noise_gain, (n0, n1), sigma)
              for r0, r1, m, n0, n1 in zip(*raw, maps, *normalised, strict=True)]
    return PairNoise(max(n.sigma for n in noises), max(n.blur for n in noises))


def difference_noise_gains(shapes: list[tuple[int, int]], sigmas: list[float], blur: float = 0.0,
                           lags: tuple[int, ...] = (1,)) -> dict[int, tuple[float, ...]]:
    """Per lag in ``lags``, per pyramid level (finest first): the RMS of white noise's differences between pixels
    ``lag`` px apart (along x and y) on that level over the RMS of its neighbour differences on the input (1 on
    level 0 without ``blur``, for any lag). ``shapes`` (h, w) per level; ``sigmas``: the Gaussian blur (px of the
    finer level) of each step before its bilinear resampling (pyramid.build_pyramid), one per step; ``blur``: a
    Gaussian (px) on the input first (the photometric stage's presmoothing; 0: none). Computed exactly from the
    separable linear map of each axis (:func:`_axis_gains`; one pass for every lag), cached per argument set."""
    lags = tuple(sorted({int(lag) for lag in lags}))
    gains = _difference_noise_gains(tuple(tuple(s) for s in shapes), tuple(float(s) for s in sigmas), float(blur),
                                    lags)
    return dict(zip(lags, gains, strict=True))


@lru_cache(maxsize=64)
def _difference_noise_gains(shapes: tuple[tuple[int, int], ...], sigmas: tuple[float, ...], blur: float,
                            lags: tuple[int, ...]) -> tuple[tuple[float, ...], ...]:
    """:func:`difference_noise_gains` on hashable arguments, a tuple of gains per lag."""
    vy, dys = _axis_gains(tuple(s[0] for s in shapes), sigmas, blur, lags)
    vx, dxs = _axis_gains(tuple(s[1] for s in shapes), sigmas, blur, lags)
    # white noise through a separable map: Var(x difference) = dx * vy, Var(y difference) = vx * dy; 2 on level 0
    return tuple(tuple(float(np.sqrt((dx[k] * vy[k] + vx[k] * dy[k]) / 4.0)) for k in range(len(shapes)))
                 for dx, dy in zip(dxs, dys, strict=True))


def _axis_gains(lengths: tuple[int, ...], sigmas: tuple[float, ...], blur: float = 0.0, lags: tuple[int, ...] = (1,)
                ) -> tuple[list[float], list[list[float]]]:
    """For one axis of lengths n_0 > n_1 > ..., the step blurs ``sigmas`` and a first ``blur`` on n_0: per
    level, the mean over interior samples of the variance of (white noise of variance 1 through the axis's
    linear map), and per lag in ``lags`` that of its difference between samples ``lag`` apart. The map is built as a
    matrix (rows: input impulses) by the very operations of pyramid.build_pyramid along that axis (a Gaussian of
    OpenCV's kernel size for float input; bilinear resampling); replicated border for the steps, reflected for the
    first blur (as photometric.affine_normalised), GAIN_ROWS rows at a time: the whole n_0 x n_0 matrix at 1226 px
    cost ~0.1 s in a fresh process (its pages), the blocks ~0.03 s. A row carries every :func:`comb_period`-th
    impulse (the period of the largest lag): their responses and the differences taken of them never share a
    sample on any level, so a column's sum of squares over the rows is the one over single impulses (sums of
    exact zeros aside), n_0 / period times fewer rows. The gains agree with the dense matrix's to float32 rounding
    (OpenCV's float32 filters round a block of rows a little differently here and there: ~4e-9 relative,
    test_census_noise.py)."""
    period = max(comb_period(lengths, sigmas, blur, lag) for lag in lags)
    sq: list[np.ndarray | None] = [None] * len(lengths)  # per level, the column sums over the impulses so far
    dsq: list[list[np.ndarray | None]] = [[None] * len(lengths) for _ in lags]  # per lag, the same of differences
    for start in range(0, period, GAIN_ROWS):  # the rows are independent: a block at a time, in cache
        rows = min(GAIN_ROWS, period - start)
        m = np.zeros((rows, lengths[0]), np.float32)
        for row in range(rows):  # impulses at start + row, + period, + 2 period, ...
            m[row, start + row::period] = 1.0
        if blur > 0:
            m = _blurred(m, blur, cv2.BORDER_REFLECT)
        for level, n in enumerate(lengths):
            if level:
                m = _blurred(m, sigmas[level - 1], cv2.BORDER_REPLICATE)
                m = cv2.resize(m, (n, m.shape[0]), interpolation=cv2.INTER_LINEAR)
            inner = (m[:, 2:-2] if n > 8 else m).astype(np.float64)
            sq[level] = _column_sums(sq[level], inner ** 2)
            for sums, lag in zip(dsq, lags, strict=True):
                diff = inner[:, lag:] - inner[:, :-lag]
                sums[level] = _column_sums(sums[level], diff * diff)
    var = [float(np.mean(v)) for v in sq]
    dvar = [[float(np.mean(v)) if v.size else 0.0 for v in sums] for sums in dsq]
    return var, dvar


def comb_period(lengths: tuple[int, ...], sigmas: tuple[float, ...], blur: float = 0.0, lag: int = 1) -> int:
    """The spacing (input samples) of the impulses :func:`_axis_gains` puts in one row: more than twice the reach
    of an impulse's response on the coarsest level plus ``lag`` samples of that level, in input samples, bounded
    by n_0 (one impulse a row). The reach grows per step by the Gaussian's kernel radius (OpenCV's size for
    float input) and the bilinear resampling's two taps, scaled to the input; the first ``blur`` adds its own."""
    reach = _kernel_radius(blur) if blur > 0 else 0.0  # input samples
    for level in range(1, len(lengths)):
        finer, coarser = lengths[0] / lengths[level - 1], lengths[0] / lengths[level]  # input samples a sample
        reach += _kernel_radius(sigmas[level - 1]) * finer + 2 * coarser
    far = reach + (lag + 2) * lengths[0] / lengths[-1]
    return min(lengths[0], 2 * math.ceil(far) + 1)


def _kernel_radius(sigma: float) -> int:
    """The radius of :func:`_blurred`'s kernel of sigma px."""
    return (int(round(sigma * 4 * 2 + 1)) | 1) // 2


def _column_sums(acc: np.ndarray | None, block: np.ndarray) -> np.ndarray:
    """acc (n,) plus the column sums of block (rows, n), float64."""
    sums = np.sum(block, axis=0)
    return sums if acc is None else acc + sums


def _blurred(m: np.ndarray, sigma: float, border: int) -> np.ndarray:
    """m (rows, n) float32 blurred along its rows by a Gaussian of sigma px (OpenCV's kernel size for float
    input, as cv2.GaussianBlur with size (0, 0))."""
    kernel = cv2.getGaussianKernel(2 * _kernel_radius(sigma) + 1, sigma, cv2.CV_32F)
    return cv2.sepFilter2D(m, cv2.CV_32F, kernel, np.ones((1, 1), np.float32), borderType=border)


def eps_floors(noise: PairNoise, k: float, gains: tuple[float, ...]) -> tuple[float, ...]:
    """The census EPS floor per level: k times the pair's noise std times each level's
    :func:`difference_noise_gains` (for its presmoothing)."""
    return tuple(k * noise.sigma * g for g in gains)
