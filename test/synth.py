"""Synthetic frame pairs with exactly known flow, for the engine tests (no external data).

The texture T is analytic: a band-limited sum of cosines, evaluated at any real position. Frame 1 is T on
the pixel grid and frame 0 samples T along the flow, I0(x) = T(x + f(x)), so I1(x + f(x)) = I0(x) holds
exactly for any flow field f -- nothing is interpolated from a raster, so the engine's own interpolation
errors show up in the tests (a pair rendered with the engine's warp would hide them).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Texture:
    """T(x, y) = lo + scale * (sum_k amps_k cos(2 pi freqs_k . (x, y) + phases_k) - offset), on an h x w grid.

    ``offset``/``scale`` map the grid's range onto [0.05, 0.95]; positions off the grid may fall a little
    outside (the frames are float images, not clipped)."""

    h: int
    w: int
    freqs: np.ndarray  # (K, 2) cycles/px as (fx, fy)
    phases: np.ndarray  # (K,)
    amps: np.ndarray  # (K,)
    offset: float = 0.0
    scale: float = 1.0

    def sample(self, x: np.ndarray, y: np.ndarray) -> np.ndarray:
        """T at positions (x, y) px (same shapes) -> float32."""
        arg = 2 * math.pi * (x[..., None] * self.freqs[:, 0] + y[..., None] * self.freqs[:, 1]) + self.phases
        return (0.05 + self.scale * (np.cos(arg) @ self.amps - self.offset)).astype(np.float32)

    @property
    def image(self) -> np.ndarray:
        """T on the pixel grid, float32 (h, w)."""
        ys, xs = np.mgrid[0:self.h, 0:self.w].astype(np.float64)
        return self.sample(xs, ys)


def texture(h: int, w: int, seed: int = 0, cell: int = 4, blur: float = 1.0, n: int = 64) -> Texture:
    """A smooth random texture for an h x w frame: n cosines, radial frequency log-uniform in [1/16, 1] x 0.6
    / cell cycles/px (the detail of noise on ``cell``-px cells), amplitudes damped by a Gaussian blur of
    ``blur`` px, values on the grid in [0.05, 0.95]."""
    rng = np.random.default_rng(seed)
    fmax = 0.6 / cell
    radius = np.exp(rng.uniform(math.log(fmax / 16.0), math.log(fmax), n))
    angle = rng.uniform(0.0, 2 * math.pi, n)
    freqs = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
    amps = np.exp(-2.0 * (math.pi * blur * radius) ** 2)
    raw = Texture(h, w, freqs, rng.uniform(0.0, 2 * math.pi, n), amps)
    grid = raw.image - 0.05
    return Texture(h, w, freqs, raw.phases, amps, float(grid.min()), 0.9 / float(grid.max() - grid.min()))


def pair_from_flow(t: Texture, flow: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(I0, I1) with I1 = T on the grid and I0(x) = T(x + flow(x)) exactly; flow (H, W, 2) px."""
    ys, xs = np.mgrid[0:t.h, 0:t.w].astype(np.float64)
    return t.sample(xs + flow[..., 0], ys + flow[..., 1]), t.image


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


def isoluminant_pair(seed: int, h: int = 60, w: int = 80) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """An RGB pair (h, w, 3) float32 whose motion (1.25, 0.5) px only colour shows: R carries a texture, G
    compensates it so that the BT.601 luma is constant, B is flat; and its flow (h, w, 2)."""
    gt = constant_flow(h, w, 1.25, 0.5)
    r0, r1 = pair_from_flow(texture(h, w, seed=seed), gt)

    def rgb(r: np.ndarray) -> np.ndarray:
        g = (0.6 - 0.299 * r - 0.114 * 0.5) / 0.587
        return np.stack([r, g, np.full_like(r, 0.5)], -1).astype(np.float32)

    return rgb(r0), rgb(r1), gt
