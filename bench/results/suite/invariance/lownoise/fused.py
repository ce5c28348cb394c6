"""Task lownoise: whether any DIS candidate is fused (FlowResult.stats.init non-empty) on the tune split's
sensor_noise pairs, per general preset (the summary's "init, fusion: 0 % by construction"). Printed: quality,
balanced, realtime and fastest each 32 pairs, fused on 0.

    python bench/results/suite/invariance/lownoise/fused.py
"""

from bench.suite.photometric import middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

for p in ("quality", "balanced", "realtime", "fastest"):
    e = FlowEstimator(FlowConfig.preset(p))
    n = fused = 0
    offered = set()
    for gen in (middlebury_photometric, real_exact_photometric, synthetic_photometric):
        for s in gen("tune", False):
            if s.variant.startswith("sensor_noise/"):
                r = e.estimate(s.f0, s.f1)
                n += 1
                fused += bool(r.stats.init)
                offered.add(r.stats.init_offered)
    print(p, n, "pairs, fused on", fused, "offered", offered)
