"""``python -m bench.suite.parallel_levels``: the numba solver's and linearisation's parallel kernels against
their serial ones on the small levels a stream refines (issue 26: does a lower ``parallel_min_pixels`` make
the stream at 320x240 faster?).

    python -m bench.suite.parallel_levels                       # 160x120 and 80x60, 400 rounds
    python -m bench.suite.parallel_levels --shapes 120x160,60x80,240x320 --out bench/results/suite/stream/stream320

On each level shape (H x W) one random L1-TV problem is solved for 10 primal-dual iterations
(numba_backend.solve_numba) and one pair linearised (linearise_numba, interpolated gradients, bspline), each
once serial (min_pixels above the level) and once on 2 threads (min_pixels 1), interleaved, ``--rounds``
times. Reported: the minimum, 25th percentile and median per call in ms. On a shared machine the minimum is
the best estimate of an uncontended (quiet-machine) call for both: load only adds time, and adds more to the
parallel kernels (a region waits for its slowest thread). The process lets idle numba threads sleep, as the
product's executables do (bench/__init__.py), and keeps freed memory as the node does.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

from flow_node.core import numba_backend as nb
from flow_node.core.models import MODEL_SPECS
from flow_node.core.solver import PDState, Problem, SolveParams
from flow_node.process import keep_freed_memory

from ..common import machine, write_json

MODES = {"serial": 1 << 40, "parallel": 1}  # min_pixels


def measure(shape: tuple[int, int], rounds: int, seed: int = 0) -> dict[str, dict[str, list[float]]]:
    """Seconds per call of the 10-iteration solve and of the linearisation on ``shape`` (H, W), per mode."""
    rng = np.random.default_rng(seed)
    h, w = shape
    f32 = np.float32
    prob = Problem((0.2 * rng.standard_normal((2, h, w))).astype(f32), (0.05 * rng.standard_normal((h, w))).astype(f32))
    state = PDState.zeros(MODEL_SPECS["l1_tv"], shape)
    state.v = (0.5 * rng.standard_normal((2, h, w))).astype(f32)
    params = SolveParams(MODEL_SPECS["l1_tv"], 0.07, 0.3, "isotropic", 10, 0.0)
    i0, i1 = rng.random((h, w), dtype=f32), rng.random((1, h, w), dtype=f32)
    g0, flow = rng.random((2, h, w), dtype=f32), (0.5 * rng.standard_normal((2, h, w))).astype(f32)
    out: dict[str, dict[str, list[float]]] = {m: {"solve": [], "linearise": []} for m in MODES}
    with nb.thread_count(2):
        for r in range(rounds + 1):  # round 0 compiles / warms up, not counted
            for mode, min_pixels in MODES.items():
                start = time.perf_counter()
                nb.solve_numba(prob, state, params, min_pixels=min_pixels)
                mid = time.perf_counter()
                nb.linearise_numba(i0, i1, g0, flow, "interpolated", min_pixels=min_pixels)
                end = time.perf_counter()
                if r:
                    out[mode]["solve"].append(mid - start)
                    out[mode]["linearise"].append(end - mid)
    return out


def summary(times: list[float]) -> dict[str, float]:
    ms = 1e3 * np.asarray(times)
    return {"min": float(ms.min()), "p25": float(np.percentile(ms, 25)), "median": float(np.median(ms))}


def markdown(res: dict[str, Any]) -> str:
    lines = ["# Parallel against serial kernels on small levels (ms per call)", "", f"`{res['command']}`", "",
             f"Load: {res['load']} (1, 5, 15 min); {res['rounds']} interleaved rounds", "",
             "| level | kernel | serial min / p25 / median | 2 threads min / p25 / median |", "|---|---|---|---|"]
    for shape, per in res["levels"].items():
        for kernel in ("solve", "linearise"):
            cells = [" / ".join(f"{per[m][kernel][k]:.3f}" for k in ("min", "p25", "median")) for m in MODES]
            label = "10 iterations" if kernel == "solve" else "linearisation"
            lines.append(f"| {shape} | {label} | {cells[0]} | {cells[1]} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m bench.suite.parallel_levels", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--shapes", default="120x160,60x80", help="comma-separated HxW level shapes")
    ap.add_argument("--rounds", type=int, default=400)
    ap.add_argument("--out", type=Path, default=None, help="directory for parallel_levels.{json,md}")
    args = ap.parse_args(argv)
    keep_freed_memory()
    shapes = [tuple(int(x) for x in s.split("x")) for s in args.shapes.split(",")]
    levels = {}
    for shape in shapes:
        raw = measure(shape, args.rounds)
        levels[f"{shape[1]}x{shape[0]}"] = {m: {k: summary(v) for k, v in per.items()} for m, per in raw.items()}
    res = {"command": "python -m bench.suite.parallel_levels " + " ".join(argv if argv is not None else sys.argv[1:]),
           "load": ", ".join(f"{x:.1f}" for x in os.getloadavg()), "rounds": args.rounds, "machine": machine(),
           "levels": levels}
    md = markdown(res)
    print(md)
    if args.out is not None:
        write_json(args.out / "parallel_levels.json", res)
        (args.out / "parallel_levels.md").write_text(md)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
