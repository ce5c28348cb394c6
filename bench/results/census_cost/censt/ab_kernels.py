"""Same-process A/B of the census kernels: grey values, census with this tree's numba_census and census with another
copy of the module (main's, before this round), interleaved per pair, on the 8 Middlebury pairs, one thread.

    python bench/results/census_cost/censt/ab_kernels.py BASE_MODULE.py --rounds 7 [--clock cpu|wall]

BASE_MODULE.py: main's flow_node/core/numba_census.py with its relative imports made absolute
(``sed 's/^from \\.\\([a-z_]*\\) import/from flow_node.core.\\1 import/'``) and its scratch names prefixed
(``sed 's/scratch("census\\./scratch("main_census./'``, so that the two keep their own buffers); the census
estimator of that name runs with the backend's level signature and census form taken from it (everything else is
this tree's). Prints, per preset, the median over rounds of each term's total over the 8 pairs and the medians of
the rounds' ratios.
"""

from __future__ import annotations

import argparse
import importlib.util
import statistics
import sys
import time

from bench.suite.data import middlebury
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig

CLOCKS = {"wall": time.perf_counter, "cpu": time.process_time}


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("base")
    ap.add_argument("--rounds", type=int, default=7)
    ap.add_argument("--presets", default="realtime,fastest,quality")
    ap.add_argument("--clock", choices=tuple(CLOCKS), default="cpu")
    args = ap.parse_args()
    spec = importlib.util.spec_from_file_location("base_numba_census", args.base)
    base = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = base  # numba's cache of its kernels finds the module by name when it reloads them
    spec.loader.exec_module(base)
    tick = CLOCKS[args.clock]
    samples = middlebury(False)
    for preset in args.presets.split(","):
        cfg = FlowConfig.preset(preset).replace(threads=1)
        backend = select_backend("numba", 1).resolved()
        ests = {"grey": FlowEstimator(cfg, backend=backend),
                "census": FlowEstimator(cfg.replace(photometric="census"), backend=backend),
                "census_main": FlowEstimator(cfg.replace(photometric="census"), backend=backend._replace(
                    signature=base.level_signature_numba, census_form=base.census_form_numba))}
        names = list(ests)
        for s in samples:  # warm-up
            for n in names:
                ests[n].estimate(s.f0, s.f1)
        totals = {n: [] for n in names}
        for r in range(args.rounds):
            acc = dict.fromkeys(names, 0.0)
            for k, s in enumerate(samples):
                order = names[(k + r) % 3:] + names[:(k + r) % 3]
                for n in order:
                    t0 = tick()
                    ests[n].estimate(s.f0, s.f1)
                    acc[n] += tick() - t0
            for n in names:
                totals[n].append(acc[n])
        med = {n: statistics.median(v) * 1e3 for n, v in totals.items()}
        ratio = {n: statistics.median(c / g for c, g in zip(totals[n], totals["grey"], strict=True)) for n in names}
        new_main = statistics.median(a / b for a, b in zip(totals["census"], totals["census_main"], strict=True))
        print(f"{preset}: grey {med['grey']:.1f} ms, census {med['census']:.1f} ms ({ratio['census']:.3f}x grey), "
              f"census with main's kernels {med['census_main']:.1f} ms ({ratio['census_main']:.3f}x grey); "
              f"census / census with main's kernels {new_main:.3f} (median of {args.rounds} rounds' ratios, "
              f"clock {args.clock})", flush=True)


if __name__ == "__main__":
    main()
