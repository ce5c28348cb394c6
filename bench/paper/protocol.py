"""The paper's evaluation protocol (section "Evaluation"): small synthetic motion on real Middlebury frames.

Per sequence the ground truth is scaled to a largest known magnitude of 1 px, frame 10 (grey) is frame 1, and
frame 2 is synthesised so that the scaled truth g is the flow in our convention, I1(x + g(x)) = I0(x): I0
evaluated at y - h(y), h the inverse-flow fixed point h(y) = g(y - h(y)) (sampling I0 at x + g(x) would make
-g the flow), by a renderer of RENDERERS (``bandlimited``: exact for I0 read as a band-limited image,
bench/paper/render.py; ``cubic``: the paper's). Unknown truth is filled from its nearest known neighbour for
the synthesis only. Why and what it costs: REPORT.md, "Protocol" (written by report.py)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

import cv2
import numpy as np

from flow_node.core.api import to_grey
from flow_node.core.flowio import read_flo, read_image
from flow_node.core.metrics import valid_mask

from ..common import SEQUENCES
from .render import render

NOISE_SIGMA = 0.002
RENDERERS = ("bandlimited", "cubic")
FIXED_POINT_ITERATIONS = 30


def fill_unknown(gt: np.ndarray) -> np.ndarray:
    """Ground truth (H, W, 2) with unknown pixels replaced by their nearest known neighbour's value."""
    from scipy.ndimage import distance_transform_edt  # bench venv only: the renderer tests run without scipy

    known = valid_mask(gt)
    if known.all():
        return gt.copy()
    idx = distance_transform_edt(~known, return_distances=False, return_indices=True)
    return gt[idx[0], idx[1]]


def scale_to_unit(gt: np.ndarray) -> tuple[np.ndarray, float]:
    """Known vectors scaled so that the largest known magnitude is exactly 1 px (unknown pixels keep their
    value), and the factor applied."""
    known = valid_mask(gt)
    peak = float(np.linalg.norm(gt[known], axis=-1).max())
    out = gt.copy()
    out[known] = gt[known] / peak
    return out, 1.0 / peak


def _sample(field: np.ndarray, map_x: np.ndarray, map_y: np.ndarray, interp: int) -> np.ndarray:
    """Sample a (H, W) or (H, W, C) float32 field at (map_x, map_y) with edge replication."""
    return cv2.remap(field, map_x, map_y, interpolation=interp, borderMode=cv2.BORDER_REPLICATE)


def pullback(g: np.ndarray, iterations: int = FIXED_POINT_ITERATIONS) -> np.ndarray:
    """h (H, W, 2) with h(y) = g(y - h(y)): the forward flow g (H, W, 2) expressed on the target grid."""
    h, w = g.shape[:2]
    xs, ys = np.meshgrid(np.arange(w, dtype=np.float32), np.arange(h, dtype=np.float32))
    hflow = g.astype(np.float32).copy()
    for _ in range(iterations):
        hflow = _sample(g, xs - hflow[..., 0], ys - hflow[..., 1], cv2.INTER_LINEAR)
    return hflow


def synthesise_second(i0: np.ndarray, g: np.ndarray, renderer: str = "bandlimited") -> np.ndarray:
    """I1 (H, W) with I1(x + g(x)) = I0(x): I0 evaluated at y - h(y), h = pullback(g), by ``renderer``."""
    if renderer not in RENDERERS:
        raise ValueError(f"unknown renderer {renderer!r}; choose one of {', '.join(RENDERERS)}")
    hh, ww = i0.shape
    xs, ys = np.meshgrid(np.arange(ww, dtype=np.float32), np.arange(hh, dtype=np.float32))
    hflow = pullback(g)
    if renderer == "cubic":
        return _sample(i0, xs - hflow[..., 0], ys - hflow[..., 1], cv2.INTER_CUBIC)
    return render(i0, xs - hflow[..., 0], ys - hflow[..., 1])


def consistency(i0: np.ndarray, i1: np.ndarray, g: np.ndarray) -> float:
    """Mean |I1(x + g(x)) - I0(x)| over pixels (I1 sampled bicubically): how well g explains the pair."""
    hh, ww = i0.shape
    xs, ys = np.meshgrid(np.arange(ww, dtype=np.float32), np.arange(hh, dtype=np.float32))
    warped = _sample(i1, xs + g[..., 0], ys + g[..., 1], cv2.INTER_CUBIC)
    inner = (slice(2, -2), slice(2, -2))
    return float(np.mean(np.abs(warped - i0)[inner]))


@dataclass(frozen=True)
class PaperPair:
    """A synthesised pair: grey frames (H, W) float32 in [0, 1]; ``gt`` (H, W, 2) is the scaled ground truth
    (unknown pixels >= 1e9, as in flow10.flo)."""

    name: str
    i0: np.ndarray
    i1: np.ndarray
    gt: np.ndarray
    scale: float = 1.0  # factor applied to the original ground truth


def make_pair(seq_dir: Path, renderer: str = "bandlimited") -> PaperPair:
    """The clean synthesised pair of one sequence (second frame by ``renderer``)."""
    i0 = to_grey(read_image(seq_dir / "frame10.png"), "frame10")
    g, scale = scale_to_unit(read_flo(seq_dir / "flow10.flo"))
    i1 = synthesise_second(i0, fill_unknown(g).astype(np.float32), renderer)
    return PaperPair(seq_dir.name, i0, i1.astype(np.float32), g, scale)


def add_noise(p: PaperPair, sigma: float = NOISE_SIGMA, seed: int = 0) -> PaperPair:
    """The noisy variant: N(0, sigma^2) added to both frames (seeded from the sequence name)."""
    rng = np.random.default_rng([seed, *p.name.encode()])
    n0 = rng.normal(0.0, sigma, p.i0.shape).astype(np.float32)
    n1 = rng.normal(0.0, sigma, p.i1.shape).astype(np.float32)
    return replace(p, i0=p.i0 + n0, i1=p.i1 + n1)


def load_pairs(data: Path, names: tuple[str, ...] = SEQUENCES,
               renderer: str = "bandlimited") -> list[PaperPair]:
    """The clean synthesised pairs of every named sequence under ``data``."""
    if not data.is_dir():
        raise SystemExit(f"Middlebury data not found at {data}; pass --data DIR")
    return [make_pair(data / n, renderer) for n in names]
