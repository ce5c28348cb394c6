"""Throwaway (task censlarge): the large set per pair (AEE over valid ground truth, CPU ms of one warm call), grey
values, census, and census with init_min_motion 14 (toy_square_translation then gets its DIS initialisation). A
diagnostic, not a proposal: init_min_motion is chosen on the tune split (it decides Middlebury's fusion too), and the
large set is report-only. PYTHONPATH=. python bench/results/census_cost/censlarge/toy_init.py"""
import time

import numpy as np

from bench.suite import data as sdata
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

samples = sdata.large(False)
for preset in ("realtime", "fastest"):
    for label, over in (("grey", ["photometric=normalise"]), ("census", ["photometric=census"]),
                        ("census, init_min_motion 14", ["photometric=census", "init_min_motion=14"])):
        est = FlowEstimator(FlowConfig.preset(preset).replace(threads=1).with_overrides(over))
        aees, ts = [], []
        for s in samples:
            est.estimate(s.f0, s.f1)
            t = time.process_time()
            r = est.estimate(s.f0, s.f1)
            ts.append(time.process_time() - t)
            ok = np.all(np.abs(s.gt) < 1e5, axis=2)
            aees.append(float(np.hypot(*(r.flow - s.gt).transpose(2, 0, 1))[ok].mean()))
        print(f"{preset} {label}: AEE per pair " + " ".join(f"{a:.2f}" for a in aees)
              + f"; sum {sum(aees):.2f}; toy CPU {1e3 * ts[-1]:.1f} ms, all {1e3 * sum(ts):.0f} ms")
