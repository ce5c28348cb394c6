"""The confidence of a flow: per pixel, in [0, 1], how well the flow explains the pair there.

Judged on the residual fusion's data cost is made of (:func:`flow_node.core.fusion.warp_residual`: brightness
and gradient mismatch after warping frame 1 back along the flow), normalised by the local image gradient so
that it reads as an endpoint-error estimate in px. The node publishes it as ``~/confidence``, ``flow_bag
eval`` writes and scores it, and the derived motion outputs weigh pixels by it (pipeline/robust.py).
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from .errors import InputError
from .fusion import box_mean, planes, warp_residual

CONFIDENCE_WINDOW = 5
CONFIDENCE_SCALE_PX = 1.0  # estimated endpoint error (px) at which the confidence is 1/2

# confidence(i0, i1, flow[, where][, shared=]) -> (H, W) float32 in [0, 1]: a backend's field
# (backends.Backend.confidence); :func:`confidence` is the numpy reference, numba_confidence.confidence_numba the
# numba kernels; ``where`` (H, W) bool, optional: the map at those pixels, 0 elsewhere (a backend may then
# compute those alone); ``shared`` (:data:`Shared`), optional: what calls on one pair have in common
Confidence = Callable[..., np.ndarray]
# confidence_at(i0, i1, flow, ys, xs[, shared=]) -> float32 of ys' shape: the same confidence at integer pixel
# points only (what the derived motion outputs' fits read); :func:`confidence_at` is the reference, a backend's
# field (backends.Backend.confidence_at) may compute the points alone (numba_confidence.confidence_at_numba)
ConfidenceAt = Callable[..., np.ndarray]
# shared: a dict one caller keeps for one pair (the same frames and flow: FlowOutput keeps one) and passes to
# each confidence call on it, in which the backend keeps what those calls have in common (the frames' planes:
# the fits' points and then the mask's pixels need frame 1's whole planes each), under keys of its own
Shared = dict[str, np.ndarray]


def kept(shared: Shared | None, key: str, make: Callable[[], np.ndarray]) -> np.ndarray:
    """``shared[key]``, made by ``make()`` and kept there the first time; ``make()`` when ``shared`` is None.
    ``make`` must return an array of its own (not a scratch buffer that a later call overwrites)."""
    if shared is None:
        return make()
    if key not in shared:
        shared[key] = make()
    return shared[key]


def confidence(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, where: np.ndarray | None = None,
               shared: Shared | None = None) -> np.ndarray:
    """Confidence of ``flow`` (H, W, 2) between frames i0, i1 (H, W): float32 (H, W) in [0, 1].

    The local data residual (:func:`warp_residual`, a CONFIDENCE_WINDOW box) divided by the local image
    gradient magnitude is an endpoint-error estimate e in px (a residual of r where the image changes by g
    per px is about r / g px of misalignment); confidence = 1 / (1 + (e / CONFIDENCE_SCALE_PX)^2), and 0
    where x + f leaves the image. Occluded pixels (their content is not in frame 1) and wrong flow have a
    large residual, hence low confidence; flat regions, where no flow is observable, have little gradient,
    hence low confidence too.

    ``where`` (H, W) bool, optional: the values at those pixels, 0 elsewhere (the reference computes the
    whole map and clears the rest; numba_confidence.confidence_numba computes near ``where`` alone).
    ``shared`` (:data:`Shared`), optional: the frames' planes are kept there for the pair's next call.
    """
    check_where(flow.shape[:2], where)
    f = np.moveaxis(flow, -1, 0)
    s0 = kept(shared, "numpy.planes0", lambda: planes(i0))  # I0 and its gradient: the residual's, the normalisation's
    r, inside = warp_residual(i0, i1, f, (s0, kept(shared, "numpy.planes1", lambda: planes(i1))))
    g = box_mean(np.abs(s0[..., 1]) + np.abs(s0[..., 2]), CONFIDENCE_WINDOW)
    err = box_mean(r, CONFIDENCE_WINDOW) / (g + 1e-3)
    conf = 1.0 / (1.0 + (err / CONFIDENCE_SCALE_PX) ** 2)
    conf[~inside] = 0.0
    if where is not None:
        conf[~where] = 0.0
    return conf.astype(np.float32, copy=False)


def confidence_at(i0: np.ndarray, i1: np.ndarray, flow: np.ndarray, ys: np.ndarray, xs: np.ndarray,
                  shared: Shared | None = None) -> np.ndarray:
    """:func:`confidence` at the pixels (ys, xs) (integer arrays of one shape, rows and columns inside the
    image): float32 of that shape. The reference: the whole map, read at the points (the oracle of
    numba_confidence.confidence_at_numba, which computes the points alone); ``shared`` as :func:`confidence`'s."""
    check_points(flow.shape[:2], ys, xs)
    return confidence(i0, i1, flow, shared=shared)[ys, xs]


def check_where(shape: tuple[int, ...], where: np.ndarray | None) -> None:
    """InputError unless ``where`` is None or a bool array of an image of ``shape`` (H, W)."""
    if where is not None and (where.dtype != np.bool_ or where.shape != tuple(shape[:2])):
        raise InputError(f"confidence: where must be a bool array of shape {tuple(shape[:2])}, got "
                         f"{where.dtype} {where.shape}")


def check_points(shape: tuple[int, ...], ys: np.ndarray, xs: np.ndarray) -> None:
    """InputError unless (ys, xs) are integer arrays of one shape, every point inside an image of ``shape``."""
    h, w = shape[:2]
    ys, xs = np.asarray(ys), np.asarray(xs)
    if ys.shape != xs.shape or not (np.issubdtype(ys.dtype, np.integer) and np.issubdtype(xs.dtype, np.integer)) \
            or (ys.size and (ys.min() < 0 or ys.max() >= h or xs.min() < 0 or xs.max() >= w)):
        raise InputError(f"confidence_at: points must be integer pixel rows and columns inside the {h}x{w} image")
