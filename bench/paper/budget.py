"""Iteration budget study for the paper reproduction: ``python -m bench.paper.budget``.

For each algorithm of Table 1 and each budget of primal-dual iterations per warp, the mean AEE over the 8
sequences with the static (mapped) weights, on the clean and the noisy pairs, in the protocol of
``python -m bench.paper`` (same pairs, presmoothing, BASE settings). The per-algorithm budgets in
algorithms.py are read off this table: the smallest budget after which four times more changes the mean AEE
by less than ~10 %. Writes bench/results/paper/budget.json.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from ..common import DEFAULT_DATA, REPO, SEQUENCES, machine, write_json
from .algorithms import ALGORITHMS
from .protocol import add_noise, load_pairs
from .run import Runner

BUDGETS: dict[str, tuple[int, ...]] = {
    "l2_l2": (50, 200, 1000, 4000),
    "l2_tv": (50, 200, 1000),
    "l2_tv_bregman": (50, 200, 1000),
    "l1_tv": (50, 200),
    "l1_tv_l2": (50, 200, 800),
    "l1_tv_tv": (50, 150, 300, 1200),
}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--algorithms", nargs="*", default=list(BUDGETS), choices=list(BUDGETS))
    ap.add_argument("--out", type=Path, default=REPO / "bench" / "results" / "paper" / "budget.json")
    args = ap.parse_args(argv)
    clean = load_pairs(args.data, tuple(SEQUENCES), "cubic")  # the paper's synthesis, as budget.json was
    variants = {"clean": clean, "noisy": [add_noise(p) for p in clean]}
    runner = Runner()
    out: dict[str, dict[str, dict[str, list[float]]]] = {}
    start = time.perf_counter()
    for alg in (a for a in ALGORITHMS if a.key in args.algorithms):
        out[alg.key] = {}
        for its in BUDGETS[alg.key]:
            row = {v: [runner.score(alg.config(iterations=its), p)["aee"] for p in pairs]
                   for v, pairs in variants.items()}
            out[alg.key][str(its)] = row
            print(f"{alg.label:14s} {its:5d} iterations/warp: mean AEE clean {np.mean(row['clean']):.4f} "
                  f"noisy {np.mean(row['noisy']):.4f}; worst sequence {max(row['clean']):.4f} / "
                  f"{max(row['noisy']):.4f}", flush=True)
    write_json(args.out, {"command": "python -m bench.paper.budget", "machine": machine(),
                          "sequences": [p.name for p in clean], "aee": out,
                          "seconds": time.perf_counter() - start})


if __name__ == "__main__":
    main()
