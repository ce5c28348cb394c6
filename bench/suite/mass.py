"""The ``mass`` regime: exactly rendered density images advected by compressible, divergent motions (issue 27).

Frame 0 is a band-limited texture read as a density; a map y = phi(x) with a known inverse moves it and keeps
its mass, I1(y) = I0(phi^-1(y)) / det(D phi)(phi^-1(y)); ground truth phi(x) - x. The maps (``affine``,
``radial``, ``separable``), their inverses and sizes: docs/suite.md, "The ``mass`` regime". 8-bit, 320x240.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterator
from dataclasses import dataclass

import numpy as np

from flow_node.bag.scenes import BandTexture

from .data import Sample
from .synthetic import BANDS, quantise, seeds

MASS_MAPS = ("affine", "radial", "separable")
SIZE = (320, 240)  # width, height
NEWTON_STEPS = 60


def newton(f: Callable[[np.ndarray], np.ndarray], df: Callable[[np.ndarray], np.ndarray], target: np.ndarray,
           start: np.ndarray) -> np.ndarray:
    """Solve f(t) = target elementwise for a monotone f (f' > 0) by Newton's method; raises if the
    residual stays above 1e-9."""
    t = start.copy()
    for _ in range(NEWTON_STEPS):
        t = t - (f(t) - target) / df(t)
    if np.max(np.abs(f(t) - target)) > 1e-9:
        raise RuntimeError("mass regime: the inverse map did not converge")
    return t


@dataclass(frozen=True)
class DensityMap:
    """A diffeomorphism of the plane: ``forward`` (..., 2) -> (..., 2), ``det`` of its Jacobian at x
    (...), and ``inverse`` (..., 2) -> (..., 2)."""

    forward: Callable[[np.ndarray], np.ndarray]
    det: Callable[[np.ndarray], np.ndarray]
    inverse: Callable[[np.ndarray], np.ndarray]


def affine_map(rng: np.random.Generator, c: np.ndarray) -> DensityMap:
    """Anisotropic zoom (each axis 0.92-1.09) with a shear up to 0.008 and a shift below 1 px."""
    sx, sy = (1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.004, 0.009) for _ in range(2))
    m = np.array([[sx, rng.uniform(-0.008, 0.008)], [rng.uniform(-0.008, 0.008), sy]])
    b = rng.uniform(-0.8, 0.8, 2)
    inv = np.linalg.inv(m)
    return DensityMap(lambda x: c + (x - c) @ m.T + b, lambda x: np.full(x.shape[:-1], np.linalg.det(m)),
                      lambda y: c + (y - c - b) @ inv.T)


def radial_map(rng: np.random.Generator, c: np.ndarray) -> DensityMap:
    """A source (A > 0) or sink (A < 0) about a centre near the image's: g(r) = 1 + A exp(-r^2 / 2 s^2),
    s 25-45 px, peak displacement |A| s exp(-1/2) of 1.5-3 px."""
    s = rng.uniform(25.0, 45.0)
    amp = rng.choice([-1.0, 1.0]) * rng.uniform(1.5, 3.0) / (s * math.exp(-0.5))
    c0 = c + rng.uniform(-30.0, 30.0, 2)

    def g(r: np.ndarray) -> np.ndarray:
        return 1.0 + amp * np.exp(-r * r / (2 * s * s))

    def dg(r: np.ndarray) -> np.ndarray:
        return -amp * r / (s * s) * np.exp(-r * r / (2 * s * s))

    def forward(x: np.ndarray) -> np.ndarray:
        d = x - c0
        return c0 + d * g(np.linalg.norm(d, axis=-1))[..., None]

    def det(x: np.ndarray) -> np.ndarray:
        r = np.linalg.norm(x - c0, axis=-1)
        return g(r) * (g(r) + r * dg(r))

    def inverse(y: np.ndarray) -> np.ndarray:
        d = y - c0
        big_r = np.linalg.norm(d, axis=-1)
        r = newton(lambda t: t * g(t), lambda t: g(t) + t * dg(t), big_r, big_r)
        scale = np.where(big_r > 0, r / np.maximum(big_r, 1e-300), 1.0)
        return c0 + d * scale[..., None]

    return DensityMap(forward, det, inverse)


def separable_map(rng: np.random.Generator, c: np.ndarray) -> DensityMap:
    """x + A sin(2 pi x / L + p) per axis, L 90-200 px, amplitude 1-2.5 px (|g'| <= 0.17)."""
    par = [(rng.uniform(1.0, 2.5), rng.uniform(90.0, 200.0), rng.uniform(0.0, 2 * math.pi)) for _ in range(2)]

    def g(k: int, t: np.ndarray) -> np.ndarray:
        a, period, ph = par[k]
        return t + a * np.sin(2 * math.pi * t / period + ph)

    def dg(k: int, t: np.ndarray) -> np.ndarray:
        a, period, ph = par[k]
        return 1.0 + a * 2 * math.pi / period * np.cos(2 * math.pi * t / period + ph)

    def forward(x: np.ndarray) -> np.ndarray:
        return np.stack([g(0, x[..., 0]), g(1, x[..., 1])], axis=-1)

    def det(x: np.ndarray) -> np.ndarray:
        return dg(0, x[..., 0]) * dg(1, x[..., 1])

    def inverse(y: np.ndarray) -> np.ndarray:
        return np.stack([newton(lambda t, k=k: g(k, t), lambda t, k=k: dg(k, t), y[..., k], y[..., k])
                         for k in range(2)], axis=-1)

    return DensityMap(forward, det, inverse)


MAPS: dict[str, Callable[[np.random.Generator, np.ndarray], DensityMap]] = {
    "affine": affine_map, "radial": radial_map, "separable": separable_map}


def mass_pair(index: int, seed: int, size: tuple[int, int] = SIZE
              ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Float64 density frames (H, W), float32 ground truth (H, W, 2) px and the label 'map/band' of seed
    ``seed`` (the map kind and band cycle with ``index``)."""
    kind = MASS_MAPS[index % len(MASS_MAPS)]
    band = tuple(BANDS)[(index // len(MASS_MAPS)) % len(BANDS)]
    rng = np.random.default_rng([seed, 27])
    tex = BandTexture.band(rng, *BANDS[band], lo=0.1, hi=0.72)
    w, h = size
    x = np.stack(np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64)), axis=-1)
    phi = MAPS[kind](rng, np.array([(w - 1) / 2.0, (h - 1) / 2.0]))
    src = phi.inverse(x)
    i0 = tex.grey(x)
    i1 = tex.grey(src) / phi.det(src)
    return i0, i1, (phi.forward(x) - x).astype(np.float32), f"{kind}/{band}"


def mass(split: str, quick: bool) -> Iterator[Sample]:
    """The regime's pairs: 9 seeds (every map x band), quick 3 (every map), 8 bit."""
    for k, s in seeds(split, 3 if quick else 9):
        i0, i1, gt, label = mass_pair(k, s)
        yield Sample(f"s{s}_{label}", quantise(i0, 8), quantise(i1, 8), gt, 8, label.split("/")[0])
