"""The image pyramid of the coarse-to-fine scheme (paper, "Large Displacements"): level shapes, Gaussian
pyramids, and carrying fields, flows and solver states between levels.

Images are float32 (H, W); flow is channel-first (2, H, W) in pixels of the level it lives on. Level 0 is
the input resolution; level l has shape ``shape * scale_factor**l`` (rounded). The driver that walks the
levels is :mod:`flow_node.core.refine`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from functools import lru_cache

import cv2
import numpy as np

from .census_noise import PairNoise, difference_noise_gains, eps_floors, noise_sigma
from .config import FlowConfig
from .photometric import compares_signatures
from .solver import PDState
from .validity import mask_levels

ANTIALIAS = 0.7  # blur (px of the finer level, times 1/scale) of every step when the finest solved level is coarser


def pyramid_shapes(shape: tuple[int, ...], levels: int, scale: float, min_size: int) -> list[tuple[int, ...]]:
    """Level shapes, finest first: shape * scale**l, stopping before a side would drop below min_size (an
    image's (H, W) or a volume's (Z, Y, X)). A new list each call (computed once per argument set: a stream
    asks for the same every frame)."""
    return list(_pyramid_shapes(tuple(shape), levels, scale, min_size))


@lru_cache(maxsize=64)
def _pyramid_shapes(shape: tuple[int, ...], levels: int, scale: float, min_size: int) -> tuple[tuple[int, ...], ...]:
    """:func:`pyramid_shapes` as a tuple, cached."""
    shapes = [shape]
    for lvl in range(1, levels):
        level = tuple(round(n * scale**lvl) for n in shape)
        if min(level) < min_size or level == shapes[-1]:
            break
        shapes.append(level)
    return tuple(shapes)


def build_pyramid(img: np.ndarray, shapes: list[tuple[int, int]], scale: float, antialias_levels: int = 0
                  ) -> list[np.ndarray]:
    """Gaussian pyramid on the given shapes: blur then bilinear-resample each step. The blur is sigma =
    1/(3 scale) px of the finer level (weak: some aliasing on a level that a finer one corrects is
    harmless), except on the first ``antialias_levels`` steps, where it is ANTIALIAS / scale (see
    :func:`make_pyramid`)."""
    levels = [img]
    for sigma, (h, w) in zip(step_sigmas(len(shapes) - 1, scale, antialias_levels), shapes[1:], strict=True):
        blurred = cv2.GaussianBlur(levels[-1], (0, 0), sigmaX=sigma, sigmaY=sigma,
                                   borderType=cv2.BORDER_REPLICATE)
        levels.append(cv2.resize(blurred, (w, h), interpolation=cv2.INTER_LINEAR))
    return levels


def step_sigmas(steps: int, scale: float, antialias_levels: int = 0) -> list[float]:
    """The blur (px of the finer level) of each of :func:`build_pyramid`'s ``steps`` steps."""
    return [(ANTIALIAS if step < antialias_levels else 1.0 / 3.0) / scale for step in range(steps)]


def resize_field(f: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """Bilinear resize of every leading channel of f (..., h, w) to (..., H, W); values unchanged."""
    h, w = shape
    if f.ndim == 3 and f.shape[0] <= 4 and f.transpose(1, 2, 0).flags.c_contiguous:
        # a channel-first view of interleaved data (an OpenCV flow, moveaxis'd): one call, no per-channel copies
        return np.ascontiguousarray(np.moveaxis(cv2.resize(f.transpose(1, 2, 0), (w, h),
                                                           interpolation=cv2.INTER_LINEAR).reshape(h, w, -1), -1, 0))
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
        p=None if state.p is None else resize_field(state.p, shape),
    )


@dataclass(frozen=True)
class Pyramid:
    """Both frames on every level, finest first: ``shapes[l]`` (h, w), ``i0[l]`` and ``i1[l]`` float32; with
    colour input for the data term (colour.py), also their channels ``c0[l]``, ``c1[l]`` (C, h, w) float32; with
    a validity mask (validity.py) ``valid0[l]`` and ``valid1[l]`` float32 in [0, 1] (None: every pixel valid);
    with the census data term and ``census_noise_k`` > 0, ``census_eps[l]``: the floor of the signature's EPS on
    level l from the pair's noise (census_noise.py; None: no floor), and with ``census_finest_radius`` 2 also
    ``census_eps_far[l]``, the floor for neighbours at distance 2. ``contrasts``: per frame, the census term's level
    contrasts measured so far ({level: value}, refine.level_contrast fills them; frame 0's may come from a stream's
    previous pair with its pyramid: engine.Seen)."""

    shapes: list[tuple[int, int]]
    i0: list[np.ndarray]
    i1: list[np.ndarray]
    c0: list[np.ndarray] | None = None
    c1: list[np.ndarray] | None = None
    valid0: list[np.ndarray] | None = None
    valid1: list[np.ndarray] | None = None
    census_eps: tuple[float, ...] | None = None
    census_eps_far: tuple[float, ...] | None = None
    contrasts: tuple[dict[int, float], dict[int, float]] = field(default_factory=lambda: ({}, {}))

    def eps_floor(self, level: int, radius: int = 1) -> float:
        """The census EPS floor on ``level`` for the signature's neighbours at distance ``radius`` (0 without one)."""
        floors = self.census_eps if radius == 1 else self.census_eps_far
        return 0.0 if floors is None else floors[level]

    def valid(self, level: int) -> tuple[np.ndarray, np.ndarray] | None:
        """Both frames' masks on ``level`` (float32 in [0, 1], validity.mask_levels), or None without a mask."""
        if self.valid0 is None or self.valid1 is None:
            return None
        return self.valid0[level], self.valid1[level]

    @property
    def coarsest(self) -> int:
        return len(self.shapes) - 1

    def scale(self, level: int) -> float:
        """Width of ``level`` over the input width (1 on level 0)."""
        return self.shapes[level][1] / self.shapes[0][1]

    def level_at_scale(self, scale: float) -> int:
        """The coarsest level whose resolution is at least ``scale`` of the input (0 if none coarser is)."""
        level = 0
        while level < self.coarsest and self.scale(level + 1) >= scale - 1e-9:
            level += 1
        return level


def noise_gain(shape: tuple[int, int], cfg: FlowConfig) -> float:
    """The factor by which white noise (a quantisation error, say) shrinks on the finest solved level of the
    pyramid of an image of ``shape`` for ``cfg``: 1 when that is the input resolution, else 1 / (2 sqrt(pi)
    sigma), the noise gain of a Gaussian of sigma input px -- the anti-alias blur of :func:`build_pyramid`
    accumulated down to that level (subsampling leaves the noise's variance as it is). Cached per argument
    set (a stream asks for the same every frame)."""
    return _noise_gain(tuple(shape), cfg.levels, cfg.scale_factor, cfg.min_size, cfg.finest_level)


@lru_cache(maxsize=64)
def _noise_gain(shape: tuple[int, int], levels: int, scale: float, min_size: int, finest_level: int) -> float:
    """:func:`noise_gain` of the config fields it depends on."""
    finest = min(finest_level, len(_pyramid_shapes(shape, levels, scale, min_size)) - 1)
    if finest == 0:
        return 1.0
    sigma = math.sqrt(sum((ANTIALIAS / scale / scale**k) ** 2 for k in range(finest)))
    return min(1.0, 1.0 / (2.0 * math.sqrt(math.pi) * sigma))


def make_pyramid(i0: np.ndarray, i1: np.ndarray, cfg: FlowConfig, *,
                 channels: tuple[np.ndarray, np.ndarray] | None = None,
                 valid: tuple[np.ndarray, np.ndarray] | None = None, levels0: list[np.ndarray] | None = None,
                 noise: PairNoise | None = None, contrasts0: dict[int, float] | None = None) -> Pyramid:
    """The Gaussian pyramids of a pair for ``cfg`` (levels, scale_factor, min_size). When the finest solved
    level is coarser than the input (``cfg.finest_level``), every step is anti-aliased (ANTIALIAS): nothing
    finer corrects what aliases on that level, and the few warps it gets start from the coarser levels'
    flow, which must not have converged to an aliased texture's wrong minimum either. With the census data
    term the finest ``cfg.census_antialias`` steps are anti-aliased too (:func:`antialias_steps`): it normalises
    contrast away, so an aliased remnant of fine texture on a coarse level -- faint in grey values -- would weigh
    as much as real structure there. ``channels``:
    both frames' colour channels (C, H, W), pyramids of each built the same way (Pyramid.c0, c1). ``valid``:
    the frames' validity masks (H, W) bool, carried down with the same blur (validity.mask_levels). ``levels0``:
    i0's pyramid for ``cfg`` when known (a stream's previous pair built it as its frame 1's: engine.Seen);
    used when its shapes are these, with its grey levels' census contrasts ``contrasts0`` when known
    (Pyramid.contrasts; taken without colour channels, whose contrasts the census term measures instead). With the
    census data term and ``cfg.census_noise_k`` > 0, the floor of
    the signature's EPS per level (Pyramid.census_eps) from ``noise``, the pair's noise as the photometric stage
    measured it (census_noise.pair_noise; None: measured here on i0 and i1, taken as white).
    """
    shapes = pyramid_shapes(i0.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
    antialias = antialias_steps(cfg, len(shapes))
    known = levels0 is not None and [level.shape for level in levels0] == shapes
    grey = [levels0 if known and k == 0 else build_pyramid(img, shapes, cfg.scale_factor, antialias)
            for k, img in enumerate((i0, i1))]
    colour = [None, None] if channels is None else \
        [channel_pyramid(frame, shapes, cfg.scale_factor, antialias) for frame in channels]
    masks = [None, None] if valid is None else \
        [mask_levels(m, build_pyramid(m.astype(np.float32), shapes, cfg.scale_factor, antialias)) for m in valid]
    floors: list[tuple[float, ...] | None] = [None, None]  # neighbours at distance 1, 2
    if compares_signatures(cfg.photometric) and cfg.census_noise_k > 0:
        noise = PairNoise(max(noise_sigma(i0), noise_sigma(i1))) if noise is None else noise
        sigmas = step_sigmas(len(shapes) - 1, cfg.scale_factor, antialias)
        gains = difference_noise_gains(shapes, sigmas, noise.blur, (1, cfg.census_finest_radius))
        for lag, lag_gains in gains.items():
            floors[lag - 1] = eps_floors(noise, cfg.census_noise_k, lag_gains)
    contrasts = (dict(contrasts0) if known and contrasts0 is not None and channels is None else {}, {})
    return Pyramid(shapes, *grey, *colour, *masks, census_eps=floors[0], census_eps_far=floors[1],
                   contrasts=contrasts)


def antialias_steps(cfg: FlowConfig, levels: int) -> int:
    """How many of the finest of ``levels`` levels' steps :func:`make_pyramid` anti-aliases for ``cfg``: every
    step when the finest solved level is coarser than the input; with the census data term at full resolution
    ``cfg.census_antialias`` of them (-1: every step); else none."""
    if min(cfg.finest_level, levels - 1) > 0:
        return levels
    if compares_signatures(cfg.photometric):
        return levels if cfg.census_antialias < 0 else min(cfg.census_antialias, levels)
    return 0


def channel_pyramid(frame: np.ndarray, shapes: list[tuple[int, int]], scale: float, antialias_levels: int = 0
                    ) -> list[np.ndarray]:
    """:func:`build_pyramid` of every channel of frame (C, H, W): (C, h, w) per level. OpenCV filters the
    channels interleaved, one call per step for all of them (the same filter on each)."""
    levels = build_pyramid(np.ascontiguousarray(np.moveaxis(frame, 0, -1)), shapes, scale, antialias_levels)
    return [np.ascontiguousarray(np.moveaxis(level.reshape(level.shape[:2] + (-1,)), -1, 0)) for level in levels]
