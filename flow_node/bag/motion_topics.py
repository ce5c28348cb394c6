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
from ..pipeline.codec import array_to_image_fields
from ..pipeline.derived import MOTION_TOPICS, MotionAnalysis, dominant_twist, finite_or_none, grid_dims
from ..pipeline.motion import MotionDetector
from .bagio import image_message, typestore


def _multiarray(kind: str, dims: tuple[tuple[str, int, int], ...], data: np.ndarray) -> Any:
    ts = typestore().types
    layout = ts["std_msgs/msg/MultiArrayLayout"](
        dim=[ts["std_msgs/msg/MultiArrayDimension"](label=label, size=size, stride=stride)
             for label, size, stride in dims], data_offset=0)
    return ts[kind](layout=layout, data=data)


def _vector(x: float, y: float, z: float) -> Any:
    return typestore().types["geometry_msgs/msg/Vector3"](x=float(x), y=float(y), z=float(z))


def motion_messages(hdr: Any, a: MotionAnalysis, detected: bool) -> Iterator[tuple[str, Any]]:
    """(topic name relative to the node, message) of every derived output there is for this pair: the
    dominant twist and the TTC grid need the pair's interval, the homography a dominant motion, the focus
    of expansion a finite focus; the others are always there. Messages with a header get ``hdr``."""
    ts = typestore().types
    d = a.dominant
    if d is not None and a.interval_s is not None:
        linear, angular = dominant_twist(d, a.interval_s)
        twist = ts["geometry_msgs/msg/Twist"](linear=_vector(*linear), angular=_vector(*angular))
        yield "motion/dominant", ts[MOTION_TOPICS["motion/dominant"]](header=hdr, twist=twist)
    if d is not None:
        yield "motion/homography", _multiarray(MOTION_TOPICS["motion/homography"], grid_dims(3, 3),
                                               np.asarray(d.homography, np.float64).ravel())
    yield "motion/divergence", image_message(hdr, array_to_image_fields(a.divergence, "32FC1"))
    if a.interval_s is not None:
        t = a.ttc
        yield "motion/ttc", _multiarray(MOTION_TOPICS["motion/ttc"], grid_dims(t.rows, t.cols),
                                        t.grid("ttc_seconds").ravel().astype(np.float32))
    f = a.foe
    if f is not None:
        point = ts["geometry_msgs/msg/Point"](x=f.x, y=f.y, z=1.0 if f.expanding else -1.0)
        yield "motion/foe", ts[MOTION_TOPICS["motion/foe"]](header=hdr, point=point)
    yield "motion/moving_mask", image_message(hdr, array_to_image_fields(a.moving_mask, "mono8"))
    yield "motion/detected", ts[MOTION_TOPICS["motion/detected"]](data=bool(detected))


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
