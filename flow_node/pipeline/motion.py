"""Dominant motion and independently moving pixels, from one flow and its confidence. Plain numpy/OpenCV.

Inputs everywhere: ``flow`` (H, W, 2) float32 px/frame, u right, v down, ``I1(x + flow(x)) = I0(x)`` on the
earlier frame's grid; ``confidence`` (H, W) in [0, 1] of the same pair
(:func:`flow_node.core.confidence.confidence`; ``FlowOutput.confidence()``).

* :func:`dominant_motion` -- the motion of most of the image (the camera's, over a scene far away or
  planar): a similarity (translation of the image centre, rotation, scale) and a homography, fitted
  robustly (:func:`flow_node.pipeline.robust.fit_robust`) on ~1024 samples weighted by the confidence.
* :func:`moving_mask` -- pixels whose flow deviates from the dominant motion's by more than
  ``abs_px + rel x |predicted flow|``, confident ones only, cleaned by a morphological opening (the
  confidence read only where the deviating pixels survive the opening).
* :class:`MotionDetector` -- a ``motion detected`` flag with hysteresis over the moving area fraction.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np

from ..core.settings import check_fields, setting
from .robust import (
    HUBER_ITERATIONS,
    SAMPLES,
    START_CONFIDENCE,
    RobustFit,
    Samples,
    Weights,
    check_flow,
    check_flow_shape,
    check_weights,
    fit_robust,
    median_slopes,
    medoid_offset,
    sample_flow,
    sample_step,
)

MASK_ABS_PX = 0.5  # a pixel moves independently when its flow is this far from the dominant motion's ...
MASK_REL = 0.1  # ... plus this fraction of the dominant motion's own length there
MASK_MIN_CONFIDENCE = 0.3  # pixels less confident than this are never marked (occlusions, flat areas)
MASK_OPENING_PX = 2  # radius of the opening's elliptic structuring element (a 5x5 ellipse)
DETECT_AREA_FRACTION = 0.01  # motion detected: a frame counts as moving with this share of the image marked ...
DETECT_ON_FRAMES = 3  # ... on after this many such frames in a row ...
DETECT_OFF_FRAMES = 5  # ... off after this many frames in a row without


@dataclass(frozen=True)
class MaskThreshold:
    """When a flow vector deviates from the dominant motion's predicted vector p: by more than
    ``abs_px + rel x |p|`` px/frame, for pixels with confidence >= ``min_confidence``; the mask is then
    opened with an ellipse of radius ``opening_px`` (0: no opening)."""

    abs_px: float = setting(MASK_ABS_PX, "moving mask: a pixel moves independently when its flow deviates from "
                            "the dominant motion's by more than this (px/frame) plus rel times the dominant "
                            "motion's length there", lo=0.0, hi=100.0, lo_open=True)
    rel: float = setting(MASK_REL, "moving mask: the part of the threshold proportional to the dominant motion's "
                         "own flow length (0.1 = 10 %)", lo=0.0, hi=10.0)
    min_confidence: float = setting(MASK_MIN_CONFIDENCE, "moving mask: pixels whose flow confidence is below this "
                                    "are never marked (occlusions, flat areas)", lo=0.0, hi=1.0)
    opening_px: int = setting(MASK_OPENING_PX, "moving mask: radius (px) of the morphological opening that removes "
                              "specks narrower than 2 r + 1 px (0 = none)", lo=0, hi=50)

    def __post_init__(self) -> None:
        check_fields(self)

    def deviates(self, du: np.ndarray, dv: np.ndarray, pu: np.ndarray, pv: np.ndarray) -> np.ndarray:
        """Bool mask (same shape): deviation (du, dv) beyond abs_px + rel x |(pu, pv)| (all px/frame)."""
        limit = self.abs_px + self.rel * np.sqrt(pu * pu + pv * pv)
        return du * du + dv * dv > limit * limit


@dataclass(frozen=True)
class DominantMotion:
    """The dominant motion of one flow (frame t-1 -> t), in pixels of the flow's grid.

    Similarity about the image centre c = ((W - 1) / 2, (H - 1) / 2): a point x of frame t-1 goes to
    ``c + scale R(rotation) (x - c) + (tx, ty)``; so (tx, ty) px/frame is the image centre's displacement,
    ``rotation_deg`` deg/frame is positive from +x (right) towards +y (down) -- clockwise on the screen, a
    positive rotation about the optical +z axis (REP 103 optical frame) -- and ``scale`` per frame is > 1 for
    an expanding image (approaching), < 1 contracting. ``homography`` (3x3, h33 = 1, row-major tuples) maps
    frame t-1 pixels to frame t pixels (homogeneous): exact for a camera rotating about its centre or a
    plane seen from a moving camera. ``inlier_share``: the confidence-weighted share of samples whose flow
    the homography explains within the mask threshold (:class:`MaskThreshold`); ``residual_px``: the robust
    scale of the homography's endpoint residual; ``samples``: how many samples had confidence > 0.
    """

    tx: float
    ty: float
    rotation_deg: float
    scale: float
    homography: tuple[tuple[float, float, float], tuple[float, float, float], tuple[float, float, float]]
    inlier_share: float
    residual_px: float
    samples: int
    center: tuple[float, float]

    def predicted_flow(self, shape: tuple[int, int]) -> np.ndarray:
        """The homography's flow on an (H, W) grid: (H, W, 2) float32 px/frame."""
        h, w = shape
        out = np.empty((h, w, 2), np.float32)
        out[..., 0], out[..., 1] = apply_homography(np.asarray(self.homography, np.float32),
                                                    np.arange(w, dtype=np.float32)[None, :],
                                                    np.arange(h, dtype=np.float32)[:, None])
        return out

    @property
    def ttc_frames(self) -> float:
        """Frames to contact of the whole image seen as one approaching plane, 1 / (scale - 1) counted from
        the newer frame; inf when the image does not expand."""
        return 1.0 / (self.scale - 1.0) if self.scale > 1.0 + 1e-6 else math.inf


def apply_homography(hm: np.ndarray, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The flow (u, v) px/frame of homography ``hm`` (3x3 on pixels) at points (x, y) px (any shapes that
    broadcast; the result takes their dtype)."""
    den = hm[2, 0] * x + hm[2, 1] * y + hm[2, 2]
    return (hm[0, 0] * x + hm[0, 1] * y + hm[0, 2]) / den - x, (hm[1, 0] * x + hm[1, 1] * y + hm[1, 2]) / den - y


class SampleFrame:
    """Samples in coordinates normalised about the image centre: X = (x - cx) / L, with L half the image
    diagonal, so that the parameters of every model are O(1); residuals and Jacobians stay in px."""

    def __init__(self, s: Samples, shape: tuple[int, int]) -> None:
        h, w = shape
        self.cx, self.cy = (w - 1) / 2.0, (h - 1) / 2.0
        self.half = max(1.0, 0.5 * math.hypot(w - 1, h - 1))
        self.s = s
        self.X = (s.x.ravel() - self.cx) / self.half
        self.Y = (s.y.ravel() - self.cy) / self.half
        self.tu = s.x.ravel() - self.cx + s.u.ravel()  # where the samples went, px relative to the centre
        self.tv = s.y.ravel() - self.cy + s.v.ravel()
        self.flow = np.concatenate([s.u.ravel(), s.v.ravel()])  # px/frame, u-components then v-components
        self.target = np.concatenate([self.tu, self.tv])  # where they went, the same way
        self._basis = np.stack([self.X, self.Y, np.ones_like(self.X)])
        self._sim_jac: np.ndarray | None = None

    def similarity(self, p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """p = (tx, ty, a, b) normalised: X' = X + tx + a X - b Y, Y' = Y + ty + b X + a Y (linear)."""
        if self._sim_jac is None:
            n = self.X.size
            jac = np.zeros((4, 2 * n))
            jac[0, :n] = jac[1, n:] = self.half
            jac[2, :n], jac[2, n:] = self.X * self.half, self.Y * self.half
            jac[3, :n], jac[3, n:] = -self.Y * self.half, self.X * self.half
            self._sim_jac = jac
        return self._sim_jac, self.flow - p @ self._sim_jac

    def homography(self, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """h (8,) normalised, h33 = 1: X' = (h0 X + h1 Y + h2) / D, Y' = (h3 X + h4 Y + h5) / D,
        D = h6 X + h7 Y + 1 (Gauss-Newton: the Jacobian at h)."""
        basis = self._basis  # (3, n): X, Y, 1
        inv = self.half / (h[6:8] @ basis[:2] + 1.0)  # px per normalised unit, over D
        p = (h[:6].reshape(2, 3) @ basis) * inv  # (2, n): pu, pv px, relative to the centre
        jac = np.zeros((8, 2, basis.shape[1]))  # (parameter, component, sample)
        jac[0:3, 0] = jac[3:6, 1] = basis * inv
        g = p * (inv / -self.half)  # d(px)/dD
        jac[6:8] = basis[:2, None, :] * g  # (2, 2, n)
        return jac.reshape(8, -1), self.target - p.reshape(-1)

    def to_pixels(self, h: np.ndarray) -> np.ndarray:
        """The normalised homography h (8,) as a 3x3 on pixels, h33 = 1: T^-1 H T with T: px -> normalised."""
        hn = np.append(h, 1.0).reshape(3, 3)
        t, t_inv = normalising(self.cx, self.cy, self.half)
        hp = t_inv @ hn @ t
        return hp / hp[2, 2]


@lru_cache(maxsize=32)
def normalising(cx: float, cy: float, half: float) -> tuple[np.ndarray, np.ndarray]:
    """:class:`SampleFrame`'s T (3x3: px -> normalised, about (cx, cy) by ``half``) and its inverse (LAPACK's, as
    np.linalg.inv gives it; read-only, computed once per image size: ~0.08 ms a call right after a solve)."""
    t = np.array([[1 / half, 0.0, -cx / half], [0.0, 1 / half, -cy / half], [0.0, 0.0, 1.0]])
    t_inv = np.linalg.inv(t)
    t.flags.writeable = t_inv.flags.writeable = False
    return t, t_inv


def similarity_start(frame: SampleFrame) -> np.ndarray:
    """A robust start (tx, ty, a, b) for :meth:`SampleFrame.similarity` (normalised): a and b from the median
    slopes of the confident samples (du/dx and dv/dy both estimate a, dv/dx and -du/dy both b), the
    translation the :func:`~flow_node.pipeline.robust.medoid_offset` of what they leave; zeros where nothing
    is confident enough. The reference :data:`SimilarityStart` (numba_fits.similarity_start_numba: the same
    values in one compiled call)."""
    s = frame.s
    keep = s.w >= START_CONFIDENCE
    (dudx, dvdx), (dudy, dvdy) = median_slopes(np.stack([s.u, s.v]), s.x, s.y, keep)  # u and v at once
    a, b = (0.0 if math.isnan(v) else float(v) for v in ((dudx + dvdy) / 2.0, (dvdx - dudy) / 2.0))
    X, Y = frame.X * frame.half, frame.Y * frame.half
    rest = np.stack([s.u.ravel() - a * X + b * Y, s.v.ravel() - b * X - a * Y], axis=-1)
    tx, ty = medoid_offset(rest, keep.ravel())
    return np.array([tx / frame.half, ty / frame.half, a, b])


# start(frame) -> (tx, ty, a, b): the similarity's robust start, :func:`similarity_start` (the numpy reference)
# or numba_fits.similarity_start_numba (compiled); derived.Fits chooses
SimilarityStart = Callable[[SampleFrame], np.ndarray]

# fit(model, frame, start, confidence, huber_iterations) -> RobustFit | None: the IRLS fit of one of
# SampleFrame's models ("similarity", "homography") from ``start`` with confidence (n,) (fit_robust's semantics,
# TUKEY_ITERATIONS biweight steps); :func:`fit_model` is the numpy reference, numba_fits.fit_model_numba
# the compiled one (derived.Fits chooses)
ModelFit = Callable[[str, SampleFrame, np.ndarray, np.ndarray, int], RobustFit | None]


def fit_model(model: str, frame: SampleFrame, start: np.ndarray, confidence: np.ndarray,
              huber_iterations: int) -> RobustFit | None:
    """:func:`~flow_node.pipeline.robust.fit_robust` of ``frame``'s ``model`` ("similarity": (tx, ty, a, b),
    "homography": h (8,), both normalised) from ``start`` with ``confidence`` (n,) in [0, 1] (the reference
    :data:`ModelFit`)."""
    return fit_robust(getattr(frame, model), start, confidence, huber_iterations=huber_iterations)


def sample_inliers(hp: np.ndarray, s: Samples, threshold: MaskThreshold) -> np.ndarray:
    """Bool (ny, nx): the samples ``s`` whose flow homography ``hp`` (3x3 on pixels, float64) explains within
    ``threshold`` (:meth:`MaskThreshold.deviates` false). The reference :data:`Inliers`."""
    pu, pv = apply_homography(hp, s.x, s.y)
    return ~threshold.deviates(s.u - pu, s.v - pv, pu, pv)


# inliers(hp, samples, threshold) -> bool (ny, nx): :func:`sample_inliers` (the numpy reference) or
# numba_fits.sample_inliers_numba (one compiled pass, the same bits); derived.Fits chooses
Inliers = Callable[[np.ndarray, Samples, MaskThreshold], np.ndarray]


def dominant_motion(flow: np.ndarray, confidence: Weights, threshold: MaskThreshold | None = None,
                    samples: int = SAMPLES, fit: ModelFit = fit_model, start: SimilarityStart = similarity_start,
                    inliers: Inliers = sample_inliers) -> DominantMotion | None:
    """The dominant motion of ``flow`` (H, W, 2) px/frame weighted by ``confidence`` (H, W) in [0, 1].

    On a regular grid of ~``samples`` points (so the cost hardly depends on the image size): a similarity
    from a robust start (median slopes, ``start``: :data:`SimilarityStart`) refined by IRLS (one Huber step,
    then Tukey's biweight; confidence times the robust weight), then from it a homography by Gauss-Newton
    IRLS (biweight) on the endpoint error in px; where that fails, the similarity stands in for it. The
    similarity gives tx, ty, rotation and scale; the homography the inlier share (within ``threshold``,
    default :class:`MaskThreshold`) and what :func:`moving_mask` compares against. None when fewer than 8
    samples have confidence > 0 or the similarity has no support. ``confidence`` may be given as its values
    at the samples (:data:`~flow_node.pipeline.robust.Weights`). ``fit`` runs the IRLS fits (:data:`ModelFit`:
    the numpy reference, or numba_fits.fit_model_numba), ``start`` their start (the reference
    :func:`similarity_start` or numba_fits.similarity_start_numba), ``inliers`` the samples within the
    threshold (:func:`sample_inliers` or numba_fits.sample_inliers_numba).
    """
    check_weights(flow, confidence)
    threshold = threshold if threshold is not None else MaskThreshold()
    s = sample_flow(flow, confidence, sample_step(flow.shape, samples))
    w = s.w.ravel()
    support = int(np.count_nonzero(w > 0.0))
    if support < 8:
        return None
    frame = SampleFrame(s, flow.shape[:2])
    sim = fit("similarity", frame, start(frame), w, HUBER_ITERATIONS)
    if sim is None:
        return None
    tx, ty, a, b = sim.params
    start = np.array([1 + a, -b, tx, b, 1 + a, ty, 0.0, 0.0])
    hom = fit("homography", frame, start, w, 0)  # the similarity's outliers are far
    if hom is None or not np.all(np.isfinite(hom.params)):
        hom = sim  # the similarity stands in (its residual scale with it)
    hp = frame.to_pixels(hom.params if hom is not sim else start)
    share = float(np.sum(s.w * inliers(hp, s, threshold)) / np.sum(s.w))
    return DominantMotion(float(tx * frame.half), float(ty * frame.half), math.degrees(math.atan2(b, 1 + a)),
                          math.hypot(1 + a, b), tuple(tuple(float(v) for v in row) for row in hp), share,
                          hom.scale, support, (frame.cx, frame.cy))


# What the mask reads the confidence from: the map (H, W), or a function of a bool (H, W) array that gives
# a map right at least where that array is True (e.g. FlowOutput.confidence_in: those pixels alone)
MaskConfidence = np.ndarray | Callable[[np.ndarray], np.ndarray]


def deviating_pixels(flow: np.ndarray, hm: np.ndarray, abs_px: np.float32, rel: np.float32) -> np.ndarray:
    """Bool (H, W): where the flow (H, W, 2) px/frame deviates from homography ``hm``'s (3x3 float32 on
    pixels) predicted flow p by more than ``abs_px + rel x |p|`` (:meth:`MaskThreshold.deviates` with
    the lengths compared). The reference :data:`Deviating`: every step a float32 numpy pass, rounded as
    written (no fused multiply-add; lengths by ``np.sqrt``, correctly rounded), so that
    numba_fits.deviating_numba reproduces it bit for bit."""
    h, w = flow.shape[:2]
    # the homography's numerators and denominator are sums of a row and a column term (apply_homography)
    x, y = np.arange(w, dtype=np.float32)[None, :], np.arange(h, dtype=np.float32)[:, None]
    den = (hm[2, 0] * x + hm[2, 2]) + hm[2, 1] * y
    pu = ((hm[0, 0] * x + hm[0, 2]) + hm[0, 1] * y) / den - x  # the predicted flow
    pv = ((hm[1, 0] * x + hm[1, 2]) + hm[1, 1] * y) / den - y
    limit = np.sqrt(pu * pu + pv * pv)
    limit *= rel
    limit += abs_px
    u, v = cv2.split(np.ascontiguousarray(flow, dtype=np.float32))
    np.subtract(u, pu, out=u)
    np.subtract(v, pv, out=v)
    return np.sqrt(u * u + v * v) > limit


# deviating(flow, hm, abs_px, rel) -> bool (H, W): :func:`deviating_pixels` (the numpy reference) or
# numba_fits.deviating_numba (one compiled pass, the same bits); derived.Fits chooses
Deviating = Callable[[np.ndarray, np.ndarray, np.float32, np.float32], np.ndarray]


def moving_mask(flow: np.ndarray, confidence: MaskConfidence, motion: DominantMotion | None,
                threshold: MaskThreshold | None = None, deviating: Deviating = deviating_pixels) -> np.ndarray:
    """Independently moving pixels: uint8 (H, W), 255 where the flow (H, W, 2) px/frame deviates from
    ``motion``'s predicted flow by more than ``threshold`` (abs px + rel x predicted length) and the
    confidence (H, W) is at least ``threshold.min_confidence``, after a morphological opening (removes
    specks narrower than 2 ``opening_px`` + 1 px); 0 elsewhere. All 0 without a dominant motion.

    The confidence is read only where the opening of the deviating pixels alone is nonzero (the deviating
    pixels when there is no opening), so ``confidence`` may be a function that computes it there alone
    (:data:`MaskConfidence`): the opening of (deviates & confident) is the same whatever the confidence
    elsewhere. Its erosion keeps a pixel q only if every pixel of q's element deviates and is confident, so
    only q in the erosion of the deviating pixels, and reads the confidence in q's element then, which lies
    in that erosion's dilation: the opening of the deviating pixels (test_pipeline_motion.py checks it).
    ``deviating`` finds the deviating pixels (:data:`Deviating`: the numpy reference or the numba kernel).
    """
    if callable(confidence):
        check_flow_shape(flow)
    else:
        check_flow(flow, confidence)
    threshold = threshold if threshold is not None else MaskThreshold()
    h, w = flow.shape[:2]
    if motion is None:
        return np.zeros((h, w), np.uint8)
    moving = deviating(flow, np.asarray(motion.homography, np.float32), np.float32(threshold.abs_px),
                       np.float32(threshold.rel))
    opening = None
    if threshold.opening_px > 0:
        r = threshold.opening_px
        kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
        opening = lambda m: cv2.morphologyEx(m, cv2.MORPH_OPEN, kernel)  # noqa: E731
    if callable(confidence):  # the pixels whose confidence the result depends on (docstring), if any
        read = moving if opening is None else opening(moving.view(np.uint8)).view(np.bool_)
        if not read.any():
            return np.zeros((h, w), np.uint8)
        confidence = confidence(read)
        check_flow(flow, confidence)
    moving &= confidence >= threshold.min_confidence
    mask = moving.view(np.uint8) * np.uint8(255)
    return mask if opening is None else opening(mask)


def moving_fraction(mask: np.ndarray) -> float:
    """The share of nonzero pixels of a mask (H, W), in [0, 1]."""
    return float(np.count_nonzero(mask)) / max(1, mask.size)


@dataclass(frozen=True)
class Hysteresis:
    """When ``motion detected`` switches (:class:`MotionDetector`): on after ``on_frames`` consecutive frames
    with at least ``area_fraction`` of the image moving independently, off after ``off_frames`` below."""

    area_fraction: float = setting(DETECT_AREA_FRACTION, "motion detected: the share of the image (0-1) in the "
                                   "moving mask from which a frame counts as moving", lo=0.0, hi=1.0, lo_open=True)
    on_frames: int = setting(DETECT_ON_FRAMES, "motion detected: turns on after this many consecutive moving "
                             "frames", lo=1, hi=1000)
    off_frames: int = setting(DETECT_OFF_FRAMES, "motion detected: turns off after this many consecutive frames "
                              "that are not moving", lo=1, hi=1000)

    def __post_init__(self) -> None:
        check_fields(self)


class MotionDetector:
    """A ``motion detected`` flag with hysteresis, for event-driven stacks.

    :meth:`update` takes each frame's moving area fraction (:func:`moving_fraction`, in [0, 1]); the flag
    turns on after ``on_frames`` consecutive frames at or above ``area_fraction`` and off after
    ``off_frames`` consecutive frames below it, so one noisy frame neither starts nor ends an event.
    :attr:`hysteresis` may be replaced between frames (the count so far is kept).
    """

    def __init__(self, area_fraction: float = DETECT_AREA_FRACTION, on_frames: int = DETECT_ON_FRAMES,
                 off_frames: int = DETECT_OFF_FRAMES) -> None:
        self.hysteresis = Hysteresis(area_fraction, on_frames, off_frames)
        self.detected = False
        self._run = 0  # consecutive frames disagreeing with the current state

    @classmethod
    def of(cls, hysteresis: Hysteresis) -> MotionDetector:
        return cls(hysteresis.area_fraction, hysteresis.on_frames, hysteresis.off_frames)

    def update(self, fraction: float) -> bool:
        """Feed one frame's moving area fraction; returns the flag after it."""
        h = self.hysteresis
        above = fraction >= h.area_fraction
        self._run = self._run + 1 if above != self.detected else 0
        if self._run >= (h.off_frames if self.detected else h.on_frames):
            self.detected, self._run = above, 0
        return self.detected

    def reset(self) -> None:
        """Off, with no frames counted (e.g. after the stream reset)."""
        self.detected, self._run = False, 0
