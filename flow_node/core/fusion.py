"""The fusion stage: per-pixel choice between flow candidates by their data cost (the per-pixel confidence of a
flow, judged on the same residual, is :mod:`flow_node.core.confidence`).

Images are float32 (h, w) grey; flows are channel-first (2, h, w) in pixels of that grid. The data cost of
a flow at a pixel is the local mean (a ``window`` x ``window`` box) of the mismatch of the frames' cost planes
after warping frame 1's back along the flow, over the pixels whose x + flow(x) stays inside the image: the
brightness and its gradient (:func:`planes`) with a grey-value data term, the soft census signature
(:func:`census_planes`) with the census one, so that the fusion is invariant to what the data term is
invariant to. Fusion takes, per pixel, the candidate of least cost, with the pyramid's own estimate (the first
candidate) weighted by a margin and forward-backward confirmed candidate pixels by CONSISTENT_COST. Two
kinds of pixel are not decided by their cost but continue the flow of the nearest decided pixel: those where
no candidate has data, and those won by a candidate that fails its forward-backward check (occluded
pixels, whose true flow has no match in frame 1 so any wrong flow onto similar grey values costs less than
the truth, and wrong vectors: the cost there is no evidence). An initialisation that is wrong somewhere
costs clearly more there, or fails its check, and is not used there: it cannot make a pair much worse than
the pyramid alone.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from functools import partial

import cv2
import numpy as np

from .census import CENSUS, CensusParams, signature
from .operators import warp_maps
from .photometric import compares_signatures

FUSION_WINDOW = 31  # px on the fusion level: the cost is a local mean, so one lucky pixel does not switch
FUSION_MARGIN = 1.3  # a candidate is taken where it costs less than this times the pyramid's flow
FINAL_MARGIN = 1.3  # after the refinement: a candidate is taken where it costs less than this times the refined flow
FINAL_ONLY_CONSISTENT = False  # True: ... and only where forward-backward consistent
CONSISTENT_COST = 0.5  # cost factor of a forward-backward consistent candidate pixel
PROPAGATE_INCONSISTENT = True  # a pixel won by a candidate failing its check is undecided (fill_undecided)


def box_mean(img: np.ndarray, window: int) -> np.ndarray:
    """Mean of ``img`` (h, w) over ``window`` x ``window`` boxes, borders reflected."""
    return cv2.boxFilter(img, -1, (window, window), borderType=cv2.BORDER_REFLECT)


def _grad(img: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Central differences (Sobel / 8), px^-1 in intensity units: (d/dx, d/dy), each (h, w)."""
    return (cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE),
            cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3, scale=0.125, borderType=cv2.BORDER_REPLICATE))


def planes(img: np.ndarray) -> np.ndarray:
    """An image with its gradient, interleaved (h, w, 3) float32: I, dI/dx, dI/dy -- what a cost compares."""
    return cv2.merge([img.astype(np.float32, copy=False), *_grad(img)])


def census_planes(img: np.ndarray, params: CensusParams = CENSUS) -> np.ndarray:
    """An image's soft census signature (census.signature), interleaved (h, w, 8) float32: what a cost compares
    with the census data term (invariant to the tone changes the data term is invariant to)."""
    return np.ascontiguousarray(np.moveaxis(signature(img, params), 0, -1))


# a frame (h, w) -> its cost planes (h, w, P) float32: planes, census_planes
CostPlanes = Callable[[np.ndarray], np.ndarray]


def cost_census(eps: float = 0.0) -> CensusParams:
    """The census constants of the fusion's cost: :data:`census.CENSUS` with EPS at least ``eps`` (a pyramid
    level's noise floor)."""
    return CENSUS if eps <= CENSUS.eps else replace(CENSUS, eps=eps)


def cost_planes(photometric: str, eps: float = 0.0) -> CostPlanes:
    """The cost planes of photometric mode ``photometric``: :func:`census_planes` (:func:`cost_census`'s constants)
    when its data term compares census signatures, else :func:`planes`."""
    if not compares_signatures(photometric):
        return planes
    return partial(census_planes, params=cost_census(eps))


def level_planes(img: np.ndarray, photometric: str, eps: float = 0.0) -> np.ndarray:
    """A pyramid level's frame (h, w) -> its cost planes (h, w, P) float32 in photometric mode ``photometric``, EPS
    floor ``eps`` (:func:`cost_planes`; the numpy reference of the backend field ``cost_planes``)."""
    return cost_planes(photometric, eps)(img)


# level_planes(img, photometric, eps) -> (h, w, P): :func:`level_planes` or a backend's (numba_fusion.planes_numba)
LevelPlanes = Callable[[np.ndarray, str, float], np.ndarray]


REMAP_CHANNELS = 4  # OpenCV's remap samples up to 4 interleaved channels exactly; more go in groups of 4


def warp_residual(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray,
                  stacks: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel mismatch of the cost planes, |S1(x + f) - S0(x)|_1 over the planes (h, w) float32 -- by default
    (:func:`planes`) |I1(x + f) - I0(x)| + |grad I1(x + f) - grad I0(x)|_1 --, and the bool mask of pixels
    whose x + f stays inside the image. The gradient part keeps the cost meaningful under a brightness change
    between the frames. Frame 1's planes are sampled bilinearly (OpenCV's remap, REMAP_CHANNELS at a time):
    enough for judging a flow -- a cost, not the data term. ``stacks`` = (the cost planes (h, w, P) of i0, of
    i1), computed once when several flows are judged on one pair (default: :func:`planes`)."""
    s0, s1 = stacks if stacks is not None else (planes(i0), planes(i1))
    map_x, map_y, inside = warp_maps(flow)
    r = np.zeros(s0.shape[:2], np.float32)
    for k in range(0, s0.shape[2], REMAP_CHANNELS):
        part = s1 if s1.shape[2] <= REMAP_CHANNELS else np.ascontiguousarray(s1[..., k:k + REMAP_CHANNELS])
        w1 = cv2.remap(part, map_x, map_y, interpolation=cv2.INTER_LINEAR,
                       borderMode=cv2.BORDER_REPLICATE).reshape(part.shape)
        r += np.abs(w1 - s0[..., k:k + REMAP_CHANNELS]).sum(axis=-1, dtype=np.float32)
    return r, inside


def data_cost(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, window: int | None = None,
              stacks: tuple[np.ndarray, np.ndarray] | None = None) -> np.ndarray:
    """Local mean of :func:`warp_residual` over the pixels of a ``window`` x ``window`` box whose x + f
    stays inside the image (h, w); inf where (almost) none does. Leaving the image is no evidence against a
    flow (a camera moving forward carries the border out), so such pixels are judged by their neighbours."""
    window = FUSION_WINDOW if window is None else window
    r, inside = warp_residual(i0, i1, flow, stacks)
    m = inside.astype(np.float32)
    support = box_mean(m, window)
    cost = box_mean(r * m, window) / np.maximum(support, 1e-6)
    cost[support < 0.05] = np.inf
    return cost


def fuse(i0: np.ndarray, i1: np.ndarray, candidates: list[np.ndarray],
         consistent: list[np.ndarray | None] | None = None,
         margin: float = FUSION_MARGIN, only_consistent: bool = False,
         propagate: bool = PROPAGATE_INCONSISTENT, planes_of: CostPlanes = planes,
         stacks: tuple[np.ndarray, np.ndarray] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Per-pixel fusion of flow candidates (each (2, h, w)); candidates[0] is the reference (the pyramid's
    own flow); another candidate is taken where it costs less than ``margin`` times the reference.
    ``consistent`` (per candidate, (h, w) bool or None) marks pixels where a forward-backward check
    confirmed a candidate: its cost counts CONSISTENT_COST times there (in flat or reflective areas a wrong
    flow can match the grey values as well as the right one; a consistency check is independent evidence),
    or, with ``only_consistent``, the candidate is considered nowhere else. With ``propagate``, a pixel a
    candidate wins while failing its check is undecided, like one where no candidate has data: it takes
    the candidate continuing the flow of the nearest decided pixel (:func:`fill_undecided`) -- the cost of
    an occluded pixel favours any wrong flow that lands on similar grey values; its neighbours' flow is
    the better guess.
    ``planes_of``: what the cost compares (:func:`cost_planes`: grey values and their gradient, or census
    signatures); ``stacks``: the frames' cost planes (h, w, P) each when already computed (then ``planes_of`` is not
    used: the engine builds a level's planes once for both of its fusions, engine.level_stacks). Returns the fused
    flow (2, h, w) float32 and the index of the chosen candidate per pixel (h, w) int."""
    stacks = stacks if stacks is not None else (planes_of(i0), planes_of(i1))
    costs = np.stack([data_cost(i0, i1, c, stacks=stacks) for c in candidates])
    costs[0] *= margin
    for k, ok in enumerate(consistent or []):
        if ok is not None and only_consistent:
            costs[k][~ok] = np.inf
        elif ok is not None:
            costs[k][ok] *= CONSISTENT_COST
    choice = np.argmin(costs, axis=0)
    undecided = ~np.isfinite(costs).any(axis=0)
    for k, ok in enumerate(consistent or []):
        if ok is not None and propagate:
            undecided |= (choice == k) & ~ok
    stack = np.stack(candidates)
    choice = fill_undecided(choice, undecided, stack)
    fused = np.take_along_axis(stack, choice[None, None], axis=0)[0]
    return fused.astype(np.float32, copy=False), choice


# fuse(i0, i1, candidates, consistent, margin, only_consistent, planes_of=, stacks=) -> (flow, choice): :func:`fuse`
# or a backend's kernels (numba_fusion.fuse_numba)
Fuse = Callable[..., tuple[np.ndarray, np.ndarray]]


def fill_undecided(choice: np.ndarray, undecided: np.ndarray, stack: np.ndarray) -> np.ndarray:
    """Where no data decides (``undecided`` (h, w) bool: every candidate leaves the image, or the winner
    failed its forward-backward check), continue the neighbours' flow instead of defaulting to the
    reference (which the regulariser and the median filter would spread inwards): an undecided pixel takes
    the candidate of ``stack`` (K, 2, h, w) whose flow there is nearest to the fused flow of the nearest
    decided pixel (on an occluded background that is the background's motion, whichever candidate the
    neighbours chose). Returns the choice (h, w) int; all undecided (or none): ``choice`` as it is."""
    if not undecided.any() or undecided.all():
        return choice
    _, labels = cv2.distanceTransformWithLabels(undecided.astype(np.uint8), cv2.DIST_L2, 5,
                                                labelType=cv2.DIST_LABEL_PIXEL)
    near = np.zeros(labels.max() + 1, np.int64)
    near[labels[~undecided]] = np.flatnonzero(~undecided.reshape(-1))
    src = near[labels[undecided]]  # flat index of each undecided pixel's nearest decided pixel
    flat = stack.reshape(stack.shape[0], 2, -1)
    target = np.take_along_axis(flat[:, :, src], choice.reshape(-1)[src][None, None], axis=0)[0]  # (2, n)
    dist = np.sum((flat[:, :, np.flatnonzero(undecided.reshape(-1))] - target[None]) ** 2, axis=1)  # (K, n)
    out = choice.copy()
    out[undecided] = np.argmin(dist, axis=0)
    return out
