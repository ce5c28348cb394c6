"""The per-frame state machine shared by the ROS node and ``flow_bag eval``.

A :class:`FlowStream` keeps the previous frame (grey float32 at processing resolution) and a
:class:`~flow_node.core.api.FlowEstimator`. Each :meth:`FlowStream.process` call takes the next decoded frame
and its stamp and returns None (first frame, or a reset) or a :class:`FlowOutput` with the flow from the
previous to this frame. Rules, in order:

* settings changed with :meth:`FlowStream.update` (config, input scale, colour scale, flow units) take effect at
  the start of the next ``process`` call; a change of ``input_scale`` resets (the stored frame has the old size);
* the stream resets (drops the previous frame, returns None) when the frame size or the encoding label
  changes, or when the stamp goes backwards (a looping bag); :meth:`FlowStream.reset` does it by hand;
* ``input_scale`` < 1 shrinks both frames (area interpolation) before solving, and the flow is returned AT
  THAT RESOLUTION in pixels of the shrunk image; multiply by ``1 / input_scale`` for full-resolution pixels.
* ``flow_units`` px/s divides the flow by the pair's own interval (newer stamp - earlier stamp): with
  latest-wins dropping a pair can span several camera frames, so px/frame alone gives no velocity. A pair
  whose stamps are equal has no velocity: InputError (the frame still becomes the previous one).
* a validity mask (:meth:`FlowStream.set_mask`: nonzero = valid, at the frames' input size; the node's
  ``~/mask`` topic or ``mask_file``) applies to every frame processed after it was set, until replaced or
  removed: each frame keeps the mask in effect when it arrived, so a pair's frames may carry different ones
  (core/validity.py). A mask of another size than the frame is an InputError for that frame;
* with ``config.temporal_init`` = 1 the previous pair's flow, carried forward to the new pair's first frame,
  initialises the next solve (fused per pixel with the pyramid's estimate, so a scene cut costs nothing but
  time); a reset or a change of the config forgets it.
* with ``config.stream_levels`` > 0 (the stream mode, core/temporal.py) the previous pair's flow, carried
  forward and scaled by the ratio of the two pairs' stamp intervals, is refined on the finest levels only;
  a pair whose prediction fails the stage's checks is solved in full. ``stream_totals`` counts both
  (``FlowOutput.stats.stream`` says which each pair was, and why).

No rclpy or rosbags here: the caller decodes messages with :mod:`flow_node.pipeline.codec`.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from ..core.api import FlowEstimator, to_grey, to_planes
from ..core.confidence import Confidence, ConfidenceAt, Shared, confidence, confidence_at
from ..core.config import FlowConfig
from ..core.errors import ConfigError, InputError
from ..core.flowio import flow_to_color
from ..core.photometric import compares_signatures
from ..core.refine import SolveStats
from ..core.solver import PDState
from ..core.temporal import FULL, PREDICTED, Prior, Seen
from ..core.validity import VALID_LEVEL, as_mask

INPUT_SCALE_RANGE = (0.05, 1.0)
COLOR_MAX_FLOW_RANGE = (0.0, 10000.0)
FLOW_UNITS = ("px/frame", "px/s")  # of ~/flow and ~/magnitude: the engine's displacement, or a velocity


def units_factor(units: str, interval_ns: int) -> float:
    """What px/frame flow is multiplied by to be in ``units`` (one of FLOW_UNITS, validated by
    :class:`StreamSettings`), for a pair ``interval_ns`` apart: 1 for px/frame; 1 / interval in seconds for
    px/s, where an interval <= 0 (equal stamps) raises InputError: no velocity can be given for it."""
    if units == FLOW_UNITS[0]:
        return 1.0
    if units != FLOW_UNITS[1]:
        raise ValueError(f"unknown flow units {units!r}")  # StreamSettings rejects them: a caller's bug
    if interval_ns <= 0:
        raise InputError(f"flow_units px/s: the pair's stamps are {interval_ns} ns apart, no velocity")
    return 1e9 / interval_ns


@dataclass(frozen=True)
class StreamSettings:
    """Everything a stream needs besides the frames, validated here (ConfigError). ``color_max_flow``: flow
    (px) at full colour saturation in the colour image; 0 scales each frame by its own maximum.
    ``flow_units``: of the output's flow and magnitude (FLOW_UNITS)."""

    config: FlowConfig = field(default_factory=FlowConfig)
    input_scale: float = 1.0
    color_max_flow: float = 10.0
    flow_units: str = FLOW_UNITS[0]

    def __post_init__(self) -> None:
        if self.flow_units not in FLOW_UNITS:
            raise ConfigError(f"flow_units: {self.flow_units!r} is not one of {', '.join(FLOW_UNITS)}")
        for name, (lo, hi) in (("input_scale", INPUT_SCALE_RANGE), ("color_max_flow", COLOR_MAX_FLOW_RANGE)):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"{name}: expected a finite number, got {value!r}")
            if not lo <= value <= hi:
                raise ConfigError(f"{name}: must be in [{lo}, {hi}], got {value}")
            object.__setattr__(self, name, float(value))


@dataclass(frozen=True)
class FlowSummary:
    """Statistics of the flow magnitude over one frame (px/frame)."""

    mean: float
    p95: float
    max: float


def magnitude(flow: np.ndarray) -> np.ndarray:
    """Per-pixel flow length (H, W) float32 in px/frame, from flow (H, W, 2)."""
    return np.sqrt(flow[..., 0] ** 2 + flow[..., 1] ** 2, dtype=np.float32)


def summarise(mag: np.ndarray) -> FlowSummary:
    """Mean, 95th percentile (nearest rank) and maximum of a magnitude image."""
    flat = mag.reshape(-1)
    k = min(flat.size - 1, int(math.ceil(0.95 * flat.size)) - 1)
    p95 = float(np.partition(flat, k)[k])
    return FlowSummary(float(flat.mean()), p95, float(flat.max()))


def scaled_shape(shape: tuple[int, int], scale: float) -> tuple[int, int]:
    """(H, W) after scaling by ``scale`` (rounded, at least 2x2)."""
    return max(2, int(round(shape[0] * scale))), max(2, int(round(shape[1] * scale)))


@dataclass
class FlowOutput:
    """One result: flow from the previous frame to the frame stamped ``stamp_ns``.

    ``flow`` (H, W, 2) float32 and ``magnitude`` (H, W) float32 are at the processing resolution (``scale``
    times the input size), in px/frame or, after :meth:`in_units`, in its units (``frame_flow`` then keeps
    the px/frame flow). Magnitude, colour image, confidence and summary are computed
    on first use only (the node publishes magnitude, colour and confidence only when subscribed, summarises
    only for diagnostics). ``frames`` holds the two grey frames the flow was solved on (for the confidence);
    ``confidence_of`` computes it (the stream's: its estimator's backend; the numpy reference by default).
    """

    flow: np.ndarray
    stamp_ns: int
    previous_stamp_ns: int
    seconds: float
    stats: SolveStats
    backend: str
    model: str
    scale: float
    color_max_flow: float
    unexplained: float = 0.0  # FlowResult.unexplained: fraction of pixels the flow does not explain
    frames: tuple[np.ndarray, np.ndarray] | None = field(default=None, repr=False)
    frame_flow: np.ndarray | None = field(default=None, repr=False)  # px/frame when ``flow`` is not (units)
    confidence_of: Confidence = field(default=confidence, repr=False)
    confidence_at_of: ConfidenceAt = field(default=confidence_at, repr=False)  # the same at points only
    _shared: Shared = field(default_factory=dict, repr=False)  # what the pair's confidence calls share (planes)
    _confidence: np.ndarray | None = field(default=None, repr=False)
    _magnitude: np.ndarray | None = field(default=None, repr=False)
    _color: np.ndarray | None = field(default=None, repr=False)
    _summary: FlowSummary | None = field(default=None, repr=False)

    @property
    def magnitude(self) -> np.ndarray:
        """|flow| (H, W) float32 px/frame, computed on first use and cached."""
        if self._magnitude is None:
            self._magnitude = magnitude(self.flow)
        return self._magnitude

    @property
    def summary(self) -> FlowSummary:
        """Magnitude mean / p95 / max, computed on first use (a few ms at VGA) and cached."""
        if self._summary is None:
            self._summary = summarise(self.magnitude)
        return self._summary

    def confidence(self) -> np.ndarray:
        """Per-pixel confidence of the flow, (H, W) float32 in [0, 1] (:func:`flow_node.core.confidence.confidence`:
        low where the data residual says the flow is wrong or the pixel occluded; ``confidence_of``), cached."""
        if self._confidence is None:  # with the planes kept by the pair's earlier calls, if any (then let go)
            self._confidence = self.confidence_of(*self._judged(), shared=self._shared or None)
            self._shared.clear()
        return self._confidence

    def _judged(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The frames and the px/frame flow the confidence judges; ValueError when the frames are not kept."""
        if self.frames is None:
            raise ValueError("this output keeps no frames; the confidence cannot be computed")
        return self.frames[0], self.frames[1], self.flow if self.frame_flow is None else self.frame_flow

    def confidence_at(self, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """:meth:`confidence` at the pixels (ys, xs) (integer arrays of one shape): read from the map when it
        is computed already, else computed at the points alone (``confidence_at_of``; not cached)."""
        if self._confidence is not None:
            return self._confidence[ys, xs]
        return self.confidence_at_of(*self._judged(), ys, xs, shared=self._shared)

    def confidence_in(self, where: np.ndarray) -> np.ndarray:
        """:meth:`confidence`, right at least where ``where`` (H, W) bool is True: the map when it is computed
        already, else computed there alone (``confidence_of`` with ``where``: 0 elsewhere; not cached)."""
        return self._confidence if self._confidence is not None else \
            self.confidence_of(*self._judged(), where, shared=self._shared)

    def color(self) -> np.ndarray:
        """Middlebury colour coding, (H, W, 3) uint8 in B, G, R order (bgr8), cached."""
        if self._color is None:
            self._color = flow_to_color(self.flow, self.color_max_flow, bgr=True)
        return self._color

    @property
    def color_computed(self) -> bool:
        """Whether :meth:`color` has been computed (it is only on demand: nobody subscribed, never)."""
        return self._color is not None

    @property
    def confidence_computed(self) -> bool:
        """Whether :meth:`confidence` has been computed (on demand only, like the colour)."""
        return self._confidence is not None

    def in_units(self, units: str) -> FlowOutput:
        """This output with its flow in ``units`` (FLOW_UNITS) over its own pair's interval (magnitude and
        colour follow, computed on first use; the confidence stays judged on px/frame); itself for px/frame.
        InputError as :func:`units_factor`."""
        factor = units_factor(units, self.stamp_ns - self.previous_stamp_ns)
        if factor == 1.0:
            return self
        return replace(self, flow=(self.flow * np.float32(factor)).astype(np.float32, copy=False),
                       frame_flow=self.flow if self.frame_flow is None else self.frame_flow, _magnitude=None,
                       _color=None, _summary=None)


@dataclass
class StreamTotals:
    """Pairs of the stream mode since the stream was made: solved from the prediction (``predicted``) and solved
    in full because the prediction failed a check (``fallbacks``; the last one's reason in ``last_fallback``).
    Pairs without a previous flow (the first after a reset) count as neither."""

    predicted: int = 0
    fallbacks: int = 0
    last_fallback: str = ""

    def count(self, stream: str) -> None:
        """Count one pair by its SolveStats.stream."""
        if stream == PREDICTED:
            self.predicted += 1
        elif stream.startswith(FULL):
            self.fallbacks += 1
            self.last_fallback = stream.partition(": ")[2]


class FlowStream:
    """Previous frame + engine; see the module docstring for the rules. Thread-safe for ``update`` and
    ``reset`` called from another thread while ``process`` runs (they apply before the next frame)."""

    def __init__(self, settings: StreamSettings | None = None) -> None:
        self._settings = settings if settings is not None else StreamSettings()
        self._estimator = FlowEstimator(self._settings.config)
        self._pending: StreamSettings | None = None
        self._reset_requested: str | None = None  # the reason of a reset asked for
        self._lock = threading.Lock()
        self._prev: np.ndarray | None = None
        self._prev_planes: np.ndarray | None = None  # _prev's colour planes (3, h, w) with config.colour channels
        self._prev_key: tuple[tuple[int, ...], str] | None = None
        self._prev_stamp: int = 0
        self._prev_flow: np.ndarray | None = None  # flow of the pair that ended with _prev (temporal_init)
        self._mask: np.ndarray | None = None  # the validity mask in effect (input size, bool), set_mask
        self._prev_mask: np.ndarray | None = None  # _prev's mask at processing resolution
        self._prev_state: PDState | None = None  # the solver state that pair ended in (stream mode)
        self._prev_seen: Seen | None = None  # what that pair computed of _prev (stream mode, Prior)
        self._prev_unexplained = 0.0  # that flow's unexplained fraction (stream mode)
        self._prev_interval = 0  # that pair's stamp interval, ns (stream mode)
        self.last_reset_reason: str = "first frame"
        self.stream_totals = StreamTotals()

    # ----------------------------------------------------------------------------------------- settings
    @property
    def settings(self) -> StreamSettings:
        """The settings in effect (pending changes not yet applied are not included)."""
        return self._settings

    @property
    def backend(self) -> str:
        return self._estimator.backend

    def update(self, config: FlowConfig | None = None, input_scale: float | None = None,
               color_max_flow: float | None = None, flow_units: str | None = None) -> StreamSettings:
        """Schedule new settings for the next frame; validates now (raises ConfigError) and returns them."""
        with self._lock:
            base = self._pending if self._pending is not None else self._settings
            changes = {k: v for k, v in (("config", config), ("input_scale", input_scale),
                                         ("color_max_flow", color_max_flow), ("flow_units", flow_units))
                       if v is not None}
            self._pending = replace(base, **changes)
            return self._pending

    def reset(self, reason: str = "reset requested") -> None:
        """Drop the previous frame before the next one (that frame then starts a new pair, for ``reason``)."""
        with self._lock:
            self._reset_requested = reason

    @property
    def mask(self) -> np.ndarray | None:
        """The validity mask in effect (:meth:`set_mask`; input size, bool), None when every pixel is valid."""
        return self._mask

    def set_mask(self, mask: np.ndarray | None) -> None:
        """The validity mask (H, W) or (H, W, 1), bool or integer, nonzero = valid, at the input frames' size,
        for every frame from the next one on; None removes it. InputError for a wrong type or no valid pixel
        (the mask in effect is then unchanged); its size is checked against each frame."""
        valid = None if mask is None else as_mask(mask, mask.shape[:2])
        with self._lock:
            self._mask = valid

    def _frame_mask(self, shape: tuple[int, int], grey_shape: tuple[int, int]) -> np.ndarray | None:
        """The mask in effect for a frame of input ``shape`` at processing size ``grey_shape`` (a shrunk
        pixel is valid only when all the pixels it averages are), or None; InputError on a size mismatch."""
        with self._lock:
            mask = self._mask
        if mask is None:
            return None
        if mask.shape != shape:
            raise InputError(f"mask is {mask.shape[1]}x{mask.shape[0]}, the frame {shape[1]}x{shape[0]}")
        if grey_shape == shape:
            return mask
        area = cv2.resize(mask.astype(np.float32), grey_shape[::-1], interpolation=cv2.INTER_AREA)
        return area >= VALID_LEVEL

    def warmup(self, shape: tuple[int, int] = (48, 64)) -> float:
        """Compile/warm the engine with the current config; returns seconds."""
        return self._estimator.warmup(shape)

    def _apply_pending(self) -> str | None:
        """Apply scheduled settings and reset requests; returns a reset reason or None."""
        with self._lock:
            pending, self._pending = self._pending, None
            reason, self._reset_requested = self._reset_requested, None
        if pending is not None:
            if pending.input_scale != self._settings.input_scale:
                reason = reason or "input_scale changed"
            if pending.config != self._settings.config:
                self._estimator.config = pending.config
                self._prev_flow = self._prev_state = self._prev_seen = None
            self._settings = pending
        return reason

    # -------------------------------------------------------------------------------------------- frames
    def _prepare(self, frame: np.ndarray, channel_order: str) -> tuple[np.ndarray, np.ndarray | None]:
        """Grey float32 [0, 1] at processing resolution, and with ``config.colour`` ``channels`` (census data
        term) and a colour frame its R, G, B planes (3, h, w) there (else None)."""
        cfg = self._settings.config
        if cfg.colour == "channels" and compares_signatures(cfg.photometric):
            grey, planes = to_planes(frame, "frame", channel_order)
        else:
            grey, planes = to_grey(frame, "frame", channel_order), None
        scale = self._settings.input_scale
        if scale == 1.0:
            return grey, planes
        h, w = scaled_shape(grey.shape, scale)
        small = [cv2.resize(p, (w, h), interpolation=cv2.INTER_AREA) for p in ([grey] if planes is None else
                                                                                 [grey, *planes])]
        return small[0], None if planes is None else np.stack(small[1:])

    def _start(self, grey: np.ndarray, planes: np.ndarray | None, key: tuple[tuple[int, ...], str], stamp_ns: int,
               reason: str, mask: np.ndarray | None = None) -> None:
        self._prev, self._prev_planes, self._prev_key, self._prev_stamp = grey, planes, key, stamp_ns
        self._prev_mask = mask
        self._prev_flow = self._prev_state = self._prev_seen = None
        self.last_reset_reason = reason

    def process(self, frame: np.ndarray, stamp_ns: int, encoding: str = "",
                channel_order: str = "rgb") -> FlowOutput | None:
        """Feed the next frame (decoded array, stamp in ns, encoding label); None if it starts a new pair.

        Raises InputError for an unusable frame (state unchanged) and ConfigError never (settings are
        validated in ``update``). ``self.last_reset_reason`` says why the last None was returned.
        """
        reason = self._apply_pending()
        grey, planes = self._prepare(frame, channel_order)
        mask = self._frame_mask(frame.shape[:2], grey.shape)
        key = (tuple(frame.shape), encoding)
        if self._prev is None:  # whatever was asked for before
            reason = "first frame"
        elif reason is None and key != self._prev_key:
            reason = (f"size changed {self._prev_key[0]} -> {key[0]}" if key[0] != self._prev_key[0]
                      else f"encoding changed {self._prev_key[1]!r} -> {encoding!r}")
        elif reason is None and stamp_ns < self._prev_stamp:
            reason = f"stamp went back {(self._prev_stamp - stamp_ns) / 1e9:.3f} s"
        if reason is not None:
            self._start(grey, planes, key, stamp_ns, reason, mask)
            return None
        prev, prev_stamp, prev_mask = self._prev, self._prev_stamp, self._prev_mask
        s = self._settings
        channels = None if planes is None or self._prev_planes is None else (self._prev_planes, planes)
        pair_mask = None if prev_mask is None and mask is None else tuple(
            np.ones(grey.shape, bool) if m is None else m for m in (prev_mask, mask))
        interval = stamp_ns - prev_stamp
        if s.config.stream_levels:
            ratio = interval / self._prev_interval if self._prev_interval > 0 else 1.0
            prior = None if self._prev_state is None else Prior(self._prev_state, self._prev_unexplained, ratio,
                                                                 self._prev_seen)
            result = self._estimator.estimate_next(prev, grey, prior, channels, pair_mask)  # all from _prepare
            self.stream_totals.count(result.stats.stream)
        else:
            previous = self._prev_flow if s.config.temporal_init else None
            result = self._estimator.estimate_grey(prev, grey, previous_flow=previous, channels=channels,
                                                   mask=pair_mask)
        self._prev, self._prev_planes, self._prev_stamp, self._prev_mask = grey, planes, stamp_ns, mask
        self._prev_flow = result.flow if s.config.temporal_init else None
        self._prev_state = result.state if s.config.stream_levels else None
        self._prev_seen = result.seen if s.config.stream_levels else None
        self._prev_unexplained, self._prev_interval = result.unexplained, interval
        out = FlowOutput(result.flow, stamp_ns, prev_stamp, result.seconds, result.stats,
                         result.backend, s.config.model, s.input_scale, s.color_max_flow, result.unexplained,
                         result.frames, confidence_of=self._estimator.confidence,
                         confidence_at_of=self._estimator.confidence_at)
        return out.in_units(s.flow_units)
