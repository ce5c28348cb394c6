"""Robust weighted least squares on a regular subsample of a flow field: the fitting core of the derived
motion outputs (:mod:`flow_node.pipeline.motion`, :mod:`flow_node.pipeline.expansion`). Plain numpy.

A fit sees a flow only at the points of a regular grid (:func:`sample_flow`), so its cost depends on the
number of samples (~1024 by default), not on the image size. Each sample carries the flow's confidence
(:func:`flow_node.core.confidence.confidence`, (H, W) in [0, 1]) as its weight; robust weights (Huber, then
Tukey's biweight) on the endpoint residual in px take out what the model does not explain (moving objects,
occlusions, wrong flow).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from ..core.errors import InputError

SAMPLES = 1024  # samples a fit looks at, whatever the image size
HUBER_K = 1.345  # Huber's constant, in robust standard deviations (95 % efficiency for Gaussian noise)
TUKEY_C = 4.685  # Tukey's biweight cut-off, in robust standard deviations (95 % efficiency)
MIN_SCALE_PX = 0.02  # floor of the robust residual scale: an exact flow must not make every weight 0 or 1/0
# Huber steps before the biweight: none from a robust start (median_slopes, medoid_offset), where a Huber
# step lets a nearly as large second group bend the fit towards it; fit_robust takes more from a poor start
HUBER_ITERATIONS = 0
TUKEY_ITERATIONS = 5  # biweight steps at most (residuals beyond TUKEY_C scales weigh nothing)
SLOPE_SPAN = 1 / 8  # median_slopes: pairs this fraction of the grid apart
START_QUANTILE = 0.25  # the first IRLS scale comes from this quantile of the residuals (reweight)
START_CANDIDATES = 16  # medoid_offset: candidate samples for the start's offset
START_CONFIDENCE = 0.5  # samples at least this confident make the robust start (median_slopes)
CONVERGED_PX = 1e-3  # a step that moves no sample by more than this ends a stage


def check_flow_shape(flow: np.ndarray) -> None:
    """InputError unless ``flow`` is (H, W, 2)."""
    if flow.ndim != 3 or flow.shape[2] != 2:
        raise InputError(f"flow: expected shape (H, W, 2), got {flow.shape}")


def check_flow(flow: np.ndarray, confidence: np.ndarray) -> None:
    """InputError unless ``flow`` is (H, W, 2) and ``confidence`` (H, W) of the same size."""
    check_flow_shape(flow)
    if confidence.shape != flow.shape[:2]:
        raise InputError(f"confidence: expected shape {flow.shape[:2]}, got {confidence.shape}")


# What the fits weigh samples by: the confidence (H, W) in [0, 1], or a function giving it at integer pixel
# points (ys, xs) -> an array of their shape (e.g. FlowOutput.confidence_at: the points alone, not the map)
Weights = np.ndarray | Callable[[np.ndarray, np.ndarray], np.ndarray]


def check_weights(flow: np.ndarray, confidence: Weights) -> None:
    """:func:`check_flow`, or only the flow's shape when ``confidence`` is a function of the points."""
    if callable(confidence):
        check_flow_shape(flow)
    else:
        check_flow(flow, confidence)


def weights_at(confidence: Weights, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
    """The confidence at the pixels (ys, xs) (integer arrays of one shape) as float64 in [0, 1]."""
    c = confidence(ys, xs) if callable(confidence) else confidence[ys, xs]
    return np.clip(np.asarray(c, np.float64), 0.0, 1.0)


def sample_step(shape: tuple[int, ...], samples: int = SAMPLES) -> int:
    """The grid step (px, >= 1) that leaves about ``samples`` points of an image of ``shape`` (H, W, ...)."""
    return max(1, int(round(math.sqrt(shape[0] * shape[1] / max(1, samples)))))


@dataclass(frozen=True)
class Samples:
    """A flow at the points of a regular grid, arrays (ny, nx) float64: pixel column ``x`` and row ``y``
    (px, of the flow's grid), flow ``u``, ``v`` (px/frame) and the confidence ``w`` in [0, 1]."""

    x: np.ndarray
    y: np.ndarray
    u: np.ndarray
    v: np.ndarray
    w: np.ndarray


@lru_cache(maxsize=32)
def _grid(h: int, w: int, step: int) -> tuple[np.ndarray, ...]:
    """:func:`sample_flow`'s points of an (h, w) image: rows yi, columns xi (int) and the same as float64
    (read-only; computed once per size and step, the same for every frame)."""
    o = step // 2
    yi, xi = np.mgrid[o:h:step, o:w:step]
    out = (yi, xi, xi.astype(np.float64), yi.astype(np.float64))
    for a in out:
        a.flags.writeable = False
    return out


def sample_flow(flow: np.ndarray, confidence: Weights, step: int) -> Samples:
    """Every ``step``-th pixel in both directions (offset step // 2, so the grid is centred), of flow (H, W, 2)
    px/frame and confidence (H, W) in [0, 1] (or its values at the points: :data:`Weights`)."""
    check_weights(flow, confidence)
    o = step // 2
    yi, xi, x, y = (a.copy() for a in _grid(*flow.shape[:2], step))  # copies: the caller's to keep
    sub = flow[o::step, o::step].astype(np.float64)
    return Samples(x, y, sub[..., 0], sub[..., 1], weights_at(confidence, yi, xi))


def masked_quantile(values: np.ndarray, keep: np.ndarray, q: float = 0.5) -> np.ndarray:
    """The ``q`` quantile (lower: the entry of rank floor((n - 1) q)) along the last axis of ``values`` over
    the entries where ``keep`` (same shape); NaN where none is kept. Shape: ``values.shape[:-1]``."""
    if values.ndim == 1:  # one quantile: a partition, O(n)
        kept = values[keep]
        k = int((kept.size - 1) * q)
        return np.asarray(np.partition(kept, k)[k] if kept.size else np.nan)
    v = np.where(keep, values, np.inf).reshape(-1, values.shape[-1])  # one row per quantile
    v.sort(axis=-1)
    n = np.count_nonzero(keep, axis=-1).reshape(-1)
    rank = ((np.maximum(n, 1) - 1) * q).astype(np.int64)
    out = v[np.arange(v.shape[0]), rank]
    return np.where(n > 0, out, np.nan).reshape(values.shape[:-1])


def masked_median(values: np.ndarray, keep: np.ndarray) -> np.ndarray:
    """:func:`masked_quantile` at 1/2."""
    return masked_quantile(values, keep, 0.5)


def robust_scale(residual: np.ndarray, keep: np.ndarray, q: float = 0.5) -> np.ndarray:
    """The robust scale px of endpoint residuals along the last axis over the entries where ``keep``:
    1.4826 x their median, or, from another quantile ``q``, that quantile times what it is to the median
    for 2-D Gaussian errors (Rayleigh: sqrt(ln 2 / -ln(1 - q))). At least MIN_SCALE_PX (also where nothing
    is kept). Shape ``residual.shape[:-1]`` (0-d for 1-d input)."""
    factor = 1.4826 * math.sqrt(math.log(2.0) / -math.log(1.0 - q))
    return np.fmax(MIN_SCALE_PX, factor * masked_quantile(residual, keep, q))  # fmax: NaN -> the floor


def reweight(residual: np.ndarray, confidence: np.ndarray, scale: np.ndarray | None,
             psi: Callable[[np.ndarray], np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """IRLS weights ``confidence`` x psi(r / s) of endpoint residuals r px (arrays (..., n); fits along the
    last axis) and the scale s used, shape (..., 1). On the first iteration (``scale`` None) s comes from
    the START_QUANTILE quantile of the samples with confidence > 0, so a start inside a group of at least
    that share of the samples keeps it even when another group is larger; afterwards from the median of
    the samples within TUKEY_C previous scales, so a group beyond the biweight's reach does not return
    through the scale."""
    if scale is None:
        scale = robust_scale(residual, confidence > 0.0, START_QUANTILE)[..., None]
    else:
        scale = robust_scale(residual, (confidence > 0.0) & (residual < TUKEY_C * scale))[..., None]
    return confidence * psi(residual / scale), scale


def _ends(a: np.ndarray, axis: int, d: int) -> tuple[np.ndarray, np.ndarray]:
    """Views of ``a`` without its last ``d`` and without its first ``d`` entries along ``axis`` (< 0): the
    first and the second sample of each pair ``d`` apart."""
    lo, hi = [slice(None)] * a.ndim, [slice(None)] * a.ndim
    lo[axis], hi[axis] = slice(0, a.shape[axis] - d), slice(d, None)
    return a[tuple(lo)], a[tuple(hi)]


def slope_span(n: int) -> int:
    """:func:`median_slopes`' pair distance on a grid axis of ``n`` samples: SLOPE_SPAN of it, at least 1."""
    return max(1, int(round(SLOPE_SPAN * n)))


def median_slopes(field: np.ndarray, x: np.ndarray, y: np.ndarray, keep: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Robust d(field)/dx and d(field)/dy of fields sampled on regular grids, arrays (..., ny, nx): the
    median, over every pair of samples SLOPE_SPAN of the grid apart along x (along y) whose both samples
    are kept, of their difference over their coordinate difference. Few pairs straddle an object's edge
    (about SLOPE_SPAN / (1 - SLOPE_SPAN) of those in the rows the edge crosses), and pairs that far apart
    see the slope of a flow with small steps (TV staircasing). ``x``, ``y`` and ``keep`` broadcast to
    ``field``'s shape. Shapes ``field.shape[:-2]``; NaN without pairs."""
    out = []
    for axis, coord in ((-1, x), (-2, y)):
        d = slope_span(field.shape[axis])
        df, dc = (second - first for first, second in (_ends(a, axis, d) for a in (field, coord)))
        first, second = _ends(keep, axis, d)
        both = np.broadcast_to(first & second & (dc != 0), df.shape)  # coordinates and keep may be shared
        flat = field.shape[:-2] + (-1,)
        slope = df / np.where(dc != 0, dc, 1.0)
        out.append(masked_median(slope.reshape(flat), both.reshape(flat)))
    return out[0], out[1]


@lru_cache(maxsize=32)
def medoid_spread(m: int, candidates: int) -> tuple[np.ndarray, np.ndarray]:
    """:func:`medoid_offset`'s candidates and references: ~``candidates`` and ~4 x ``candidates`` indices
    spread evenly over m samples (the same for every frame of a size: computed once)."""
    idx, ref = (np.unique(np.rint(np.linspace(0, m - 1, min(m, c))).astype(np.int64))
                for c in (candidates, 4 * candidates))
    idx.flags.writeable = ref.flags.writeable = False
    return idx, ref


def medoid_offset(rest: np.ndarray, keep: np.ndarray, candidates: int = START_CANDIDATES) -> np.ndarray:
    """A robust 2-D location of the vectors ``rest`` (..., m, 2) over the entries where ``keep`` (..., m):
    of ~``candidates`` samples spread over the m, the one whose median distance to the kept samples (to
    ~4 x ``candidates`` of them spread over the m) is the least (least median of squares over candidates).
    Unlike the per-component median it is one sample of one group, also when two groups are almost
    equally large. Shape (..., 2); 0 where nothing is kept."""
    idx, ref = medoid_spread(rest.shape[-2], candidates)
    cand, other = rest[..., idx, :], rest[..., ref, :]  # (..., c, 2), (..., r, 2)
    dx, dy = other[..., None, :, 0] - cand[..., :, None, 0], other[..., None, :, 1] - cand[..., :, None, 1]
    d = dx * dx + dy * dy  # squared: the median by rank and the least of them are the distances' (no root)
    score = np.where(keep[..., idx], masked_median(d, np.broadcast_to(keep[..., None, ref], d.shape)), np.inf)
    best = np.argmin(np.nan_to_num(score, nan=np.inf), axis=-1)
    out = np.take_along_axis(cand, best[..., None, None], axis=-2)[..., 0, :]
    return np.where(np.any(keep, axis=-1)[..., None], out, 0.0)


def huber_weight(z: np.ndarray) -> np.ndarray:
    """Huber's IRLS weight of residuals ``z`` in robust scales: 1 up to HUBER_K, HUBER_K / z beyond."""
    return np.minimum(1.0, HUBER_K / np.maximum(z, 1e-12))


def tukey_weight(z: np.ndarray) -> np.ndarray:
    """Tukey's biweight of residuals ``z`` in robust scales: (1 - (z / TUKEY_C)^2)^2, 0 beyond TUKEY_C."""
    t = np.maximum(1.0 - (z / TUKEY_C) ** 2, 0.0)
    return t * t


# linearise(params) -> (J (p, 2n), e (2n,)): the model's Jacobian at ``params``, transposed (one row per
# parameter: contiguous rows make the weighting cheap), and the residual flow - model(params) at the n
# samples, u-components first then v-components; a linear model returns a constant J.
Linearise = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class RobustFit:
    """The result of :func:`fit_robust`: parameters (p,), per-sample endpoint residual (n,) px and its
    robust scale px (:func:`robust_scale` over the samples within TUKEY_C of the last iteration's scale)."""

    params: np.ndarray
    residual: np.ndarray
    scale: float


def _step(jac: np.ndarray, err: np.ndarray, weight: np.ndarray) -> np.ndarray | None:
    """The weighted least-squares step (p,) solving jac.T @ step ~ err (``jac`` (p, 2n)) with each sample's
    two components weighted by ``weight`` (n,); None when the weighted system is singular (no support)."""
    p = jac.shape[0]
    jw = (jac.reshape(p, 2, -1) * weight).reshape(p, -1)  # both components of a sample weighted alike
    normal = jw @ jac.T
    trace = float(np.trace(normal))
    if not (math.isfinite(trace) and trace > 0.0 and np.isfinite(normal).all()):
        return None
    normal.flat[::p + 1] += 1e-12 * trace
    try:
        step = np.linalg.solve(normal, jw @ err)
    except np.linalg.LinAlgError:
        return None
    return step if np.all(np.isfinite(step)) else None


def fit_robust(linearise: Linearise, start: np.ndarray, confidence: np.ndarray,
               huber_iterations: int = HUBER_ITERATIONS, tukey_iterations: int = TUKEY_ITERATIONS) -> RobustFit | None:
    """Iteratively reweighted (Gauss-Newton) least squares of a flow model on n samples.

    Each iteration takes the endpoint residual r (px) of every sample at the current parameters and weights
    confidence x psi(r / s) (:func:`reweight`, which says where the scale s comes from): Huber's for up to
    ``huber_iterations``, then Tukey's biweight for ``tukey_iterations`` (outliers beyond TUKEY_C scales
    weigh nothing, so samples moving otherwise leave no bias). Both stages stop early once no sample's
    model flow moves by CONVERGED_PX. With a scale that follows the residuals, a fit started far off can
    settle on a compromise that bends to include a large outlying group, so ``start`` (p,) should be a
    robust estimate already (e.g. from :func:`median_slopes`). ``confidence`` (n,) in [0, 1]. None when
    no sample has weight or the system is singular.
    """
    n = confidence.size
    params = np.asarray(start, np.float64).copy()
    jac, err = linearise(params)
    scale = None
    for psi, iterations in ((huber_weight, huber_iterations), (tukey_weight, tukey_iterations)):
        for _ in range(iterations):
            weight, scale = reweight(np.hypot(err[:n], err[n:]), confidence, scale, psi)
            step = _step(jac, err, weight)
            if step is None:  # no support left (or none at all)
                return None
            params = params + step
            moved = float(np.max(np.abs(step @ jac)))  # px: the largest change of a sample's model flow
            jac, err = linearise(params)
            if moved < CONVERGED_PX:
                break
    residual = np.hypot(err[:n], err[n:])
    keep = (confidence > 0.0) & (residual < TUKEY_C * (np.inf if scale is None else scale[0]))
    return RobustFit(params, residual, float(robust_scale(residual, keep)))
