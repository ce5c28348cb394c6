"""The census data term: what it compares, and its linearisation (numpy reference; numba: numba_census.py).

Brightness constancy compares grey values, so any change of the grey values between the frames -- a tone
curve, a gain field, flicker -- reads as motion. The census data term compares, at every pixel, how its
grey value relates to its eight neighbours', normalised by the local contrast (a soft census signature,
after Stein 2004 and its use inside TV-L1 by Mueller et al. 2011 and Ranftl et al. 2012):

    F_k(I)(x) = GAIN * (I(x + d_k) - I(x)) / (s(x) + EPS),   s(x) = sqrt(mean_k (I(x + d_k) - I(x))^2)

for the offsets d_k of the 3 x 3 neighbourhood (K = 8 channels), or with ``radius`` 2 the ring of eight
pixels at distance 2 (d_k = 2 x the 3 x 3 offsets: the 5 x 5 window's corners and edge midpoints; FlowConfig
``census_finest_radius`` on the finest solved level). Over one pixel any smooth monotonic tone curve is affine
to first order, and a smooth gain field is a constant: both scale the differences and s alike, so F does not
change (exactly for a gain and offset, to second order in the grey-value span of the window for a curve).
EPS (in units of the frame's robust range) keeps flat, noise-only areas from being amplified.

Each channel is linearised like the grey value (paper, "Large Displacements"): with W = I1(x + v0) the
warped frame 1 (sampled directly, :func:`warped_frames`: the data term needs its values, not the grey-value
linearisation) and a_k the channel's gradient (the mean of frame 0's and of the warped one's, as the
``interpolated`` scheme does for grey values), rho_k(v) = a_k . v + c_k. The model's data term is then

    l2: 1/2 sum_k rho_k^2          l1: sum_k |rho_k|  (solved by majorise-minimise, see below)

Both are collapsed per pixel into one quadratic form 1/2 v^T T v + g . v (+ const): T = sum_k w_k a_k a_k^T,
g = sum_k w_k c_k a_k, stored as (5, H, W) = (T11, T12, T22, g1, g2); the solver's data prox is then a 2 x 2
solve (models.prox_data_quadratic). For l2, w_k = 1. For l1, |rho| is majorised at the linearisation point by
rho^2 / (2 |rho_k(v0)|) (+ const) -- iteratively reweighted least squares, one reweighting per warp --
with w_k = 1 / sqrt(rho_k(v0)^2 + DELTA^2): each warp minimises an upper bound of the L1 data term that
touches it at v0, so the warps decrease it. A pixel whose x + v0 leaves the image has T = g = 0 (no data
term), as for grey values.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Protocol

import numpy as np

from .operators import warp_maps
from .photometric import reliability_stride
from .warping import Sample, sample_coefficients

# the 8 neighbours (dy, dx) of the 3 x 3 neighbourhood
OFFSETS: tuple[tuple[int, int], ...] = ((-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1))
# OFFSETS as the numba kernels take them, (dy, dx) int64 arrays (K) (numba_census, numba_judge)
OFFSETS_DY, OFFSETS_DX = (np.array([d[k] for d in OFFSETS], np.int64) for k in (0, 1))


@dataclass(frozen=True)
class CensusParams:
    """The census data term's constants (the module doc's names).

    ``gain``: scale of the signature (sets the data term's weight against the regulariser's alpha);
    ``eps``: contrast (of the frame's robust range) below which differences are damped, not normalised (the data
    term's: FlowConfig.census_eps, or census_coarse_eps on coarse levels, refine.level_census);
    ``delta``: residual (signature units) below which the L1 majoriser is quadratic;
    ``radius``: the neighbours' distance (px), 1 (the 3 x 3 neighbourhood) or 2 (:func:`offsets`)."""

    gain: float = 0.1
    eps: float = 0.01
    delta: float = 0.2
    radius: int = 1


CENSUS = CensusParams()


def offsets(radius: int) -> tuple[tuple[int, int], ...]:
    """The signature's 8 neighbour offsets (dy, dx) px at distance ``radius``: radius x :data:`OFFSETS`."""
    return tuple((radius * dy, radius * dx) for dy, dx in OFFSETS)


def shifted(img: np.ndarray, dy: int, dx: int) -> np.ndarray:
    """img(x + (dy, dx)) on img's grid, edge values repeated outside. (H, W) -> (H, W)."""
    h, w = img.shape
    r = max(abs(dy), abs(dx), 1)
    padded = np.pad(img, r, mode="edge")
    return padded[r + dy:r + dy + h, r + dx:r + dx + w]


def signature(img: np.ndarray, params: CensusParams = CENSUS) -> np.ndarray:
    """The soft census signature F(img) of the module doc: (H, W) float32 -> (K, H, W) float32."""
    img = img.astype(np.float32, copy=False)
    diffs = np.stack([shifted(img, dy, dx) - img for dy, dx in offsets(params.radius)])
    return (normalised(diffs, params) * np.float32(params.gain)).astype(np.float32)


def normalised(diffs: np.ndarray, params: CensusParams = CENSUS) -> np.ndarray:
    """The K neighbour differences (K, ...) over their RMS plus EPS: the signature in units of the gain."""
    return diffs / (np.sqrt(np.mean(diffs * diffs, axis=0)) + np.float32(params.eps))


CONTRAST_SAMPLES = 1200  # median_contrast samples about this many interior pixels of a level (all on small ones)


def contrast_stride(h: int, w: int) -> int:
    """The stride of :func:`median_contrast`'s grid on an (h, w) level: sqrt(interior pixels / CONTRAST_SAMPLES),
    at least 1."""
    return max(1, int(np.sqrt((h - 2) * (w - 2) / CONTRAST_SAMPLES)))


def median_contrast(frames: np.ndarray) -> float:
    """How much texture a pyramid level holds: the median over interior pixels (on a grid of stride
    sqrt(pixels / CONTRAST_SAMPLES), at least 1: :func:`contrast_stride`) of s(x), the RMS of the 8 neighbour
    differences (the module doc's), of the channel with the largest median. frames (C, H, W) float32 -> in the
    frames' units (their robust range); 0 for a level smaller than 3 x 3. ~0.1 ms per level and frame (numba:
    numba_census.median_contrast_numba, the same value bit for bit, ~0.01 ms)."""
    h, w = frames.shape[1:]
    if h < 3 or w < 3:
        return 0.0
    st = contrast_stride(h, w)
    centre = frames[:, 1:h - 1:st, 1:w - 1:st]
    ny, nx = centre.shape[1:]
    sq = np.zeros_like(centre)
    for dy, dx in OFFSETS:
        d = frames[:, 1 + dy:1 + dy + (ny - 1) * st + 1:st, 1 + dx:1 + dx + (nx - 1) * st + 1:st] - centre
        sq += d * d
    return float(np.median(np.sqrt(sq / len(OFFSETS)), axis=(1, 2)).max())


def signature_gradient(f: np.ndarray) -> np.ndarray:
    """Central differences of every channel of f (K, H, W): (2, K, H, W) [x, y], zero on the image border
    (as the paper's central scheme)."""
    g = np.zeros((2,) + f.shape, np.float32)
    g[0, :, :, 1:-1] = 0.5 * (f[:, :, 2:] - f[:, :, :-2])
    g[1, :, 1:-1, :] = 0.5 * (f[:, 2:, :] - f[:, :-2, :])
    return g


def signature_form(f0: np.ndarray, g0: np.ndarray, f1: np.ndarray, outside: np.ndarray, v0: np.ndarray,
                   robust: bool, params: CensusParams = CENSUS) -> np.ndarray:
    """The census data term around v0 collapsed to (T11, T12, T22, g1, g2), (5, H, W) float32 (module doc).

    f0 (K, H, W), g0 (2, K, H, W): frame 0's signature and its gradient on this level; f1 (K, H, W): the
    warped frame's signature (any K: colour.py stacks the signatures of several channels); ``outside``
    (H, W) bool: no data term there (:func:`warped_frames`); v0 (2, H, W) px; ``robust``: the L1 data term's
    weights (else 1)."""
    g1 = signature_gradient(f1)
    ax, ay = 0.5 * (g0[0] + g1[0]), 0.5 * (g0[1] + g1[1])
    r0 = f1 - f0
    c = r0 - ax * v0[0] - ay * v0[1]
    wk = 1.0 / np.sqrt(r0 * r0 + np.float32(params.delta) ** 2) if robust else np.ones_like(r0)
    wk = wk * ~outside
    wax, way = wk * ax, wk * ay
    return np.stack([(wax * ax).sum(0), (wax * ay).sum(0), (way * ay).sum(0),
                     (wax * c).sum(0), (way * c).sum(0)]).astype(np.float32)


def form_residual(form: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The gradient T v + g of the quadratic form at v (2, H, W): (2, H, W); zero at its minimiser."""
    return np.stack([form[0] * v[0] + form[1] * v[1] + form[3], form[1] * v[0] + form[2] * v[1] + form[4]])


def level_signature(frames: np.ndarray, params: CensusParams = CENSUS) -> tuple[np.ndarray, np.ndarray]:
    """Frame 0's signatures on one pyramid level (computed once per level, used by every warp there): of an
    image (H, W) (K, H, W), of a channel stack (C, H, W) (colour.py) the channels' signatures stacked
    (C K, H, W); and their gradients (2, K or C K, H, W)."""
    stack = frames if frames.ndim == 3 else frames[None]
    f0 = np.concatenate([signature(ch, params) for ch in stack]) if len(stack) > 1 else signature(stack[0], params)
    return f0, signature_gradient(f0)


def warped_frames(coefs: np.ndarray, frames: np.ndarray, v0: np.ndarray, kernel: str,
                  sample: Sample = sample_coefficients) -> tuple[np.ndarray, np.ndarray]:
    """Frame 1's channels sampled at x + v0 (2, H, W) (a value-only warp): (C, H, W) float32, from their
    interpolation coefficients ``coefs`` (C, H, W) (warping.Warper.coefficients, once per level) with a
    backend's ``sample``; and the mask (H, W) bool of pixels whose x + v0 leaves the image
    (operators.warp_maps). There the channels of ``frames`` (C, H, W) themselves stand in: the inside
    neighbours' signatures then compare values of frame 1 only, which share its tone curve (with frame 0
    there, a tone change between the frames would bias every pixel next to the outside band)."""
    map_x, map_y, inside = warp_maps(v0)
    warped = sample(coefs, map_x, map_y, kernel)
    return np.where(inside, warped, frames).astype(np.float32, copy=False), ~inside


def census_form(f0: np.ndarray, g0: np.ndarray | None, coefs: np.ndarray, frames: np.ndarray, v0: np.ndarray,
                kernel: str, robust: bool, params: CensusParams = CENSUS, sample: Sample = sample_coefficients,
                out: np.ndarray | None = None) -> np.ndarray:
    """One warp's census data term: the quadratic form (5, H, W) around v0 (2, H, W).

    f0 (C K, H, W), g0 (2, C K, H, W): frame 0's signatures of its C channels and their gradients on this level
    (:func:`level_signature`, stacked channel by channel); ``coefs``, ``frames``
    (C, H, W): frame 1's channels and their interpolation coefficients (``kernel``), sampled at x + v0 by
    :func:`warped_frames`; ``robust``: the L1 data term (else L2). C = 1 for grey input; with C channels
    (colour.py) the form is the mean over them (scaled by 1 / C, so that alpha means what it means for grey).
    Into ``out`` (5, H, W) float32 when given (and returned)."""
    if g0 is None:
        raise ValueError("census_form needs frame 0's signature gradients (census.level_signature)")
    warped, outside = warped_frames(coefs, frames, v0, kernel, sample)
    f1 = np.concatenate([signature(w, params) for w in warped])
    form = signature_form(f0, g0, f1, outside, v0, robust, params)
    form = form if len(warped) == 1 else (form * np.float32(1.0 / len(warped))).astype(np.float32)
    if out is None:
        return form
    out[...] = form
    return out


# level_signature(frames, params) -> (f0, g0) and census_form(f0, g0, coefs, frames, v0, kernel, robust, params,
# out=None) -> q: the numpy references above or a backend's kernels (numba_census.py)
# (the numba kernels take frame 0's gradient inside the form kernel: their level signature's second item is None)
LevelSignature = Callable[[np.ndarray, CensusParams], tuple[np.ndarray, np.ndarray | None]]


class CensusForm(Protocol):
    """A backend's :func:`census_form`: the form (5, H, W) of one warp, into ``out`` when given."""

    def __call__(self, f0: np.ndarray, g0: np.ndarray | None, coefs: np.ndarray, frames: np.ndarray, v0: np.ndarray,
                 kernel: str, robust: bool, params: CensusParams, *, out: np.ndarray | None = None) -> np.ndarray: ...


# reliability samples every SAMPLE_SPACING-th point of photometric.reliability_stride's grid (~5,000 at any size
# above ~250x250: nine interpolated samples each, and the fraction's binomial noise is still below 1 %)
SAMPLE_SPACING = 2
OUTLIER = 0.5  # mean |signature residual| / gain above which a pixel is unexplained (see reliability)


def reliability(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, sample: Sample = sample_coefficients,
                params: CensusParams = CENSUS, *, samples: int | None = None) -> float:
    """The judge of every data term's flow (engine.Judged): the fraction of sampled pixels (SAMPLE_SPACING times
    its stride) whose signature is not explained by the flow, i.e. whose mean |F(I1)(x + flow) - F(I0)(x)| over the K
    channels exceeds OUTLIER (in units of the gain). F(I1) at x + flow is the signature of I1 sampled (Keys)
    at x + flow and its 8 neighbours; F(I0) is taken on the sampled pixels only. Invariant to what census is
    invariant to, so a tone change does not read as unexplained, whatever the data term (docs/engine.md, "The
    judge"). i0, i1 (H, W) as the photometric stage judges them; flow (H, W, 2) px."""
    h, w = i0.shape
    s = SAMPLE_SPACING * reliability_stride(h, w, samples)  # the reliability grid for ``samples``
    ys, xs = np.arange(0, h, s), np.arange(0, w, s)
    map_x = xs.astype(np.float32)[None, :] + flow[::s, ::s, 0]
    map_y = ys.astype(np.float32)[:, None] + flow[::s, ::s, 1]
    inside = (map_x >= 1) & (map_x <= w - 2) & (map_y >= 1) & (map_y <= h - 2)
    if not inside.any():
        return 1.0
    taps = ((0, 0),) + OFFSETS
    mx = np.concatenate([map_x + dx for _, dx in taps])
    my = np.concatenate([map_y + dy for dy, _ in taps])
    warped = sample(np.asarray(i1, np.float32), mx, my, "keys").reshape((len(taps),) + map_x.shape)
    grid = np.stack([i0[np.clip(ys + dy, 0, h - 1)][:, np.clip(xs + dx, 0, w - 1)] for dy, dx in taps])
    residual = np.mean(np.abs(normalised(warped[1:] - warped[0], params) - normalised(grid[1:] - grid[0], params)),
                       axis=0)
    return float(np.mean(residual[inside] > OUTLIER))

