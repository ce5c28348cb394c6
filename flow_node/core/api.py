"""The engine's public entry: validate two frames, convert them to grey [0, 1], run coarse-to-fine."""

from __future__ import annotations

import logging
import math
import time
from dataclasses import dataclass, field

import numpy as np

from .backends import Backend, select_backend
from .confidence import Shared
from .config import FlowConfig
from .engine import Judged, estimate_pair, solve_pair, warm_fusion
from .errors import InputError
from .layout import interleaved_flow
from .refine import SolveStats
from .solver import PDState
from .temporal import FULL, Prior, Seen, estimate_predicted, result_fails
from .validity import MaskInput, as_masks
from .volume import estimate_volume, is_volume

log = logging.getLogger("flow_node")

# Floating-point frames are intensities in [0, 1]; values beyond this magnitude are garbage (1e30 in a 32FC1
# image, a float TIFF of raw counts) whose squares overflow the solver's float32 arithmetic.
FLOAT_INPUT_LIMIT = 1e6

# ITU-R BT.601 luma weights for R, G, B
_LUMA = np.array([0.299, 0.587, 0.114], dtype=np.float32)


def to_grey(img: np.ndarray, name: str = "image", channel_order: str = "rgb") -> np.ndarray:
    """Validate an image and convert it to float32 grey (H, W) in [0, 1].

    Accepts (H, W), (H, W, 1), (H, W, 3) and (H, W, 4) arrays; uint8 is divided by 255, uint16 by 65535,
    floating point is taken as already in [0, 1] (must be finite, magnitude at most FLOAT_INPUT_LIMIT).
    ``channel_order`` is ``rgb`` or ``bgr`` for colour input (alpha, if present, is ignored). Raises
    InputError naming the problem.
    """
    out = to_unit(img, name, channel_order)
    return np.ascontiguousarray(out @ _LUMA if out.ndim == 3 else out, dtype=np.float32)


def to_planes(img: np.ndarray, name: str = "image", channel_order: str = "rgb"
              ) -> tuple[np.ndarray, np.ndarray | None]:
    """:func:`to_grey` of an image and, for colour input, its R, G, B planes (3, H, W) float32 in [0, 1]
    (None for grey input): what the census data term compares with ``colour = channels`` (colour.py)."""
    out = to_unit(img, name, channel_order)
    if out.ndim == 2:
        return np.ascontiguousarray(out, dtype=np.float32), None
    return np.ascontiguousarray(out @ _LUMA, dtype=np.float32), np.ascontiguousarray(np.moveaxis(out, -1, 0))


def to_unit(img: np.ndarray, name: str = "image", channel_order: str = "rgb") -> np.ndarray:
    """Validate an image (as :func:`to_grey`) and convert it to float32 in [0, 1]: (H, W) for grey input,
    (H, W, 3) RGB for colour input (possibly a view)."""
    if not isinstance(img, np.ndarray):
        raise InputError(f"{name}: expected a numpy array, got {type(img).__name__}")
    if img.ndim == 3 and img.shape[2] in (1, 3, 4):
        channels = img.shape[2]
    elif img.ndim == 2:
        channels = 0
    else:
        raise InputError(f"{name}: expected shape (H, W) or (H, W, 1|3|4), got {img.shape}")
    if img.shape[0] < 2 or img.shape[1] < 2:
        raise InputError(f"{name}: image is {img.shape[1]}x{img.shape[0]} px; need at least 2x2")
    if img.dtype in (np.uint8, np.uint16):  # one pass: cast and scale in the ufunc loop
        out = np.divide(img, np.float32(255.0 if img.dtype == np.uint8 else 65535.0), dtype=np.float32)
    elif img.dtype in (np.float32, np.float64, np.float16):
        out = img.astype(np.float32, copy=False)  # the engine never writes to its input
        peak = float(np.max(np.abs(out)))  # NaN if any NaN, inf if any inf
        if not math.isfinite(peak):
            raise InputError(f"{name}: contains NaN or infinite values")
        if peak > FLOAT_INPUT_LIMIT:
            raise InputError(f"{name}: float values reach {peak:.3g}; float frames must be intensities in "
                             f"[0, 1] (magnitude at most {FLOAT_INPUT_LIMIT:g})")
    else:
        raise InputError(f"{name}: unsupported dtype {img.dtype}; use uint8, uint16 or float in [0, 1]")
    if channels == 1:
        return out[:, :, 0]
    if channels >= 3:
        return out[:, :, :3] if channel_order == "rgb" else out[:, :, 2::-1]
    return out


@dataclass
class FlowResult:
    """Flow (H, W, 2) float32 px/frame plus what the solve did.

    ``unexplained``: the fraction of (sampled) pixels whose census signature the flow does not explain
    (census.reliability, whatever the data term): ~0.0-0.2 for a flow that matches the frames, near 1 for garbage.
    ``frames``: the normalised pair that figure judges (photometric.stage), which the confidence
    (confidence.confidence) is computed on when asked for."""

    flow: np.ndarray
    stats: SolveStats
    seconds: float
    backend: str
    unexplained: float = 0.0
    frames: tuple[np.ndarray, np.ndarray] | None = None
    state: PDState | None = field(default=None, repr=False)  # estimate_next's: the solver state it ended in
    seen: Seen | None = field(default=None, repr=False)  # estimate_next's: what it computed of frame 1 (Prior)


class FlowEstimator:
    """A configured engine: resolves the backend once, then estimates flow for pairs of frames.

    The node and the bag tools keep one of these; ``config`` may be swapped between calls. ``backend``: a
    :class:`~flow_node.core.backends.Backend` to run instead of the one ``config.backend`` selects (a study
    or test combining one backend's kernels with another's); a later change of ``config.backend``,
    ``config.threads`` or ``config.parallel_min_pixels`` selects again.
    """

    def __init__(self, config: FlowConfig | None = None, backend: Backend | None = None) -> None:
        self._config = config if config is not None else FlowConfig()
        self._backend = backend if backend is not None else select_backend(*_backend_key(self._config))

    @property
    def backend(self) -> str:
        """Name of the resolved backend (``numpy`` or ``numba``)."""
        return self._backend.name

    @property
    def config(self) -> FlowConfig:
        return self._config

    @config.setter
    def config(self, cfg: FlowConfig) -> None:
        if _backend_key(cfg) != _backend_key(self._config):
            self._backend = select_backend(*_backend_key(cfg))
        self._config = cfg

    def warmup(self, shape: tuple[int, int] = (48, 64)) -> float:
        """Run one small solve with the current config, the fusion stage once (engine.warm_fusion) and the
        confidence once, so that JIT compilation (numba), or reading the compiled kernels from numba's cache
        in a fresh process, happens now, not on the first real frame. Returns the seconds it took."""
        rng = np.random.default_rng(0)
        f0 = rng.random(shape, dtype=np.float32)
        f1 = np.roll(f0, 1, axis=1)
        start = time.perf_counter()
        self.estimate(f0, f1)
        with self._backend.running():
            warm_fusion(self._backend, self._config.photometric)
            self._backend.splat(np.zeros((2,) + shape, np.float32), np.zeros((4,) + shape, np.float32))  # stream
            holes = np.ones(shape, np.float32)
            holes[0, 0] = 0.0  # one hole: the fill's pull steps run
            self._backend.fill(np.zeros((2,) + shape, np.float32), holes)
        still = np.zeros(shape + (2,), np.float32)
        self.confidence(f0, f1, still)
        self.confidence_at(f0, f1, still, np.zeros(1, np.int64), np.zeros(1, np.int64))  # points alone
        self.confidence_at(f0, f1, still, *np.mgrid[0:shape[0]:2, 0:shape[1]:2], shared={})  # dense: the map near them
        return time.perf_counter() - start

    def confidence(self, i0: np.ndarray, i1: np.ndarray, flow: np.ndarray,
                   where: np.ndarray | None = None, shared: Shared | None = None) -> np.ndarray:
        """The per-pixel confidence of ``flow`` (H, W, 2) px/frame between grey frames i0, i1 (H, W):
        (H, W) float32 in [0, 1] (:func:`flow_node.core.confidence.confidence`; with ``where`` (H, W) bool
        its values there alone, 0 elsewhere; ``shared``: a dict kept for the pair's calls, in which the
        backend keeps what they share, confidence.Shared), with this estimator's backend on its threads."""
        with self._backend.running():
            return self._backend.confidence(i0, i1, flow, where, shared=shared)

    def confidence_at(self, i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, ys: np.ndarray,
                      xs: np.ndarray, shared: Shared | None = None) -> np.ndarray:
        """:meth:`confidence` at the pixels (ys, xs) only (integer arrays of one shape, inside the image):
        float32 of that shape (:func:`flow_node.core.confidence.confidence_at`), with this backend."""
        with self._backend.running():
            return self._backend.confidence_at(i0, i1, flow, ys, xs, shared=shared)

    def estimate(self, frame0: np.ndarray, frame1: np.ndarray, initial_flow: np.ndarray | None = None,
                 channel_order: str = "rgb", mask: MaskInput = None) -> FlowResult:
        """Flow from frame0 to frame1 (both images of the same size), I1(x + flow) ~ I0(x). Colour frames are
        compared by their luma, or with ``config.colour`` ``channels`` (and the census data term) channel by
        channel. ``mask``: the validity mask (validity.py; nonzero = valid): one (H, W) array for both frames
        or a pair (mask0, mask1); invalid pixels carry no data term and get their flow from their neighbours."""
        if self._config.colour != "channels":
            return self.estimate_grey(to_grey(frame0, "frame0", channel_order),
                                      to_grey(frame1, "frame1", channel_order), initial_flow, mask=mask)
        (i0, c0), (i1, c1) = to_planes(frame0, "frame0", channel_order), to_planes(frame1, "frame1", channel_order)
        return self.estimate_grey(i0, i1, initial_flow, channels=None if c0 is None or c1 is None else (c0, c1),
                                  mask=mask)

    def estimate_grey(self, i0: np.ndarray, i1: np.ndarray, initial_flow: np.ndarray | None = None,
                      previous_flow: np.ndarray | None = None,
                      channels: tuple[np.ndarray, np.ndarray] | None = None, mask: MaskInput = None) -> FlowResult:
        """:meth:`estimate` for frames that already went through :func:`to_grey` (float32 (H, W) in [0, 1],
        finite): a stream that converts each frame once on arrival need not validate it again per pair.

        ``initial_flow`` (H, W, 2) px is a warm start; ``previous_flow`` (H, W, 2) the flow of the pair
        that ended with i0 (a stream's; used when ``config.temporal_init`` is 1). Both are fused per pixel
        with the pyramid's estimate on the level where they are trusted (``config.init_scale``).
        ``channels``: both frames' colour planes (C, H, W) from :func:`to_planes` (i0, i1 their luma), used by
        the census data term when ``config.colour`` is ``channels`` (colour.py)."""
        valid = check_pair(i0, i1, channels, mask)
        init, prev = (_channel_first(f, name, i0.shape) for f, name in ((initial_flow, "initial_flow"),
                                                                        (previous_flow, "previous_flow")))
        start = time.perf_counter()
        with self._backend.running():
            flow, stats, judged = estimate_pair(i0, i1, self._config, self._backend, init, prev,
                                                self._colour(channels), valid)
            unexplained = unexplained_of(flow, judged)
        seconds = time.perf_counter() - start  # preprocessing, output layout, reliability: the engine's work
        return FlowResult(flow, stats, seconds, self._backend.name, unexplained, judged.frames)

    def estimate_next(self, i0: np.ndarray, i1: np.ndarray, prior: Prior | None,
                      channels: tuple[np.ndarray, np.ndarray] | None = None, mask: MaskInput = None) -> FlowResult:
        """:meth:`estimate_grey` for the next pair of a stream, with the solver state it ends in
        (``FlowResult.state``, for the next pair's ``prior``). ``prior``: the previous pair's state, its
        unexplained fraction and the interval ratio (temporal.Prior), None when there is no previous pair.
        With ``config.stream_levels`` > 0 and a prior, the stream stage (core/temporal.py) refines the
        carried-forward state on the finest levels only, and the pair is solved in full when its checks
        fail (``stats.stream`` says which, and why). Without either: the single-pair solve. ``channels`` and
        ``mask`` as for :meth:`estimate_grey`; the stream stage does not carry them yet, so a pair with
        either is solved in full."""
        valid = check_pair(i0, i1, channels, mask)
        channels = self._colour(channels)
        start = time.perf_counter()
        with self._backend.running():
            reason: str | None = None
            if self._config.stream_levels and prior is not None and (channels is not None or valid is not None):
                reason = "mask or colour channels (not carried by the stream stage)"
            elif self._config.stream_levels and prior is not None:
                attempt = estimate_predicted(i0, i1, self._config, self._backend, prior)
                reason = attempt if isinstance(attempt, str) else None
                if reason is None:
                    state, stats, judged, seen = attempt
                    flow = interleaved_flow(state.v, stats.shapes[0], check_finite=True)
                    unexplained = unexplained_of(flow, judged, self._config.stream_check_samples)
                    reason = result_fails(self._config, prior, unexplained)
            if reason is not None or not self._config.stream_levels or prior is None:
                known = None if prior is None or prior.seen is None else prior.seen.sample
                state, stats, judged = solve_pair(i0, i1, self._config, self._backend, channels=channels,
                                                  valid=valid, sample0=known)
                seen = Seen(judged.samples[1]) if valid is None else None  # i1 as given
                flow = interleaved_flow(state.v, stats.shapes[0], check_finite=True)
                unexplained = unexplained_of(flow, judged)
                stats.stream = "" if reason is None else f"{FULL}: {reason}"
        seconds = time.perf_counter() - start
        return FlowResult(flow, stats, seconds, self._backend.name, unexplained, judged.frames, state, seen)

    def _colour(self, channels: tuple[np.ndarray, np.ndarray] | None) -> tuple[np.ndarray, np.ndarray] | None:
        """The colour planes the engine is given: ``channels`` with ``config.colour`` ``channels``, else None."""
        return channels if self._config.colour == "channels" else None


def _backend_key(cfg: FlowConfig) -> tuple[str, int, int]:
    """The settings the backend is selected by: (backend, threads, parallel_min_pixels)."""
    return cfg.backend, cfg.threads, cfg.parallel_min_pixels


def check_pair(i0: np.ndarray, i1: np.ndarray, channels: tuple[np.ndarray, np.ndarray] | None,
               mask: MaskInput) -> tuple[np.ndarray, np.ndarray] | None:
    """InputError unless the grey frames (H, W) and the colour planes (C, H, W), if any, are of one size;
    returns the validity masks (validity.as_masks: None without a mask)."""
    if i0.shape != i1.shape:
        raise InputError(f"frames differ in size: frame0 is {i0.shape[1]}x{i0.shape[0]}, "
                         f"frame1 is {i1.shape[1]}x{i1.shape[0]}")
    if channels is not None and (channels[0].shape != channels[1].shape or channels[0].shape[1:] != i0.shape):
        raise InputError(f"colour planes {channels[0].shape} and {channels[1].shape} do not match the "
                         f"frames' size {i0.shape}")
    return as_masks(mask, i0.shape)


def unexplained_of(flow: np.ndarray, judged: Judged, samples: int | None = None) -> float:
    """The unexplained fraction of a finished ``flow`` (H, W, 2), finite (the output layout checked it:
    layout.interleaved_flow's ``check_finite``), by the photometric stage's own judge (on about ``samples``
    pixels: photometric.reliability_stride)."""
    return judged.unexplained(flow, samples)


def _channel_first(flow: np.ndarray | None, name: str, shape: tuple[int, int]) -> np.ndarray | None:
    """A (H, W, 2) flow as a float32 (2, H, W) view or copy; InputError unless it matches ``shape``."""
    if flow is None:
        return None
    if flow.shape != shape + (2,):
        raise InputError(f"{name}: expected shape {shape + (2,)}, got {flow.shape}")
    if not np.isfinite(flow).all():
        raise InputError(f"{name}: contains NaN or infinite values")
    return np.moveaxis(flow, -1, 0).astype(np.float32, copy=False)


def estimate_flow(frame0: np.ndarray, frame1: np.ndarray, config: FlowConfig | None = None, *,
                  initial_flow: np.ndarray | None = None, mask: MaskInput = None) -> np.ndarray:
    """Dense optical flow from frame0 to frame1: float32 (H, W, 2), channel 0 = u (x), 1 = v (y), px/frame.

    Colour input is taken as RGB. ``config`` defaults to ``FlowConfig()``; see FlowConfig.preset. ``mask``:
    the validity mask, one (H, W) bool/integer array for both frames or a pair (mask0, mask1), nonzero =
    valid (validity.py). Two volumes (Z, Y, X) give (Z, Y, X, 3) with components x, y, z in voxels per frame
    (:func:`flow_node.core.volume.estimate_volume`; a 3-D array at most 4 wide in x is taken as an image:
    call that function directly for so thin a volume).
    """
    if is_volume(frame0) or is_volume(frame1):
        if initial_flow is not None or mask is not None:
            raise InputError("initial_flow and mask are not supported for volumes")
        return estimate_volume(frame0, frame1, config).flow
    return FlowEstimator(config).estimate(frame0, frame1, initial_flow, mask=mask).flow
