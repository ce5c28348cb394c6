"""The stream stage: the previous pair's flow, carried to the new frame, starts the refinement on the finest
one or two levels only (docs/engine.md, "The stream mode").

In a stream consecutive flows are nearly the same. The previous pair's flow lives on the grid of its first
frame; under constant velocity the point x moves on to x + f(x) and keeps its velocity there, so the
prediction of the new pair's flow at x + f(x) is f(x) (:func:`predict`: a forward splat, the fastest point
winning where several land on one pixel -- the nearer surface -- and the holes, disoccluded pixels and the
border the motion brings in, filled by normalised convolution, densify.push_pull). The solver's other
variables (the dual of the regulariser, and the extended models' w) are carried along the same way (holes:
0): a primal-dual method restarted with zero duals first fits each pixel's data alone and needs tens of
iterations to regularise that again, while with the carried duals a few iterations correct the prediction.
The prediction replaces the coarse levels, the initialisation matcher and their warps:
:func:`refine_prediction` refines it on the levels ``finest + cfg.stream_levels - 1`` down to the finest
solved one, with ``cfg.stream_warps`` warps of ``cfg.stream_iterations`` primal-dual iterations each (on the
finest solved level ``cfg.stream_finest_warps`` x ``cfg.stream_finest_iterations`` where set).

A pair's second frame is the next pair's first: what the pair computed of it -- its sorted sample, and where the
frame's normalising map repeats (``normalise``: the pair's map; census: the frame's own, so always) its normalised
image, pyramid and noise std -- is handed on (:class:`Seen`, ``Prior.seen``) and not computed again.

A per-frame check decides whether the prediction holds (:func:`prediction_fails`, :func:`result_fails`); when
it does not, the caller runs the full single-pair solve (engine.estimate_pair) instead:

* the previous flow itself was unreliable (its unexplained fraction above ``cfg.stream_max_unexplained``:
  after a scene cut every flow is);
* the pair spans a different interval than the previous one by more than ``cfg.stream_max_gap`` (a dropped run
  of frames: the motion no longer continues; shorter gaps scale the prediction by the ratio);
* the photometric stage found an exposure change between the frames (``normalise`` mode: it then compares
  local contrast, a data term of another scale than the one the carried state was solved on);
* the prediction's robust data cost on its start level -- the fraction of pixels whose census signature it
  does not explain (census.reliability) -- is above ``cfg.stream_max_predicted`` (a scene cut, a jump);
* after the refinement, the result explains the pair worse than the previous pair's result by more than
  ``cfg.stream_margin``, or is unreliable (``cfg.stream_max_unexplained``).

Flows are channel-first (2, h, w) px of their grid; images grey float32 (h, w).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from .backends import Backend
from .config import FlowConfig
from .densify import push_pull
from .engine import Judged, Seen, photometric_stage
from .layout import interleaved_flow
from .pyramid import Pyramid, make_pyramid, resize_state
from .refine import SolveStats, finest_level, refine_levels
from .solver import PDState

PREDICTED = "predicted"  # SolveStats.stream of a pair solved from the prediction
FULL = "full"  # ... of a pair the stream solved from scratch; followed by ": <reason>"

# splat(flow (2, h, w), carried (C, h, w)) -> (flow, carried, weight (h, w)): densify.splat_forward (the numpy
# reference) or a backend's kernel (numba_temporal.splat_numba)
Splat = Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]]


@dataclass(frozen=True)
class Prior:
    """What a stream knows before a pair: the previous pair's solver ``state`` (solver.PDState on its finest
    solved level: the flow v (2, h, w) px of that level on the grid of that pair's first frame, and the duals)
    at this pair's resolution; that result's ``unexplained`` fraction (api.FlowResult); this pair's
    interval over the previous pair's (``interval_ratio``; 1 for evenly spaced stamps); and what the previous
    pair computed of this pair's first frame (``seen``, :class:`Seen`; None: computed again)."""

    state: PDState
    unexplained: float
    interval_ratio: float = 1.0
    seen: Seen | None = None


def predict(previous: PDState, shape: tuple[int, int], ratio: float, splat: Splat,
            fill: Callable[[np.ndarray, np.ndarray], np.ndarray] = push_pull, duals: float = 1.0) -> PDState:
    """The previous pair's solver state carried to the new pair's first frame on a grid of ``shape``:
    resampled to it (flow vectors rescaled), the flow multiplied by the interval ``ratio``, everything
    splatted forward along the flow (``splat``), the flow's holes filled by normalised convolution
    (``fill``: densify.push_pull or a backend's), the other variables' holes left at 0; the duals (y, z)
    multiplied by ``duals`` (cfg.stream_duals; 0: zeros, not splatted). A new PDState, float32."""
    state = previous if previous.v.shape[1:] == shape else resize_state(previous, shape)
    flow = state.v * np.float32(ratio) if ratio != 1.0 else state.v
    kept = duals != 0.0
    variables = (state.y if kept else None, state.w, state.z if kept else None)  # what the splat moves
    others = [a for a in variables if a is not None]
    stacked = np.concatenate([a.reshape((-1,) + shape) for a in others]) if others else np.zeros((0,) + shape)
    values, carried, weight = splat(np.ascontiguousarray(flow, dtype=np.float32),
                                    np.ascontiguousarray(stacked, dtype=np.float32))
    ends = np.cumsum([a.size // (shape[0] * shape[1]) for a in others])[:-1]
    moved = iter(part.reshape(a.shape) for part, a in zip(np.split(carried, ends), others, strict=True))
    y, w, z = (None if a is None else next(moved) for a in variables)
    if not kept:
        y, z = np.zeros_like(state.y), None if state.z is None else np.zeros_like(state.z)
    elif duals != 1.0:  # the splat moves values without arithmetic: scaling after it is scaling before it
        y, z = y * np.float32(duals), None if z is None else z * np.float32(duals)
    return PDState(fill(values, weight), y, w, z)


def stream_span(pyr: Pyramid, cfg: FlowConfig) -> tuple[int, int]:
    """(start, finest): the levels a predicted pair is refined on, coarse to fine -- ``cfg.stream_levels``
    levels ending at the finest solved one (clamped to the pyramid)."""
    finest = finest_level(pyr, cfg)
    return min(pyr.coarsest, finest + max(cfg.stream_levels, 1) - 1), finest


@lru_cache(maxsize=8)
def stream_schedule(cfg: FlowConfig) -> FlowConfig:
    """The settings of the refinement of a prediction: ``cfg`` with every level at ``cfg.stream_warps`` warps
    of ``cfg.stream_iterations`` iterations -- the finest solved level at ``cfg.stream_finest_warps`` x
    ``cfg.stream_finest_iterations`` where those are set (0: the same as the others) --, the regularisation
    weight ``cfg.stream_alpha`` and the relaxation ``cfg.stream_relaxation`` where set (0: ``cfg.alpha``, or
    ``cfg.census_alpha`` with the census term; ``cfg.pd_relaxation``; the
    census term's own iteration and warp counts do not apply here) and the pyramid cut
    below the levels it visits (the shapes of the levels kept are the same). Derived, never written back;
    cached per config."""
    levels = min(cfg.levels, cfg.finest_level + max(cfg.stream_levels, 1))
    return cfg.replace(warps=cfg.stream_warps, iterations=cfg.stream_iterations,
                       finest_warps=cfg.stream_finest_warps, finest_iterations=cfg.stream_finest_iterations,
                       census_iterations=0, census_finest_iterations=0, census_finest_warps=0,
                       levels=levels, alpha=cfg.stream_alpha or cfg.alpha,
                       census_alpha=0.0 if cfg.stream_alpha else cfg.census_alpha,
                       pd_relaxation=cfg.stream_relaxation or cfg.pd_relaxation)


def refine_prediction(pyr: Pyramid, cfg: FlowConfig, backend: Backend, predicted: PDState,
                      stats: SolveStats) -> PDState:
    """Refine the ``predicted`` state (:func:`predict`, on the start level of :func:`stream_span`) down to
    the finest solved level with :func:`stream_schedule`'s warps (``cfg`` is that schedule; the median filter
    after a level's warps but its last is ``cfg.stream_inner_median``'s where set). Returns the state
    on the finest solved level; iterations go to ``stats``."""
    start, finest = stream_span(pyr, cfg)
    stats.start_level = start
    return refine_levels(pyr, cfg, backend, predicted, start, finest, stats, finest, cfg.stream_inner_median)


def judged_on(judged: Judged, shape: tuple[int, int], known0: np.ndarray | None = None
              ) -> tuple[np.ndarray, np.ndarray]:
    """The judged pair (the photometric stage's frames) on a grid of ``shape`` (h, w), resampled by area
    average; frame 0's is ``known0`` when given (:class:`Seen`)."""
    h, w = shape
    if judged.frames[0].shape == (h, w):
        return judged.frames
    n0, n1 = (cv2.resize(n, (w, h), interpolation=cv2.INTER_AREA) if k == 1 or known0 is None else known0
              for k, n in enumerate(judged.frames))
    return n0, n1


def predicted_cost(judged: Judged, predicted: np.ndarray, frames: tuple[np.ndarray, np.ndarray] | None = None
                   ) -> float:
    """The prediction's robust data cost: the fraction of sampled pixels of the judged pair (``frames``: the
    photometric stage's frames resampled to the prediction's grid by area average, :func:`judged_on`; computed
    here when None) that the prediction (2, h, w) does not explain, by the stage's judge (census signatures,
    census.reliability)."""
    h, w = predicted.shape[1:]
    n0, n1 = judged_on(judged, (h, w)) if frames is None else frames
    return judged.judge(n0, n1, interleaved_flow(predicted, (h, w)))


def prior_fails(cfg: FlowConfig, prior: Prior) -> str | None:
    """Why the prior cannot start this pair (a full solve's reason), or None: an unreliable previous flow, or
    an interval ratio beyond ``cfg.stream_max_gap`` either way."""
    if prior.unexplained > cfg.stream_max_unexplained:
        return f"previous flow unreliable ({prior.unexplained:.2f} unexplained)"
    if not 1.0 / cfg.stream_max_gap <= prior.interval_ratio <= cfg.stream_max_gap:
        return f"stamp gap ({prior.interval_ratio:.2f}x the previous pair's interval)"
    return None


def prediction_fails(cfg: FlowConfig, cost: float) -> str | None:
    """Why the prediction is not refined (its data cost, :func:`predicted_cost`, above
    ``cfg.stream_max_predicted``: a scene cut or a jump), or None."""
    if cost > cfg.stream_max_predicted:
        return f"prediction does not fit ({cost:.2f} unexplained)"
    return None


def result_fails(cfg: FlowConfig, prior: Prior, unexplained: float) -> str | None:
    """Why the refined prediction is not kept, or None: it is unreliable (``cfg.stream_max_unexplained``) or
    explains the pair worse than the previous result by more than ``cfg.stream_margin``."""
    if unexplained > cfg.stream_max_unexplained or unexplained > prior.unexplained + cfg.stream_margin:
        return f"refined prediction worse ({unexplained:.2f} unexplained, previous {prior.unexplained:.2f})"
    return None


def estimate_predicted(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend, prior: Prior
                       ) -> tuple[PDState, SolveStats, Judged, Seen] | str:
    """The stream stage on one pair (grey float32 (H, W) in [0, 1]): the photometric stage, the prediction
    from ``prior``, its check and its refinement -- (state on the finest solved level, stats, the Judged
    pair) as engine.solve_pair returns them, and what it computed of i1 for the next pair (:class:`Seen`) --
    or the reason the prediction does not hold (the caller then solves the pair in full). The result's own
    check (:func:`result_fails`) is the caller's, on its reliability."""
    reason = prior_fails(cfg, prior)
    if reason is not None:
        return reason
    schedule = stream_schedule(cfg)
    seen = prior.seen
    (s0, s1), judged = photometric_stage(i0, i1, cfg, backend, None if seen is None else seen.sample, seen)
    normalised = judged.frames
    if cfg.photometric == "normalise" and s0 is not normalised[0]:
        # the stage hands the solver the normalised pair itself unless it found an exposure change between the
        # frames (then: local contrast, a data term of another scale than the carried state was solved on)
        return "exposure step"
    key, key1 = judged.keys
    same = key is not None and seen is not None and seen.key == key  # i0 normalised as the previous pair did
    pyr = make_pyramid(s0, s1, schedule, levels0=seen.levels if same else None, noise=judged.noise,
                       contrasts0=seen.contrasts if same else None)
    start, _ = stream_span(pyr, schedule)
    predicted = predict(prior.state, pyr.shapes[start], prior.interval_ratio, backend.splat, backend.fill,
                        cfg.stream_duals)
    frames = judged_on(judged, pyr.shapes[start], seen.area if same else None)
    reason = prediction_fails(cfg, predicted_cost(judged, predicted.v, frames))
    if reason is not None:
        return reason
    stats = SolveStats(shapes=pyr.shapes, iterations=[0] * len(pyr.shapes), stream=PREDICTED)
    state = refine_prediction(pyr, schedule, backend, predicted, stats)
    sigma = None if judged.noise is None or judged.noise.frames is None else judged.noise.frames[1]
    return state, stats, judged, Seen(judged.samples[1], key1, pyr.i1, frames[1],
                                      None if judged.maps is None else judged.maps[0][1], sigma, pyr.contrasts[1])
