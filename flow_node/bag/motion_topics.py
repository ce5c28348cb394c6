"""``flow_bag eval --motion``: the derived motion outputs of a pair as rosbags messages, and their report
figures (against the same outputs derived from the ground-truth flow, when the bag has it).

Topics and values: :data:`flow_node.pipeline.derived.MOTION_TOPICS` (docs/node.md, "Derived outputs").
"""

from __future__ import annotations

import math
import time
from collections.abc import Iterator
from typing import Any

import numpy as np

from ..core.metrics import valid_mask
from ..pipeline.derived import MotionAnalysis, finite_or_none
from ..pipeline.motion import MotionDetector
from ..pipeline.motion_msgs import motion_messages as pipeline_motion_messages
from .bagio import image_message, typestore


class _RosbagsKit:
    """rosbags' side of :class:`~flow_node.pipeline.motion_msgs.MessageKit`: its typestore's classes, its
    Image, numpy arrays as sequences."""

    @staticmethod
    def make(type_name: str, **fields: Any) -> Any:
        return typestore().types[type_name](**fields)

    @staticmethod
    def image(header: Any, fields: dict[str, Any]) -> Any:
        return image_message(header, fields)

    @staticmethod
    def sequence(data: np.ndarray) -> Any:
        return data


def motion_messages(hdr: Any, a: MotionAnalysis, detected: bool) -> Iterator[tuple[str, Any]]:
    """(topic name relative to the node, message) of every derived output there is for this pair
    (:func:`flow_node.pipeline.motion_msgs.motion_messages`, what the node publishes), as rosbags messages
    with the header ``hdr``."""
    return pipeline_motion_messages(_RosbagsKit(), hdr, a, detected)


def motion_record(a: MotionAnalysis, detector: MotionDetector) -> dict[str, Any]:
    """The report's per-frame figures: :meth:`MotionAnalysis.summary`, the detector's flag after this frame
    and the seconds all the derived outputs took (computed here, so the messages reuse them)."""
    start = time.perf_counter()
    for name in ("dominant", "divergence", "ttc", "foe", "moving_mask"):
        getattr(a, name)
    seconds = time.perf_counter() - start
    return a.summary() | {"detected": detector.update(a.moving_fraction), "seconds": seconds}


def truth_errors(a: MotionAnalysis, gt: np.ndarray) -> dict[str, float | None]:
    """The outputs against those of the ground-truth flow ``gt`` (H, W, 2) (every known pixel fully
    confident): dominant translation (px) and rotation (deg) error, the central TTC's relative error (None
    unless both approach), and the moving mask's IoU (None when neither marks a pixel)."""
    known = valid_mask(gt)
    ref = MotionAnalysis(np.where(known[..., None], gt, 0.0).astype(np.float32), known.astype(np.float32),
                         a.interval_s, a.settings)
    d, g = a.dominant, ref.dominant
    out: dict[str, float | None] = {"translation_err_px": None, "rotation_err_deg": None}
    if d is not None and g is not None:
        out = {"translation_err_px": math.hypot(d.tx - g.tx, d.ty - g.ty),
               "rotation_err_deg": abs(d.rotation_deg - g.rotation_deg)}
    t, tg = a.ttc.centre.ttc_frames, ref.ttc.centre.ttc_frames
    out["ttc_centre_rel_err"] = finite_or_none(abs(t / tg - 1.0)) if math.isfinite(tg) else None
    mask, truth = a.moving_mask > 0, ref.moving_mask > 0
    union = int(np.count_nonzero(mask | truth))
    out["mask_iou"] = float(np.count_nonzero(mask & truth)) / union if union else None
    return out
