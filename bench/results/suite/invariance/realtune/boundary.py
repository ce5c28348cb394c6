"""Where the error is on real_exact's tune pairs (task realtune): per grey pair, the mean AEE (px) of the
non-occluded background and foreground pixels by their distance (px) to the motion boundary.

    PYTHONPATH=$PWD .venv-bench/bin/python bench/results/suite/invariance/realtune/boundary.py rt=realtime fa=fastest
"""

from __future__ import annotations

import sys

import numpy as np
from scipy import ndimage

from bench.suite.methods import FlowNode, parse_method
from bench.suite.realexact import pairs, real_exact

BANDS = ((0, 3), (3, 8), (8, 16), (16, 10**9))


def main(methods: list[str]) -> None:
    specs = list(pairs("tune", False))
    samples = [s for s in real_exact("tune", False) if not s.name.endswith("_rgb")]
    for spec_str in methods:
        name, cfg = parse_method(spec_str)
        node = FlowNode(cfg)
        for sp, s in zip(specs, samples, strict=True):
            flow = np.asarray(node.run(node.prepare(s))[0], np.float32)
            known = np.all(np.abs(s.gt) < 1e9, axis=2)
            err = np.linalg.norm(flow - np.where(known[..., None], s.gt, 0), axis=2)
            fg = known & (s.gt[..., 0] == sp.fg_shift[0] / sp.factor) & (s.gt[..., 1] == sp.fg_shift[1] / sp.factor)
            bg = known & ~fg
            edge = ~known | (ndimage.binary_dilation(fg, iterations=1) & ~fg)
            dist = ndimage.distance_transform_edt(~edge)
            noc = known & ~s.occluded
            cells = []
            for lo, hi in BANDS:
                m = noc & (dist >= lo) & (dist < hi)
                b, f = m & bg, m & fg
                cells.append(f"d{lo}-{hi if hi < 10**9 else 'inf'}: bg {err[b].mean() if b.any() else 0:.3f} "
                             f"({b.sum()}) fg {err[f].mean() if f.any() else 0:.3f} ({f.sum()})")
            print(f"{name} {s.name} {s.f0.shape} bg {sp.shift} fg {sp.fg_shift} f {sp.factor} "
                  f"all {err[known].mean():.3f} occ {err[known & s.occluded].mean():.3f}")
            print("   ", " | ".join(cells))


if __name__ == "__main__":
    main(sys.argv[1:])
