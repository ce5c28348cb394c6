"""Diagnosis (task q640): per pyramid level of quality's census pyramid (15 levels, 0.8), the median 3x3 contrast
census.median_contrast of both frames of a 640x480 tune pair, for census_antialias values.

    PYTHONPATH=$PWD python bench/results/suite/invariance/q640/level_contrast.py SEED AA[,AA...]
"""

from __future__ import annotations

import sys

from bench.suite.synthetic import _pair, quantise
from flow_node.core.census import median_contrast
from flow_node.core.config import FlowConfig
from flow_node.core.pyramid import build_pyramid, pyramid_shapes

seed = int(sys.argv[1])
i0, i1, _, label = _pair(seed, seed, (640, 480))
f0, f1 = (quantise(i, 8).astype("float32") / 255.0 for i in (i0, i1))
cfg = FlowConfig.preset("quality")
shapes = pyramid_shapes(f0.shape, cfg.levels, cfg.scale_factor, cfg.min_size)
for aa in (int(a) for a in sys.argv[2].split(",")):
    n = len(shapes) - 1 if aa < 0 else aa
    p0, p1 = (build_pyramid(f, shapes, cfg.scale_factor, n) for f in (f0, f1))
    cells = [f"{s[1]}px {min(median_contrast(a[None]), median_contrast(b[None])):.4f}"
             for s, a, b in zip(shapes, p0, p1, strict=True)]
    print(f"s{seed} {label} aa={aa}: " + " ".join(cells))
