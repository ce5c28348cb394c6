"""Tune-only 640x480 fine pairs for quality census candidates (task q640), as zoom640's extra640.py draws them
(index = seed < 1000: motion = index % 4, band = index % 3), quality census at alpha 0.045.

    PYTHONPATH=$PWD python bench/results/suite/invariance/q640/cand640.py SEEDS NAME=k=v;k=v NAME2=... > out.txt

SEEDS: comma list or FIRST-LAST; a candidate with no changes is ``base`` (today's quality census).
"""

from __future__ import annotations

import sys
import time

import numpy as np

from bench.suite.synthetic import _pair, quantise
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

BASE = FlowConfig.preset("quality").replace(photometric="census", alpha=0.045, threads=1)
spec = sys.argv[1]
seeds = (list(range(int(spec.split("-")[0]), int(spec.split("-")[1]) + 1)) if "-" in spec
         else [int(s) for s in spec.split(",")])


def parse(arg: str) -> tuple[str, FlowConfig]:
    name, _, rest = arg.partition("=")
    kw = {}
    for kv in filter(None, rest.split(";")):
        k, v = kv.split("=")
        kw[k] = type(getattr(BASE, k))(v)
    return name, BASE.replace(**kw)


cands = dict(parse(a) for a in sys.argv[2:]) or {"base": BASE}
est = {n: FlowEstimator(c) for n, c in cands.items()}
print("seed label " + " ".join(cands))
allv: dict[str, list[float]] = {n: [] for n in cands}
times: dict[str, float] = {n: 0.0 for n in cands}
for k in seeds:
    i0, i1, gt, label = _pair(k, k, (640, 480))
    f0, f1 = quantise(i0, 8), quantise(i1, 8)
    row = []
    for n, e in est.items():
        t = time.process_time()
        a = float(np.hypot(*np.moveaxis(e.estimate(f0, f1).flow - gt, -1, 0)).mean())
        times[n] += time.process_time() - t
        allv[n].append(a)
        row.append(f"{a:.4f}")
    print(f"s{k} {label} " + " ".join(row), flush=True)
print("mean " + " ".join(f"{np.mean(v):.4f}" for v in allv.values()))
print("worst " + " ".join(f"{max(v):.3f}" for v in allv.values()))
print("cpu_s " + " ".join(f"{t:.1f}" for t in times.values()))
