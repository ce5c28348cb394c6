"""Task litesc's probe: how far a tune family's change of frame 2 moves the census signature on each pyramid level,
as an equivalent displacement in full-resolution px (approximate; for the summary's "why", not a benchmark).

For every tune real_exact_photometric pair: frame 2 unchanged (U) and under a tune variant (V), both normalised on
their own 2-98 % range (as the photometric stage does, roughly), the stream_lite pyramid (every step anti-aliased),
the signature F (EPS 0.007) on each level; r_L = mean |F(V_L) - F(U_L)|, s_L = mean |F(U_L shifted 0.1 level px) -
F(U_L)|; equivalent displacement e_L = 0.1 * r_L / s_L level px = 0.1 * 2^L * r_L / s_L full px.
Run: PYTHONPATH=. python bench/results/suite/invariance/litesc/window_probe.py
"""
from __future__ import annotations

from collections import defaultdict

import cv2
import numpy as np

from bench.suite.realexact import real_exact_photometric
from flow_node.core.census import CensusParams, signature
from flow_node.core.config import FlowConfig
from flow_node.core.pyramid import build_pyramid, pyramid_shapes


def norm(img: np.ndarray) -> np.ndarray:
    """(H, W) -> float32 on its own 2-98 % range."""
    x = np.asarray(img, np.float64) / (255.0 if img.dtype == np.uint8 else 1.0)
    lo, hi = np.percentile(x, (2, 98))
    return ((x - lo) / max(hi - lo, 1e-6)).astype(np.float32)


def main() -> None:
    cfg = FlowConfig.preset("stream_lite")
    params = CensusParams(eps=cfg.census_eps, delta=cfg.census_delta)
    base: dict[str, np.ndarray] = {}
    acc: dict[tuple[str, int], list[float]] = defaultdict(list)
    for s in real_exact_photometric("tune", False):
        if s.f1.ndim != 2:
            continue
        key = s.name.split("_f")[0]
        if s.variant == "unchanged":
            base[key] = s.f1
            continue
        u, v = norm(base[key]), norm(s.f1)
        shapes = pyramid_shapes(u.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
        pu, pv = (build_pyramid(x, shapes, cfg.scale_factor, len(shapes)) for x in (u, v))
        for lev in range(0, 3):
            fu, fv = signature(pu[lev], params), signature(pv[lev], params)
            h, w = pu[lev].shape
            shifted = cv2.warpAffine(pu[lev], np.float32([[1, 0, 0.1], [0, 1, 0]]), (w, h),
                                     flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
            fs = signature(shifted, params)
            c = (slice(3, -3), slice(3, -3))
            r = float(np.mean(np.abs(fv - fu)[:, c[0], c[1]]))
            sh = float(np.mean(np.abs(fs - fu)[:, c[0], c[1]]))
            acc[(s.variant.split("/")[0], lev)].append(0.1 * 2**lev * r / sh)
    fams = sorted({f for f, _ in acc})
    print("| family | level 0 (full) | level 1 (half: fastest) | level 2 (quarter: stream_lite) | 2 / 1 |")
    print("|---|---:|---:|---:|---:|")
    for f in fams:
        e = [float(np.mean(acc[(f, lev)])) for lev in range(3)]
        print(f"| {f} | {e[0]:.3f} | {e[1]:.3f} | {e[2]:.3f} | {e[2] / e[1]:.2f} |")


if __name__ == "__main__":
    main()
