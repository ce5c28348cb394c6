"""Cold start (issue 29): what a fresh process pays for its first flow, per preset, on a large-motion pair
(initialisation and fusion run) and a small one, against a warm call in one process. The columns and the target:
docs/engine.md, "Compiled kernels: the on-disk cache and threads".

    python -m bench.cold_start                   # -> bench/results/cold_start/cold_start.json, a table on stdout
    python -m bench.cold_start --runs 5 --no-new-install
    python -m bench.cold_start --no-bytecode     # every child compiles flow_node's sources (PYTHONDONTWRITEBYTECODE)
"""

from __future__ import annotations

import argparse
import os
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from .common import DEFAULT_DATA, REPO, run_record, write_json
from .suite.data import LARGE_DATA

PRESETS = ("quality", "balanced", "realtime", "fastest")
PAIRS = {"large": (LARGE_DATA / "kitti2012_000000", "frame0.png", "frame1.png"),
         "small": (DEFAULT_DATA / "Dimetrodon", "frame10.png", "frame11.png")}
_WARM = """import contextlib, io, os, sys, tempfile, time
from flow_node.cli.estimate import main, read_frame
from flow_node.core import FlowConfig, FlowEstimator
est = FlowEstimator(FlowConfig.preset(sys.argv[3]))
i0, i1 = read_frame(sys.argv[1]), read_frame(sys.argv[2])
seconds = [est.estimate_grey(i0, i1).seconds for _ in range(4)]
cli = []
with tempfile.TemporaryDirectory() as out, contextlib.redirect_stdout(io.StringIO()):
    for _ in range(4):
        t = time.perf_counter()
        main([sys.argv[1], sys.argv[2], "-o", os.path.join(out, "flow.flo"), "--preset", sys.argv[3]])
        cli.append(time.perf_counter() - t)
print(sorted(seconds[1:])[1], sorted(cli[1:])[1])"""
_START = """import numpy as np
import flow_node.cli.estimate
from flow_node import process
from flow_node.core import numba_backend, numba_fusion
process.defer_kernel_bitcode()
numba_backend.image_gradient_numba(np.zeros((4, 4), np.float32), "central")
process.skip_final_collection()"""


def env(cache: Path, bytecode: bool = True) -> dict[str, str]:
    """The children's environment: this tree first on the path, numba's cache in ``cache``; Python's bytecode
    cached as an installed package's is (pip compiles it at install), unless not ``bytecode``: then every process
    compiles flow_node's sources again (PYTHONDONTWRITEBYTECODE=1, as on this machine's shells and CI's)."""
    base = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    return {**base, "PYTHONPATH": str(REPO), "NUMBA_CACHE_DIR": str(cache), "OMP_WAIT_POLICY": "passive",
            **({} if bytecode else {"PYTHONDONTWRITEBYTECODE": "1"})}


def run(args: list[str], cache: Path, bytecode: bool = True) -> tuple[float, str]:
    """Wall seconds and stdout of one fresh ``python args`` process (:func:`env`)."""
    start = time.perf_counter()
    out = subprocess.run([sys.executable, *args], env=env(cache, bytecode), capture_output=True, text=True, check=True)
    return time.perf_counter() - start, out.stdout


def estimate(pair: str, preset: str, cache: Path, bytecode: bool = True) -> tuple[float, float]:
    """One fresh ``flow_estimate -v``: wall seconds and the engine's seconds it reports."""
    folder, f0, f1 = PAIRS[pair]
    with tempfile.TemporaryDirectory() as out:
        wall, text = run(["-m", "flow_node.cli.estimate", str(folder / f0), str(folder / f1), "-o",
                          str(Path(out) / "flow.flo"), "--preset", preset, "-v"], cache, bytecode)
    match = re.search(r"time=([0-9.]+)s", text)
    assert match, text
    return wall, float(match.group(1))


def measure(pair: str, preset: str, cache: Path, runs: int, new_install: bool, bytecode: bool = True
            ) -> dict[str, Any]:
    """One row: new install (own empty cache), fresh processes and warm calls (``cache``, populated); every
    child with Python's bytecode cached or not (:func:`env`)."""
    row: dict[str, Any] = {"pair": pair, "preset": preset, "bytecode": bytecode}
    if new_install:
        with tempfile.TemporaryDirectory() as empty:
            row["new_install_wall_s"], row["new_install_call_s"] = estimate(pair, preset, Path(empty), bytecode)
    estimate(pair, preset, cache, bytecode)  # populates the shared cache for this path (and the bytecode's)
    folder, f0, f1 = PAIRS[pair]
    fresh, start, warm, warm_cli = [], [], [], []
    for _ in range(runs):  # interleaved: a busy moment of a shared machine hits all three alike
        fresh.append(estimate(pair, preset, cache, bytecode))
        start.append(run(["-c", _START], cache, bytecode)[0])
        engine, cli = run(["-c", _WARM, str(folder / f0), str(folder / f1), preset], cache, bytecode)[1].split()
        warm.append(float(engine))
        warm_cli.append(float(cli))
    row["fresh_wall_s"] = statistics.median(w for w, _ in fresh)
    row["fresh_call_s"] = statistics.median(c for _, c in fresh)
    row["start_s"] = statistics.median(start)
    row["warm_call_s"] = statistics.median(warm)
    row["warm_cli_s"] = statistics.median(warm_cli)
    row["target_s"] = 1.5 * row["warm_call_s"] + row["start_s"]
    row["met"] = row["fresh_wall_s"] <= row["target_s"]
    row["target_cli_s"] = 1.5 * row["warm_cli_s"] + row["start_s"]
    row["met_cli"] = row["fresh_wall_s"] <= row["target_cli_s"]
    return row


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--runs", type=int, default=3, help="fresh processes per row (median)")
    p.add_argument("--presets", default=",".join(PRESETS))
    p.add_argument("--no-new-install", action="store_true", help="skip the empty-cache first calls (slow)")
    p.add_argument("--no-bytecode", action="store_true", help="every child compiles flow_node's sources again "
                   "(PYTHONDONTWRITEBYTECODE=1) instead of reading cached bytecode as an installed package does")
    p.add_argument("--out", type=Path, default=Path("bench/results/cold_start/cold_start.json"))
    args = p.parse_args(argv)
    head = run_record("bench.cold_start", argv)  # the command, and the load as it starts
    with tempfile.TemporaryDirectory() as tmp:
        rows = [measure(pair, preset, Path(tmp), args.runs, not args.no_new_install, not args.no_bytecode)
                for preset in args.presets.split(",") for pair in PAIRS]
    write_json(args.out, {**head, "rows": rows})
    print("pair   preset    new install  fresh wall  first call  warm call  start  1.5 warm + start"
          "  warm CLI  1.5 warm CLI + start")
    for r in rows:
        new = f"{r['new_install_wall_s']:9.2f} s" if "new_install_wall_s" in r else "        -  "
        print(f"{r['pair']:6s} {r['preset']:9s} {new} {r['fresh_wall_s']:9.3f} s {r['fresh_call_s']:9.3f} s "
              f"{r['warm_call_s']:8.3f} s {r['start_s']:5.3f} s {r['target_s']:6.3f} s",
              "met   " if r["met"] else "missed",
              f"{r['warm_cli_s']:8.3f} s {r['target_cli_s']:6.3f} s", "met" if r["met_cli"] else "missed")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
