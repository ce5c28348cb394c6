"""The ``missing`` regime: exactly rendered pairs with pixels that carry no data, their values replaced by
garbage, and ground truth everywhere (issue 27). The three kinds (``blobs``, ``stripes``, ``dead``), the
masks a ``<preset>+mask`` method is given and the scores: docs/suite.md, "missing"."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np

from .data import Sample
from .synthetic import _pair, quantise, seeds

KINDS = ("blobs", "stripes", "dead")
SIZE = (320, 240)


def _ellipse(h: int, w: int, cy: float, cx: float, ry: float, rx: float) -> np.ndarray:
    ys, xs = np.mgrid[0:h, 0:w]
    return ((ys - cy) / ry) ** 2 + ((xs - cx) / rx) ** 2 <= 1.0


def _band(h: int, w: int, x0: float, slope: float, width: float) -> np.ndarray:
    ys, xs = np.mgrid[0:h, 0:w]
    return np.abs(xs - (x0 + slope * (ys - h / 2))) <= width / 2


def masks_for(kind: str, h: int, w: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """The invalid pixels of frame 0 and frame 1 for ``kind`` ((H, W) bool each, True = garbage)."""
    if kind == "blobs":
        ry, rx = rng.uniform(0.3, 0.4) * h, rng.uniform(0.18, 0.25) * w
        body = _ellipse(h, w, h + 10, rng.uniform(0.35, 0.65) * w, ry, rx)
        for _ in range(2):
            body |= _ellipse(h, w, rng.uniform(0.15, 0.55) * h, rng.uniform(0.1, 0.9) * w, *rng.uniform(8, 16, 2))
        return body, body
    if kind == "stripes":
        x0, slope, width = rng.uniform(0.25, 0.55) * w, rng.uniform(-0.5, 0.5), rng.uniform(18, 26)
        move = rng.uniform(20, 40) * rng.choice([-1.0, 1.0])
        return _band(h, w, x0, slope, width), _band(h, w, x0 + move, slope, width)
    dead = rng.random((h, w)) < 0.01
    dead |= np.roll(dead & (rng.random((h, w)) < 0.3), 1, axis=(0, 1))  # some in 2x2-ish clusters
    dead[:, rng.choice(w, 2, replace=False)] = True
    return dead, dead


def garbage(kind: str, img: np.ndarray, bad: np.ndarray, rng: np.random.Generator,
            static: np.ndarray) -> np.ndarray:
    """img with its ``bad`` pixels replaced by the kind's garbage (``static``: the body's texture)."""
    out = img.copy()
    if kind == "blobs":
        out[bad] = static[bad]
    elif kind == "stripes":
        out[bad] = np.clip(0.06 + rng.normal(0.0, 0.03, int(bad.sum())), 0.0, 1.0)
    else:
        out[bad] = (np.arange(bad.size).reshape(bad.shape)[bad] % 2).astype(np.float64)  # stuck black / white
    return out


def missing(split: str, quick: bool) -> Iterator[Sample]:
    """Fine 320x240 pairs, 8 bit, with the kind's pixels replaced by garbage; ground truth everywhere."""
    for k, s in seeds(split, 3 if quick else 6):
        i0, i1, gt, label = _pair(s, k, SIZE)
        kind = KINDS[k % len(KINDS)]
        rng = np.random.default_rng([s, 27])
        bad0, bad1 = masks_for(kind, *i0.shape, rng)
        static = 0.2 + 0.6 * np.clip(np.cumsum(rng.normal(0, 0.05, i0.shape), axis=1) % 1.0, 0, 1)
        f0, f1 = (garbage(kind, img, bad, rng, static) for img, bad in ((i0, bad0), (i1, bad1)))
        yield Sample(f"s{s}_{label}_{kind}", quantise(f0, 8), quantise(f1, 8), gt, 8, kind, valid=(~bad0, ~bad1))
