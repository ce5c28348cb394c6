"""Exactly rendered synthetic regimes: band-limited textures under small motions, delivered at 8-16 bit,
with sensor noise, exposure changes, low contrast or large flat areas. Every pair comes from a seed, whose
scene is the same in every regime (docs/suite.md, "Rendering" and "Seeds and splits")."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from flow_node.bag.scenes import FINE_MOTIONS, BandTexture, Layer, Scene, fine_motion, render_grey_pair

from .data import Sample

# Texture bands (cycles/px): each spans a few octaves up to its finest scale (period 6, 4 and 3 px).
BANDS: dict[str, tuple[float, float]] = {"band6": (1 / 40, 1 / 6), "band4": (1 / 20, 1 / 4),
                                         "band3": (1 / 10, 1 / 3)}
SPLITS = ("tune", "report", "all")
REPORT_SEED0 = 1000  # report seeds are REPORT_SEED0 + k, tune seeds k
EXPOSURES: tuple[tuple[float, float], ...] = ((0.75, 0.05), (0.8, 0.04), (1.25, -0.02), (1.33, -0.05))
NOISE_SIGMAS = (1.0, 2.0, 3.0)  # grey levels of 255
LOW_CONTRASTS = (24.0, 10.0)  # grey levels of 255 between the texture's extremes
DEPTHS = (8, 10, 12, 16)


def seeds(split: str, count: int) -> list[tuple[int, int]]:
    """(index in split, seed) pairs: ``tune`` 0..count-1, ``report`` 1000.., ``all`` both."""
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; choose one of {', '.join(SPLITS)}")
    out = []
    if split in ("tune", "all"):
        out += [(k, k) for k in range(count)]
    if split in ("report", "all"):
        out += [(k, REPORT_SEED0 + k) for k in range(count)]
    return out


def quantise(img: np.ndarray, bits: int) -> np.ndarray:
    """Float [0, 1] (H, W) -> integers 0 .. 2**bits - 1 (rounded, clipped): uint8 for 8 bit, else uint16."""
    top = float(2**bits - 1)
    q = np.rint(np.clip(img, 0.0, 1.0) * top)
    return q.astype(np.uint8 if bits == 8 else np.uint16)


def scene_for(index: int, seed: int, size: tuple[int, int], contrast: float | None = None,
              flat: bool = False, span: tuple[float, float] = (0.1, 0.72)) -> tuple[Scene, str]:
    """The scene of ``seed`` at ``size`` (width, height) and its label 'motion/band': motion kind and band
    cycle with ``index``; the texture's grey range is ``span`` (the same texture and motion for any span),
    or with ``contrast`` (fraction of full scale) a narrower range about 0.41; ``flat`` blends about half
    the area to a constant grey."""
    kind = FINE_MOTIONS[index % len(FINE_MOTIONS)]
    band = tuple(BANDS)[index % len(BANDS)]  # 4 motions x 3 bands: every combination in 12 seeds
    rng = np.random.default_rng(seed)
    lo, hi = span if contrast is None else (0.41 - contrast / 2, 0.41 + contrast / 2)
    tex = BandTexture.band(rng, *BANDS[band], lo=lo, hi=hi)
    motion = fine_motion(kind, size, rng)
    if flat:
        mask = BandTexture.band(rng, 1 / 160, 1 / 60, n=12)
        tex = BandTexture(tex.freqs, tex.phases, tex.amps, tex.tint, lo, hi, flat=mask, flat_level=(lo + hi) / 2)
    return Scene(f"{kind}_{band}", size, (Layer(tex, motion),)), f"{kind}/{band}"


def _pair(seed: int, index: int, size: tuple[int, int], contrast: float | None = None,
          flat: bool = False) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Float64 frames, float32 ground truth and label of :func:`scene_for`."""
    scene, label = scene_for(index, seed, size, contrast, flat)
    i0, i1, gt = render_grey_pair(scene)
    return i0, i1, gt.astype(np.float32), label


def fine(split: str, quick: bool, size: tuple[int, int]) -> Iterator[Sample]:
    """Fine textures x {shift, rotation, zoom, affine} at ``size``, 8 bit (12 seeds at 320x240, 8 at
    640x480; quick 4)."""
    for k, s in seeds(split, 4 if quick else (12 if size[0] <= 320 else 8)):
        i0, i1, gt, label = _pair(s, k, size)
        yield Sample(f"s{s}_{label}", quantise(i0, 8), quantise(i1, 8), gt, 8, label.split("/")[0])


def bit_depth(split: str, quick: bool) -> Iterator[Sample]:
    """The fine 320x240 pairs delivered at 8, 10, 12 and 16 bit (10-bit content as uint16 up to 1023)."""
    for k, s in seeds(split, 2 if quick else 6):
        i0, i1, gt, label = _pair(s, k, (320, 240))
        for bits in DEPTHS:
            yield Sample(f"s{s}_{label}_{bits}bit", quantise(i0, bits), quantise(i1, bits), gt, bits, f"{bits} bit")


def noise(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 pairs with Gaussian sensor noise of sigma 1, 2, 3 grey levels on both frames, 8 bit."""
    for k, s in seeds(split, 3 if quick else 6):
        i0, i1, gt, label = _pair(s, k, (320, 240))
        sigma = NOISE_SIGMAS[k % len(NOISE_SIGMAS)]
        rng = np.random.default_rng([s, 1])
        n0, n1 = (img + rng.normal(0.0, sigma / 255.0, img.shape) for img in (i0, i1))
        yield Sample(f"s{s}_{label}_sigma{sigma:g}", quantise(n0, 8), quantise(n1, 8), gt, 8,
                     f"sigma {sigma:g}")


def exposure_label(gain: float, offset: float) -> str:
    return f"gain {gain:g} {offset * 255:+.0f}"


def exposure(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 pairs unchanged and with frame 1 = gain * frame 1 + offset (gains 0.75 .. 1.33, offsets
    in grey levels of 255), 8 bit; the texture's range [0.1, 0.72] keeps every variant unclipped."""
    for k, s in seeds(split, 2 if quick else 4):
        i0, i1, gt, label = _pair(s, k, (320, 240))
        yield Sample(f"s{s}_{label}_unchanged", quantise(i0, 8), quantise(i1, 8), gt, 8, "unchanged")
        for gain, offset in EXPOSURES:
            yield Sample(f"s{s}_{label}_g{gain:g}", quantise(i0, 8), quantise(gain * i1 + offset, 8), gt, 8,
                         exposure_label(gain, offset))


def low_contrast(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 pairs whose texture spans only 24 or 10 grey levels of 255, 8 bit."""
    for k, s in seeds(split, 2 if quick else 6):
        levels = LOW_CONTRASTS[k % len(LOW_CONTRASTS)]
        i0, i1, gt, label = _pair(s, k, (320, 240), contrast=levels / 255.0)
        yield Sample(f"s{s}_{label}_c{levels:g}", quantise(i0, 8), quantise(i1, 8), gt, 8, f"{levels:g} levels")


def flat_areas(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 pairs with about half of the area flat grey (moving with the scene), 8 bit."""
    for k, s in seeds(split, 2 if quick else 6):
        i0, i1, gt, label = _pair(s, k, (320, 240), flat=True)
        yield Sample(f"s{s}_{label}_flat", quantise(i0, 8), quantise(i1, 8), gt, 8, label.split("/")[0])
