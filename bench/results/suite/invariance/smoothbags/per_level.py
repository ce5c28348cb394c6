"""Diagnosis only (task smoothbags): per pyramid level AEE of realtime census / grey on the rendered tune scenes.

    PYTHONPATH=$PWD python bench/results/suite/invariance/smoothbags/per_level.py NAME [SCENES [SEEDS]]

NAME as in tuneset.py (grey, census, or key=value+...). Wraps refine.solve_level to record the flow after each
level and compares it (upsampled to full size) with the ground truth; prints the mean over pairs per level, and
the final AEE split into pixels where frame 0's 3x3 contrast is low (< 0.01 of the range) and the rest.
"""

from __future__ import annotations

import sys

import numpy as np
from tuneset import add, config, pairs

from flow_node.core import refine
from flow_node.core.api import FlowEstimator
from flow_node.core.pyramid import resize_flow

records: list[tuple[int, tuple[int, int], np.ndarray]] = []  # (level, shape, flow after it) of the last pair
solve_level = refine.solve_level
refine.solve_level = lambda pyr, level, cfg, backend, state, *a, **kw: (  # noqa: E731 - record, then return
    solve_level(pyr, level, cfg, backend, state, *a, **kw),
    records.append((level, pyr.shapes[level], state.v.copy())))[0]
name = sys.argv[1]
add(name)
scenes = sys.argv[2].split(",") if len(sys.argv) > 2 else ["deformation", "rotation", "zoom"]
seeds = [int(s) for s in sys.argv[3].split(",")] if len(sys.argv) > 3 else list(range(101, 109))
est = FlowEstimator(config(name))
for scene in scenes:
    per: dict[str, list[float]] = {}
    flat_err, tex_err, flat_frac = [], [], []
    for _s, _seed, _k, f0, f1, gt in pairs([scene], seeds):
        records.clear()
        flow = est.estimate(f0, f1).flow
        err = np.hypot(*np.moveaxis(flow - gt, -1, 0))
        for level, shape, v in records:
            up = resize_flow(v, gt.shape[:2])
            lerr = float(np.mean(np.hypot(*(up - gt.transpose(2, 0, 1)))))
            per.setdefault(f"L{level}({shape[1]}px)", []).append(lerr)
        g = (f0 @ np.array([0.299, 0.587, 0.114]) if f0.ndim == 3 else f0).astype(np.float64)
        g = (g - g.min()) / max(np.ptp(g), 1e-9)
        pad = np.pad(g, 1, mode="edge")
        d = [pad[1 + dy:1 + dy + g.shape[0], 1 + dx:1 + dx + g.shape[1]] - g
             for dy in (-1, 0, 1) for dx in (-1, 0, 1) if dy or dx]
        s = np.sqrt(np.mean(np.square(d), axis=0))
        low = s < 0.01
        flat_frac.append(float(low.mean()))
        flat_err.append(float(err[low].mean()) if low.any() else np.nan)
        tex_err.append(float(err[~low].mean()))
        per.setdefault("final", []).append(float(err.mean()))
    print(f"{name} {scene}: " + " ".join(f"{k} {np.mean(v):.4f}" for k, v in per.items())
          + f" | low-contrast px {np.mean(flat_frac):.2f}: AEE {np.nanmean(flat_err):.4f}, rest {np.mean(tex_err):.4f}",
          flush=True)
