"""The initialisation stage: flow candidates the variational refinement starts from.

Sources (``FlowConfig.initialisation``; the temporal one is added by a stream, ``FlowConfig.temporal_init``):

* ``none`` -- the pyramid alone (the paper's scheme);
* ``dis_ultrafast`` / ``dis_fast`` / ``dis_medium`` -- OpenCV's DIS optical flow (Kroeger et al. 2016,
  ``cv2.DISOpticalFlow``) with that preset: dense inverse search over patches on its own pyramid;
* ``dis_fine`` -- DIS medium, and where that moves far also DIS medium searching down to full resolution
  (its finest scale 0; the presets stop at half size or coarser): two candidates, about 4x DIS medium's
  time on large motions;
* ``orb`` / ``sift`` -- sparse descriptor matches (OpenCV detectors, mutual nearest
  neighbours with Lowe's ratio test, then a local-consistency filter), densified edge-aware
  (:mod:`flow_node.core.densify`, the idea of EpicFlow);
* a caller's ``initial_flow`` (API) and the previous pair's flow carried forward (``previous``, a stream).

A DIS source first runs a cheap gate (:func:`gate_passes`: DIS ultrafast on the half-size pair); a pair
it finds moving less than half of ``init_min_motion`` gets no DIS run of the source and no candidate.

Every candidate is a dense flow (2, H, W) float32 at the input resolution in px. The engine does not trust
any of them blindly: it fuses them per pixel with the pyramid's own estimate (:mod:`flow_node.core.fusion`).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from concurrent.futures import Future
from dataclasses import dataclass
from typing import Protocol

import cv2
import numpy as np

from .densify import densify, forward_propagate, splat_points
from .photometric import compares_signatures

# source -> (OpenCV DIS preset, finest scale or None for the preset's own)
DIS_PRESETS = {"dis_ultrafast": (cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST, None),
               "dis_fast": (cv2.DISOPTICAL_FLOW_PRESET_FAST, None),
               "dis_medium": (cv2.DISOPTICAL_FLOW_PRESET_MEDIUM, None),
               "dis_fine": (cv2.DISOPTICAL_FLOW_PRESET_MEDIUM, 0)}
MATCHERS = ("orb", "sift")  # AKAZE is not in OpenCV 5's main modules (opencv-python-headless)
SOURCES = ("none", *DIS_PRESETS, *MATCHERS)  # the choices of FlowConfig.initialisation
RATIO = 0.8  # Lowe's ratio test
MAX_FEATURES = 3000
CONSISTENCY_NEIGHBOURS = 8
CONSISTENCY_PX = 4.0  # a match may deviate this much (plus 20 % of the flow) from its neighbours' median


INITIAL_FLOW = "initial_flow"  # the name of a caller's warm start among the candidates
FB_TOLERANCE_PX = 1.0  # forward-backward mismatch (plus 5 % of the flow) below which a DIS vector is trusted


@dataclass(frozen=True)
class Candidate:
    """One initialisation: its source name, dense flow (2, H, W) float32 (px at input resolution) and
    optionally the same source's ``backward`` flow (2, H, W), frame 1 -> frame 0: where the two agree
    (:func:`forward_backward_consistent`, checked on each fusion level) fusion trusts the candidate more
    (:data:`flow_node.core.fusion.CONSISTENT_COST`). The backward flow may still be computing on a
    background thread (a Future, :func:`in_background`): :meth:`backward_flow` waits for it. ``far``:
    whether the source already found that the flow moves far (:func:`moves_far` at the engine's
    threshold), None when it did not judge it."""

    name: str
    flow: np.ndarray
    backward: np.ndarray | Future[np.ndarray] | None = None
    far: bool | None = None

    def backward_flow(self) -> np.ndarray | None:
        """The backward flow (2, H, W), waited for when it is computed in the background; None without one.
        An error of that computation is raised here."""
        return self.backward.result() if isinstance(self.backward, Future) else self.backward


def in_background(fn: Callable[[], np.ndarray]) -> Future[np.ndarray]:
    """``fn()`` on a new daemon thread; its result (or exception) in the returned Future. The engine runs a
    DIS backward flow so (OpenCV releases the GIL): it is needed only at the first fusion, so it overlaps
    the pyramid and the coarse levels' refinement on the other core instead of adding to the latency."""
    future: Future[np.ndarray] = Future()

    def run() -> None:
        try:
            future.set_result(fn())
        except BaseException as exc:  # noqa: BLE001 -- handed to the waiting caller, re-raised there
            future.set_exception(exc)

    threading.Thread(target=run, name="flow_node-dis-backward", daemon=True).start()
    return future


def forward_backward_consistent(forward: np.ndarray, backward: np.ndarray) -> np.ndarray:
    """(h, w) bool: forward (2, h, w) i0 -> i1 and backward (2, h, w) i1 -> i0 flows agree at x, i.e.
    |f(x) + b(x + f(x))| < FB_TOLERANCE_PX + 5 % of |f(x)| (px of that grid), and x + f(x) stays inside
    the image. Occluded pixels (no correspondence) and wrong vectors fail it."""
    h, w = forward.shape[1:]
    xs = np.arange(w, dtype=np.float32)[None, :] + forward[0]
    ys = np.arange(h, dtype=np.float32)[:, None] + forward[1]
    bu, bv = (cv2.remap(np.ascontiguousarray(b), xs, ys, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
              for b in backward)
    err2 = (forward[0] + bu) ** 2 + (forward[1] + bv) ** 2
    tol = FB_TOLERANCE_PX + 0.05 * np.sqrt(forward[0] ** 2 + forward[1] ** 2)
    inside = (xs >= 0) & (xs <= w - 1) & (ys >= 0) & (ys <= h - 1)
    return inside & (err2 < tol * tol)


# forward_backward_consistent(forward, backward) -> mask: the numpy reference or a backend's kernel
Consistent = Callable[[np.ndarray, np.ndarray], np.ndarray]


def to_u8(img: np.ndarray) -> np.ndarray:
    """Grey float32 in [0, 1] (H, W) -> uint8 (rounded half to even, clipped), the input OpenCV's matchers
    need: np.clip(np.rint(img * 255), 0, 255) in two OpenCV passes (negatives set to 0 first, so the
    absolute value of convertScaleAbs changes nothing) instead of four numpy ones."""
    return cv2.convertScaleAbs(cv2.max(np.asarray(img, dtype=np.float32), 0.0), alpha=255.0)


# OpenCV's DIS refuses frames under 12 px a side (its patches and pyramid); smaller ones get no DIS candidate
DIS_MIN_SIDE = 16


# The gate: DIS ultrafast on the frames at half size (INTER_AREA), i.e. its patch search down to 1/8 of the
# resolution (the preset itself: 1/4): ~0.2-0.4x its time at 320x240 to 1242x375. A pair goes on to the
# source's own DIS run when the gate's 95th percentile (px of the input) exceeds GATE_FRACTION of the
# engine's threshold. On the suite's pairs (Middlebury, the large set, the bags, the fine textures) the
# gate's percentile is within 20 % of DIS ultrafast's and DIS medium's, so at half the threshold it keeps
# back no pair that those would fuse: the candidates, and the results, are the same as without it.
GATE_FRACTION = 0.5
# A small object moving far: besides "more than 5 % of the pixels beyond init_min_motion" (the 95th percentile),
# a pair moves far when more than 1 % of its pixels move beyond TAIL_FACTOR x init_min_motion (the 99th
# percentile). On ../shared/data/large's toy square (2 % of the pixels move 50 px) DIS on the rank-equalised
# frames reads p95 15 px but p99 50 px; Middlebury's largest p99 is 22 px (Urban2), every other large pair is
# far by its p95 already (docs/engine.md, "init_min_motion").
TAIL_FACTOR = 1.5


def gate_passes(u0: np.ndarray, u1: np.ndarray, min_motion: float) -> bool:
    """Whether the gate (see GATE_FRACTION) finds the uint8 pair moving far enough to run the source's
    DIS; True for frames too small to halve for DIS (they go straight to the source)."""
    h, w = u0.shape
    if min(h, w) < 2 * DIS_MIN_SIDE:
        return True
    size = (w // 2, h // 2)
    a, b = (cv2.resize(u, size, interpolation=cv2.INTER_AREA) for u in (u0, u1))
    flow = cv2.DISOpticalFlow_create(cv2.DISOPTICAL_FLOW_PRESET_ULTRAFAST).calc(a, b, None)[::2, ::2]
    u, v = flow[..., 0] * np.float32(w / size[0]), flow[..., 1] * np.float32(h / size[1])  # px of the input
    return beyond(u * u + v * v, GATE_FRACTION * min_motion)  # on every 2nd pixel of the half-size grid


def beyond(squared: np.ndarray, threshold: float) -> bool:
    """"Moves far" on squared flow magnitudes (any shape, px²), for the gate and :func:`moves_far`: more than 5 %
    of them beyond ``threshold`` px (the 95th percentile is, by its nearest rank; np.percentile costs ~0.1 ms, a
    third of the gate's DIS run at 320x240, and decided the same on every DIS flow of Middlebury, the large set and
    the bags) or more than 1 % beyond TAIL_FACTOR x ``threshold`` (the 99th)."""
    t = np.float32(threshold)
    return bool(np.count_nonzero(squared > t * t) > 0.05 * squared.size
                or np.count_nonzero(squared > (t * np.float32(TAIL_FACTOR)) ** 2) > 0.01 * squared.size)


def dis_candidates(i0: np.ndarray, i1: np.ndarray, preset: str, min_motion: float) -> list[Candidate]:
    """DIS as a candidate; when its motion will get it fused (:func:`moves_far`), also the backward flow
    for the consistency check (otherwise that second DIS run is saved). A cheap gate runs first
    (:func:`gate_passes`): a pair it finds moving less than GATE_FRACTION of ``min_motion`` gets no DIS run
    of the source and no candidate. ``dis_fine`` runs DIS medium and, only when that moves far (small motions
    pay one DIS medium run), the full-resolution search too: when that moves far as well, both are
    candidates (the full-resolution one first; each wins on different pairs), otherwise neither is fused."""
    u0, u1 = to_u8(i0), to_u8(i1)
    if not gate_passes(u0, u1, min_motion):
        return []
    code, finest = DIS_PRESETS[preset]
    algo = cv2.DISOpticalFlow_create(code)  # calc without an initial flow: runs independent
    fwd = np.moveaxis(algo.calc(u0, u1, None), -1, 0)
    if not moves_far(fwd, min_motion):
        return [Candidate(preset, fwd, far=False)]
    own = Candidate(preset if finest is None else "dis_medium", fwd, dis_backward(code, None, u0, u1), far=True)
    if finest is None:
        return [own]
    algo.setFinestScale(finest)
    fine = np.moveaxis(algo.calc(u0, u1, None), -1, 0)
    if not moves_far(fine, min_motion):  # the full-resolution search judges the motion better: none fused
        return [Candidate(preset, fine, far=False)]
    return [Candidate(preset, fine, dis_backward(code, finest, u0, u1), far=True), own]


def dis_backward(code: int, finest: int | None, u0: np.ndarray, u1: np.ndarray) -> Future[np.ndarray]:
    """DIS (OpenCV preset ``code``, finest scale ``finest`` or the preset's) from u1 to u0 (uint8 (H, W)),
    (2, H, W) float32, started in the background (:func:`in_background`) on a DIS object of its own."""
    algo = cv2.DISOpticalFlow_create(code)
    if finest is not None:
        algo.setFinestScale(finest)
    return in_background(lambda: np.moveaxis(algo.calc(u1, u0, None), -1, 0))


def moves_far(flow: np.ndarray, min_motion: float) -> bool:
    """Whether flow (2, H, W), px, on every 4th pixel, moves beyond ``min_motion`` by :func:`beyond` (its 95th
    percentile, or its 99th beyond TAIL_FACTOR times that: a small object moving far) -- the gate's rule."""
    u, v = flow[0, ::4, ::4], flow[1, ::4, ::4]
    return beyond(u * u + v * v, min_motion)


def _detector(kind: str) -> cv2.Feature2D:
    if kind == "orb":
        return cv2.ORB_create(nfeatures=MAX_FEATURES)
    return cv2.SIFT_create(nfeatures=MAX_FEATURES)


def sparse_matches(i0: np.ndarray, i1: np.ndarray, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """Descriptor matches from i0 to i1: points (N, 2) in i0 and their displacements (N, 2), px (x, y).

    Mutual nearest neighbours that pass the ratio test, then :func:`consistent` (N may be 0)."""
    det = _detector(kind)
    a, b = to_u8(i0), to_u8(i1)
    k0, d0 = det.detectAndCompute(a, None)
    k1, d1 = det.detectAndCompute(b, None)
    empty = np.zeros((0, 2), np.float32)
    if d0 is None or d1 is None or len(k0) < 2 or len(k1) < 2:
        return empty, empty
    norm = cv2.NORM_L2 if kind == "sift" else cv2.NORM_HAMMING
    matcher = cv2.BFMatcher(norm)
    fwd = matcher.knnMatch(d0, d1, k=2)
    back = {m[0].queryIdx: m[0].trainIdx for m in matcher.knnMatch(d1, d0, k=1) if m}
    keep = [m[0] for m in fwd if len(m) == 2 and m[0].distance < RATIO * m[1].distance
            and back.get(m[0].trainIdx) == m[0].queryIdx]
    if not keep:
        return empty, empty
    p0 = np.array([k0[m.queryIdx].pt for m in keep], np.float32)
    p1 = np.array([k1[m.trainIdx].pt for m in keep], np.float32)
    d = p1 - p0
    ok = consistent(p0, d)
    return p0[ok], d[ok]


def consistent(points: np.ndarray, flows: np.ndarray) -> np.ndarray:
    """Bool (N,) mask of matches that agree with the median flow of their CONSISTENCY_NEIGHBOURS nearest
    matches (within CONSISTENCY_PX + 20 % of that median's length): isolated wrong matches go."""
    n = len(points)
    if n <= CONSISTENCY_NEIGHBOURS:
        return np.ones(n, bool)
    d2 = np.sum((points[:, None, :] - points[None, :, :]) ** 2, axis=-1)
    np.fill_diagonal(d2, np.inf)
    nn = np.argpartition(d2, CONSISTENCY_NEIGHBOURS, axis=1)[:, :CONSISTENCY_NEIGHBOURS]
    med = np.median(flows[nn], axis=1)
    dev = np.linalg.norm(flows - med, axis=1)
    return dev <= CONSISTENCY_PX + 0.2 * np.linalg.norm(med, axis=1)


def matches_flow(i0: np.ndarray, i1: np.ndarray, kind: str) -> np.ndarray | None:
    """Sparse ``kind`` matches densified edge-aware: (2, H, W) float32, or None when nothing matched."""
    points, flows = sparse_matches(i0, i1, kind)
    if len(points) < 3:
        return None
    values, weight = splat_points(i0.shape, points, flows)
    return densify(i0, values, weight)


def propagated_flow(i0: np.ndarray, previous: np.ndarray) -> np.ndarray:
    """The previous pair's flow (2, H, W) on the grid of its first frame, carried forward to the grid of
    its second frame (= this pair's i0) and densified edge-aware over the holes: (2, H, W) float32."""
    values, weight = forward_propagate(previous)
    return densify(i0, values, weight)


class InitSettings(Protocol):
    """The settings the stage reads (a :class:`~flow_node.core.config.FlowConfig`; config.py imports this
    module for SOURCES, so the stage names what it needs instead of importing the config)."""

    @property
    def initialisation(self) -> str: ...

    @property
    def init_min_motion(self) -> float: ...

    @property
    def temporal_init(self) -> int: ...

    @property
    def photometric(self) -> str: ...


# grey levels a frame's ranks are taken on (equalised): 12 bits; on 8 (cv2.equalizeHist) a tone curve merges or
# splits enough levels of a flat-shaded scene to move DIS (the large set's Blender cube under gamma 2: 45 px, 32 on
# 12 bits; git show 4983857:bench/results/suite/invariance/cube/summary.md)
RANK_LEVELS = 4096


def equalised(img: np.ndarray) -> np.ndarray:
    """A frame (H, W) float32, normalised by its own robust range (the census stage's map: its 2nd and 98th
    percentiles at 0 and 1), mapped to its mid-ranks: at each pixel the fraction of the frame's pixels darker
    than it plus half of those as bright, (H, W) float32 in (0, 1), on RANK_LEVELS levels over [0, 1] (the
    darkest and brightest 2 % are one level each). Any strictly monotone tone change of the frame (gain, offset,
    gamma, S-curve, knee) moves neither the percentiles' pixels nor the ranks, so it leaves the result
    unchanged up to that quantisation: with the census data term the sources see what the data term compares,
    not the frames' tone curves (docs/engine.md, "Large displacements", With the census data term)."""
    top = RANK_LEVELS - 1
    q = np.clip(np.rint(img * np.float32(top)), 0, top).astype(np.uint16)
    counts = np.bincount(q.ravel(), minlength=RANK_LEVELS)
    return np.take(((np.cumsum(counts) - 0.5 * counts) * (1.0 / q.size)).astype(np.float32), q)  # take: ~2x indexing


def initialise(i0: np.ndarray, i1: np.ndarray, cfg: InitSettings, initial_flow: np.ndarray | None = None,
               previous_flow: np.ndarray | None = None,
               ranks: Callable[[np.ndarray], np.ndarray] = equalised) -> list[Candidate]:
    """Every candidate for this pair: the caller's ``initial_flow`` (2, H, W), the carried-forward
    ``previous_flow`` (2, H, W, on the previous pair's first frame; used only with ``cfg.temporal_init``)
    and the source ``cfg.initialisation`` computes. Empty: the pyramid alone. With the census data term
    (``cfg.photometric``) every source sees each frame :func:`equalised` on its own (by ``ranks``: that function
    or a backend's, the same bits), not the photometric stage's per-frame affine map (docs/engine.md, "Large
    displacements", With the census data term)."""
    source = cfg.initialisation
    propagate = previous_flow is not None and bool(cfg.temporal_init)
    dis = source in DIS_PRESETS and min(i0.shape) >= DIS_MIN_SIDE
    if compares_signatures(cfg.photometric) and (propagate or dis or source in MATCHERS):  # only if a source reads them
        i0, i1 = ranks(i0), ranks(i1)
    out = []
    if initial_flow is not None:
        out.append(Candidate(INITIAL_FLOW, initial_flow.astype(np.float32, copy=False)))
    if propagate:
        out.append(Candidate("previous", propagated_flow(i0, previous_flow)))
    if dis:
        out.extend(dis_candidates(i0, i1, source, cfg.init_min_motion))
    elif source in MATCHERS:
        flow = matches_flow(i0, i1, source)
        if flow is not None:
            out.append(Candidate(source, flow))
    return out


def beyond_reach(candidates: list[Candidate], min_motion: float) -> list[Candidate]:
    """The candidates worth fusing: a caller's ``initial_flow`` always; a computed one only when it says
    the pair moves far (:func:`moves_far`: the 95th percentile of its |flow|, px on every 4th pixel, above
    ``min_motion`` = ``FlowConfig.init_min_motion``, or its 99th above TAIL_FACTOR times that). Below that
    the pyramid's own estimate is the more accurate one (on Middlebury, whose largest motions are ~21 px,
    fusing DIS anyway costs quality 0.32 -> 0.51 mean AEE: DIS is less precise, and a data cost cannot always
    tell), so only the candidate's computation is spent, not accuracy."""
    # a DIS candidate says whether dis_candidates found it moves far (same threshold): not judged twice
    return [c for c in candidates
            if c.name == INITIAL_FLOW or (c.far if c.far is not None else moves_far(c.flow, min_motion))]
