"""A volume's first flow in a fresh process against its later ones, on two source trees (issue 29's masked
loads, docs/engine.md "Masked loads past an array"): is the first call slower than the warm ones?

    python -m bench.volume_first_call --tree /path/before --tree . --runs 3
        # -> bench/results/volume_first_call/volume_first_call.json (+ .md)

Each process imports flow_node from one tree (PYTHONPATH; its own NUMBA_CACHE_DIR, filled by a discarded
first process) and runs :func:`estimate_volume` three times on one pair of bench.volume's ``shear`` scene
(rendered once, shared by all processes): CPU time (time.process_time) of each call. Processes alternate
between the trees, per case and run. Cases: 64^3 (volume defaults on one thread, without and with
incompressibility) and 128^3 (defaults, one thread: the fused serial kernels; two: the parallel ones)."""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from .common import REPO, md_table, run_record, write_result
from .volume import CONFIG, INCOMPRESSIBILITY, scene

RESULTS = REPO / "bench" / "results" / "volume_first_call"
CASES = {"64": (64, 0.0, 1), "64 +incompressible": (64, INCOMPRESSIBILITY, 1), "128": (128, 0.0, 1),
         "128 two threads": (128, 0.0, 2)}  # size, incompressibility, threads (2: the parallel kernels)
_CHILD = """import json, sys, time
import numpy as np
from flow_node.core.volume import estimate_volume
from bench.volume import CONFIG
pair = np.load(sys.argv[1])
cfg = CONFIG.replace(incompressibility=float(sys.argv[2]), threads=int(sys.argv[3]))
times = []
for _ in range(3):
    t = time.process_time()
    estimate_volume(pair["v0"], pair["v1"], cfg)
    times.append(time.process_time() - t)
print(json.dumps(times))
"""


def child(tree: Path, pair: Path, inc: float, threads: int) -> list[float]:
    """CPU seconds of a fresh process's three calls on ``pair`` with flow_node from ``tree``."""
    env = dict(os.environ, PYTHONPATH=f"{tree}{os.pathsep}{REPO}", NUMBA_CACHE_DIR=str(tree / ".numba_cache"))
    out = subprocess.run([sys.executable, "-c", _CHILD, str(pair), str(inc), str(threads)], env=env, check=True,
                         capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--tree", type=Path, action="append", required=True, help="a source tree (twice or more)")
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--no-write", action="store_true")
    args = ap.parse_args(argv)
    record = run_record("bench.volume_first_call", argv)
    trees = [t.resolve() for t in args.tree]
    rows: dict[str, Any] = {}
    with tempfile.TemporaryDirectory() as tmp:
        for case, (size, inc, threads) in CASES.items():
            pair = Path(tmp) / f"pair{size}.npz"
            if not pair.exists():
                v0, v1, _, _ = scene("shear", (size,) * 3, 3)
                np.savez(pair, v0=v0, v1=v1)
            for tree in trees:  # fills each tree's cache for this path; not counted
                child(tree, pair, inc, threads)
            runs: dict[str, list[list[float]]] = {str(t): [] for t in trees}
            for _ in range(args.runs):
                for tree in trees:
                    runs[str(tree)].append(child(tree, pair, inc, threads))
            rows[case] = {t: {"calls_cpu_s": r, "first_median": statistics.median(x[0] for x in r),
                              "later_median": statistics.median(statistics.median(x[1:]) for x in r)}
                          for t, r in runs.items()}
    record["load_average_end"] = os.getloadavg()
    md = "\n".join(md_table(["case", "tree", "first call CPU s", "later calls CPU s", "first / later"],
                  [[case, t, f"{v['first_median']:.2f}", f"{v['later_median']:.2f}",
                    f"{v['first_median'] / v['later_median']:.2f}"] for case, r in rows.items() for t, v in r.items()]))
    write_result(None if args.no_write else RESULTS / "volume_first_call",
                 {**record, "config": str(CONFIG), "cases": rows}, md)


if __name__ == "__main__":
    main()
