"""Do the numba backend's threads pay? ``realtime`` and ``fastest`` with the solver's parallel-level threshold
(``numba_backend.PARALLEL_MIN_PIXELS``) and the thread count varied, beside OpenCV DIS medium, interleaved
round-robin on the same frames.

    .venv-bench/bin/python -m bench.threads --out bench/results/threads.json

Regimes of the suite: fine textures at 320x240 and 640x480 (``tune`` seeds, 6 pairs each), the 8 Middlebury
pairs (584x388 and 640x480) and the 7 large-motion pairs of ../shared/data/large (up to 1241x376). Each variant
is one (preset, threads, threshold) setting applied before its call; the flow must not depend on it (checked:
the AEE is reported per variant). Run it on an otherwise idle machine: the question is whether a second core
helps when it is free.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core import numba_backend as nb
from flow_node.core.config import FlowConfig

from .common import machine, write_json
from .suite import data, synthetic
from .suite.methods import build

THRESHOLDS = (120_000, 70_000, 15_000)  # 120k = the shipped value; 70k threads a 320x240 finest level
PRESETS = ("realtime", "fastest")


def regimes(pairs: int) -> dict[str, list[Any]]:
    """The pairs of each regime measured."""
    return {"fine_320": list(synthetic.fine("tune", False, (320, 240)))[:pairs],
            "fine_640": list(synthetic.fine("tune", False, (640, 480)))[:pairs],
            "middlebury": data.middlebury(False), "large": data.large(False)}


def measure(name: str, samples: list[Any], rounds: int) -> dict[str, Any]:
    """Median ms per call and mean AEE of every variant on one regime's pairs."""
    configs = {f"{p} {n}": FlowConfig.preset(p).replace(threads=n) for p in PRESETS for n in (1, 2)}
    made = build(configs, ("dis_medium",))
    variants: dict[str, tuple[Any, int, int]] = {"dis_medium": (made["dis_medium"], 0, 0)}
    for preset in PRESETS:
        variants[f"{preset} 1 thread"] = (made[f"{preset} 1"], 1, THRESHOLDS[0])
        for thr in THRESHOLDS:
            variants[f"{preset} 2 threads from {thr // 1000}k px"] = (made[f"{preset} 2"], 2, thr)
    times: dict[str, list[float]] = {k: [] for k in variants}
    errors: dict[str, list[float]] = {k: [] for k in variants}
    shipped = nb.PARALLEL_MIN_PIXELS
    try:
        for r in range(rounds):
            for s in samples:
                for variant, (method, threads, thr) in variants.items():
                    if threads:  # the thread count is the variant's config's
                        nb.PARALLEL_MIN_PIXELS = thr
                    prepared = method.prepare(s)
                    t0 = time.perf_counter()
                    out = method.run(prepared)
                    times[variant].append(time.perf_counter() - t0)
                    if r == 0:
                        flow = out[0] if isinstance(out, tuple) else out
                        known = np.all(np.isfinite(s.gt) & (np.abs(s.gt) < 1e9), axis=-1)
                        errors[variant].append(float(np.mean(np.linalg.norm(flow - s.gt, axis=-1)[known])))
    finally:
        nb.PARALLEL_MIN_PIXELS = shipped
    dis = float(np.median(times["dis_medium"]))
    return {"regime": name, "pairs": len(samples), "rounds": rounds,
            "variants": {k: {"ms_median": 1e3 * float(np.median(v)), "over_dis_medium": float(np.median(v)) / dis,
                             "mean_aee": float(np.mean(errors[k]))} for k, v in times.items()}}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--rounds", type=int, default=5, help="round-robin rounds over the pairs")
    p.add_argument("--pairs", type=int, default=6)
    p.add_argument("--out", type=Path, default=Path("bench/results/threads.json"))
    args = p.parse_args(argv)
    started = time.monotonic()
    results = [measure(name, samples, args.rounds) for name, samples in regimes(args.pairs).items()]
    write_json(args.out, {"command": "python -m bench.threads " + " ".join(sys.argv[1:]), "machine": machine(),
                          "bench_seconds": time.monotonic() - started, "results": results})
    for res in results:
        for name, v in res["variants"].items():
            print(f"{res['regime']:10s} {name:34s} {v['ms_median']:8.2f} ms {v['over_dis_medium']:5.2f}x DIS medium  "
                  f"AEE {v['mean_aee']:.4f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
