"""The engine's stages, composed: photometric preprocessing -> initialisation -> coarse-to-fine refinement
with the paper's models -> fusion -> output layout (docs/design.md, "Engine stages").

Each stage is one function with one interface, in the module named for it:

==============  ===================================================================  =======================
stage           interface                                                            module
==============  ===================================================================  =======================
photometric     (i0, i1, cfg, backend) -> (solver pair, Judged)                      ``core/photometric.py``
initialisation  (i0, i1, cfg, initial, previous) -> [Candidate]                      ``core/initialise.py``
refinement      (pyramid, cfg, backend, state, first, last, stats, finest) -> state  ``core/refine.py``
fusion          (i0, i1, [flow]) -> (flow, choice), a backend field                  ``core/fusion.py``
output layout   (2, h, w) -> (H, W, 2) at the input size                             ``core/layout.py``
(stream)        (i0, i1, cfg, backend, prior) -> (state, stats, Judged) | reason     ``core/temporal.py``
(confidence)    (i0, i1, flow) -> (H, W) in [0, 1], on demand                        ``core/confidence.py``
==============  ===================================================================  =======================

Without a candidate -- or when no computed candidate says the pair moves further than ``cfg.init_min_motion``
(:func:`~flow_node.core.initialise.beyond_reach`) -- the refinement runs over the whole pyramid from zero
flow (the paper's scheme). With candidates it runs from the coarsest level down to just above the *start
level* -- the coarsest level with at least ``cfg.init_scale`` of the input resolution, where the
initialisation is trusted -- and there the pyramid's estimate and every candidate (resampled to that level)
are fused per pixel by data cost (a pixel won by a candidate failing its forward-backward check -- an
occluded one, typically -- continues its decided neighbours' flow instead); the refinement then continues
from the fused flow to the finest solved level, where its result and the candidates are fused once more (an
initialisation the refinement drifted away from wrongly is recovered there).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .backends import Backend
from .census_noise import PairNoise, channel_noise, pair_noise
from .colour import NormalisedChannels, normalised_channels
from .config import FlowConfig
from .fusion import FINAL_MARGIN, FINAL_ONLY_CONSISTENT
from .initialise import INITIAL_FLOW, Candidate, beyond_reach, initialise
from .layout import interleaved_flow
from .models import MODEL_SPECS
from .photometric import (
    FrameMap,
    FrameMaps,
    PairMap,
    Reliability,
    Samples,
    compares_signatures,
    frame_key,
    frame_maps,
    frame_samples,
    pair_map,
    stage,
)
from .pyramid import Pyramid, make_pyramid, noise_gain, resize_flow, resize_state
from .refine import SolveStats, finest_level, refine_levels
from .solver import PDState
from .validity import fill_invalid


@dataclass(frozen=True)
class Judged:
    """What the photometric stage hands back besides the solver's pair: the pair a flow is judged on
    (``frames``, (H, W) float32 each) and the reliability figure (``judge``: the backend's census.reliability,
    census signatures whatever the data term, so a flow is judged by what no tone change alters: a grey-value
    flow bent by a tone curve reads as unexplained, a right one does not); ``samples``: the input frames'
    sorted samples the stage took its ranges from (photometric.frame_samples; a stream hands frame 1's to its
    next pair, temporal.Prior); ``keys``: what each frame's normalised image depends on besides the frame
    (:func:`frame_keys`; None outside the ``normalise`` and census modes), computed once here for the stream
    stage's reuse (:class:`Seen`); ``noise``: with the census data term and ``census_noise_k`` > 0, the pair's
    noise for the signature's EPS floor (census_noise.pair_noise, handed to make_pyramid), else None; ``maps``:
    with the census data term, the frames' own maps (photometric.frame_maps), else None."""

    frames: tuple[np.ndarray, np.ndarray]
    judge: Reliability
    samples: Samples
    keys: tuple[MapKey | None, MapKey | None] = (None, None)
    noise: PairNoise | None = None
    maps: FrameMaps | None = None

    def unexplained(self, flow: np.ndarray, samples: int | None = None) -> float:
        """The fraction of sampled pixels (about ``samples``) ``flow`` (H, W, 2) px does not explain
        (census.reliability)."""
        return self.judge(*self.frames, flow, samples=samples)


@dataclass(frozen=True)
class Seen:
    """What a pair computed of its second frame that the next pair, whose first frame it is, need not compute
    again (a stream: temporal.Prior): its sorted ``sample`` (photometric.sorted_sample: the photometric stage's
    ranges come from it) and, with the census data term, its own ``map`` (photometric.frame_map, of that
    sample); and, from a pair the stream stage refined in ``normalise`` or a census mode, what the frame's
    normalised image depends on besides the frame (``key``: :func:`frame_keys`), the frame's normalised pyramid
    (``levels``, finest first, as pyramid.make_pyramid built it; level 0, the normalised frame itself, is the
    next pair's normalised frame 0), its normalised image on the stream's start level by area average (``area``:
    temporal.judged_on), with the census noise floor its noise std (``sigma``: census_noise.pair_noise) and with the
    census term its level contrasts (``contrasts``: pyramid.Pyramid.contrasts, refine.level_contrast). The
    next pair takes those only when its own key for the frame is the same -- the normalised frame is then the
    same, bit for bit --, else it builds them again."""

    sample: np.ndarray
    key: MapKey | None = None
    levels: list[np.ndarray] | None = None
    area: np.ndarray | None = None
    map: FrameMap | None = None
    sigma: float | None = None
    contrasts: dict[int, float] | None = None


def photometric_stage(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend,
                      sample0: np.ndarray | None = None, known0: Seen | None = None,
                      colour: NormalisedChannels | None = None) -> tuple[tuple[np.ndarray, np.ndarray], Judged]:
    """The photometric stage (photometric.stage with the pyramid's noise gain) and its own judge: what the
    solver sees of the pair (H, W) float32, and the :class:`Judged` pair (every data term judged on census
    signatures, the backend's census.reliability). ``sample0``: frame 0's sorted sample when
    known (photometric.frame_samples: a stream's previous pair sorted it as its frame 1); ``known0``: what a
    previous pair computed of frame 0 (:class:`Seen`, of the same sample): its map, and its normalised image and
    noise std, taken when this pair's key for frame 0 is the same (the normalised frame is then the same bit for
    bit). ``colour``: both frames' channels as :func:`colour_stage` took and normalised them
    (colour.NormalisedChannels), when the census term compares them: the noise floor is then the channels'
    (census_noise.channel_noise, on the maps they were normalised by), not the luma's."""
    samples = frame_samples(i0, i1, sample0, backend.sample)
    signatures = compares_signatures(cfg.photometric)
    pmap = None if signatures else pair_map(samples)
    gain = noise_gain(i0.shape, cfg)
    # once, for the stage and the noise floor
    maps = (frame_maps(samples, gain, None if known0 is None else known0.map, cfg.census_presmooth)
            if signatures else None)
    keys = frame_keys(pmap, maps, gain, cfg.photometric)
    same = known0 is not None and keys[0] is not None and keys[0] == known0.key
    n0 = known0.levels[0] if same and known0.levels else None
    solver_pair, frames = stage(i0, i1, cfg.photometric, gain, samples, pmap, n0, maps)
    judge = backend.reliability
    noise = None
    if signatures and cfg.census_noise_k > 0:
        noise = (pair_noise((i0, i1), maps, gain, solver_pair, backend.noise, known0.sigma if same else None)
                 if colour is None else channel_noise(colour.raw, colour.maps, gain, colour.normalised, backend.noise))
    return solver_pair, Judged(frames, judge, samples, keys, noise, maps)


# what a frame's normalised image depends on besides the frame (frame_keys)
MapKey = tuple[float, ...]


def frame_keys(pmap: PairMap | None, maps: FrameMaps | None, gain: float, photometric: str
               ) -> tuple[MapKey | None, MapKey | None]:
    """Per frame, what its normalised image depends on besides the frame: in ``normalise`` mode (``photometric``)
    the pair's normalising map (photometric.pair_map) with the pyramid's noise ``gain``
    (pyramid.noise_gain), the same for both frames; with the
    census data term (each frame normalised on its own: photometric.normalise_frames) the frame's own map, the
    presmoothing and the noise gain (photometric.frame_key). Two pairs that give a frame they share equal keys map
    it to the same normalised frame (:class:`Seen`). None in other modes (the stream stage then builds everything
    again)."""
    if photometric == "normalise" and pmap:
        key = (*pmap, gain)
        return key, key
    if maps is not None:
        return frame_key(maps, 0, gain), frame_key(maps, 1, gain)
    return None, None


def colour_stage(shape: tuple[int, int], channels: tuple[np.ndarray, np.ndarray] | None, cfg: FlowConfig,
                 backend: Backend | None = None) -> NormalisedChannels | None:
    """The colour part of the photometric stage: both frames' channels (C, H, W) each normalised on its own
    (colour.normalised_channels, with the pyramid's noise gain; channel c of both presmoothed alike, by
    FlowConfig.census_presmooth at least; each channel's maps taken once, of the ``backend``'s sorted samples, the
    same arrays as the numpy reference's) when the census data term compares them; None
    otherwise (grey-value terms and grey input use the luma only)."""
    if channels is None or not compares_signatures(cfg.photometric):
        return None
    gain = noise_gain(shape, cfg)
    return normalised_channels(*channels, gain, cfg.census_presmooth, None if backend is None else backend.sample)


def start_level(pyr: Pyramid, cfg: FlowConfig, finest: int | None = None) -> int:
    """The level the refinement restarts from with an initialisation: the coarsest one with at least
    ``cfg.init_scale`` of the input resolution, never finer than the finest solved level (``finest``;
    default: :func:`~flow_node.core.refine.finest_level` of ``cfg``)."""
    return max(pyr.level_at_scale(cfg.init_scale), finest_level(pyr, cfg) if finest is None else finest)


def refine_from(pyr: Pyramid, cfg: FlowConfig, backend: Backend, candidates: list[Candidate],
                stats: SolveStats) -> PDState:
    """Refinement and fusion: the whole pyramid from zero flow, or (with candidates) down to the start
    level, fusion there, then on to the finest solved level (``cfg.init_finest_level`` when a candidate the
    engine computed is fused: :func:`~flow_node.core.refine.finest_level`). Returns the state on the finest
    solved level."""
    state = PDState.zeros(MODEL_SPECS[cfg.model], pyr.shapes[-1])
    stats.init_offered = "+".join(c.name for c in candidates)
    candidates = beyond_reach(candidates, cfg.init_min_motion)
    if not candidates:
        finest = finest_level(pyr, cfg)
        return refine_levels(pyr, cfg, backend, state, pyr.coarsest, finest, stats, finest)
    finest = finest_level(pyr, cfg, initialised=any(c.name != INITIAL_FLOW for c in candidates))
    start = start_level(pyr, cfg, finest)
    if start < pyr.coarsest:
        state = refine_levels(pyr, cfg, backend, state, pyr.coarsest, start + 1, stats, finest)
        state = resize_state(state, pyr.shapes[start])
    on_level = candidates_on_level(pyr, start, candidates, backend)
    stacks = level_stacks(pyr, start, backend, cfg.photometric)
    state.v, choice = fuse_on_level(pyr, start, state.v, on_level, backend, stacks=stacks)
    stats.init = "+".join(c.name for c in candidates)
    stats.start_level = start
    stats.init_share = float(np.mean(choice > 0))
    state = refine_levels(pyr, cfg, backend, state, start, finest, stats, finest)
    if finest != start:  # else the second fusion reuses the start level's candidates and planes
        on_level, stacks = (candidates_on_level(pyr, finest, candidates, backend),
                            level_stacks(pyr, finest, backend, cfg.photometric))
    state.v, choice = fuse_on_level(pyr, finest, state.v, on_level, backend, final=True, stacks=stacks)
    stats.final_init_share = float(np.mean(choice > 0))
    return state


# the candidates on one level: their flows (2, h, w) and forward-backward masks (h, w) bool, None when unchecked
OnLevel = tuple[list[np.ndarray], list[np.ndarray | None]]


def candidates_on_level(pyr: Pyramid, level: int, candidates: list[Candidate], backend: Backend) -> OnLevel:
    """Every candidate resampled to ``level`` and, where it has a backward flow, its forward-backward check
    there (the backend's); computed once per level, also when both fusions are on the same level."""
    shape = pyr.shapes[level]
    flows = [on_grid(c.flow, shape) for c in candidates]
    backward = [c.backward_flow() for c in candidates]
    trusted = [None if b is None else backend.consistent(f, on_grid(b, shape))
               for f, b in zip(flows, backward, strict=True)]
    return flows, trusted


def level_stacks(pyr: Pyramid, level: int, backend: Backend, photometric: str) -> tuple[np.ndarray, np.ndarray]:
    """Both frames' cost planes (h, w, P) on ``level`` (the backend's fusion.level_planes: census signatures with
    the level's EPS floor, or grey values and their gradient, as the data term of ``photometric`` compares);
    computed once per level, also when both fusions are on the same level (the speed presets': their start level
    is their finest solved level)."""
    eps = pyr.eps_floor(level)
    return backend.cost_planes(pyr.i0[level], photometric, eps), backend.cost_planes(pyr.i1[level], photometric, eps)


def fuse_on_level(pyr: Pyramid, level: int, flow: np.ndarray, on_level: OnLevel, backend: Backend,
                  final: bool = False, stacks: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, np.ndarray]:
    """Fuse the refinement's ``flow`` (2, h, w) on ``level`` with the candidates there (``on_level``, from
    :func:`candidates_on_level`); returns the fused flow and the per-pixel choice (0 = ``flow``). On the
    start level (``final`` False) candidates are preferred (FUSION_MARGIN) and forward-backward consistent
    pixels trusted more; after the refinement (``final``) the same with FINAL_MARGIN (a candidate is taken
    where it costs less than that times the refined flow, a consistent one at CONSISTENT_COST of its cost:
    BENCHMARKS.md, "Large motions at a bounded cost", measures what that keeps of the refinement). The
    backend's fusion (numpy reference or numba kernels, same results). The cost compares the level's ``stacks``
    (:func:`level_stacks`; default: grey values and their gradient): with the census term its signatures, so the
    choice is as invariant as the term (docs/engine.md, "Large displacements")."""
    flows, trusted = [flow, *on_level[0]], [None, *on_level[1]]
    if final:
        return backend.fuse(pyr.i0[level], pyr.i1[level], flows, trusted, FINAL_MARGIN,
                            only_consistent=FINAL_ONLY_CONSISTENT, stacks=stacks)
    return backend.fuse(pyr.i0[level], pyr.i1[level], flows, trusted, stacks=stacks)


def warm_fusion(backend: Backend, photometric: str = "normalise") -> None:
    """Run the backend's fusion, its cost planes for ``photometric`` and forward-backward check once on a small
    synthetic level (and, when ``photometric``'s data term compares signatures, the initialisation's ranks), so that
    a warm-up compiles them, or loads them from numba's cache, before the first frame that moves far (a warm-up
    solve does not reach them: only such pairs are fused, and DIS skips its small frames). Two candidates leave the
    32 x 128 level on opposite sides, so a stripe between them is undecided and every pass of the fusion runs."""
    i0 = np.random.default_rng(0).random((32, 128), dtype=np.float32)
    left = np.zeros((2, 32, 128), np.float32)
    left[0] = -100.0
    if compares_signatures(photometric):
        backend.ranks(i0)
    s0 = backend.cost_planes(i0, photometric, 0.0)
    backend.fuse(i0, i0, [left, -left], [None, backend.consistent(-left, left)], stacks=(s0, s0))


def on_grid(flow: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """A candidate's flow (2, h, w) on a level of ``shape``: itself when it already lives there (the
    finest level at full resolution; a resize to the same size would only copy it), else resized."""
    return flow if flow.shape[1:] == shape else resize_flow(flow, shape)


def estimate_pair(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend,
                  initial_flow: np.ndarray | None = None, previous_flow: np.ndarray | None = None,
                  channels: tuple[np.ndarray, np.ndarray] | None = None,
                  valid: tuple[np.ndarray, np.ndarray] | None = None
                  ) -> tuple[np.ndarray, SolveStats, Judged]:
    """Flow from i0 to i1 (grey float32 (H, W) in [0, 1], same size): float32 (H, W, 2), u then v, px;
    the stats; and the photometric stage's :class:`Judged` pair (what the flow's reliability and
    confidence are judged on, and the judge).

    ``initial_flow`` (2, H, W) is a caller's warm start; ``previous_flow`` (2, H, W) the previous pair's
    flow in a stream (used when ``cfg.temporal_init``). Both only enter through the fusion, so a wrong one
    costs time, not accuracy. The finest solved level is ``cfg.finest_level`` (clamped); its flow is
    upsampled to (H, W) by the output layout stage.

    ``channels``: both frames' colour channels (C, H, W) float32 in [0, 1] (i0, i1 being their luma); with the
    census data term they are what it compares (colour.py, each channel normalised on its own), otherwise
    they are not used. ``valid``: the frames' validity masks (H, W) bool (validity.py): invalid pixels are
    filled before every stage and carry no data term in the refinement.
    """
    state, stats, judged = solve_pair(i0, i1, cfg, backend, initial_flow, previous_flow, channels, valid)
    return interleaved_flow(state.v, stats.shapes[0], check_finite=True), stats, judged


def solve_pair(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, backend: Backend,
               initial_flow: np.ndarray | None = None, previous_flow: np.ndarray | None = None,
               channels: tuple[np.ndarray, np.ndarray] | None = None,
               valid: tuple[np.ndarray, np.ndarray] | None = None, sample0: np.ndarray | None = None
               ) -> tuple[PDState, SolveStats, Judged]:
    """:func:`estimate_pair` before the output layout: the solver state on the finest solved level (its
    flow (2, h, w) in px of that level; a stream carries the whole state to the next pair, temporal.py),
    the stats (``stats.shapes[0]`` is the input size) and the Judged pair. ``sample0``: i0's sorted sample
    when known (photometric_stage; not used with ``valid``, which changes the frames first)."""
    if valid is not None:
        i0, i1 = fill_invalid(i0, valid[0]), fill_invalid(i1, valid[1])
        sample0 = None
    colour = colour_stage(i0.shape, channels, cfg, backend)
    (i0, i1), judged = photometric_stage(i0, i1, cfg, backend, sample0, colour=colour)
    candidates = initialise(i0, i1, cfg, initial_flow, previous_flow, backend.ranks)
    pyr = make_pyramid(i0, i1, cfg, channels=None if colour is None else colour.normalised, valid=valid,
                       noise=judged.noise)
    stats = SolveStats(shapes=pyr.shapes, iterations=[0] * len(pyr.shapes))
    return refine_from(pyr, cfg, backend, candidates, stats), stats, judged
