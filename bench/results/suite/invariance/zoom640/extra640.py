"""Tune-only extra 640x480 fine pairs (task zoom640): the suite's fine_640 regime has 8 tune seeds (0-7) and no
failing zoom pair among them, so this scores more tune seeds (index = seed, as bench.suite.synthetic.fine draws
them: motion = index % 4, band = index % 3) for every candidate rule.

    PYTHONPATH=$PWD python bench/results/suite/invariance/zoom640/extra640.py FIRST LAST [NAMES [PRESET]] > extra640.txt

``rt`` is the preset's census rule before this task (census_empty_contrast 0); ran first on realtime, where
that was the preset itself.
"""

from __future__ import annotations

import os
import sys

import numpy as np

from bench.suite.synthetic import _pair, quantise
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

BASE = sys.argv[4] if len(sys.argv) > 4 else "realtime"  # the preset the candidates change
RT = FlowConfig.preset(BASE).replace(photometric="census", threads=1, census_empty_contrast=0.0)  # today's rule
CHANGES: dict[str, dict[str, float]] = {  # the s* ran at commit 0c03dcb (the census_coarse_scale experiment)
    "rt": {}, "s16": dict(census_coarse_scale=0.16), "s16only": dict(census_coarse_width=0, census_coarse_scale=0.16),
    "s30": dict(census_coarse_scale=0.3), "c002": dict(census_empty_contrast=0.002),
    "c001": dict(census_empty_contrast=0.001), "c003": dict(census_empty_contrast=0.003),
    "c005": dict(census_empty_contrast=0.005)}
first, last, step = int(sys.argv[1]), int(sys.argv[2]), int(os.environ.get("STEP", "1"))
names = sys.argv[3].split(",") if len(sys.argv) > 3 else ["rt", "s16", "s16only", "s30", "c002"]
CANDIDATES = {n: RT.replace(**CHANGES[n]) for n in names}
estimators = {k: FlowEstimator(c) for k, c in CANDIDATES.items()}
rows: dict[str, dict[str, list[float]]] = {}
print("seed label " + " ".join(CANDIDATES))
for k in range(first, last + 1, step):
    i0, i1, gt, label = _pair(k, k, (640, 480))
    f0, f1 = quantise(i0, 8), quantise(i1, 8)
    aee = {n: float(np.hypot(*np.moveaxis(e.estimate(f0, f1).flow - gt, -1, 0)).mean())
           for n, e in estimators.items()}
    for n, a in aee.items():
        rows.setdefault(label.split("/")[0], {}).setdefault(n, []).append(a)
    print(f"s{k} {label} " + " ".join(f"{a:.4f}" for a in aee.values()), flush=True)
print("\nmotion " + " ".join(CANDIDATES) + "  (mean AEE; worst)")
for motion, per in rows.items():
    print(motion + " " + " ".join(f"{np.mean(v):.4f}/{max(v):.3f}" for v in per.values()))
allv = {n: [a for per in rows.values() for a in per[n]] for n in CANDIDATES}
print("all " + " ".join(f"{np.mean(v):.4f}/{max(v):.3f}" for v in allv.values()))
