"""The confidence of a flow: per pixel, in [0, 1], how well the flow explains the pair there.

Judged on the residual fusion's data cost is made of (:func:`flow_node.core.fusion.warp_residual`: brightness
and gradient mismatch after warping frame 1 back along the flow), normalised by the local image gradient so
that it reads as an endpoint-error estimate in px. The node publishes it as ``~/confidence``, ``flow_bag
eval`` writes and scores it, and the derived motion outputs weigh pixels by it (pipeline/robust.py).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .fusion import box_mean, planes, warp_residual

CONFIDENCE_WINDOW = 5
CONFIDENCE_SCALE_PX = 1.0  # estimated endpoint error (px) at which the confidence is 1/2

# confidence(i0, i1, flow) -> (H, W) float32 in [0, 1]: a backend's field (backends.Backend.confidence);
# :func:`confidence` is the numpy reference, numba_confidence.confidence_numba the numba kernels
Confidence = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def confidence(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray) -> np.ndarray:
    """Confidence of ``flow`` (H, W, 2) between frames i0, i1 (H, W): float32 (H, W) in [0, 1].

    The local data residual (:func:`warp_residual`, a CONFIDENCE_WINDOW box) divided by the local image
    gradient magnitude is an endpoint-error estimate e in px (a residual of r where the image changes by g
    per px is about r / g px of misalignment); confidence = 1 / (1 + (e / CONFIDENCE_SCALE_PX)^2), and 0
    where x + f leaves the image. Occluded pixels (their content is not in frame 1) and wrong flow have a
    large residual, hence low confidence; flat regions, where no flow is observable, have little gradient,
    hence low confidence too.
    """
    f = np.moveaxis(flow, -1, 0)
    s0 = planes(i0)  # I0 and its gradient: the residual's and the normalisation's
    r, inside = warp_residual(i0, i1, f, (s0, planes(i1)))
    g = box_mean(np.abs(s0[..., 1]) + np.abs(s0[..., 2]), CONFIDENCE_WINDOW)
    err = box_mean(r, CONFIDENCE_WINDOW) / (g + 1e-3)
    conf = 1.0 / (1.0 + (err / CONFIDENCE_SCALE_PX) ** 2)
    conf[~inside] = 0.0
    return conf.astype(np.float32, copy=False)
