"""Task lownoise: FlowConfig variants on the tune split's unchanged and sensor_noise pairs only (a quick screen; the
candidate is then run through the whole tune split with bench.suite).

    python bench/results/suite/invariance/lownoise/sweep.py PRESET OUT.json 'name:field=value,field=value' ...
"""

from __future__ import annotations

import json
import sys
import time

import numpy as np

from bench.suite import metrics
from bench.suite.photometric import UNCHANGED, middlebury_photometric, synthetic_photometric
from bench.suite.realexact import real_exact_photometric
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig

REGIMES = {"photometric_real": middlebury_photometric, "real_exact_photometric": real_exact_photometric,
           "photometric": synthetic_photometric}


def parse(spec: str) -> tuple[str, dict]:
    name, _, fields = spec.partition(":")
    out = {}
    for kv in filter(None, fields.split(",")):
        k, v = kv.split("=")
        out[k] = type(getattr(FlowConfig(), k))(v) if not isinstance(getattr(FlowConfig(), k), bool) else v == "1"
    return name, out


def main() -> None:
    preset, out = sys.argv[1], sys.argv[2]
    specs = [parse(s) for s in sys.argv[3:]]
    base = FlowConfig.preset(preset)
    ests = {n: FlowEstimator(base.replace(**f)) for n, f in specs}
    for e in ests.values():
        e.warmup()
    res: dict = {}
    t0 = time.time()
    for regime, gen in REGIMES.items():
        samples = [s for s in gen("tune", False) if s.variant == UNCHANGED or s.variant.startswith("sensor_noise/")]
        for n, e in ests.items():
            rows: dict[str, list[float]] = {"unchanged": [], "sensor_noise": []}
            for s in samples:
                flow = e.estimate(s.f0, s.f1).flow
                rows[s.variant.split("/")[0]].append(metrics.score_pair(flow, s.gt, s.occluded)["aee"])
            m = {k: float(np.mean(x)) for k, x in rows.items()}
            res.setdefault(regime, {})[n] = m
            print(f"{time.time() - t0:7.1f}s {regime} {n}: unchanged {m['unchanged']:.4f} noisy "
                  f"{m['sensor_noise']:.4f} ({m['sensor_noise'] / m['unchanged']:.2f}x)", flush=True)
    with open(out, "w") as fh:
        json.dump(res, fh, indent=1)


if __name__ == "__main__":
    main()
