"""What ``keep_freed_memory`` (flow_node/process.py, applied by every executable's main()) buys a whole
``flow_bag eval``: paired whole processes, with it and with glibc's defaults, back to back.

    .venv-bench/bin/python -m bench.allocator --out bench/results/allocator.json

Writes one synthetic bag (``--scene``, ``--frames``, ``--size``) and evaluates it with ``--preset`` in fresh
interpreters that run ``flow_bag``'s main(); the "default" side replaces keep_freed_memory with a no-op first.
Per process: wall seconds, and minor page faults (fresh pages touched) from getrusage. Order alternates
(keep, default, default, keep, ...) so neither side always runs first.
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np

from .common import machine, write_json

_CHILD = """
import json, resource, sys, time
import flow_node.bag.cli as cli
if sys.argv[1] == "default":
    cli.keep_freed_memory = lambda: False
t0 = time.perf_counter()
code = cli.main(["eval", sys.argv[2], "-o", sys.argv[3], "--preset", sys.argv[4], "-q"])
print(json.dumps({"code": code, "seconds": time.perf_counter() - t0,
                  "minflt": resource.getrusage(resource.RUSAGE_SELF).ru_minflt}))
"""


def run_once(mode: str, bag: Path, out: Path, preset: str) -> dict[str, Any]:
    """One whole flow_bag eval process; its wall seconds (main() only) and page faults."""
    proc = subprocess.run([sys.executable, "-c", _CHILD, mode, str(bag), str(out), preset], capture_output=True,
                          text=True, check=True)
    res = json.loads(proc.stdout.strip().splitlines()[-1])
    if res["code"] != 0:
        raise RuntimeError(f"flow_bag eval failed in mode {mode}: {proc.stderr[-500:]}")
    return res


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--scene", default="objects")
    p.add_argument("--frames", type=int, default=30)
    p.add_argument("--size", default="640x480")
    p.add_argument("--preset", default="realtime")
    p.add_argument("--pairs", type=int, default=6)
    p.add_argument("--out", type=Path, default=Path("bench/results/allocator.json"))
    args = p.parse_args(argv)
    from flow_node.bag.cli import main as flow_bag

    started = time.monotonic()
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        bag = Path(tmp) / "bag"
        if flow_bag(["synth", "--scene", args.scene, "--frames", str(args.frames), "--size", args.size, str(bag)]):
            raise SystemExit("could not write the bag")
        run_once("keep", bag, Path(tmp) / "warm", args.preset)  # JIT cache and page cache warm for both sides
        for k in range(args.pairs):
            for mode in (("keep", "default") if k % 2 == 0 else ("default", "keep")):
                runs.append(run_once(mode, bag, Path(tmp) / f"out_{k}_{mode}", args.preset) | {"mode": mode, "pair": k})
                print(json.dumps(runs[-1]), flush=True)
    pairs = [{m: next(r for r in runs if r["pair"] == k and r["mode"] == m) for m in ("keep", "default")}
             for k in range(args.pairs)]
    ratios = [q["keep"]["seconds"] / q["default"]["seconds"] for q in pairs]
    summary = {"keep_over_default_seconds_per_pair": ratios,
               "keep_over_default_seconds_median": float(np.median(ratios)),
               "median_seconds": {m: float(np.median([q[m]["seconds"] for q in pairs])) for m in ("keep", "default")},
               "median_minflt": {m: float(np.median([q[m]["minflt"] for q in pairs])) for m in ("keep", "default")}}
    write_json(args.out, {"command": "python -m bench.allocator " + " ".join(sys.argv[1:]), "machine": machine(),
                          "bag": {"scene": args.scene, "frames": args.frames, "size": args.size},
                          "preset": args.preset, "bench_seconds": time.monotonic() - started, "runs": runs,
                          "summary": summary})
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
