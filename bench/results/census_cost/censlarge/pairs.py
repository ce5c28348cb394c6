"""Throwaway (task censlarge): per pair, grey (normalise) against census: the whole call's and the solve's CPU time
(median over rounds, interleaved), the initialisation used and the iterations per level.
PYTHONPATH=. python bench/results/census_cost/censlarge/pairs.py large|fine_320|middlebury realtime,fastest ROUNDS"""
from __future__ import annotations

import statistics
import sys
import time

from bench.suite import data as sdata
from bench.suite import synthetic
from flow_node.core.api import FlowEstimator
from flow_node.core.backends import select_backend
from flow_node.core.config import FlowConfig

DATA = {"large": lambda: sdata.large(False), "middlebury": lambda: sdata.middlebury(False),
        "fine_320": lambda: list(synthetic.fine("tune", False, (320, 240)))}


def main() -> None:
    which, presets, rounds = sys.argv[1], sys.argv[2].split(","), int(sys.argv[3])
    samples = DATA[which]()
    for preset in presets:
        ests, solve_t = {}, {}
        for term in ("normalise", "census"):
            cfg = FlowConfig.preset(preset).replace(threads=1).with_overrides([f"photometric={term}"])
            backend = select_backend(cfg.backend, cfg.threads, cfg.parallel_min_pixels).resolved()
            acc = [0.0]

            def timed(problem, state, params, _solve=backend.solve, _acc=acc):  # noqa: ANN001, ANN202
                t = time.process_time()
                k = _solve(problem, state, params)
                _acc[0] += time.process_time() - t
                return k
            ests[term] = FlowEstimator(cfg, backend=backend._replace(solve=timed))
            solve_t[term] = acc
        info, tot, sol = {}, {}, {}
        for s in samples:
            for term in ests:
                r = ests[term].estimate(s.f0, s.f1)
                info[s.name, term] = (r.stats.init or "-", r.stats.iterations)
        for rnd in range(rounds):
            for k, s in enumerate(samples):
                for term in (("normalise", "census") if (k + rnd) % 2 == 0 else ("census", "normalise")):
                    solve_t[term][0] = 0.0
                    t = time.process_time()
                    ests[term].estimate(s.f0, s.f1)
                    tot.setdefault((s.name, term), []).append(time.process_time() - t)
                    sol.setdefault((s.name, term), []).append(solve_t[term][0])
        print(f"## {which} {preset}: per pair, CPU ms (median of {rounds} rounds, interleaved)\n")
        print("| pair | grey total | census total | ratio | grey solve | census solve | grey init / its "
              "| census init / its |")
        print("|---|---:|---:|---:|---:|---:|---|---|")
        sums = {"g": 0.0, "c": 0.0, "gs": 0.0, "cs": 0.0}
        for s in samples:
            g, c = (statistics.median(tot[s.name, t]) for t in ests)
            gs, cs = (statistics.median(sol[s.name, t]) for t in ests)
            sums["g"] += g
            sums["c"] += c
            sums["gs"] += gs
            sums["cs"] += cs
            gi, ci = info[s.name, "normalise"], info[s.name, "census"]
            print(f"| {s.name} | {1e3 * g:.1f} | {1e3 * c:.1f} | {c / g:.2f} | {1e3 * gs:.1f} | {1e3 * cs:.1f} "
                  f"| {gi[0]} {gi[1]} | {ci[0]} {ci[1]} |")
        print(f"| sum | {1e3 * sums['g']:.1f} | {1e3 * sums['c']:.1f} | {sums['c'] / sums['g']:.2f} "
              f"| {1e3 * sums['gs']:.1f} | {1e3 * sums['cs']:.1f} | | |\n")


if __name__ == "__main__":
    main()
