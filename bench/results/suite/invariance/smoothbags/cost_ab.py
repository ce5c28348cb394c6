"""CPU-time A/B (task smoothbags): realtime census today (DELTA 0.2, alpha 0.04) against DELTA 0.07 / alpha 0.08 on
the 8 Middlebury pairs, one thread, interleaved per pair (A B B A alternating by round), ROUNDS rounds after a warm-up;
prints the median per-pair ratio and the summed CPU times.

    PYTHONPATH=$PWD ROUNDS=3 python bench/results/suite/invariance/smoothbags/cost_ab.py
"""

from __future__ import annotations

import os
import time

import numpy as np

from bench.suite.data import middlebury
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

CEN = FlowConfig.preset("realtime").replace(photometric="census", threads=1)
EST = {"today": FlowEstimator(CEN.replace(census_delta=0.2, census_alpha=0.0)), "smooth": FlowEstimator(CEN)}
pairs = middlebury(False)
for s in pairs:  # warm-up (compilation, caches)
    for e in EST.values():
        e.estimate(s.f0, s.f1)
cpu: dict[str, list[float]] = {k: [] for k in EST}
ratios = []
for r in range(int(os.environ.get("ROUNDS", "3"))):
    for s in pairs:
        order = list(EST) if (r % 2 == 0) else list(EST)[::-1]
        t = {}
        for k in order:
            t0 = time.process_time()
            EST[k].estimate(s.f0, s.f1)
            t[k] = time.process_time() - t0
            cpu[k].append(t[k])
        ratios.append(t["smooth"] / t["today"])
print(f"median per-pair CPU ratio smooth/today {np.median(ratios):.3f} (n={len(ratios)}); summed CPU s: "
      + ", ".join(f"{k} {sum(v):.2f}" for k, v in cpu.items()))
