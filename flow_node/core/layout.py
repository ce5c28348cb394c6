"""The output layout stage: the engine's channel-first (2, h, w) flow becomes the API's float32 (H, W, 2),
u then v, at the input size -- the layout of a ``.flo`` file and of a 32FC2 image."""

from __future__ import annotations

import cv2
import numpy as np

from .errors import NonFiniteResult


def ensure_finite(flow: np.ndarray) -> np.ndarray:
    """``flow`` unchanged if every value is finite, else NonFiniteResult: the last line of defence that keeps
    NaN/inf from ever being published or written as a result (~0.1 ms at 640x480: numpy's SIMD isfinite;
    a float64 sum took 0.7 ms)."""
    if not np.isfinite(flow).all():
        bad = int(np.count_nonzero(~np.isfinite(flow)))
        raise NonFiniteResult(f"the engine's flow has {bad} NaN/inf value(s) of {flow.size}: input unusable")
    return flow


def interleaved_flow(v: np.ndarray, shape: tuple[int, int], check_finite: bool = False) -> np.ndarray:
    """The engine's output: a (2, h, w) flow as float32 (H, W, 2) at ``shape``, vectors in pixels of ``shape``.

    Rescales the vectors at the solved size (if it differs), interleaves there and resizes bilinearly:
    bilinear interpolation is linear, so scaling first gives the same field and the full-size array is
    written once, not three times (resize, scale, interleave). The scaling is a float32 product per
    channel-first plane (the same products as on the interleaved array, whose length-2 innermost axis made
    numpy's broadcast loop ~10x slower: 0.35 ms per frame at 640x480). ``check_finite``: the engine's result,
    so :func:`ensure_finite` runs on the interleaved flow at the solved size, before the resize (bilinear weights
    are convex, so the resized field is finite where this one is; the check reads 1 / 4 of the values at half
    size, 1 / 16 at quarter size; task litefast).
    """
    h, w = shape
    u, v1 = (c.astype(np.float32, copy=False) for c in v)
    if v.shape[1:] != (h, w):
        u, v1 = u * np.float32(w / v.shape[2]), v1 * np.float32(h / v.shape[1])
    small = cv2.merge([u, v1])
    if check_finite:
        ensure_finite(small)
    if small.shape[:2] == (h, w):
        return small
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


