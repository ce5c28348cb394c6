"""Divergence, time to contact and the focus of expansion of one flow. Plain numpy/OpenCV.

Inputs as in :mod:`flow_node.pipeline.motion`: ``flow`` (H, W, 2) float32 px/frame (u right, v down,
``I1(x + flow(x)) = I0(x)``, on the earlier frame's grid) and ``confidence`` (H, W) in [0, 1].

Time to contact. A surface at distance Z approaching the camera at speed V (Z / V = tau frames) is seen
magnified by s = Z_{t-1} / Z_t per frame about its focus of expansion e: flow(x) = (s - 1)(x - e), whose
divergence du/dx + dv/dy is 2 (s - 1) = 2 / tau. So tau = 2 / div frames, exactly for a constant s, counted
from the newer frame (the distance at frame t over the approach during the last interval). Per region, the
flow is fitted robustly by an affine field (:func:`region_ttc`); its gradient J gives the divergence
trace(J) and the expansion sqrt(det(I + J)) - 1 = s - 1 (equal to div / 2 for a pure expansion, and
unchanged by an image rotation, which adds -theta^2 to the trace), and TTC = 1 / (s - 1) frames. Times in
seconds multiply by the pair's interval (newer stamp - earlier stamp).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import cv2
import numpy as np

from .robust import (
    CONVERGED_PX,
    HUBER_ITERATIONS,
    MIN_SCALE_PX,
    SAMPLES,
    START_CONFIDENCE,
    TUKEY_ITERATIONS,
    Weights,
    check_weights,
    huber_weight,
    median_slopes,
    medoid_offset,
    reweight,
    robust_scale,
    sample_flow,
    sample_step,
    tukey_weight,
    weights_at,
)

REGION_GRID = (3, 3)  # rows x columns of TTC regions; the centre cell is the central region
REGION_SAMPLES = 1296  # samples over the whole image for the region fits (a 12 x 12 grid per cell of 3x3)
MIN_SUPPORT = 0.25  # a region whose samples' mean confidence is below this has no TTC (NaN)
MIN_EXPANSION = 1e-4  # expansion per frame below which a region is not approaching (TTC inf: > 10^4 frames)


def divergence(flow: np.ndarray) -> np.ndarray:
    """du/dx + dv/dy of ``flow`` (H, W, 2) px/frame: (H, W) float32 in 1/frame (> 0 expanding, e.g. an
    approaching surface; 2 / div is its time to contact in frames). Central differences smoothed across
    (3x3 Sobel / 8), replicated border; not masked by confidence."""
    u, v = flow[..., 0], flow[..., 1]
    du = cv2.Sobel(u, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    dv = cv2.Sobel(v, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE)
    return du + dv


@dataclass(frozen=True)
class RegionTTC:
    """One region of the grid: ``bounds`` (x0, y0, x1, y1) px, end exclusive; ``divergence`` 1/frame and
    ``expansion`` s - 1 per frame of its robust affine fit; ``ttc_frames`` = 1 / expansion (inf when not
    approaching: expansion < MIN_EXPANSION, NaN without support); ``ttc_seconds`` = ttc_frames x the pair
    interval (None without an interval); ``support`` the mean confidence of its samples in [0, 1]."""

    row: int
    col: int
    bounds: tuple[int, int, int, int]
    divergence: float
    expansion: float
    ttc_frames: float
    ttc_seconds: float | None
    support: float


@dataclass(frozen=True)
class TimeToContact:
    """The regions of a ``rows`` x ``cols`` grid over the image, row-major from the top left."""

    rows: int
    cols: int
    regions: tuple[RegionTTC, ...]

    def grid(self, field: str = "ttc_frames") -> np.ndarray:
        """One field of every region as (rows, cols) float64 (None -> NaN)."""
        vals = [getattr(r, field) for r in self.regions]
        return np.array([math.nan if v is None else v for v in vals], np.float64).reshape(self.rows, self.cols)

    @property
    def centre(self) -> RegionTTC:
        """The central region (the middle cell; for an even count the one below/right of the centre)."""
        return self.regions[(self.rows // 2) * self.cols + self.cols // 2]


def region_bounds(shape: tuple[int, int], grid: tuple[int, int]) -> list[tuple[int, int, int, int]]:
    """(x0, y0, x1, y1) px of every cell of a rows x cols grid over an (H, W) image, row-major."""
    h, w = shape
    rows, cols = grid
    ys = [round(k * h / rows) for k in range(rows + 1)]
    xs = [round(k * w / cols) for k in range(cols + 1)]
    return [(xs[c], ys[r], xs[c + 1], ys[r + 1]) for r in range(rows) for c in range(cols)]


def _affine_basis(X: np.ndarray, Y: np.ndarray) -> np.ndarray:
    """The affine fits' basis (1, X, Y) of R regions' samples X, Y (R, m): (R, 3, m)."""
    return np.stack([np.ones_like(X), X, Y], axis=1)


def _affine_fits(basis: np.ndarray, uv: np.ndarray, w: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted least-squares affine fits u ~ a0 + a1 X + a2 Y and v ~ b0 + b1 X + b2 Y of R regions at
    once, each from its m samples (``basis`` (R, 3, m) of :func:`_affine_basis`, w (R, m); uv (R, m, 2)):
    coefficients (R, 3, 2) as [[a0, b0], [a1, b1], [a2, b2]] (0 where a region's weighted system is
    singular) and whether it was not (R,)."""
    wb = basis * w[:, None, :]
    normal = wb @ basis.transpose(0, 2, 1)  # (R, 3, 3)
    total = normal[:, 0, 0]
    ok = np.linalg.det(normal) > 1e-9 * np.maximum(total, 1e-30) ** 3
    normal[~ok] = np.eye(3)
    return np.where(ok[:, None, None], np.linalg.solve(normal, wb @ uv), 0.0), ok


def _affine_residual(basis: np.ndarray, uv: np.ndarray, coef: np.ndarray) -> np.ndarray:
    """Endpoint residual px (R, m) of samples uv (R, m, 2) with ``basis`` (R, 3, m) against the fits coef
    (R, 3, 2)."""
    d = uv - basis.transpose(0, 2, 1) @ coef
    return np.hypot(d[..., 0], d[..., 1])


def _affine_start(X: np.ndarray, Y: np.ndarray, uv: np.ndarray, conf: np.ndarray, k: int) -> np.ndarray:
    """Robust starts (R, 3, 2) for :func:`_affine_fits` of R regions, each from its k x k samples (X, Y,
    conf (R, k^2), uv (R, k^2, 2)): the slopes from :func:`median_slopes`, the offsets the median of what
    they leave, over the samples at least START_CONFIDENCE confident; 0 where nothing is."""
    r = X.shape[0]
    keep = conf >= START_CONFIDENCE
    fields = np.moveaxis(uv, -1, 0).reshape(2, r, k, k)  # u and v of every region, in one batch
    dx, dy = median_slopes(fields, *(np.broadcast_to(a.reshape(r, k, k), (2, r, k, k)) for a in (X, Y, keep)))
    coef = np.zeros((r, 3, 2))
    coef[:, 1, :], coef[:, 2, :] = dx.T, dy.T
    coef[np.isnan(coef)] = 0.0  # no pairs: no slope (the slopes are finite otherwise)
    coef[:, 0, :] = medoid_offset(uv - coef[:, None, 1, :] * X[..., None] - coef[:, None, 2, :] * Y[..., None], keep)
    return coef


def region_fits(X: np.ndarray, Y: np.ndarray, uv: np.ndarray, conf: np.ndarray,
                start: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The robust affine fits of R regions at once (the numpy reference :data:`RegionFit`): from ``start``
    (R, 3, 2) (:func:`_affine_start`), IRLS with Huber's weights for HUBER_ITERATIONS steps, then Tukey's
    for TUKEY_ITERATIONS, each region with its own robust scale (:func:`~flow_node.pipeline.robust.reweight`)
    on the endpoint residual px of its m samples at X, Y (R, m) (normalised, |X|, |Y| <= 1) with flow uv
    (R, m, 2) px/frame and confidence conf (R, m); every region steps until none changes its coefficients
    by CONVERGED_PX together. Coefficients (R, 3, 2) (:func:`_affine_fits`) and whether each region's last
    weighted system was regular (R,)."""
    coef, ok, scale = start, np.ones(X.shape[0], bool), None
    basis = _affine_basis(X, Y)
    for psi, iterations in ((huber_weight, HUBER_ITERATIONS), (tukey_weight, TUKEY_ITERATIONS)):
        for _ in range(iterations):
            weight, scale = reweight(_affine_residual(basis, uv, coef), conf, scale, psi)
            previous, (coef, ok) = coef, _affine_fits(basis, uv, weight)
            # |X|, |Y| <= 1: no sample's model flow moved by more than the coefficients' changes together
            if np.max(np.abs(coef - previous).sum(axis=1)) < CONVERGED_PX:
                break
    return coef, ok


# fit(X, Y, uv, conf, start) -> (coef (R, 3, 2), ok (R,)): the region fits; :func:`region_fits` is the numpy
# reference, numba_fits.region_fits_numba the compiled one (derived.Fits chooses)
RegionFit = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]]


def region_ttc(flow: np.ndarray, confidence: Weights, interval_s: float | None = None,
               grid: tuple[int, int] = REGION_GRID, samples: int = REGION_SAMPLES,
               fit: RegionFit = region_fits) -> TimeToContact:
    """Divergence, expansion and time to contact per cell of a ``grid`` (rows, cols) over the image.

    In each cell the flow (H, W, 2) px/frame is fitted by an affine field u = a0 + a1 X + a2 Y,
    v = b0 + b1 X + b2 Y on a regular k x k grid of points (k^2 ~ ``samples`` / cells), weighted by
    ``confidence`` (H, W) and made robust (a start from median slopes, then IRLS with Huber's and Tukey's
    weights on the endpoint residual px, each cell with its own robust scale; all cells at once), so an
    object crossing part of a cell does not move its figure. divergence = a1 + b2 (1/frame), expansion =
    sqrt(det(I + J)) - 1 with J = [[a1, a2], [b1, b2]], TTC = 1 / expansion frames (see the module
    docstring); ``interval_s`` (the pair's, seconds) gives TTC in seconds. ``confidence`` may be given as
    its values at the samples (:data:`~flow_node.pipeline.robust.Weights`). ``fit`` runs the IRLS
    (:data:`RegionFit`: the numpy reference, or numba_fits.region_fits_numba).
    """
    check_weights(flow, confidence)
    rows, cols = grid
    count = rows * cols
    cells = region_bounds(flow.shape[:2], grid)
    bounds = np.array(cells, np.float64)  # (R, 4)
    k = max(2, int(round(math.sqrt(samples / count))))
    t = np.linspace(0.0, 1.0, k)
    xi = np.rint(bounds[:, 0:1] + t * (bounds[:, 2:3] - 1 - bounds[:, 0:1])).astype(np.int64)  # (R, k)
    yi = np.rint(bounds[:, 1:2] + t * (bounds[:, 3:4] - 1 - bounds[:, 1:2])).astype(np.int64)
    px = np.broadcast_to(xi[:, None, :], (count, k, k)).reshape(count, -1)  # (R, k^2)
    py = np.broadcast_to(yi[:, :, None], (count, k, k)).reshape(count, -1)
    uv = flow[py, px].astype(np.float64)  # (R, k^2, 2)
    conf = weights_at(confidence, py, px)
    half = np.maximum(1.0, (bounds[:, 2:4] - bounds[:, 0:2]) / 2.0)  # (R, 2) px
    mid = (bounds[:, 0:2] + bounds[:, 2:4] - 1) / 2.0
    X, Y = (px - mid[:, 0:1]) / half[:, 0:1], (py - mid[:, 1:2]) / half[:, 1:2]
    coef, ok = fit(X, Y, uv, conf, _affine_start(X, Y, uv, conf, k))
    jac = np.swapaxes(coef[:, 1:, :], 1, 2) / half[:, None, :]  # (R, 2, 2): [[du/dx, du/dy], [dv/dx, dv/dy]]
    div = jac[:, 0, 0] + jac[:, 1, 1]
    det = (1.0 + jac[:, 0, 0]) * (1.0 + jac[:, 1, 1]) - jac[:, 0, 1] * jac[:, 1, 0]
    expansion = np.where(ok & (det > 0.0), np.sqrt(np.abs(det)) - 1.0, np.nan)
    support = conf.mean(axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        ttc = np.where(expansion > MIN_EXPANSION, 1.0 / expansion, np.inf)
    ttc[(support < MIN_SUPPORT) | np.isnan(expansion)] = np.nan
    values = zip(div.tolist(), expansion.tolist(), ttc.tolist(), support.tolist(), strict=True)  # Python floats
    return TimeToContact(rows, cols, tuple(
        RegionTTC(r // cols, r % cols, cells[r], d, e, t, None if interval_s is None else t * interval_s, c)
        for r, (d, e, t, c) in enumerate(values)))


@dataclass(frozen=True)
class FocusOfExpansion:
    """The point (x, y) px of the flow's grid whose flow lines meet (least squares); ``expanding`` is True
    when the flow points away from it (approaching), False towards it (a focus of contraction);
    ``spread_px`` is the robust scale of the flow lines' distances to it."""

    x: float
    y: float
    expanding: bool
    spread_px: float


FOE_MIN_ISOTROPY = 0.05  # smallest / largest eigenvalue of the lines' normal matrix: below, the lines are
# nearly parallel (a pan: the focus is at infinity) and there is no finite focus
FOE_MAX_DISTANCE = 4.0  # image diagonals from the centre beyond which a focus is not reported


def focus_of_expansion(flow: np.ndarray, confidence: Weights, samples: int = SAMPLES) -> FocusOfExpansion | None:
    """The least-squares intersection of the flow lines of ``flow`` (H, W, 2) px/frame, weighted by
    ``confidence`` (H, W) and by |flow|^2 (a longer vector has a better-known direction), made robust by
    Huber IRLS on the point-line distance (px). Each sample x with flow f gives the line x + t f; the focus
    p minimises sum w (n . (p - x))^2 with n = (-f_y, f_x). None when the lines are nearly parallel (a pan,
    no finite focus), the focus lies more than FOE_MAX_DISTANCE diagonals away, or nothing moves. Computed
    on the flow as it is: an image rotation moves it (the lines of a rotation do not meet). ``confidence``
    may be given as its values at the samples (:data:`~flow_node.pipeline.robust.Weights`)."""
    s = sample_flow(flow, confidence, sample_step(flow.shape, samples))
    nx, ny = -s.v, s.u
    length = np.hypot(nx, ny)
    weight = s.w.copy()
    h, w = flow.shape[:2]
    p = np.array([(w - 1) / 2.0, (h - 1) / 2.0])
    spread = MIN_SCALE_PX
    for _ in range(4):
        a = np.array([[np.sum(weight * nx * nx), np.sum(weight * nx * ny)],
                      [np.sum(weight * nx * ny), np.sum(weight * ny * ny)]])
        eig = np.linalg.eigvalsh(a)
        if not np.isfinite(eig).all() or eig[1] <= 1e-12 or eig[0] < FOE_MIN_ISOTROPY * eig[1]:
            return None
        p = np.linalg.solve(a, np.array([np.sum(weight * nx * (nx * s.x + ny * s.y)),
                                         np.sum(weight * ny * (nx * s.x + ny * s.y))]))
        dist = np.abs(nx * (p[0] - s.x) + ny * (p[1] - s.y)) / np.maximum(length, 1e-12)
        spread = float(robust_scale(dist.ravel(), ((s.w > 0.0) & (length > 1e-6)).ravel()))
        weight = s.w * huber_weight(dist / spread)
    if math.hypot(p[0] - (w - 1) / 2.0, p[1] - (h - 1) / 2.0) > FOE_MAX_DISTANCE * math.hypot(w, h):
        return None
    outward = np.sum(weight * ((s.x - p[0]) * s.u + (s.y - p[1]) * s.v))
    return FocusOfExpansion(float(p[0]), float(p[1]), bool(outward > 0.0), spread)
