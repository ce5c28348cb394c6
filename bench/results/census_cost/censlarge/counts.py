"""Throwaway (task censlarge): per solve call, the level shape, iterations run, the form kind and the CPU time;
summed per (preset, term, data set).
PYTHONPATH=. python bench/results/census_cost/censlarge/counts.py large|fine_320|middlebury PRESETS ROUNDS"""
from __future__ import annotations

import sys
import time
from collections import defaultdict

from bench.suite import data as sdata
from bench.suite import synthetic
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig

DATA = {"large": lambda: sdata.large(False), "middlebury": lambda: sdata.middlebury(False),
        "fine_320": lambda: list(synthetic.fine("tune", False, (320, 240)))}


def main() -> None:
    which = sys.argv[1] if len(sys.argv) > 1 else "large"
    presets = sys.argv[2].split(",") if len(sys.argv) > 2 else ["realtime", "fastest"]
    rounds = int(sys.argv[3]) if len(sys.argv) > 3 else 3
    samples = DATA[which]()
    for preset in presets:
        recs: dict[str, list] = {}
        ests = {}
        for term in ("normalise", "census"):
            cfg = FlowConfig.preset(preset).replace(threads=1).with_overrides([f"photometric={term}"])
            backend = select_backend(cfg.backend, cfg.threads, cfg.parallel_min_pixels).resolved()
            rec: list = []
            solve = backend.solve

            def timed(problem, state, params, _solve=solve, _rec=rec):  # noqa: ANN001, ANN202
                t = time.process_time()
                k = _solve(problem, state, params)
                _rec.append((state.v.shape[1:], k, problem.q is not None, time.process_time() - t))
                return k
            ests[term] = FlowEstimator(cfg, backend=backend._replace(solve=timed))
            recs[term] = rec
        for s in samples:  # warm
            for term in ests:
                ests[term].estimate(s.f0, s.f1)
        for term in recs:
            recs[term].clear()
        for _ in range(rounds):
            for s in samples:
                for term in ests:
                    ests[term].estimate(s.f0, s.f1)
        print(f"## {which} {preset} ({len(samples)} pairs, {rounds} rounds; per round)")
        print("| term | shape | calls | iterations | ms | us/iter | ns/(iter px) |")
        print("|---|---|---:|---:|---:|---:|---:|")
        for term, rec in recs.items():
            agg: dict = defaultdict(lambda: [0, 0, 0.0])
            for shape, k, _, t in rec:
                a = agg[shape]
                a[0] += 1
                a[1] += k
                a[2] += t
            tot = [0, 0, 0.0]
            for shape in sorted(agg, key=lambda s: -s[0] * s[1]):
                c, k, t = agg[shape]
                tot = [tot[0] + c, tot[1] + k, tot[2] + t]
                print(f"| {term} | {shape[1]}x{shape[0]} | {c / rounds:.1f} | {k / rounds:.0f} "
                      f"| {1e3 * t / rounds:.2f} | {1e6 * t / k:.1f} | {1e9 * t / k / (shape[0] * shape[1]):.2f} |")
            print(f"| {term} | all | {tot[0] / rounds:.1f} | {tot[1] / rounds:.0f} | {1e3 * tot[2] / rounds:.2f} | | |")
        print()


if __name__ == "__main__":
    main()
