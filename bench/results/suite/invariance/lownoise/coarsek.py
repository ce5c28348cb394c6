"""Task lownoise: the noise floor scaled by F on the levels coarser than the finest solved one only (K F there, K on the
finest), by monkeypatch on refine.census_problem; a screen on the tune split's unchanged and sensor_noise pairs.

    python bench/results/suite/invariance/lownoise/coarsek.py PRESET OUT.json F,...
"""

import json
import sys

import numpy as np

from bench.suite import metrics
from bench.suite.photometric import UNCHANGED, middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core import refine
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

REGIMES = {"photometric_real": middlebury_photometric, "real_exact_photometric": real_exact_photometric,
           "photometric": synthetic_photometric}
_census = refine.census_problem
SCALE = {"f": 1.0}


def census_problem(c0, c1, cfg, backend, robust, eps_floor=0.0, finest=False, *a, **kw):
    return _census(c0, c1, cfg, backend, robust, eps_floor * (1.0 if finest else SCALE["f"]), finest, *a, **kw)


refine.census_problem = census_problem


def main() -> None:
    preset, out, fs = sys.argv[1], sys.argv[2], [float(f) for f in sys.argv[3].split(",")]
    est = FlowEstimator(FlowConfig.preset(preset))
    res: dict = {}
    for regime, gen in REGIMES.items():
        samples = [s for s in gen("tune", False) if s.variant == UNCHANGED or s.variant.startswith("sensor_noise/")]
        for f in fs:
            SCALE["f"] = f
            rows: dict[str, list[float]] = {"unchanged": [], "sensor_noise": []}
            for s in samples:
                flow = est.estimate(s.f0, s.f1).flow
                rows[s.variant.split("/")[0]].append(metrics.score_pair(flow, s.gt, s.occluded)["aee"])
            m = {k: float(np.mean(x)) for k, x in rows.items()}
            res.setdefault(regime, {})[f"c{f:g}"] = m
            print(f"{regime} coarse x{f:g}: unchanged {m['unchanged']:.4f} noisy {m['sensor_noise']:.4f}", flush=True)
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
