"""The refinement stage: coarse-to-fine warping with the paper's models (paper, "Large Displacements").

A generic driver over a :class:`~flow_node.core.pyramid.Pyramid` with the per-warp solver and the warp passed
in (a :class:`~flow_node.core.backends.Backend`: numpy reference or numba kernels). :func:`refine_levels` walks
a range of levels, coarse to fine, from a given state, so the engine can start it anywhere: on the coarsest
level from zero flow, or on the level where an initialisation is trusted (:mod:`flow_node.core.engine`).
Flow is channel-first (2, h, w) in pixels of its level.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from .backends import Backend
from .bregman import bregman
from .census import CENSUS, CensusParams, median_contrast
from .config import FlowConfig
from .edges import level_edge_weight
from .layout import interleaved_flow
from .models import MODEL_SPECS, weight_coefficient, weight_data, weight_quadratic
from .operators import gain_linearise, mass_gain, mass_linearise, warp_source
from .photometric import compares_signatures
from .pyramid import Pyramid, make_pyramid, resize_state
from .solver import PDState, Problem, SolveParams
from .validity import data_weight, fill_flow
from .wmedian import median_filter
from .workspace import scratch


@dataclass
class SolveStats:
    """What a solve did: iterations per level (finest first) and the level shapes; the initialisation used
    (``init``: the candidates' names joined by '+', '' for none; ``init_offered``: those the initialisation
    stage computed, before the ones within the pyramid's reach were dropped), the level the refinement restarted from
    with it (``start_level``, -1 without one), the share of pixels the fusion there took from a candidate
    (``init_share``) and the share the fusion after the finest level took (``final_init_share``: where
    the refinement did not improve on a candidate)."""

    shapes: list[tuple[int, int]] = field(default_factory=list)
    iterations: list[int] = field(default_factory=list)
    bregman_iterations: int = 0
    init: str = ""
    init_offered: str = ""
    start_level: int = -1
    init_share: float = 0.0
    final_init_share: float = 0.0
    stream: str = ""  # in a stream mode (temporal.py): 'predicted', or 'full: <why the prediction failed>'

    @property
    def total_iterations(self) -> int:
        return sum(self.iterations)


def warp_medians(cfg: FlowConfig, inner: int = -1) -> tuple[int, int]:
    """The median filter's sizes after a level's warps (0: none): (after each warp but the last, after the last).
    ``cfg.median_filter`` for both, but before the last warp ``inner`` where set (>= 0: the stream stage's
    ``cfg.stream_inner_median``, temporal.py), else with the census data term ``cfg.census_median_filter`` where
    set (not -1): the last warp's median shapes the flow the level hands on, the earlier ones only the next
    warp's linearisation point (docs/engine.md, "The census data term", "The stream mode")."""
    if inner < 0 and compares_signatures(cfg.photometric):
        inner = cfg.census_median_filter
    return (cfg.median_filter if inner < 0 else inner), cfg.median_filter


def weighs(cfg: FlowConfig, last: bool, on_finest: bool) -> bool:
    """Whether ``cfg.median_weight_warps`` names a warp (``last``: a level's last; ``on_finest``: of the finest
    solved level) for the weighted median: every warp, each level's last, the finest solved level's last, or
    ('coarse') every warp of the coarser levels and the finest solved level's last."""
    mode = cfg.median_weight_warps
    return (mode == "every" or (mode == "last" and last) or (mode == "finest" and last and on_finest)
            or (mode == "coarse" and (last or not on_finest)))


def warp_median(v: np.ndarray, i0: np.ndarray, size: int, cfg: FlowConfig, backend: Backend,
                weighted: bool = True) -> np.ndarray:
    """The median filter after a warp: plain (:func:`median_filter`), or with ``cfg.median_weight_sigma`` > 0 and
    ``weighted`` (the warp is one ``cfg.median_weight_warps`` names) the backend's weighted median guided by the
    level's frame 0 ``i0`` (wmedian.py; docs/engine.md "Weighted median") over ``cfg.median_filter``'s window,
    where a 3 x 3 window's flow range exceeds ``cfg.median_weight_range``."""
    if cfg.median_weight_sigma <= 0.0 or not weighted:
        return median_filter(v, size)
    return backend.weighted_median(v, i0, size, cfg.median_weight_sigma, cfg.median_occlusion_sigma,
                                   cfg.median_weight_range, cfg.median_filter or size)


def level_schedule(cfg: FlowConfig, finest: bool) -> tuple[int, int]:
    """(warps, primal-dual iterations per warp) of a level: ``cfg.finest_warps`` / ``cfg.finest_iterations``
    on the ``finest`` solved level where set (non-zero), else ``cfg.warps`` / ``cfg.iterations``; with the census
    data term ``cfg.census_iterations`` / ``cfg.census_finest_iterations`` / ``cfg.census_finest_warps`` first where
    set (docs/engine.md, "The census data term": its time round; "Presets": task cschedule)."""
    iterations, finest_iterations, finest_warps = cfg.iterations, cfg.finest_iterations, cfg.finest_warps
    if compares_signatures(cfg.photometric):
        iterations = cfg.census_iterations or iterations
        finest_iterations = cfg.census_finest_iterations or finest_iterations
        finest_warps = cfg.census_finest_warps or finest_warps
    if not finest:
        return cfg.warps, iterations
    return finest_warps or cfg.warps, finest_iterations or iterations


def level_params(cfg: FlowConfig, level: int, iterations: int) -> SolveParams:
    """The solver settings of one level: alpha (``cfg.census_alpha`` instead with the census data term where set)
    scaled by ``level_alpha_factor**level``, ``iterations`` per warp (:func:`level_schedule`)."""
    gamma = cfg.image_gamma if cfg.reconstruction == "joint" else 0.0  # the joint model's data term (joint.py)
    alpha = (cfg.census_alpha or cfg.alpha) if compares_signatures(cfg.photometric) else cfg.alpha
    return SolveParams(MODEL_SPECS[cfg.model], alpha * cfg.level_alpha_factor**level, cfg.alpha1,
                       cfg.tv_norm, iterations, cfg.tolerance, gamma=gamma, relaxation=cfg.pd_relaxation)


def solve_level(pyr: Pyramid, level: int, cfg: FlowConfig, backend: Backend, state: PDState, on_finest: bool,
                bregman_steps: int = 0, inner_median: int = -1) -> tuple[int, int]:
    """As many warps as :func:`level_schedule` gives (``on_finest``: ``level`` is the finest solved one):
    linearise around the current flow, run the backend's solver and median-filter the flow (:func:`warp_medians`,
    ``inner_median`` the stream stage's); then
    ``bregman_steps`` Bregman steps on the last linearisation. ``state`` lives on ``level`` and is updated in
    place. The data term (``cfg.photometric``): grey values (the backend's fused
    warp of frame 1 and its gradient with ``cfg.warp_kernel``, outside pixels masked; the level's warp source and
    frame 0's gradient are scratch arrays reused from call to call, workspace.py) or census signatures
    (:func:`census_problem`, on the pyramid's colour channels when it has them, else on the grey frames).
    Returns (iterations, Bregman iterations)."""
    warps, per_warp = level_schedule(cfg, on_finest)
    params = level_params(cfg, level, per_warp)
    robust = params.spec.data == "l1"
    valid = pyr.valid(level)
    # the edge-weighted TV's g, once per level (None: off); plain TV on and near frame 0's invalid pixels
    g = level_edge_weight(pyr.i0[level], cfg, level, None if valid is None else valid[0], backend.edge_weight)
    if compares_signatures(cfg.photometric):
        colour = pyr.c0 is not None and pyr.c1 is not None
        frames = (pyr.c0[level], pyr.c1[level]) if colour else (pyr.i0[level][None], pyr.i1[level][None])
        radius = cfg.census_finest_radius if on_finest else 1  # the signature's neighbours' distance here
        linearised = census_problem(*frames, cfg, backend, robust, pyr.eps_floor(level, radius), on_finest, g,
                                    (*pyr.contrasts, level))
    else:
        linearised = problem_source(cfg)(pyr.i0[level], pyr.i1[level], cfg, backend, robust, g)
    if valid is not None:
        linearised = masked_problem(linearised, *valid, params.spec.data)
    iterations = 0
    sizes = warp_medians(cfg, inner_median)
    for warp in range(warps):
        if valid is not None and warp == 0:  # the level's start: masked pixels from their neighbours' flow
            state.v = fill_flow(state.v, data_weight(*valid, state.v))
        problem = linearised(state.v)
        iterations += backend.solve(problem, state, params)
        last = warp == warps - 1
        size = sizes[last]
        if size:
            state.v = warp_median(state.v, pyr.i0[level], size, cfg, backend, weighs(cfg, last, on_finest))
    extra = bregman(problem, state, params, backend.solve, bregman_steps) if bregman_steps else 0
    return iterations, extra


# a level's linearisation: flow v0 (2, h, w) -> the problem of one warp around it
Linearisation = Callable[[np.ndarray], Problem]


def grey_problem(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend, robust: bool,
                 g: np.ndarray | None = None) -> Linearisation:
    """The paper's data term on grey values: per warp rho(v) = a . v + c (operators.linearise, or the backend's
    fused kernel) around v0; ``g`` the TV term's edge weight (edges.py), None for none (as in every builder of a
    level's problems here: built in, not a dataclasses.replace per warp, ~2.6 us each)."""
    h, w = i0.shape
    src1 = warp_source(i1, cfg.gradient_scheme, cfg.warp_kernel, backend.warper,
                       out=scratch("refine.source", (3, h, w)), gradient=backend.gradient)
    g0 = (backend.gradient(i0, cfg.gradient_scheme, out=scratch("refine.grad0", (2, h, w)))
          if cfg.gradient_scheme == "interpolated" else None)

    def around(v0: np.ndarray) -> Problem:
        return Problem(*backend.linearise(i0, src1, g0, v0, cfg.gradient_scheme, cfg.warp_kernel, backend.warper), g=g)

    return around


# The brightness term beside the mass term (FlowConfig.mass_brightness) is used on pyramid levels whose smaller side is
# at least this (px): on coarser levels a fine texture is washed out, the local density change is most of what is left
# of the image, and the term reads it as motion (on every level beta 0.1 took a report separable pair to 7.6 px, 0.25
# a tune one to 8.2; from 60 px on, the tune split has no such pair up to beta 1). The border band it holds is the
# finest level's (docs/engine.md, "Mass preservation").
MASS_BRIGHTNESS_MIN_SIDE = 60


def mass_problem(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend, robust: bool,
                 g: np.ndarray | None = None) -> Linearisation:
    """Mass preservation (the continuity equation, models.apply_a): per warp the grey-value linearisation
    around v0, turned into that of I1(x + v) det(Id + grad v) = I0(x) (operators.mass_linearise). With
    ``cfg.mass_brightness`` = beta > 0 the grey-value linearisation stays beside it as a brightness-constancy term
    of weight beta on the frames brought to equal mass (operators.mass_gain, gain_linearise; folded into (ab, cb)
    by models.weight_data), on levels whose smaller side is at least MASS_BRIGHTNESS_MIN_SIDE px (docs/engine.md,
    "Mass preservation"); ``g``: the TV term's edge weight (:func:`grey_problem`)."""
    grey = grey_problem(i0, i1, cfg, backend, robust)
    beta, data = cfg.mass_brightness, MODEL_SPECS[cfg.model].data
    with_term = beta > 0.0 and min(i0.shape) >= MASS_BRIGHTNESS_MIN_SIDE
    gain = mass_gain(i0, i1) if with_term else 1.0

    def around(v0: np.ndarray) -> Problem:
        lin = grey(v0)
        a, m, c = mass_linearise(i0, lin.a, lin.c, v0)
        if not with_term:
            return Problem(a, c, m=m, g=g)
        ab, cb = weight_data(*gain_linearise(i0, lin.a, lin.c, v0, gain), np.float32(beta), data)
        return Problem(a, c, m=m, ab=ab, cb=cb, g=g)

    return around


def problem_source(cfg: FlowConfig) -> Callable[..., Linearisation]:
    """The per-warp problem of ``cfg``'s grey-value data term: mass preservation or brightness constancy (the
    constraint is checked against the photometric mode in config.py; census signatures: :func:`census_problem`)."""
    return mass_problem if cfg.constraint == "mass" else grey_problem


def level_census(cfg: FlowConfig, width: int, eps_floor: float = 0.0, contrast: float = math.inf,
                 finest: bool = False) -> CensusParams:
    """The census constants of a pyramid level ``width`` px wide: CENSUS with EPS ``cfg.census_eps``, or
    ``cfg.census_coarse_eps`` on levels narrower than ``cfg.census_coarse_width`` or whose ``contrast`` (the
    larger of both frames' census.median_contrast) is below ``cfg.census_empty_contrast`` (docs/engine.md,
    "Presets"), raised to ``eps_floor`` (the pair's noise on that level, Pyramid.census_eps) where that is
    larger; on the ``finest`` solved level the neighbours at distance ``cfg.census_finest_radius``; the L1
    majoriser's DELTA ``cfg.census_delta``."""
    coarse = width < cfg.census_coarse_width or contrast < cfg.census_empty_contrast
    base = CENSUS if (cfg.census_delta, cfg.census_eps) == (CENSUS.delta, CENSUS.eps) else replace(
        CENSUS, delta=cfg.census_delta, eps=cfg.census_eps)
    params = replace(base, eps=cfg.census_coarse_eps) if coarse else base
    params = replace(params, radius=cfg.census_finest_radius) if finest and cfg.census_finest_radius != 1 else params
    return replace(params, eps=eps_floor) if eps_floor > params.eps else params


# per frame, the contrasts measured so far ({level: value}: Pyramid.contrasts), and the level
ContrastMemo = tuple[dict[int, float], dict[int, float], int]


def level_contrast(c0: np.ndarray, c1: np.ndarray, cfg: FlowConfig,
                   contrast: Callable[[np.ndarray], float] = median_contrast, memo: ContrastMemo | None = None
                   ) -> float:
    """What :func:`level_census` needs of a level's contrast (census.median_contrast of the channels c0, c1
    (C, h, w), by ``contrast``: a backend's): the larger of both frames', measured
    only where it decides -- inf when ``cfg.census_empty_contrast`` is off or the level is narrower than
    ``cfg.census_coarse_width`` (damped by width anyway), and frame 0's alone when that is already at or above the
    threshold (the level is not empty whatever frame 1's is). A level is empty only when both frames' texture is
    gone: the anti-alias blur empties both alike, while a frame that is flat alone was flattened by its own tone
    curve (an S-curve crushing a dark scene, issue 25 task crush), and damping the level would take the other
    frame's texture from the data term too. ``memo``: each frame's contrasts measured so far (taken
    from there, and added to it; a stream hands frame 1's to the next pair: Pyramid.contrasts)."""
    if cfg.census_empty_contrast <= 0 or c0.shape[2] < cfg.census_coarse_width:
        return math.inf

    def of(k: int, frames: np.ndarray) -> float:
        if memo is None:
            return contrast(frames)
        known, level = memo[k], memo[2]
        if level not in known:
            known[level] = contrast(frames)
        return known[level]

    first = of(0, c0)
    return first if first >= cfg.census_empty_contrast else max(first, of(1, c1))


def census_problem(c0: np.ndarray, c1: np.ndarray, cfg: FlowConfig, backend: Backend, robust: bool,
                   eps_floor: float = 0.0, finest: bool = False, g: np.ndarray | None = None,
                   memo: ContrastMemo | None = None) -> Linearisation:
    """The census data term (census.py) on the frames' channels c0, c1 (C, h, w): the grey frames (C = 1) or
    colour channels (colour.py). Once per level frame 0's (stacked) signatures and frame 1's interpolation
    coefficients; per warp the backend's form around v0 (frame 1 sampled at x + v0, its signatures, the
    quadratic form: census.census_form). The form replaces (a, c) in the solve: they are zeros. ``eps_floor``:
    the least EPS of both frames' signatures on this level; ``finest``: this is the finest solved level
    (:func:`level_census`, with :func:`level_contrast` and its ``memo``); ``g``: the TV term's edge weight
    (:func:`grey_problem`)."""
    coefs = backend.warper.coefficients(c1, cfg.warp_kernel)
    params = level_census(cfg, c0.shape[2], eps_floor, level_contrast(c0, c1, cfg, backend.contrast, memo), finest)
    f0, g0 = backend.signature(c0, params)
    h, w = c0.shape[1:]
    a, c = np.zeros((2, h, w), np.float32), np.zeros((h, w), np.float32)
    form = np.empty((5, h, w), np.float32)  # one per level: each warp's form overwrites the last one's, whose solve
    # is done (solve_level; the Bregman steps take the last warp's); fresh 1-1.5 MB a warp cost ~9 % of the kernel at
    # 320 x 240 (task fastcens)

    def around(v0: np.ndarray) -> Problem:
        return Problem(a, c, q=backend.census_form(f0, g0, coefs, c1, v0, cfg.warp_kernel, robust, params, out=form),
                       g=g)

    return around


def masked_problem(linearised: Linearisation, valid0: np.ndarray, valid1: np.ndarray, data: str) -> Linearisation:
    """A level's linearisation with the validity mask (validity.py): per warp the data term weighted by
    :func:`~flow_node.core.validity.data_weight` around v0 (models.weight_data / weight_quadratic; ``data``
    the model's data term, "l1" or "l2"). Masked pixels keep the regulariser only. With mass preservation
    the whole residual a . v + M : grad v + c is weighted (M as well as a and c), and so is the brightness
    term beside it (ab, cb)."""

    def around(v0: np.ndarray) -> Problem:
        p = linearised(v0)
        m = data_weight(valid0, valid1, v0)
        if p.q is not None:
            return replace(p, q=weight_quadratic(p.q, m))
        a, c = weight_data(p.a, p.c, m, data)
        mass = {}
        if p.m is not None:  # M scales like a: the residual is linear in (a, M, c)
            mass["m"] = weight_coefficient(p.m, m, data)
        if p.ab is not None:
            mass["ab"], mass["cb"] = weight_data(p.ab, p.cb, m, data)
        return replace(p, a=a, c=c, **mass)

    return around


def refine_levels(pyr: Pyramid, cfg: FlowConfig, backend: Backend, state: PDState, first: int, last: int,
                  stats: SolveStats, finest: int, inner_median: int = -1) -> PDState:
    """Solve levels ``first`` down to ``last`` (first >= last), carrying primal and dual variables to each
    finer level (flow vectors rescaled). ``state`` may live on any level; it is resampled to ``first``.
    ``finest`` is the finest level the solve goes down to (:func:`finest_level`): that level gets the
    ``cfg.finest_warps`` / ``cfg.finest_iterations`` schedule and, when ``last`` reaches it, the Bregman steps
    (``cfg.bregman_iterations``); ``inner_median``: :func:`solve_level`'s. Iterations are added to ``stats``;
    returns the state on ``last``."""
    for lvl in range(first, last - 1, -1):
        if state.v.shape[1:] != pyr.shapes[lvl]:
            state = resize_state(state, pyr.shapes[lvl])
        steps = cfg.bregman_iterations if lvl == finest else 0
        its, extra = solve_level(pyr, lvl, cfg, backend, state, lvl == finest, steps, inner_median)
        stats.iterations[lvl] += its
        stats.bregman_iterations += extra
    return state


def finest_level(pyr: Pyramid, cfg: FlowConfig, initialised: bool = False) -> int:
    """The finest level solved, clamped to the coarsest level the pyramid has: ``cfg.finest_level``; for a
    pair an initialisation the engine computed is fused on (``initialised``), the coarser of that and
    ``cfg.init_finest_level``."""
    level = max(cfg.finest_level, cfg.init_finest_level) if initialised else cfg.finest_level
    return min(level, pyr.coarsest)


def coarse_to_fine(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend) -> tuple[np.ndarray, SolveStats]:
    """The refinement stage alone on a pair, from zero flow over the whole pyramid (no photometric stage,
    no initialisation, no fusion: the paper's scheme as it stands): flow float32 (H, W, 2) px and stats."""
    pyr = make_pyramid(i0, i1, cfg)
    stats = SolveStats(shapes=pyr.shapes, iterations=[0] * len(pyr.shapes))
    state = PDState.zeros(MODEL_SPECS[cfg.model], pyr.shapes[-1])
    finest = finest_level(pyr, cfg)
    state = refine_levels(pyr, cfg, backend, state, pyr.coarsest, finest, stats, finest)
    return interleaved_flow(state.v, pyr.shapes[0]), stats
