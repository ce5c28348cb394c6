"""One-off (round onesig): per census preset and large-set pair, the flow's SHA-256 (16 hex digits), the
initialisation and the fusions' candidate shares, as JSON into hash_<tag>.json (run in each tree).

    PYTHONPATH=$PWD python bench/results/census_cost/onesig/accuracy/flowhash.py <tag>
"""

import hashlib
import json
import sys

import numpy as np

from bench.suite.data import large
from flow_node.core import FlowConfig, FlowEstimator

PRESETS = (("realtime_census", "realtime", {}), ("fastest_census", "fastest", {}),
           ("quality_census", "quality", {"alpha": 0.045}))


def main() -> None:
    out = {}
    samples = large(False)
    for name, base, extra in PRESETS:
        est = FlowEstimator(FlowConfig.preset(base).replace(photometric="census", **extra))
        for s in samples:
            res = est.estimate(s.f0, s.f1)
            out[f"{name}/{s.name}"] = [hashlib.sha256(np.ascontiguousarray(res.flow).tobytes()).hexdigest()[:16],
                                       res.stats.init, round(float(res.stats.init_share), 6),
                                       round(float(res.stats.final_init_share), 6)]
    with open(f"hash_{sys.argv[1]}.json", "w") as f:
        json.dump(out, f, indent=1)


if __name__ == "__main__":
    main()
