"""Real photographs moved exactly: regimes ``real_exact`` and ``real_exact_photometric``.

Windows of a full-resolution photograph moved by integer shifts, a foreground from another photograph moved
by its own, both block-averaged by f: the flow is exactly s / f and t / f px (mixed blocks unknown, 1e10;
occluded blocks marked in ``Sample.occluded``). Construction, splits and photographs: docs/suite.md, "Real
photographs moved exactly"; test/test_realexact.py checks every pair against it."""

from __future__ import annotations

import math
from collections.abc import Iterator
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from ..common import DEFAULT_DATA, SEQUENCES
from .data import LARGE_DATA, Sample, read_float
from .photometric import photometric_samples
from .synthetic import quantise

MAX_SHIFT = 13  # full-resolution px
UNKNOWN = 1e10
# (background A, foreground B, factor f, mask shape) per split; shifts and geometry are drawn from a seed.
REPORT = (("Dimetrodon", "Grove3", 2, "ellipse"), ("Hydrangea", "Urban2", 2, "polygon"),
          ("RubberWhale", "Venus", 2, "ellipse"), ("Venus", "Dimetrodon", 2, "polygon"),
          ("Grove3", "RubberWhale", 3, "ellipse"), ("Urban2", "Hydrangea", 2, "polygon"),
          ("kitti2012_000000", "tartanair_a_000010_to_000009", 2, "ellipse"),
          ("kitti2012_000045", "Dimetrodon", 3, "polygon"),
          ("tartanair_a_000010_to_000009", "kitti2012_000000", 4, "polygon"),
          ("tartanair_c_000000_to_000001", "Hydrangea", 2, "ellipse"))
TUNE = (("Grove2", "tartanair_b_000380_to_000381", 2, "ellipse"), ("Urban3", "Grove2", 3, "polygon"),
        ("tartanair_b_000380_to_000381", "Urban3", 2, "polygon"), ("Urban3", "tartanair_b_000380_to_000381", 4,
                                                                  "ellipse"))
SPLIT_PAIRS = {"tune": TUNE, "report": REPORT}


@dataclass(frozen=True)
class Spec:
    """One pair: photographs A (background) and B (foreground), factor f, shifts s (background) and t
    (foreground) in full-resolution px, frame 0's window (x0, y0, cw, ch) in A, the offset (bx, by) such that
    window pixel (x, y) inside M0 shows B[y + by, x + bx], and the mask M0 (ch, cw) bool."""

    name: str
    background: str
    foreground: str
    factor: int
    shift: tuple[int, int]
    fg_shift: tuple[int, int]
    window: tuple[int, int, int, int]
    fg_offset: tuple[int, int]
    mask: np.ndarray


@lru_cache(maxsize=16)
def photograph(name: str) -> np.ndarray:
    """A source photograph, float64 in [0, 1], (H, W) or (H, W, 3) RGB (read-only)."""
    path = DEFAULT_DATA / name / "frame10.png" if name in SEQUENCES else LARGE_DATA / name / "frame0.png"
    img = read_float(Path(path))
    img.flags.writeable = False
    return img


def grey(img: np.ndarray) -> np.ndarray:
    """BT.601 luma per pixel (the same arithmetic for every pixel, so equal inputs give equal bits)."""
    return img if img.ndim == 2 else 0.299 * img[..., 0] + 0.587 * img[..., 1] + 0.114 * img[..., 2]


def block_mean(img: np.ndarray, f: int) -> np.ndarray:
    """Mean of each f x f block of (H, W[, C]) (H, W multiples of f), summed in one fixed order for every
    block: (H/f, W/f[, C])."""
    acc = np.zeros((img.shape[0] // f, img.shape[1] // f) + img.shape[2:])
    for i in range(f):
        for j in range(f):
            acc += img[i::f, j::f]
    return acc / (f * f)


def _shift_choice(rng: np.random.Generator, f: int, avoid: tuple[int, int] | None = None) -> tuple[int, int]:
    """An integer shift with components in -MAX_SHIFT..MAX_SHIFT, none a multiple of f; at least f px (one
    output px) away from ``avoid`` in some component."""
    comps = [c for c in range(-MAX_SHIFT, MAX_SHIFT + 1) if c % f]
    while True:
        s = (int(rng.choice(comps)), int(rng.choice(comps)))
        if avoid is None or max(abs(s[0] - avoid[0]), abs(s[1] - avoid[1])) >= f:
            return s


def _mask(rng: np.random.Generator, shape: str, size: tuple[int, int], fg_size: tuple[int, int]) -> np.ndarray:
    """A mask (ch, cw) bool of 15-30 % of the window of ``size`` (cw, ch): an ellipse or a star-shaped
    polygon (7 vertices at jittered even angles), smaller only where its bounding box would exceed 90 % of
    the window or the foreground photograph ``fg_size`` (w, h) minus 2 px; placed at random inside."""
    import cv2

    cw, ch = size
    aspect = rng.uniform(0.6, 1.6)
    if shape == "ellipse":
        angles, radii = np.linspace(0.0, 2 * math.pi, 256, endpoint=False), np.ones(256)
    else:
        angles = (np.arange(7) + rng.uniform(-0.35, 0.35, 7)) * (2 * math.pi / 7)
        radii = rng.uniform(0.6, 1.0, 7)
    pts = np.stack([radii * np.cos(angles) * math.sqrt(aspect), radii * np.sin(angles) / math.sqrt(aspect)], -1)
    unit = 0.5 * abs(float(np.dot(pts[:, 0], np.roll(pts[:, 1], 1)) - np.dot(pts[:, 1], np.roll(pts[:, 0], 1))))
    extent = pts.max(axis=0) - pts.min(axis=0)
    scale = min(math.sqrt(rng.uniform(0.15, 0.30) * cw * ch / unit), min(0.9 * cw, fg_size[0] - 2) / extent[0],
                min(0.9 * ch, fg_size[1] - 2) / extent[1])
    pts = pts * scale
    lo, hi = -pts.min(axis=0), np.array([cw - 1.0, ch - 1.0]) - pts.max(axis=0)
    centre = lo + (hi - lo) * rng.uniform(0.2, 0.8, 2)
    out = np.zeros((ch, cw), np.uint8)
    cv2.fillPoly(out, [np.rint(pts + centre).astype(np.int32)], 1)
    return out.astype(bool)


def make_spec(split: str, k: int) -> Spec:
    """Pair k of ``split`` ('tune' or 'report'), drawn from the seed (2500, split, k)."""
    a_name, b_name, f, shape = SPLIT_PAIRS[split][k]
    rng = np.random.default_rng([2500, tuple(SPLIT_PAIRS).index(split), k])
    s = _shift_choice(rng, f)
    t = _shift_choice(rng, f, avoid=s)
    (h, w), (bh, bw) = photograph(a_name).shape[:2], photograph(b_name).shape[:2]
    cw, ch = f * ((w - MAX_SHIFT) // f), f * ((h - MAX_SHIFT) // f)
    x0 = max(0, s[0]) + (w - cw - abs(s[0])) // 2  # frame 0 at x0, frame 1 at x0 - sx: both inside A
    y0 = max(0, s[1]) + (h - ch - abs(s[1])) // 2
    mask = _mask(rng, shape, (cw, ch), (bw, bh))
    ys, xs = np.nonzero(mask)
    bx = int(rng.integers(-xs.min(), bw - xs.max()))
    by = int(rng.integers(-ys.min(), bh - ys.max()))
    name = f"{split[0]}{k}_{a_name.split('_to_')[0]}+{b_name.split('_to_')[0]}_f{f}"
    return Spec(name, a_name, b_name, f, s, t, (x0, y0, cw, ch), (bx, by), mask)


def translate(mask: np.ndarray, d: tuple[int, int]) -> np.ndarray:
    """``mask`` moved by the integer d = (dx, dy): out[y + dy, x + dx] = mask[y, x] (False where nothing lands)."""
    out = np.zeros_like(mask)
    ys, xs = np.nonzero(mask)
    keep = (ys + d[1] >= 0) & (ys + d[1] < mask.shape[0]) & (xs + d[0] >= 0) & (xs + d[0] < mask.shape[1])
    out[ys[keep] + d[1], xs[keep] + d[0]] = True
    return out


def compose(spec: Spec, frame: int, colour: bool) -> tuple[np.ndarray, np.ndarray]:
    """Full-resolution frame 0 or 1 of ``spec`` ((ch, cw) grey, or (ch, cw, 3) RGB if ``colour``) and its
    foreground mask: the background window moved by -frame * s in A, the foreground pixels moved by
    frame * t, pasted on top."""
    a, b = photograph(spec.background), photograph(spec.foreground)
    if not colour:
        a, b = grey(a), grey(b)
    x0, y0, cw, ch = spec.window
    out = a[y0 - frame * spec.shift[1]:y0 - frame * spec.shift[1] + ch,
            x0 - frame * spec.shift[0]:x0 - frame * spec.shift[0] + cw].copy()
    t = (frame * spec.fg_shift[0], frame * spec.fg_shift[1])
    mask = translate(spec.mask, t)
    ys, xs = np.nonzero(mask)
    out[ys, xs] = b[ys - t[1] + spec.fg_offset[1], xs - t[0] + spec.fg_offset[0]]
    return out, mask


def ground_truth(spec: Spec) -> tuple[np.ndarray, np.ndarray]:
    """Flow (H, W, 2) float32 px at the output resolution (mixed blocks 1e10) and the occluded blocks
    (H, W) bool: a pixel of a block covered by the foreground in frame 1 or leaving the window."""
    f, (sx, sy), (tx, ty) = spec.factor, spec.shift, spec.fg_shift
    m1 = translate(spec.mask, spec.fg_shift)
    fg_count = block_mean(spec.mask.astype(np.float64), f)
    gt = np.full(fg_count.shape + (2,), UNKNOWN, np.float32)
    gt[fg_count == 0.0] = (sx / f, sy / f)
    gt[fg_count == 1.0] = (tx / f, ty / f)
    bg_lost = ~spec.mask & ~translate(~m1, (-sx, -sy))  # x + s off the window or under the foreground
    fg_lost = spec.mask & ~translate(np.ones_like(spec.mask), (-tx, -ty))  # x + t off the window
    occluded = block_mean((bg_lost | fg_lost).astype(np.float64), f) > 0.0
    return gt, occluded


def pairs(split: str, quick: bool) -> Iterator[Spec]:
    """The split's specs ('all': tune then report); quick: the first 3 of each."""
    for part in (("tune", "report") if split == "all" else (split,)):
        if part not in SPLIT_PAIRS:
            raise ValueError(f"unknown split {split!r}; choose one of tune, report, all")
        for k in range(3 if quick else len(SPLIT_PAIRS[part])):
            yield make_spec(part, k)


def _frames(spec: Spec, colour: bool) -> tuple[np.ndarray, np.ndarray]:
    """Both frames at the output resolution, float64 in [0, 1], before quantisation."""
    return block_mean(compose(spec, 0, colour)[0], spec.factor), block_mean(compose(spec, 1, colour)[0], spec.factor)


def has_colour(spec: Spec) -> bool:
    """Whether both photographs of ``spec`` are RGB (then the pair also comes as an RGB sample)."""
    return photograph(spec.background).ndim == 3 and photograph(spec.foreground).ndim == 3


def real_exact(split: str, quick: bool) -> Iterator[Sample]:
    """Every pair of the split (report 10, tune 4; quick 3), 8-bit grey ('grey') and, where both
    photographs are colour, RGB ('rgb')."""
    for spec in pairs(split, quick):
        gt, occluded = ground_truth(spec)
        for colour in (False, True) if has_colour(spec) else (False,):
            f0, f1 = _frames(spec, colour)
            yield Sample(spec.name + ("_rgb" if colour else ""), quantise(f0, 8), quantise(f1, 8), gt, 8,
                         "rgb" if colour else "grey", occluded)


def real_exact_photometric(split: str, quick: bool) -> Iterator[Sample]:
    """The pairs of :func:`real_exact` (quick: 2 of each split part) unchanged and under the split's
    photometric families (:func:`bench.suite.photometric.photometric_samples`; RGB for white balance)."""
    for k, spec in enumerate(pairs(split, quick)):
        if quick and k % 3 == 2:
            continue
        gt, occluded = ground_truth(spec)
        rgb = _frames(spec, True) if has_colour(spec) else None
        yield from photometric_samples(spec.name, *_frames(spec, False), gt, split, 2500 + k, rgb, occluded)
