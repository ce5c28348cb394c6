"""Synthetic scenes with exact ground-truth flow, rendered by backward mapping from continuous textures.

A scene is a stack of layers (background first, top last). Each layer has a texture — a function of
continuous texture coordinates p (float64, (..., 2) as (x, y)) — a shape in texture coordinates (None for
the background) and a motion ``phi_t`` taking texture coordinates to image coordinates at frame t, with its
inverse ``psi_t``. Frame t samples, at every pixel x, the top layer whose shape contains ``psi_t(x)``:

    I_t(x) = T(psi_t(x)),        gt_t(x) = phi_t(psi_{t-1}(x)) - x      (x a pixel of frame t-1)

so ``I_t(x + gt_t(x)) = T(psi_{t-1}(x)) = I_{t-1}(x)`` holds exactly wherever the point stays visible
(the flow of an occluded point is still its true motion, as in Middlebury). Nothing is resampled from a
raster, so the ground truth is exactly the motion used to render. Pure numpy; no ROS imports.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import ConfigError

SCENES = ("translation", "rotation", "zoom", "deformation", "objects")


@dataclass(frozen=True)
class Texture:
    """A smooth random texture: a normalised sum of cosines with random frequency, direction and phase.

    ``freqs`` (K, 2) cycles/px, ``phases`` (K,) rad, ``amps`` (K,); ``tint`` (3,) RGB factor in (0, 1].
    Grey values lie in [lo, hi] (a margin below 1 leaves room for a brightness gain).
    """

    freqs: np.ndarray
    phases: np.ndarray
    amps: np.ndarray
    tint: np.ndarray
    lo: float = 0.08
    hi: float = 0.82

    @classmethod
    def random(cls, rng: np.random.Generator, n: int = 28, fmin: float = 1 / 48, fmax: float = 1 / 5) -> Texture:
        """K cosines with log-uniform radial frequency in [fmin, fmax] cycles/px and 1/sqrt(f) amplitudes."""
        radius = np.exp(rng.uniform(math.log(fmin), math.log(fmax), n))
        angle = rng.uniform(0.0, math.pi, n)
        freqs = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
        amps = radius ** -0.5
        amps = amps / np.sqrt(np.sum(amps**2) / 2.0)  # unit standard deviation of the sum
        tint = rng.uniform(0.55, 1.0, 3)
        return cls(freqs, rng.uniform(0.0, 2 * math.pi, n), amps, tint / tint.max())

    def grey(self, p: np.ndarray) -> np.ndarray:
        """Intensity in [lo, hi] at texture coordinates p (..., 2) -> (...)."""
        s = np.cos(2 * math.pi * (p @ self.freqs.T) + self.phases) @ self.amps
        return self.lo + (self.hi - self.lo) * (0.5 + 0.5 * np.tanh(0.9 * s))


@dataclass(frozen=True)
class AffineMotion:
    """phi_t(p) = c + s**t R(theta t) (p - c) + v t: translation v px/frame, rotation theta rad/frame and
    scale s per frame about centre c (x, y)."""

    center: tuple[float, float]
    velocity: tuple[float, float] = (0.0, 0.0)
    theta: float = 0.0
    scale: float = 1.0

    def _linear(self, t: float) -> np.ndarray:
        a = self.theta * t
        return self.scale**t * np.array([[math.cos(a), -math.sin(a)], [math.sin(a), math.cos(a)]])

    def forward(self, p: np.ndarray, t: float) -> np.ndarray:
        c, v = np.asarray(self.center), np.asarray(self.velocity)
        return c + (p - c) @ self._linear(t).T + v * t

    def inverse(self, x: np.ndarray, t: float) -> np.ndarray:
        c, v = np.asarray(self.center), np.asarray(self.velocity)
        return c + (x - c - v * t) @ np.linalg.inv(self._linear(t)).T


@dataclass(frozen=True)
class WaveMotion:
    """A smooth non-rigid deformation: phi_t(p) = p + v t + a sin(w t) d(p), with
    d(p) = (sin(2 pi (p_y / L) + e_x), sin(2 pi (p_x / L) + e_y)). Invertible while 2 pi a / L < 1;
    the inverse is the fixed point p = x - v t - a sin(w t) d(p), iterated to float64 precision."""

    velocity: tuple[float, float] = (0.0, 0.0)
    amplitude: float = 3.0
    wavelength: float = 64.0
    omega: float = 0.6
    shifts: tuple[float, float] = (0.0, 1.3)

    def __post_init__(self) -> None:
        if 2 * math.pi * abs(self.amplitude) / self.wavelength >= 0.8:
            raise ConfigError("deformation too strong to invert: need 2 pi amplitude / wavelength < 0.8")

    def _disp(self, p: np.ndarray, t: float) -> np.ndarray:
        k = 2 * math.pi / self.wavelength
        d = np.stack([np.sin(k * p[..., 1] + self.shifts[0]), np.sin(k * p[..., 0] + self.shifts[1])], axis=-1)
        return np.asarray(self.velocity) * t + self.amplitude * math.sin(self.omega * t) * d

    def forward(self, p: np.ndarray, t: float) -> np.ndarray:
        return p + self._disp(p, t)

    def inverse(self, x: np.ndarray, t: float) -> np.ndarray:
        p = x.copy()
        for _ in range(200):
            nxt = x - self._disp(p, t)
            if np.max(np.abs(nxt - p)) < 1e-12:
                return nxt
            p = nxt
        raise ConfigError("deformation inverse did not converge")  # unreachable for a contraction


Motion = AffineMotion | WaveMotion


@dataclass(frozen=True)
class Layer:
    """A textured layer; ``shape`` (cx, cy, rx, ry, kind) in texture coordinates, kind 'ellipse' or 'box';
    None covers the plane."""

    texture: Texture
    motion: Motion
    shape: tuple[float, float, float, float, str] | None = None

    def covers(self, p: np.ndarray) -> np.ndarray:
        """Bool (...) mask of texture coordinates inside the shape."""
        if self.shape is None:
            return np.ones(p.shape[:-1], bool)
        cx, cy, rx, ry, kind = self.shape
        dx, dy = (p[..., 0] - cx) / rx, (p[..., 1] - cy) / ry
        if kind == "box":
            return (np.abs(dx) <= 1.0) & (np.abs(dy) <= 1.0)
        return dx * dx + dy * dy <= 1.0


@dataclass(frozen=True)
class Scene:
    """Layers over an image of ``size`` (width, height), with an optional brightness gain per frame."""

    name: str
    size: tuple[int, int]
    layers: tuple[Layer, ...]
    brightness: float = 0.0

    def pixel_grid(self) -> np.ndarray:
        """Pixel centres (H, W, 2) as (x, y), float64."""
        w, h = self.size
        xs, ys = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
        return np.stack([xs, ys], axis=-1)

    def _visible(self, t: float, x: np.ndarray | None = None) -> tuple[np.ndarray, list[np.ndarray]]:
        """Index (...) of the top layer at image points x (..., 2) of frame t (default: every pixel), and
        each layer's texture coordinates there."""
        x = self.pixel_grid() if x is None else x
        coords = [layer.motion.inverse(x, t) for layer in self.layers]
        top = np.zeros(x.shape[:2], np.int32)
        for i, (layer, p) in enumerate(zip(self.layers, coords, strict=True)):
            top[layer.covers(p)] = i
        return top, coords

    def layer_map(self, t: int) -> np.ndarray:
        """Index (H, W) int32 of the layer visible at every pixel of frame t (0: the background): with
        t = 0 the exact mask of what moves otherwise in the pair 0 -> 1."""
        return self._visible(t)[0]

    def render(self, t: int, x: np.ndarray | None = None) -> np.ndarray:
        """Frame t as float64 RGB (H, W, 3) in [0, 1]: texture grey times layer tint times the gain.

        ``x`` (..., 2) samples the continuous frame at arbitrary image points instead of the pixel grid.
        """
        top, coords = self._visible(t, x)
        out = np.zeros(top.shape + (3,))
        for i, (layer, p) in enumerate(zip(self.layers, coords, strict=True)):
            m = top == i
            out[m] = layer.texture.grey(p[m])[:, None] * layer.texture.tint
        return np.clip(out * (1.0 + self.brightness) ** t, 0.0, 1.0)

    def ground_truth(self, t: int) -> np.ndarray:
        """Flow from frame t-1 to frame t, float64 (H, W, 2) on the pixel grid of frame t-1."""
        top, coords = self._visible(t - 1)
        x = self.pixel_grid()
        gt = np.zeros_like(x)
        for i, (layer, p) in enumerate(zip(self.layers, coords, strict=True)):
            m = top == i
            gt[m] = layer.motion.forward(p[m], t) - x[m]
        return gt


def make_scene(name: str, size: tuple[int, int], rng: np.random.Generator, brightness: float = 0.0) -> Scene:
    """Build scene ``name`` (one of SCENES) for an image of ``size`` (width, height) from ``rng``."""
    w, h = size
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    bg = Texture.random(rng)
    if name == "translation":
        v = rng.uniform(1.0, 2.5, 2) * rng.choice([-1.0, 1.0], 2)
        layers: tuple[Layer, ...] = (Layer(bg, AffineMotion(c, (float(v[0]), float(v[1])))),)
    elif name == "rotation":
        theta = math.radians(float(rng.uniform(1.5, 2.5)) * float(rng.choice([-1.0, 1.0])))
        layers = (Layer(bg, AffineMotion(c, theta=theta)),)
    elif name == "zoom":
        layers = (Layer(bg, AffineMotion(c, scale=float(rng.uniform(1.02, 1.035)))),)
    elif name == "deformation":
        v = rng.uniform(-1.0, 1.0, 2)
        wave = WaveMotion((float(v[0]), float(v[1])), amplitude=float(rng.uniform(2.0, 3.0)),
                          wavelength=float(rng.uniform(0.6, 0.9) * max(w, h)), omega=0.5,
                          shifts=(float(rng.uniform(0, 6.28)), float(rng.uniform(0, 6.28))))
        layers = (Layer(bg, wave),)
    elif name == "objects":
        layers = (Layer(bg, AffineMotion(c, (0.8, -0.4))),) + _objects(size, rng)
    elif name in LARGE_MOTION_SCENES:
        layers = LARGE_MOTION_SCENES[name](size, rng, bg)
    else:
        raise ConfigError(f"unknown scene {name!r}; choose one of {', '.join(SCENES)}")
    return Scene(name, size, layers, brightness)


def _objects(size: tuple[int, int], rng: np.random.Generator, count: int = 3) -> tuple[Layer, ...]:
    """``count`` ellipses/boxes with their own textures and translations, crossing so that they occlude."""
    w, h = size
    out = []
    for i in range(count):
        cx, cy = rng.uniform(0.25, 0.75) * w, rng.uniform(0.25, 0.75) * h
        r = rng.uniform(0.12, 0.2) * min(w, h)
        kind = "box" if i % 2 else "ellipse"
        v = rng.uniform(1.0, 3.0, 2) * rng.choice([-1.0, 1.0], 2)
        shape = (float(cx), float(cy), float(r * rng.uniform(0.8, 1.3)), float(r), kind)
        out.append(Layer(Texture.random(rng, fmax=1 / 6), AffineMotion((float(cx), float(cy)),
                                                                       (float(v[0]), float(v[1]))), shape))
    return tuple(out)


# ------------------------------------------------------------------------- large displacements (issue 12)
def _fast_objects(size: tuple[int, int], rng: np.random.Generator, speeds: tuple[float, float],
                  count: int, centre_frame: float = 3.0) -> tuple[Layer, ...]:
    """``count`` textured ellipses/boxes moving at ``speeds`` (min, max) px/frame in random directions,
    placed so that each crosses the middle third of the image around frame ``centre_frame``; they pass in
    front of each other and of the background (occlusions and disocclusions every frame)."""
    w, h = size
    out = []
    for i in range(count):
        speed = float(rng.uniform(*speeds))
        angle = float(rng.uniform(0.0, 2 * math.pi))
        v = (speed * math.cos(angle), speed * math.sin(angle))
        mx, my = rng.uniform(1 / 3, 2 / 3) * w, rng.uniform(1 / 3, 2 / 3) * h
        cx, cy = float(mx - centre_frame * v[0]), float(my - centre_frame * v[1])  # texture coords at t = 0
        r = float(rng.uniform(0.12, 0.2) * min(w, h))
        shape = (cx, cy, r * float(rng.uniform(0.8, 1.3)), r, "box" if i % 2 else "ellipse")
        out.append(Layer(Texture.random(rng, fmin=1 / 100, fmax=1 / 6), AffineMotion((cx, cy), v), shape))
    return tuple(out)


def _coarse_texture(rng: np.random.Generator, bg: Texture) -> Texture:
    """A texture with structure from 1/160 to 1/5 cycles/px for a fast scene: a motion of tens of pixels
    is ambiguous on a texture without periods that long (the given ``bg``'s tint is kept)."""
    t = Texture.random(rng, n=36, fmin=1 / 160)
    return Texture(t.freqs, t.phases, t.amps, bg.tint)


def fast_pan(size: tuple[int, int], rng: np.random.Generator, bg: Texture) -> tuple[Layer, ...]:
    """A camera panning 20-40 px/frame (scaled to a 320 px wide image, at most 150 px) over a textured
    background, with three objects crossing at 40-110 px/frame."""
    bg = _coarse_texture(rng, bg)
    w, h = size
    k = w / 320.0
    pan = min(150.0, float(rng.uniform(20.0, 40.0)) * k)
    angle = float(rng.uniform(0.0, 2 * math.pi))
    layers = (Layer(bg, AffineMotion(((w - 1) / 2.0, (h - 1) / 2.0), (pan * math.cos(angle),
                                                                       pan * math.sin(angle)))),)
    return layers + _fast_objects(size, rng, (min(150.0, 40.0 * k), min(150.0, 110.0 * k)), 3)


def fast_objects(size: tuple[int, int], rng: np.random.Generator, bg: Texture) -> tuple[Layer, ...]:
    """A nearly still background (a 1-3 px/frame drift) and four objects at 60-150 px/frame (scaled to a
    320 px wide image, at most 150 px): the motion a pyramid loses, with large occluded areas."""
    bg = _coarse_texture(rng, bg)
    w, h = size
    k = w / 320.0
    drift = rng.uniform(1.0, 3.0, 2) * rng.choice([-1.0, 1.0], 2)
    layers = (Layer(bg, AffineMotion(((w - 1) / 2.0, (h - 1) / 2.0), (float(drift[0]), float(drift[1])))),)
    return layers + _fast_objects(size, rng, (min(150.0, 60.0 * k), min(150.0, 150.0 * k)), 4)


LARGE_MOTION_SCENES = {"fast_pan": fast_pan, "fast_objects": fast_objects}
SCENES = SCENES + tuple(LARGE_MOTION_SCENES)


# ---------------------------------------------------------------------------------------------------------
# Band-limited textures, flat areas and general affine motion (the broad accuracy suite, bench/suite, and
# exactly rendered test pairs). Frames are rendered the same way: I_t(x) = T(psi_t(x)), nothing resampled.

FINE_MOTIONS = ("shift", "rotation", "zoom", "affine")


@dataclass(frozen=True)
class BandTexture(Texture):
    """A band-limited texture: the sum of cosines of :class:`Texture`, mapped *linearly* to [lo, hi]
    (Texture's tanh would add harmonics above the band, which alias near 0.5 cycles/px). ``clip`` standard
    deviations of the sum map to lo and hi; values beyond are clipped (~5e-4 of the pixels at 3.5).

    Optional flat areas: where the unit-variance field of ``flat`` (a low-frequency BandTexture) exceeds
    ``flat_threshold``, the grey blends (C1 smoothstep over ``flat_ramp`` standard deviations) to the
    constant ``flat_level``; the areas move with the texture, so their flow is the motion's.
    """

    clip: float = 3.5
    flat: BandTexture | None = None
    flat_threshold: float = 0.0
    flat_ramp: float = 0.4
    flat_level: float = 0.4

    @classmethod
    def band(cls, rng: np.random.Generator, fmin: float, fmax: float, n: int = 40, lo: float = 0.1,
             hi: float = 0.72) -> BandTexture:
        """K = n cosines of equal amplitude, radial frequency log-uniform in [fmin, fmax] cycles/px
        (keep fmax < 0.5 for a texture the pixel grid samples without aliasing), random directions."""
        radius = np.exp(rng.uniform(math.log(fmin), math.log(fmax), n))
        angle = rng.uniform(0.0, 2 * math.pi, n)
        freqs = np.stack([radius * np.cos(angle), radius * np.sin(angle)], axis=-1)
        amps = np.full(n, math.sqrt(2.0 / n))  # unit standard deviation of the sum
        return cls(freqs, rng.uniform(0.0, 2 * math.pi, n), amps, np.ones(3), lo, hi)

    def field(self, p: np.ndarray) -> np.ndarray:
        """The unit-variance sum of cosines at texture coordinates p (..., 2) -> (...)."""
        return np.cos(2 * math.pi * (p @ self.freqs.T) + self.phases) @ self.amps

    def grey(self, p: np.ndarray) -> np.ndarray:
        """Intensity in [lo, hi] at texture coordinates p (..., 2) -> (...)."""
        g = self.lo + (self.hi - self.lo) * np.clip(0.5 + self.field(p) / (2 * self.clip), 0.0, 1.0)
        if self.flat is None:
            return g
        w = np.clip((self.flat.field(p) - self.flat_threshold) / self.flat_ramp + 0.5, 0.0, 1.0)
        w = w * w * (3.0 - 2.0 * w)
        return (1.0 - w) * g + w * self.flat_level


@dataclass(frozen=True)
class LinearMotion:
    """A general affine motion about ``center`` c: frame 1 maps p -> c + M (p - c) + b, and
    phi_t(p) = p + t ((M - I)(p - c) + b) (the displacement grows linearly with t). Invertible for t in
    [0, 1] because the largest singular value of M - I must be < 0.5."""

    center: tuple[float, float]
    matrix: tuple[tuple[float, float], tuple[float, float]] = ((1.0, 0.0), (0.0, 1.0))
    offset: tuple[float, float] = (0.0, 0.0)

    def __post_init__(self) -> None:
        if np.linalg.norm(np.asarray(self.matrix) - np.eye(2), 2) >= 0.5:
            raise ConfigError("affine motion too strong: need the largest singular value of M - I < 0.5")

    def displacement(self, p: np.ndarray) -> np.ndarray:
        """The frame-1 displacement (M - I)(p - c) + b at points p (..., 2)."""
        e = np.asarray(self.matrix) - np.eye(2)
        return (p - np.asarray(self.center)) @ e.T + np.asarray(self.offset)

    def forward(self, p: np.ndarray, t: float) -> np.ndarray:
        return p + t * self.displacement(p)

    def inverse(self, x: np.ndarray, t: float) -> np.ndarray:
        """Solves x = p + t d(p): (I + t (M - I)) (p - c) = x - c - t b."""
        a = np.eye(2) + t * (np.asarray(self.matrix) - np.eye(2))
        rhs = x - np.asarray(self.center) - t * np.asarray(self.offset)
        return np.asarray(self.center) + np.linalg.solve(a, rhs.reshape(-1, 2).T).T.reshape(x.shape)


def fine_motion(kind: str, size: tuple[int, int], rng: np.random.Generator, max_disp: float = 3.0,
                min_disp: float = 0.3) -> LinearMotion:
    """A random motion of ``kind`` (one of FINE_MOTIONS) about the image centre whose largest displacement
    over the image of ``size`` (width, height) is uniform in [min_disp, max_disp] px: a shift, a rotation or
    a zoom whose corners move that far, or a general affine map (shear and anisotropic scale) plus shift."""
    w, h = size
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    corners = np.array([[0.0, 0.0], [w - 1.0, 0.0], [0.0, h - 1.0], [w - 1.0, h - 1.0]]) - np.asarray(c)
    d = float(rng.uniform(min_disp, max_disp))
    radius = float(np.hypot(*corners[0]))
    sign = float(rng.choice([-1.0, 1.0]))
    if kind == "shift":
        a = rng.uniform(0.0, 2 * math.pi)
        return LinearMotion(c, offset=(d * math.cos(a), d * math.sin(a)))
    if kind == "rotation":
        theta = sign * 2.0 * math.asin(d / (2.0 * radius))  # a corner moves by the chord d
        m = ((math.cos(theta), -math.sin(theta)), (math.sin(theta), math.cos(theta)))
        return LinearMotion(c, m)
    if kind == "zoom":
        s = 1.0 + sign * d / radius
        return LinearMotion(c, ((s, 0.0), (0.0, s)))
    if kind == "affine":
        e, b = rng.normal(size=(2, 2)), rng.normal(size=2) * radius * 0.01
        peak = float(np.max(np.linalg.norm(corners @ e.T + b, axis=-1)))
        e, b = e * (d / peak), b * (d / peak)
        m = np.eye(2) + e
        return LinearMotion(c, ((float(m[0, 0]), float(m[0, 1])), (float(m[1, 0]), float(m[1, 1]))),
                            (float(b[0]), float(b[1])))
    raise ConfigError(f"unknown motion {kind!r}; choose one of {', '.join(FINE_MOTIONS)}")


def render_grey_pair(scene: Scene) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Frames 0 and 1 of ``scene`` as float64 grey (H, W) in [0, 1] (BT.601 luma of the rendered RGB) and
    the exact flow 0 -> 1, float64 (H, W, 2): I1(x + gt(x)) = I0(x) wherever the point stays visible."""
    luma = np.array([0.299, 0.587, 0.114])
    return scene.render(0) @ luma, scene.render(1) @ luma, scene.ground_truth(1)
