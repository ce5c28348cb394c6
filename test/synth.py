"""Synthetic frame pairs with exactly known flow, for the engine tests (no external data).

A smooth random texture T is the second frame; the first frame samples T along the flow,
I0(x) = T(x + f(x)), so that I1(x + f(x)) = I0(x) holds by construction for any flow field f.
"""

from __future__ import annotations

import cv2
import numpy as np


def texture(h: int, w: int, seed: int = 0, cell: int = 4, blur: float = 1.0) -> np.ndarray:
    """Smooth random texture in [0, 1], float32 (h, w): bicubic-upsampled noise, Gaussian blurred."""
    rng = np.random.default_rng(seed)
    coarse = rng.random((h // cell + 2, w // cell + 2)).astype(np.float32)
    img = cv2.resize(coarse, (w + 2 * cell, h + 2 * cell), interpolation=cv2.INTER_CUBIC)[cell:-cell, cell:-cell]
    img = cv2.GaussianBlur(img, (0, 0), blur)
    img -= img.min()
    return (img / img.max()).astype(np.float32)


def pair_from_flow(t: np.ndarray, flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I0, I1) with I1 = t and I0(x) = t(x + flow(x)); flow (H, W, 2) px."""
    h, w = t.shape
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    i0 = cv2.remap(t, xs + flow[..., 0], ys + flow[..., 1], cv2.INTER_CUBIC, borderMode=cv2.BORDER_REFLECT)
    return i0.astype(np.float32), t


def constant_flow(h: int, w: int, u: float, v: float) -> np.ndarray:
    f = np.zeros((h, w, 2), np.float32)
    f[..., 0], f[..., 1] = u, v
    return f


def rotation_flow(h: int, w: int, degrees: float) -> np.ndarray:
    """Flow of a rotation by `degrees` about the image centre."""
    th = np.deg2rad(degrees)
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    cx, cy = (w - 1) / 2, (h - 1) / 2
    x, y = xs - cx, ys - cy
    f = np.zeros((h, w, 2), np.float32)
    f[..., 0] = np.cos(th) * x - np.sin(th) * y - x
    f[..., 1] = np.sin(th) * x + np.cos(th) * y - y
    return f


def block_flow(h: int, w: int, box: tuple[int, int, int, int], u: float, v: float,
               disk: bool = False) -> np.ndarray:
    """Zero flow except (u, v) inside box = (y0, y1, x0, x1), or inside the disk inscribed in it."""
    f = np.zeros((h, w, 2), np.float32)
    y0, y1, x0, x1 = box
    if disk:
        ys, xs = np.mgrid[0:h, 0:w]
        r = min(y1 - y0, x1 - x0) / 2
        m = (ys - (y0 + y1 - 1) / 2) ** 2 + (xs - (x0 + x1 - 1) / 2) ** 2 <= r * r
    else:
        m = np.zeros((h, w), bool)
        m[y0:y1, x0:x1] = True
    f[m] = (u, v)
    return f


def interior(a: np.ndarray, margin: int = 6) -> np.ndarray:
    """a without a border of `margin` pixels (where warped content leaves the image)."""
    return a[margin:-margin, margin:-margin]
