"""What a robot does with a flow: the derived motion outputs of one frame pair, computed on first use.

The per-frame entry for the node and ``flow_bag eval``::

    analysis = MotionAnalysis.of(out, settings)  # out: the FlowStream's FlowOutput of this pair
    analysis.dominant        # DominantMotion | None   -> ~/motion/dominant, ~/motion/homography
    analysis.divergence      # (H, W) float32 1/frame  -> ~/motion/divergence
    analysis.ttc             # TimeToContact (3x3)     -> ~/motion/ttc
    analysis.foe             # FocusOfExpansion | None -> ~/motion/foe
    analysis.moving_mask     # (H, W) uint8 0/255      -> ~/motion/moving_mask
    detector.update(analysis.moving_fraction)  # bool  -> ~/motion/detected (a MotionDetector per stream)

Each output is computed only when asked for (and then cached), so a node computes what is subscribed;
the moving mask needs the dominant motion. No rclpy, no rosbags.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property
from typing import NamedTuple

import numpy as np

from ..core.settings import check_fields, setting
from .expansion import (
    REGION_GRID,
    REGION_SAMPLES,
    FocusOfExpansion,
    RegionFit,
    TimeToContact,
    divergence,
    focus_of_expansion,
    region_fits,
    region_ttc,
)
from .motion import (
    Deviating,
    DominantMotion,
    Hysteresis,
    Inliers,
    MaskThreshold,
    ModelFit,
    SimilarityStart,
    deviating_pixels,
    dominant_motion,
    fit_model,
    moving_fraction,
    moving_mask,
    sample_inliers,
    similarity_start,
)
from .robust import SAMPLES, Weights, check_flow, check_flow_shape
from .stream import FlowOutput


@dataclass(frozen=True)
class MotionSettings:
    """Settings of the derived outputs: ``samples`` for the dominant motion and the focus of expansion,
    ``region_samples`` and the ``grid_rows`` x ``grid_cols`` grid for the time to contact, ``mask`` for what
    counts as moving independently (:class:`~flow_node.pipeline.motion.MaskThreshold`), ``detector`` for
    the ``motion detected`` flag (:class:`~flow_node.pipeline.motion.Hysteresis`). Each field describes
    itself (flow_node.core.settings): the node's ``motion.*`` parameters are these fields."""

    samples: int = setting(SAMPLES, "dominant motion and focus of expansion: flow samples on a regular grid over "
                           "the image (the cost hardly depends on the image size)", lo=64, hi=1 << 20)
    region_samples: int = setting(REGION_SAMPLES, "time to contact: flow samples over the whole image, shared "
                                  "by the grid's cells", lo=64, hi=1 << 20)
    grid_rows: int = setting(REGION_GRID[0], "time to contact: rows of the grid of regions", lo=1, hi=16)
    grid_cols: int = setting(REGION_GRID[1], "time to contact: columns of the grid of regions", lo=1, hi=16)
    mask: MaskThreshold = field(default_factory=MaskThreshold)
    detector: Hysteresis = field(default_factory=Hysteresis)

    def __post_init__(self) -> None:
        check_fields(self)

    @property
    def grid(self) -> tuple[int, int]:
        """(rows, cols) of the time-to-contact regions."""
        return self.grid_rows, self.grid_cols


class Fits(NamedTuple):
    """Who runs the IRLS fits: the dominant motion's (:data:`~flow_node.pipeline.motion.ModelFit`) and the
    time to contact's (:data:`~flow_node.pipeline.expansion.RegionFit`), the moving mask's deviating
    pixels (:data:`~flow_node.pipeline.motion.Deviating`), the dominant motion's robust start
    (:data:`~flow_node.pipeline.motion.SimilarityStart`) and its inlier samples
    (:data:`~flow_node.pipeline.motion.Inliers`); the same results either way (test_fits_numba.py; the
    start, the inliers and the mask bit for bit)."""

    name: str
    model: ModelFit
    regions: RegionFit
    deviating: Deviating
    start: SimilarityStart
    inliers: Inliers


NUMPY_FITS = Fits("numpy", fit_model, region_fits, deviating_pixels, similarity_start, sample_inliers)


def fits_for(backend: str) -> Fits:
    """The fits of an engine's backend (``FlowOutput.backend``): the numba kernels (numba_fits) with
    ``numba``, else the numpy reference."""
    if backend != "numba":
        return NUMPY_FITS
    from .numba_fits import (  # numba only with its backend
        deviating_numba,
        fit_model_numba,
        region_fits_numba,
        sample_inliers_numba,
        similarity_start_numba,
    )

    return Fits("numba", fit_model_numba, region_fits_numba, deviating_numba, similarity_start_numba,
                sample_inliers_numba)


def warm_fits(fits: Fits, shape: tuple[int, int] = (48, 64)) -> float:
    """Run ``fits`` once (the dominant motion, the TTC and the moving mask of a small zoom, (H, W) ``shape``)
    so that numba compiles its kernels now, or loads them from its cache (~10 s the first time, without a
    cache), not on the first analysed frame. Returns the seconds it took."""
    start = time.perf_counter()
    ys, xs = np.mgrid[0:shape[0], 0:shape[1]].astype(np.float32)
    flow = 0.01 * np.stack([xs - shape[1] / 2.0, ys - shape[0] / 2.0], axis=-1)
    analysis = MotionAnalysis(flow, np.ones(shape, np.float32), fits=fits)
    analysis.dominant, analysis.ttc, analysis.moving_mask  # noqa: B018
    return time.perf_counter() - start


class MotionAnalysis:
    """The derived outputs of one flow (H, W, 2) float32 px/frame and its confidence (H, W) in [0, 1].

    ``interval_s`` is the pair's interval in seconds (newer stamp - earlier stamp; None or <= 0: times in
    seconds are None). Every attribute is computed on first access and cached; ``confidence`` may be given
    as a function that computes it, called on first use (the divergence alone does not need it).
    ``confidence_at`` (optional; ``FlowOutput.confidence_at``) gives the confidence at integer pixel points
    (ys, xs) alone: the fits (dominant motion, TTC, focus of expansion) read it only at their ~1000 samples,
    so while the map is not computed anyway (given) they take it there instead. ``confidence_in``
    (optional; ``FlowOutput.confidence_in``) gives it right at least where a bool (H, W) array is True: the
    moving mask reads it only where the deviating pixels survive its opening
    (:func:`~flow_node.pipeline.motion.moving_mask`), so while the map is not computed it takes it there.
    ``fits`` runs the IRLS fits (:class:`Fits`; the numpy reference by default, :meth:`of` takes the
    stream's backend's).
    """

    def __init__(self, flow: np.ndarray, confidence: np.ndarray | Callable[[], np.ndarray],
                 interval_s: float | None = None, settings: MotionSettings | None = None,
                 confidence_at: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                 confidence_in: Callable[[np.ndarray], np.ndarray] | None = None,
                 fits: Fits = NUMPY_FITS) -> None:
        check_flow_shape(flow)
        if not callable(confidence):
            check_flow(flow, confidence)
        self.flow, self._confidence, self._confidence_at = flow, confidence, confidence_at
        self._confidence_in = confidence_in
        self.fits = fits
        self._at_points: dict[tuple[tuple[int, ...], bytes, bytes], np.ndarray] = {}
        self.interval_s = interval_s if interval_s is not None and interval_s > 0.0 else None
        self.settings = settings if settings is not None else MotionSettings()

    @cached_property
    def confidence(self) -> np.ndarray:
        """The confidence (H, W) in [0, 1] (computed now if it was given as a function)."""
        conf = self._confidence() if callable(self._confidence) else self._confidence
        check_flow(self.flow, conf)
        return conf

    @property
    def _map_at_hand(self) -> bool:
        """Whether the confidence map is given or computed already."""
        return not callable(self._confidence) or "confidence" in self.__dict__

    @property
    def weights(self) -> Weights:
        """What the fits weigh their samples by: the confidence map when it is at hand (given, or computed
        already), else its values at the samples alone (``confidence_at``, each set of points once)."""
        if self._confidence_at is None or self._map_at_hand:
            return self.confidence
        return self._points

    def _points(self, ys: np.ndarray, xs: np.ndarray) -> np.ndarray:
        """``confidence_at`` at (ys, xs), cached per set of points (the dominant motion and the focus of
        expansion sample the same grid)."""
        key = (ys.shape, ys.tobytes(), xs.tobytes())
        if key not in self._at_points and self._confidence_at is not None:  # weights: only when it is given
            self._at_points[key] = self._confidence_at(ys, xs)
        return self._at_points[key]

    @classmethod
    def of(cls, out: FlowOutput, settings: MotionSettings | None = None) -> MotionAnalysis:
        """The analysis of a stream's output: its flow in px/frame (``frame_flow`` when ``flow`` is in
        px/s), its confidence (computed on first use, if it was not already; at the fits' samples and
        where the mask reads it alone while the map is not), its pair's interval and its backend's fits."""
        flow = out.flow if out.frame_flow is None else out.frame_flow
        return cls(flow, out.confidence, (out.stamp_ns - out.previous_stamp_ns) / 1e9, settings, out.confidence_at,
                   out.confidence_in, fits_for(out.backend))

    @cached_property
    def dominant(self) -> DominantMotion | None:
        """:func:`~flow_node.pipeline.motion.dominant_motion` (None without confident flow)."""
        return dominant_motion(self.flow, self.weights, self.settings.mask, self.settings.samples, self.fits.model,
                               self.fits.start, self.fits.inliers)

    @cached_property
    def divergence(self) -> np.ndarray:
        """:func:`~flow_node.pipeline.expansion.divergence`, (H, W) float32 1/frame (no confidence needed)."""
        return divergence(self.flow)

    @cached_property
    def ttc(self) -> TimeToContact:
        """:func:`~flow_node.pipeline.expansion.region_ttc` on the settings' grid."""
        return region_ttc(self.flow, self.weights, self.interval_s, self.settings.grid,
                          self.settings.region_samples, self.fits.regions)

    @cached_property
    def foe(self) -> FocusOfExpansion | None:
        """:func:`~flow_node.pipeline.expansion.focus_of_expansion` (None for a pan or no motion)."""
        return focus_of_expansion(self.flow, self.weights, self.settings.samples)

    @cached_property
    def moving_mask(self) -> np.ndarray:
        """:func:`~flow_node.pipeline.motion.moving_mask` against :attr:`dominant`, (H, W) uint8 0/255; the
        confidence from the map when it is at hand, else (``confidence_in``) where the mask reads it alone."""
        conf = self.confidence if self._confidence_in is None or self._map_at_hand else self._confidence_in
        return moving_mask(self.flow, conf, self.dominant, self.settings.mask, self.fits.deviating)

    @property
    def moving_fraction(self) -> float:
        """Share of the image in :attr:`moving_mask`, in [0, 1] (what a MotionDetector is fed)."""
        return moving_fraction(self.moving_mask)

    def summary(self) -> dict[str, object]:
        """The scalar outputs as plain JSON-able values (reports): dominant motion, central TTC (frames
        and s), focus of expansion and moving fraction; None where undefined, inf/NaN as None."""
        d, c, f = self.dominant, self.ttc.centre, self.foe
        return {
            "dominant": None if d is None else {"tx": d.tx, "ty": d.ty, "rotation_deg": d.rotation_deg,
                                                "scale": d.scale, "inlier_share": d.inlier_share,
                                                "residual_px": d.residual_px},
            "ttc_centre_frames": finite_or_none(c.ttc_frames),
            "ttc_centre_seconds": None if c.ttc_seconds is None else finite_or_none(c.ttc_seconds),
            "divergence_centre": finite_or_none(c.divergence),
            "foe": None if f is None else {"x": f.x, "y": f.y, "expanding": f.expanding},
            "moving_fraction": self.moving_fraction,
        }


# The node's derived topics (relative names: ~/motion/<name>) and their standard message types; the node
# and ``flow_bag eval --motion`` (flow_node.bag.motion_topics) fill them with the values below.
MOTION_TOPICS: dict[str, str] = {
    "motion/dominant": "geometry_msgs/msg/TwistStamped",
    "motion/homography": "std_msgs/msg/Float64MultiArray",
    "motion/divergence": "sensor_msgs/msg/Image",
    "motion/ttc": "std_msgs/msg/Float32MultiArray",
    "motion/foe": "geometry_msgs/msg/PointStamped",
    "motion/moving_mask": "sensor_msgs/msg/Image",
    "motion/detected": "std_msgs/msg/Bool",
}


Vec3 = tuple[float, float, float]


def dominant_twist(d: DominantMotion, interval_s: float) -> tuple[Vec3, Vec3]:
    """``~/motion/dominant`` as a twist of the image content in the camera's optical frame (x right, y down,
    z forward), per second over the pair's ``interval_s``: linear = (tx, ty px/s, (scale - 1) 1/s: the
    expansion rate, > 0 approaching), angular = (0, 0, rotation rad/s, positive from +x towards +y)."""
    return ((d.tx / interval_s, d.ty / interval_s, (d.scale - 1.0) / interval_s),
            (0.0, 0.0, math.radians(d.rotation_deg) / interval_s))


def grid_dims(rows: int, cols: int) -> tuple[tuple[str, int, int], tuple[str, int, int]]:
    """std_msgs MultiArrayDimension (label, size, stride) of a row-major rows x cols array."""
    return ("rows", rows, rows * cols), ("cols", cols, cols)


def finite_or_none(value: float) -> float | None:
    """``value`` if finite, else None (JSON has no inf or NaN)."""
    return value if math.isfinite(value) else None
