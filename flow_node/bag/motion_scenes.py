"""Exactly rendered scenes with known derived outputs: dominant motion, time to contact, moving objects.

Built from :mod:`flow_node.bag.scenes` (band-limited textures evaluated at the exact inverse motion, nothing
resampled): a textured background moved by a similarity -- still, a pan, a rotation or a zoom about the
image centre, or an approaching plane (a zoom by s = 1 + 1 / tau per frame about a focus of expansion) --
and textured ellipses and boxes moving relative to it. Each object moves exactly as the background plus a
constant ``delta`` (1.5-3 px/frame), so its flow deviates from the dominant motion by |delta| at every
pixel, and the moving mask of the pair 0 -> 1 is exactly the objects' pixels in frame 0
(``Scene.layer_map(0) > 0``). Pure numpy; used by ``bench.motion`` and the tests.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.errors import ConfigError
from .scenes import AffineMotion, BandTexture, Layer, Scene

MOTION_KINDS = ("still", "pan", "rotation", "zoom", "approach")
BAND = (1 / 40, 1 / 6)  # cycles/px: the fine suite's band6 (periods of 6 to 40 px)
DELTA_PX = (1.5, 3.0)  # an object's motion relative to the background, px/frame
TTC_FRAMES = (10.0, 200.0)  # approach scenes: time to contact, log-uniform, frames


@dataclass(frozen=True)
class MotionTruth:
    """The exact derived outputs of a pair 0 -> 1: the dominant similarity about the image centre
    (tx, ty px/frame, rotation deg/frame, scale per frame; :class:`flow_node.pipeline.motion.DominantMotion`'s
    convention), the time to contact in frames (approach scenes: 1 / (scale - 1), the same in every region;
    None otherwise), the focus of expansion (approach; None otherwise) and the objects' share of the
    image."""

    kind: str
    tx: float
    ty: float
    rotation_deg: float
    scale: float
    ttc_frames: float | None
    foe: tuple[float, float] | None
    object_share: float


def _objects(size: tuple[int, int], rng: np.random.Generator, share: float, count: int,
             bg: AffineMotion) -> tuple[Layer, ...]:
    """``count`` ellipses/boxes of ``share`` of the image together (before overlaps), each moving like the
    background ``bg`` plus its own delta of DELTA_PX px/frame."""
    w, h = size
    c = np.asarray(bg.center)
    lin = bg.scale * np.array([[math.cos(bg.theta), -math.sin(bg.theta)], [math.sin(bg.theta), math.cos(bg.theta)]])
    out = []
    for i in range(count):
        kind = "box" if i % 2 else "ellipse"
        aspect = float(rng.uniform(0.7, 1.4))
        area = share * w * h / count
        ry = math.sqrt(area / ((4.0 if kind == "box" else math.pi) * aspect))
        rx = aspect * ry
        o = np.array([rng.uniform(rx + 8, w - rx - 8), rng.uniform(ry + 8, h - ry - 8)])
        angle, length = rng.uniform(0.0, 2 * math.pi), rng.uniform(*DELTA_PX)
        delta = length * np.array([math.cos(angle), math.sin(angle)])
        velocity = (lin - np.eye(2)) @ (o - c) + np.asarray(bg.velocity) + delta  # bg flow at o, plus delta
        motion = AffineMotion((float(o[0]), float(o[1])), (float(velocity[0]), float(velocity[1])), bg.theta, bg.scale)
        out.append(Layer(BandTexture.band(rng, *BAND), motion, (float(o[0]), float(o[1]), rx, ry, kind)))
    return tuple(out)


def motion_scene(kind: str, size: tuple[int, int], rng: np.random.Generator, object_share: float = 0.0,
                 objects: int = 2, ttc_frames: float | None = None) -> tuple[Scene, MotionTruth]:
    """A scene of ``kind`` (one of MOTION_KINDS) at ``size`` (width, height) and its truth.

    still: nothing moves; pan: 0.5-3 px/frame in any direction; rotation: 0.5-2 deg/frame either way;
    zoom: scale 1 +- (0.005-0.02) per frame; all about the image centre. approach: a plane with a time to
    contact of ``ttc_frames`` (default: log-uniform in TTC_FRAMES), its focus of expansion uniform in the
    middle half of the image.
    ``objects`` objects covering ``object_share`` (0-0.5) of the image move over the background.
    """
    if kind not in MOTION_KINDS:
        raise ConfigError(f"unknown motion scene {kind!r}; choose one of {', '.join(MOTION_KINDS)}")
    if not 0.0 <= object_share <= 0.5:
        raise ConfigError(f"object_share must be in [0, 0.5], got {object_share}")
    w, h = size
    c = ((w - 1) / 2.0, (h - 1) / 2.0)
    sign = float(rng.choice([-1.0, 1.0]))
    ttc, foe = None, None
    if kind == "pan":
        angle, length = rng.uniform(0.0, 2 * math.pi), rng.uniform(0.5, 3.0)
        bg = AffineMotion(c, (float(length * math.cos(angle)), float(length * math.sin(angle))))
    elif kind == "rotation":
        bg = AffineMotion(c, theta=math.radians(sign * float(rng.uniform(0.5, 2.0))))
    elif kind == "zoom":
        bg = AffineMotion(c, scale=1.0 + sign * float(rng.uniform(0.005, 0.02)))
    elif kind == "approach":
        drawn = float(math.exp(rng.uniform(*np.log(TTC_FRAMES))))
        ttc = drawn if ttc_frames is None else float(ttc_frames)
        foe = (float(rng.uniform(w / 4, 3 * w / 4)), float(rng.uniform(h / 4, 3 * h / 4)))
        bg = AffineMotion(foe, scale=1.0 + 1.0 / ttc)
    else:
        bg = AffineMotion(c)
    layers = (Layer(BandTexture.band(rng, *BAND), bg),)
    if object_share > 0.0:
        layers += _objects(size, rng, object_share, objects, bg)
    scene = Scene(kind, size, layers)
    # the background's flow at the image centre is the dominant translation (centre of the similarity)
    t = bg.forward(np.array(c), 1.0) - np.array(c)
    share = float(np.mean(scene.layer_map(0) > 0)) if object_share > 0.0 else 0.0
    truth = MotionTruth(kind, float(t[0]), float(t[1]), math.degrees(bg.theta), bg.scale, ttc, foe, share)
    return scene, truth


# `flow_bag synth`'s scenes with known derived outputs (docs/bags.md): an approaching textured plane (time to
# contact 10-200 frames, the focus of expansion in the middle half), and a pan with two objects covering ~20 %
# of the image moving on their own
SYNTH_SCENES: dict[str, tuple[str, float]] = {"approach": ("approach", 0.0), "pan_objects": ("pan", 0.2)}


def synth_scene(name: str, size: tuple[int, int], rng: np.random.Generator, brightness: float = 0.0) -> Scene:
    """Scene ``name`` (one of SYNTH_SCENES) for ``flow_bag synth``, with its brightness change per frame."""
    if name not in SYNTH_SCENES:
        raise ConfigError(f"unknown scene {name!r}; choose one of {', '.join(SYNTH_SCENES)}")
    kind, share = SYNTH_SCENES[name]
    scene, _ = motion_scene(kind, size, rng, object_share=share)
    return Scene(name, size, scene.layers, brightness)
