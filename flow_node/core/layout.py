"""The output layout stage: the engine's channel-first (2, h, w) flow becomes the API's float32 (H, W, 2),
u then v, at the input size -- the layout of a ``.flo`` file and of a 32FC2 image."""

from __future__ import annotations

import cv2
import numpy as np


def interleaved_flow(v: np.ndarray, shape: tuple[int, int]) -> np.ndarray:
    """The engine's output: a (2, h, w) flow as float32 (H, W, 2) at ``shape``, vectors in pixels of ``shape``.

    Interleaves at the solved size, then (if it differs) rescales the vectors there and resizes bilinearly:
    bilinear interpolation is linear, so scaling first gives the same field and the full-size array is
    written once, not three times (resize, scale, interleave).
    """
    small = cv2.merge([v[0].astype(np.float32, copy=False), v[1].astype(np.float32, copy=False)])
    h, w = shape
    if small.shape[:2] == (h, w):
        return small
    small *= np.array([w / v.shape[2], h / v.shape[1]], dtype=np.float32)
    return cv2.resize(small, (w, h), interpolation=cv2.INTER_LINEAR)


