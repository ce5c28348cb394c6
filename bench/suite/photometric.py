"""Families of photometric changes a camera applies to frame 2 (frame 1 unchanged), and the regimes that
apply them: ``photometric`` (exact synthetic renders) and ``photometric_real`` (the Middlebury pairs).

Every change is a pure function of a float64 frame in [0, 1] ((H, W) grey or (H, W, 3) RGB) and a seed,
returning a frame of the same shape in [0, 1], applied before the 8-bit quantisation. The families, their
variants and the tune/report split of whole families: docs/suite.md, "Photometric families"."""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass
from functools import partial

import numpy as np

from flow_node.bag.scenes import BandTexture, Layer, Scene, render_grey_pair
from flow_node.core.flowio import read_flo

from ..common import DEFAULT_DATA, SEQUENCES
from . import synthetic
from .data import LUMA, MIDDLEBURY_QUICK, Sample, read_float
from .synthetic import quantise

Change = Callable[[np.ndarray, int], np.ndarray]  # (frame float64 in [0, 1], seed) -> same shape


@dataclass(frozen=True)
class Variant:
    """One photometric change: its family, its name within the family, the function, and whether it needs
    an RGB frame."""

    family: str
    name: str
    change: Change
    rgb_only: bool = False

    @property
    def label(self) -> str:
        """'family/name', the report's variant label."""
        return f"{self.family}/{self.name}"

    @property
    def slug(self) -> str:
        """The label as a sample-name suffix (no spaces or slashes)."""
        return self.label.replace("/", "_").replace(" ", "_")

    def __call__(self, frame: np.ndarray, seed: int = 0) -> np.ndarray:
        """The changed frame: float64, same shape, in [0, 1]."""
        return np.clip(self.change(np.clip(np.asarray(frame, np.float64), 0.0, 1.0), seed), 0.0, 1.0)


# ---------------------------------------------------------------------------------------- tone curves
def gamma(x: np.ndarray, seed: int, g: float) -> np.ndarray:
    """x^g."""
    return x**g


def smoothstep(x: np.ndarray, seed: int) -> np.ndarray:
    """3x^2 - 2x^3: contrast up in the mid-tones, down at both ends."""
    return x * x * (3.0 - 2.0 * x)


def logistic(x: np.ndarray, seed: int, k: float) -> np.ndarray:
    """The logistic of slope k about 0.5, rescaled so that 0 -> 0 and 1 -> 1."""
    lo = 1.0 / (1.0 + math.exp(k / 2.0))
    return (1.0 / (1.0 + np.exp(-k * (x - 0.5))) - lo) / (1.0 - 2.0 * lo)


def log_curve(x: np.ndarray, seed: int, a: float) -> np.ndarray:
    """log1p(a x) / log1p(a): strong lift of the shadows, compression of the highlights."""
    return np.log1p(a * x) / math.log1p(a)


def knee(x: np.ndarray, seed: int, at: float, slope: float) -> np.ndarray:
    """Identity up to ``at``, slope ``slope`` above it."""
    return np.where(x <= at, x, at + slope * (x - at))


# ----------------------------------------------------------------------------------------- gain fields
def _apply_gain(x: np.ndarray, gain: np.ndarray) -> np.ndarray:
    """x times a gain field (H, W), broadcast over RGB channels."""
    return x * (gain[..., None] if x.ndim == 3 else gain)


def _distance(shape: tuple[int, ...], centre: tuple[float, float]) -> tuple[np.ndarray, float]:
    """Distance (H, W) in px of each pixel from ``centre`` (fractions of width, height), and the distance of
    the farthest corner."""
    h, w = shape[:2]
    cx, cy = centre[0] * (w - 1), centre[1] * (h - 1)
    far = max(math.hypot(px - cx, py - cy) for px in (0, w - 1) for py in (0, h - 1))
    return np.hypot(np.arange(w) - cx, (np.arange(h) - cy)[:, None]), far


def _radius(shape: tuple[int, ...], centre: tuple[float, float]) -> np.ndarray:
    """:func:`_distance` over the farthest corner's: 1 at that corner."""
    dist, far = _distance(shape, centre)
    return dist / far


def vignette_cos4(x: np.ndarray, seed: int, corner: float) -> np.ndarray:
    """Natural vignetting cos^4(theta) of a lens whose corner ray is at theta_c, cos^4(theta_c) = corner."""
    tan_c = math.tan(math.acos(corner**0.25))
    return _apply_gain(x, 1.0 / (1.0 + (_radius(x.shape, (0.5, 0.5)) * tan_c) ** 2) ** 2)


def vignette_quadratic(x: np.ndarray, seed: int, corner: float, centre: tuple[float, float]) -> np.ndarray:
    """Gain 1 - (1 - corner) r^2 about ``centre``; ``corner`` at the farthest corner."""
    return _apply_gain(x, 1.0 - (1.0 - corner) * _radius(x.shape, centre) ** 2)


def planar_gain(x: np.ndarray, seed: int, start: float, end: float, direction: tuple[float, float]) -> np.ndarray:
    """A linear gain from ``start`` to ``end`` along ``direction`` (unit-square (dx, dy)) across the frame."""
    h, w = x.shape[:2]
    t = np.arange(w)[None, :] / (w - 1) * direction[0] + np.arange(h)[:, None] / (h - 1) * direction[1]
    t = (t - t.min()) / (t.max() - t.min())
    return _apply_gain(x, start + (end - start) * t)


def blob_gain(x: np.ndarray, seed: int) -> np.ndarray:
    """1 + a exp(-r^2 / 2 sigma^2): a (0.3 or -0.25) and the centre (middle half of the frame) drawn from
    ``seed``; sigma a quarter of the frame's diagonal."""
    rng = np.random.default_rng([seed, 2501])
    cx, cy = rng.uniform(0.25, 0.75, 2)
    amp = float(rng.choice([0.3, -0.25]))
    r, _ = _distance(x.shape, (float(cx), float(cy)))
    sigma = 0.25 * math.hypot(x.shape[0], x.shape[1])
    return _apply_gain(x, 1.0 + amp * np.exp(-0.5 * (r / sigma) ** 2))


# ------------------------------------------------------------------------------- global and per channel
def gain_offset(x: np.ndarray, seed: int, gain: float, offset: float) -> np.ndarray:
    """gain * x + offset (clipped to [0, 1] by :class:`Variant`)."""
    return gain * x + offset


def white_balance(x: np.ndarray, seed: int, gains: tuple[float, float, float]) -> np.ndarray:
    """Per-channel gains on an (H, W, 3) RGB frame."""
    if x.ndim != 3 or x.shape[2] != 3:
        raise ValueError(f"white balance needs an (H, W, 3) RGB frame, got {x.shape}")
    return x * np.asarray(gains)


def low_light(x: np.ndarray, seed: int, gain: float, sigma: float, stream: int = 2502) -> np.ndarray:
    """gain * x plus Gaussian noise of ``sigma`` grey levels of 255, re-quantised to 8 bit; ``stream`` keys the
    noise's draw per family (low light 2502; sensor noise, its tune-side twin at gain 1 -- no darkening, no coarser
    quantisation, sigma 3.5 / 10 matching low light's noise over the frame's range, 2 / (0.6 * 255) and
    4 / (0.4 * 255) -- 2504)."""
    noisy = gain * x + np.random.default_rng([seed, stream]).normal(0.0, sigma / 255.0, x.shape)
    return np.rint(np.clip(noisy, 0.0, 1.0) * 255.0) / 255.0


def _family(name: str, *variants: tuple[str, Change], rgb_only: bool = False) -> tuple[Variant, ...]:
    return tuple(Variant(name, v, fn, rgb_only) for v, fn in variants)


FAMILIES: dict[str, tuple[Variant, ...]] = {
    "gamma": _family("gamma", *((f"{g:g}", partial(gamma, g=g)) for g in (0.5, 0.8, 1.25, 2.0))),
    "vignetting": _family("vignetting", ("cos4 0.7", partial(vignette_cos4, corner=0.7)),
                          ("quad 0.85", partial(vignette_quadratic, corner=0.85, centre=(0.5, 0.5))),
                          ("quad 0.75 off-centre", partial(vignette_quadratic, corner=0.75, centre=(0.35, 0.4)))),
    "clipping": _family("clipping", *((f"{g:g}x{o:+.2f}", partial(gain_offset, gain=g, offset=o))
                                      for g, o in ((1.3, -0.1), (1.5, -0.25), (1.8, -0.35)))),
    "s_curve": _family("s_curve", ("smoothstep", smoothstep), ("logistic 8", partial(logistic, k=8.0))),
    "log_knee": _family("log_knee", ("log 8", partial(log_curve, a=8.0)),
                        ("knee 0.7", partial(knee, at=0.7, slope=0.3)), ("knee 0.5", partial(knee, at=0.5, slope=0.5))),
    "illumination": _family("illumination",
                            ("planar 0.8-1.2", partial(planar_gain, start=0.8, end=1.2, direction=(1.0, 0.0))),
                            ("planar 1.15-0.85 diag", partial(planar_gain, start=1.15, end=0.85, direction=(1.0, 1.0))),
                            ("blob", blob_gain)),
    "flicker": _family("flicker", *((f"{g:g}x{o:+.2f}", partial(gain_offset, gain=g, offset=o))
                                    for g, o in ((0.93, 0.01), (1.06, -0.01)))),
    "white_balance": _family("white_balance", *(("gains {:g} {:g} {:g}".format(*g), partial(white_balance, gains=g))
                                                for g in ((1.15, 1.0, 0.85), (0.85, 1.0, 1.2))), rgb_only=True),
    "low_light": _family("low_light", *((f"{g:g}x sigma {s:g}", partial(low_light, gain=g, sigma=s))
                                        for g, s in ((0.6, 2.0), (0.4, 4.0)))),
    "sensor_noise": _family("sensor_noise", *((f"sigma {s:g}", partial(low_light, gain=1.0, sigma=s, stream=2504))
                                              for s in (3.5, 10.0))),
}
TUNE_FAMILIES = ("gamma", "vignetting", "clipping", "sensor_noise")
REPORT_FAMILIES = ("s_curve", "log_knee", "illumination", "flicker", "white_balance", "low_light")
UNCHANGED, UNCHANGED_RGB = "unchanged", "unchanged rgb"


def families(split: str) -> tuple[str, ...]:
    """The families a split applies: tune -> TUNE_FAMILIES, report -> REPORT_FAMILIES, all -> both."""
    table = {"tune": TUNE_FAMILIES, "report": REPORT_FAMILIES, "all": TUNE_FAMILIES + REPORT_FAMILIES}
    if split not in table:
        raise ValueError(f"unknown split {split!r}; choose one of {', '.join(table)}")
    return table[split]


def variants(split: str, rgb: bool) -> list[Variant]:
    """The split's variants for grey frames (``rgb`` False: every variant that is not RGB-only) or the
    RGB-only ones (``rgb`` True)."""
    return [v for f in families(split) for v in FAMILIES[f] if v.rgb_only == rgb]


def photometric_samples(name: str, i0: np.ndarray, i1: np.ndarray, gt: np.ndarray, split: str, seed: int,
                        rgb: tuple[np.ndarray, np.ndarray] | None = None,
                        occluded: np.ndarray | None = None) -> Iterator[Sample]:
    """8-bit samples of one pair: grey float64 frames i0, i1 (H, W) in [0, 1] unchanged (variant
    'unchanged') and with each grey variant of the split applied to i1; with ``rgb`` (two (H, W, 3) frames)
    and RGB-only variants in the split, also the RGB pair unchanged ('unchanged rgb') and with each of
    those. ``gt`` (H, W, 2) float32 px and ``occluded`` are passed on."""
    def sample(suffix: str, f0: np.ndarray, f1: np.ndarray, label: str) -> Sample:
        return Sample(f"{name}_{suffix}", quantise(f0, 8), quantise(f1, 8), gt, 8, label, occluded)

    yield sample(UNCHANGED, i0, i1, UNCHANGED)
    for v in variants(split, rgb=False):
        yield sample(v.slug, i0, v(i1, seed), v.label)
    colour = variants(split, rgb=True)
    if rgb is not None and colour:
        yield sample("rgb_unchanged", rgb[0], rgb[1], UNCHANGED_RGB)
        for v in colour:
            yield sample(v.slug, rgb[0], v(rgb[1], seed), v.label)


# --------------------------------------------------------------------------------------------- regimes
SPAN = (0.04, 0.96)  # the synthetic textures' grey range here: tone curves and clipping act on all of it
SIZE = (320, 240)


def _rgb_render(scene: Scene, grey: tuple[np.ndarray, np.ndarray], seed: int,
                band: str) -> tuple[np.ndarray, np.ndarray]:
    """An exact RGB pair of ``scene``: R = its texture, B = a second texture of the same band and range
    moving with the same motion, G = their mean (each channel exact, nothing resampled). ``grey`` is the
    scene's rendered grey pair."""
    layer = scene.layers[0]
    tex = BandTexture.band(np.random.default_rng([seed, 2503]), *synthetic.BANDS[band], lo=layer.texture.lo,
                           hi=layer.texture.hi)
    j0, j1, _ = render_grey_pair(Scene(scene.name, scene.size, (Layer(tex, layer.motion),)))
    return (np.stack([grey[0], 0.5 * (grey[0] + j0), j0], axis=-1),
            np.stack([grey[1], 0.5 * (grey[1] + j1), j1], axis=-1))


def synthetic_photometric(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 textures spanning grey 0.04-0.96 (seed s: the texture and motion of seed s in
    ``fine_320``), each pair unchanged and under every variant of the split (4 seeds; quick 2); RGB samples
    for white balance from :func:`_rgb_render`."""
    for k, s in synthetic.seeds(split, 2 if quick else 4):
        scene, label = synthetic.scene_for(k, s, SIZE, span=SPAN)
        i0, i1, gt = render_grey_pair(scene)
        rgb = _rgb_render(scene, (i0, i1), s, label.split("/")[1]) if variants(split, rgb=True) else None
        yield from photometric_samples(f"s{s}_{label.replace('/', '_')}", i0, i1, gt.astype(np.float32), split,
                                       s, rgb)


def middlebury_photometric(split: str, quick: bool) -> Iterable[Sample]:
    """The Middlebury pairs (quick: 3) frame10 -> frame11, grey (BT.601 luma) and RGB for white balance,
    unchanged and with every variant of the split on frame11 (the seed of sequence k is k)."""
    for k, n in enumerate(MIDDLEBURY_QUICK if quick else SEQUENCES):
        c0, c1 = (read_float(DEFAULT_DATA / n / f) for f in ("frame10.png", "frame11.png"))
        yield from photometric_samples(n, c0 @ LUMA, c1 @ LUMA, read_flo(DEFAULT_DATA / n / "flow10.flo"), split,
                                       k, (c0, c1))
