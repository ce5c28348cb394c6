"""The suite's ``stream`` regime: exactly rendered 40-frame sequences of flow_node.bag.scenes (issue 26), grey,
with NOISE grey levels of sensor noise, 8 bit; the kinds and the splits: docs/suite.md, "Streams".
:func:`bag_sequences` gives the bundled bags as sequences of kind ``bag`` (8-bit grey by the engine's to_grey,
so that DIS runs on the same frames; the ground truth matched by stamp)."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flow_node.bag.scenes import AffineMotion, Layer, LinearMotion, Scene, Texture, WaveMotion, make_scene
from flow_node.core.api import to_grey

from .data import BAGS, LUMA, read_bag
from .synthetic import quantise, seeds

FRAMES = 40
NOISE = 1.0  # grey levels (of 255): a camera's sensor noise on every frame, independent from frame to frame
KINDS = ("pan", "rotation", "zoom", "accelerating", "decelerating", "objects", "cut", "exposure")
# motions neither split has, to judge the stream mode on (split ``heldout``, two seeds each): camera shake, a
# non-rigid wave, a shear
HELDOUT_KINDS = ("shake", "wave", "shear")
HELDOUT_SEED0 = 7000


@dataclass(frozen=True)
class TimeWarped:
    """A scene motion run on warped time: phi_t = motion.phi_{tau(t)} with tau(t) = t + accel t^2 (accel > 0
    speeds up, < 0 slows down; tau stays increasing over the sequence). Exact like the motion itself."""

    motion: AffineMotion
    accel: float

    def tau(self, t: float) -> float:
        return t + self.accel * t * t

    def forward(self, p: np.ndarray, t: float) -> np.ndarray:
        return self.motion.forward(p, self.tau(t))

    def inverse(self, x: np.ndarray, t: float) -> np.ndarray:
        return self.motion.inverse(x, self.tau(t))


@dataclass(frozen=True)
class Shaken:
    """A pan with camera shake: phi_t(p) = p + v t + j_t, the jitter j_t (px) drawn per frame (``jitter``: one
    (x, y) per integer t). Exact at integer t, where the frames are rendered."""

    velocity: tuple[float, float]
    jitter: tuple[tuple[float, float], ...]

    def _shift(self, t: float) -> np.ndarray:
        return np.asarray(self.velocity) * t + np.asarray(self.jitter[round(t)])

    def forward(self, p: np.ndarray, t: float) -> np.ndarray:
        return p + self._shift(t)

    def inverse(self, x: np.ndarray, t: float) -> np.ndarray:
        return x - self._shift(t)


@dataclass(frozen=True)
class Sequence:
    """A rendered sequence: ``frames`` uint8 (H, W), ``gt[t]`` the flow of pair t -> t+1 (H, W, 2) float32 or
    None where there is none (across a scene cut), its kind and name, and ``event``: the index of the first
    frame after a cut or exposure step (-1 without)."""

    name: str
    kind: str
    frames: list[np.ndarray]
    gt: list[np.ndarray | None]
    event: int = -1

    @property
    def size(self) -> tuple[int, int]:
        return int(self.frames[0].shape[1]), int(self.frames[0].shape[0])


def _texture(rng: np.random.Generator) -> Texture:
    return Texture.random(rng, n=36, fmin=1 / 120, fmax=1 / 5)


def _direction(rng: np.random.Generator, speed: float) -> tuple[float, float]:
    a = float(rng.uniform(0.0, 2 * math.pi))
    return speed * math.cos(a), speed * math.sin(a)


def scene_of(kind: str, size: tuple[int, int], rng: np.random.Generator) -> Scene:
    """The scene of one sequence kind (not ``cut``/``exposure``, which are built from two/one of these)."""
    w, h = size
    k = w / 320.0
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    tex = _texture(rng)
    if kind == "pan":
        motion: AffineMotion | TimeWarped = AffineMotion(c, _direction(rng, float(rng.uniform(2.0, 6.0)) * k))
    elif kind == "rotation":
        theta = math.radians(float(rng.uniform(0.4, 0.9)) * float(rng.choice([-1.0, 1.0])))
        motion = AffineMotion(c, _direction(rng, 0.5 * k), theta=theta)
    elif kind == "zoom":
        s = 1.0 + float(rng.uniform(0.01, 0.015)) * float(rng.choice([-1.0, 1.0]))
        motion = AffineMotion(c, scale=s)
    elif kind == "accelerating":  # velocity tau'(t) = 1 + 2 a t from 1 (x 0.5 px) to 1 + 2 a (FRAMES - 1)
        top = float(rng.uniform(10.0, 16.0))
        motion = TimeWarped(AffineMotion(c, _direction(rng, 0.5 * k)), (top - 1.0) / (2 * (FRAMES - 1)))
    elif kind == "decelerating":  # velocity from 1 (x 6 px) down to 0.1 of it
        theta = math.radians(0.5 * float(rng.choice([-1.0, 1.0])))
        motion = TimeWarped(AffineMotion(c, _direction(rng, 6.0 * k), theta=theta), -0.9 / (2 * (FRAMES - 1)))
    elif kind == "shake":  # a pan of 1-3 px/frame, each frame displaced by 1.5-3 px (std) of jitter
        amp, speed = float(rng.uniform(1.5, 3.0)), float(rng.uniform(1.0, 3.0)) * k
        jitter = tuple((float(a), float(b)) for a, b in rng.normal(0.0, amp * k, (FRAMES + 1, 2)))
        motion = Shaken(_direction(rng, speed), jitter)
    elif kind == "wave":  # a pan of 2 px/frame under a travelling non-rigid wave of 3 px
        motion = WaveMotion(velocity=_direction(rng, 2.0 * k), amplitude=3.0 * k, wavelength=64.0 * k, omega=0.15)
    elif kind == "shear":  # a pan of 2 px/frame with a growing horizontal shear: phi_t = c + [[1, k t], [0, 1]] (p - c)
        # + v t, scenes.LinearMotion's form, invertible at every t since I + t (M - I) is unit triangular
        v = _direction(rng, 2.0 * k)
        shear = float(rng.uniform(0.006, 0.01)) * float(rng.choice([-1, 1]))
        motion = LinearMotion(c, ((1.0, shear), (0.0, 1.0)), v)
    elif kind == "objects":
        objects = make_scene("objects", size, rng)
        bg = Layer(tex, AffineMotion(c, _direction(rng, float(rng.uniform(1.0, 2.0)) * k)))
        return Scene(kind, size, (bg,) + objects.layers[1:])
    else:
        raise ValueError(f"unknown sequence kind {kind!r}")
    return Scene(kind, size, (Layer(tex, motion),))  # type: ignore[arg-type]  # TimeWarped is a motion


def grey(scene: Scene, t: int) -> np.ndarray:
    """Frame t of ``scene`` as float64 grey (H, W) in [0, 1]."""
    return scene.render(t) @ LUMA


def render(kind: str, seed: int, size: tuple[int, int], frames: int = FRAMES) -> Sequence:
    """The sequence of ``kind`` and ``seed`` at ``size`` (width, height)."""
    index = (KINDS + HELDOUT_KINDS).index(kind)
    rng = np.random.default_rng([seed, index])
    noise = np.random.default_rng([seed, index, 1])
    name, event = f"s{seed}_{kind}", frames // 2

    def delivered(img: np.ndarray) -> np.ndarray:
        return quantise(img + noise.normal(0.0, NOISE / 255.0, img.shape), 8)

    if kind == "cut":
        a, b = scene_of("pan", size, rng), scene_of("rotation", size, rng)
        imgs = [grey(a, t) if t < event else grey(b, t - event) for t in range(frames)]
        gt = [a.ground_truth(t + 1) if t + 1 < event else None if t + 1 == event
              else b.ground_truth(t + 1 - event) for t in range(frames - 1)]
        return Sequence(name, kind, [delivered(i) for i in imgs], _f32(gt), event)
    if kind == "exposure":
        a = scene_of("pan", size, rng)
        gain, offset = ((1.3, -0.04), (0.75, 0.05))[seed % 2]
        imgs = [grey(a, t) * (gain if t >= event else 1.0) + (offset if t >= event else 0.0) for t in range(frames)]
        gt = [a.ground_truth(t + 1) for t in range(frames - 1)]
        return Sequence(name, kind, [delivered(i) for i in imgs], _f32(gt), event)
    scene = scene_of(kind, size, rng)
    return Sequence(name, kind, [delivered(grey(scene, t)) for t in range(frames)],
                    _f32([scene.ground_truth(t + 1) for t in range(frames - 1)]))


def _f32(gt: list[np.ndarray | None]) -> list[np.ndarray | None]:
    return [None if g is None else g.astype(np.float32) for g in gt]


def sequences(split: str, size: tuple[int, int], kinds: tuple[str, ...] = KINDS, frames: int = FRAMES
              ) -> Iterator[Sequence]:
    """One sequence of every kind for the split's seeds (``tune``: 0.., ``report``: 1000..), in order; split
    ``heldout``: two of each of HELDOUT_KINDS (seeds 7000..), which ``kinds`` does not filter."""
    if split == "heldout":
        for k in range(2 * len(HELDOUT_KINDS)):
            yield render(HELDOUT_KINDS[k % len(HELDOUT_KINDS)], HELDOUT_SEED0 + k, size, frames)
        return
    for k, seed in seeds(split, len(KINDS)):
        if KINDS[k] in kinds:
            yield render(KINDS[k], seed, size, frames)


def grey8(frame: np.ndarray, encoding: str) -> np.ndarray:
    """A decoded image (codec.decode: array and encoding label) as (H, W) uint8 grey: the engine's own
    conversion (api.to_grey: BT.601 luma, channel order from the label, bit depth to [0, 1]), times 255."""
    g = to_grey(frame, channel_order="bgr" if encoding.startswith("bgr") else "rgb")
    return np.rint(g * 255.0).astype(np.uint8)


def bag_sequence(folder: Path) -> Sequence:
    """A bundled bag as a sequence of kind ``bag`` (module docstring): frames in stamp order, ``gt[t]`` the
    ground truth stamped like frame t + 1 (None where the bag has none)."""
    stamps, frames, gts = read_bag(folder)
    return Sequence(f"bag_{folder.name}", "bag", [grey8(*frames[s]) for s in stamps],
                    _f32([gts.get(s) for s in stamps[1:]]))


def bag_sequences(folder: Path = BAGS) -> Iterator[Sequence]:
    """Every bag below ``folder`` (the bundled ones by default) as a sequence, by name."""
    for bag in sorted(p.parent for p in folder.glob("*/metadata.yaml")):
        yield bag_sequence(bag)
