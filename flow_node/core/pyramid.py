"""Coarse-to-fine warping (paper, "Large Displacements"): one generic driver, the per-warp solver passed in.

Images are float32 (H, W) in [0, 1]; flow is channel-first (2, H, W) in pixels of the level it lives on,
until the driver returns it interleaved (H, W, 2) at full resolution.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from .config import FlowConfig
from .models import MODEL_SPECS, residual
from .operators import div, image_gradient, linearise, warp_source
from .solver import LevelSolver, PDState, Problem, SolveParams
from .warping import NUMPY_WARPER, Warper


@dataclass
class SolveStats:
    """What a solve did: iterations per level (finest first) and the level shapes."""

    shapes: list[tuple[int, int]] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    bregman_iterations: int = 0

    @property
    def total_iterations(self) -> int:
        return sum(self.iterations)


def pyramid_shapes(shape: tuple[int, int], levels: int, scale: float, min_size: int) -> list[tuple[int, int]]:
    """Level shapes, finest first: shape * scale**l, stopping before a side would drop below min_size."""
    h, w = shape
    shapes = [(h, w)]
    for lvl in range(1, levels):
        nh, nw = round(h * scale**lvl), round(w * scale**lvl)
        if min(nh, nw) < min_size or (nh, nw) == shapes[-1]:
            break
        shapes.append((nh, nw))
    return shapes


def build_pyramid(img: np.ndarray, shapes: list[tuple[int, int]], scale: float) -> list[np.ndarray]:
    """Gaussian pyramid on the given shapes: blur (sigma = 1/(3 scale)) then area-resample each step."""
    sigma = 1.0 / (3.0 * scale)
    levels = [img]
    for h, w in shapes[1:]:
        blurred = cv2.GaussianBlur(levels[-1], (0, 0), sigmaX=sigma, sigmaY=sigma,
                                   borderType=cv2.BORDER_REPLICATE)
        levels.append(cv2.resize(blurred, (w, h), interpolation=cv2.INTER_LINEAR))
    return levels


def resize_field(f: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Bilinear resize of every leading channel of f (..., h, w) to (..., H, W); values unchanged."""
    h, w = shape
    flat = f.reshape((-1,) + f.shape[-2:])
    out = np.empty((flat.shape[0], h, w), dtype=f.dtype)
    for ch, dst in zip(flat, out, strict=True):
        cv2.resize(np.ascontiguousarray(ch), (w, h), dst=dst, interpolation=cv2.INTER_LINEAR)
    return out.reshape(f.shape[:-2] + (h, w))


def resize_flow(flow: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Resize a (2, h, w) flow to shape and rescale its vectors to the new pixel size."""
    out = resize_field(flow, shape)
    out[0] *= shape[1] / flow.shape[2]
    out[1] *= shape[0] / flow.shape[1]
    return out


def resize_state(state: PDState, shape: tuple[int, int]) -> PDState:
    """Carry primal and dual variables to a finer level (flow vectors rescaled, the rest resampled)."""
    return PDState(
        v=resize_flow(state.v, shape),
        y=resize_field(state.y, shape),
        w=None if state.w is None else resize_field(state.w, shape),
        z=None if state.z is None else resize_field(state.z, shape),
    )


def interleaved_flow(v: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The engine's output: a (2, h, w) flow as float32 (H, W, 2) at ``shape``, vectors in pixels of ``shape``.

    Interleaves at the solved size, then (if it differs) rescales the vectors there and resizes bilinearly:
    bilinear interpolation is linear, so scaling first gives the same field and the full-size array is
    written once, not three times (resize, scale, interleave).
    """
    small = cv2.merge([v[0].astype(np.float32, copy=False), v[1].astype(np.float32, copy=False)])
    h, w = shape
    if small.shape[:2] == (h, w):
        return small
    small *= np.array([w / v.shape[2], h / v.shape[1]], dtype=np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


def median_filter(v: np.ndarray, size: int) -> np.ndarray:
    """Median of each flow component over size x size windows (OpenCV; size 3 or 5)."""
    out = np.empty_like(v)
    for ch, dst in zip(v, out, strict=True):
        cv2.medianBlur(np.ascontiguousarray(ch), size, dst=dst)
    return out


def coarse_to_fine(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, solve: LevelSolver,
                   initial_flow: np.ndarray | None = None,
                   warper: Warper = NUMPY_WARPER) -> tuple[np.ndarray, SolveStats]:
    """Estimate flow from i0 to i1 with warping on a Gaussian pyramid: float32 (H, W, 2), u then v, px.

    On each level, coarsest first: ``cfg.warps`` times linearise around the current flow (``warper``: the
    backend's cubic warp of frame 1 and its gradient, outside pixels masked), run ``solve`` and
    median-filter the flow; then carry
    primal and dual variables to the next level. After the finest solved level, ``cfg.bregman_iterations``
    Bregman steps on the last linearisation (see :func:`bregman`). The finest solved level is
    ``cfg.finest_level`` (clamped to the coarsest level the image has); when it is not 0 its flow is
    upsampled bilinearly to (H, W) with the vectors rescaled; finer levels are not solved. The result is
    interleaved (:func:`interleaved_flow`), the layout of the API and of a 32FC2 image.
    """
    spec = MODEL_SPECS[cfg.model]
    shapes = pyramid_shapes(i0.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
    finest = min(cfg.finest_level, len(shapes) - 1)
    p0 = build_pyramid(i0, shapes, cfg.scale_factor)
    p1 = build_pyramid(i1, shapes, cfg.scale_factor)
    stats = SolveStats(shapes=shapes, iterations=[0] * len(shapes))
    state = PDState.zeros(spec, shapes[-1])
    if initial_flow is not None:
        state.v = resize_flow(initial_flow.astype(np.float32, copy=False), shapes[-1])  # a new array
    for lvl in range(len(shapes) - 1, finest - 1, -1):
        if state.v.shape[1:] != shapes[lvl]:
            state = resize_state(state, shapes[lvl])
        params = SolveParams(spec, cfg.alpha * cfg.level_alpha_factor**lvl, cfg.alpha1, cfg.tv_norm,
                             cfg.iterations, cfg.tolerance)
        src1 = warp_source(p1[lvl], cfg.gradient_scheme, cfg.warp_kernel, warper)
        g0 = image_gradient(p0[lvl], cfg.gradient_scheme) if cfg.gradient_scheme == "interpolated" else None
        for _ in range(cfg.warps):
            a, c = linearise(p0[lvl], src1, g0, state.v, cfg.gradient_scheme, cfg.warp_kernel, warper)
            stats.iterations[lvl] += solve(Problem(a, c), state, params)
            if cfg.median_filter:
                state.v = median_filter(state.v, cfg.median_filter)
        if lvl == finest and cfg.bregman_iterations:
            stats.bregman_iterations = bregman(Problem(a, c), state, params, solve, cfg.bregman_iterations)
    return interleaved_flow(state.v, shapes[0]), stats


def bregman(problem: Problem, state: PDState, p: SolveParams, solve: LevelSolver, n: int) -> int:
    """Contrast-restoring Bregman iterations (paper, "Bregman Iterations") on one linearised problem.

    L2 data: the shifted data term -- the residual is added back, c_{k+1} = c_k + rho(v_k) with the
    original c, which is the paper's b-update written on the data. L1 data: the original form, the
    linear term -alpha <b_k, v> in G with b_k = (K* y_k)_v / alpha = -div(y_k / alpha), the subgradient
    of R at v_k that the dual variable provides (the solver's y is already y / alpha, see solver.py).
    Returns the iterations run.
    """
    total = 0
    c_shift = problem.c
    for _ in range(n):
        if p.spec.data == "l2":
            c_shift = c_shift + residual(state.v, problem.a, problem.c)
            step = Problem(problem.a, c_shift)
        else:
            step = Problem(problem.a, problem.c, -div(state.y))
        total += solve(step, state, p)
    return total
