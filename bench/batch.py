"""Batch evaluation on Dask: throughput with 1 and 2 workers, and the Dask layer against a plain loop.

    .venv/bin/python -m bench.batch [--bags 40] [--distinct 8] [--frames 50] [--size 160x120]
                                    [--preset realtime] [--repeats 2] [--out bench/results/batch.json]

Writes ``--distinct`` synthetic bags (flow_bag synth, scenes in turn, seeds 0..) and copies them up to
``--bags``, then evaluates the whole folder, each time into a fresh output (nothing cached), as:

- ``loop``: one process running ``evaluate_bag`` for every job in a plain for loop: the same per-bag work
  (single-bag eval, key, report) without Dask, in the environment the embedded cluster gives its workers
  (``WORKER_ENV``: one numeric thread, glibc keeping freed memory): the peer of the 1-worker run;
- ``dask-1`` / ``dask-2``: ``flow_bag eval FOLDER --workers N`` (embedded LocalCluster, N single-threaded
  worker processes).

Each variant is a fresh interpreter started the same way, timed from start to exit (what a user waits for:
imports, cluster start and stop, JIT cache loads included); variants are interleaved, their order rotated
every repeat. Reported: bags per minute, the Dask layer's cost (dask-1 over loop, per repeat and of the
medians) and the 2-worker speed-up. The machine is shared: compare the paired ratios, not absolute times.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from flow_node.bag.batch import WORKER_ENV, evaluate_bag, find_bags, make_jobs
from flow_node.bag.batch_report import write_batch_report
from flow_node.bag.evaluate import EvalOptions
from flow_node.bag.scenes import SCENES
from flow_node.bag.synth import SynthSpec, write_synth_bag
from flow_node.core.config import FlowConfig

REPO = Path(__file__).resolve().parent.parent
VARIANTS = ("loop", "dask-1", "dask-2")


def make_bags(folder: Path, count: int, distinct: int, frames: int, size: tuple[int, int]) -> None:
    """``distinct`` synthetic bags, copied (content-identical, other names) up to ``count`` bags."""
    for k in range(distinct):
        write_synth_bag(folder / f"bag_{k:03d}", SynthSpec(scene=SCENES[k % len(SCENES)], frames=frames, size=size,
                                                           seed=k))
    for k in range(distinct, count):
        shutil.copytree(folder / f"bag_{k % distinct:03d}", folder / f"bag_{k:03d}")


def loop_main(bags: str, out: str, preset: str) -> None:
    """The peer: every job in a plain loop in this process, then the same batch report."""
    start = time.monotonic()
    configs = [FlowConfig.preset(preset)]
    opts = EvalOptions(progress=False)
    jobs = make_jobs(find_bags([bags], exclude=out), Path(out), configs, opts)
    Path(out).mkdir(parents=True)
    outcomes = [evaluate_bag(job) for job in jobs]
    write_batch_report(outcomes, Path(out), configs, time.monotonic() - start, "plain loop, 1 process")


def command(variant: str, bags: Path, out: Path, preset: str) -> list[str]:
    if variant == "loop":
        return [sys.executable, "-m", "bench.batch", "--loop-run", str(bags), str(out), "--preset", preset]
    return [sys.executable, "-m", "flow_node.bag", "eval", str(bags), "--output", str(out), "--preset", preset,
            "--workers", variant.split("-")[1], "-q"]


def run_variant(variant: str, bags: Path, out: Path, preset: str) -> dict[str, Any]:
    """One timed run in a fresh interpreter; the numbers of its batch report."""
    shutil.rmtree(out, ignore_errors=True)
    start = time.monotonic()
    env = os.environ | WORKER_ENV if variant == "loop" else None  # the loop runs as a worker process would
    proc = subprocess.run(command(variant, bags, out, preset), cwd=REPO, env=env, capture_output=True, text=True)
    wall = time.monotonic() - start
    if proc.returncode != 0:
        raise SystemExit(f"{variant} failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    report = json.loads((out / "report.json").read_text())
    tasks = [r["task_seconds"] for r in report["bags"]]
    return {"variant": variant, "process_seconds": wall, "batch_seconds": report["wall_seconds"],
            "task_seconds_sum": sum(tasks), "bags": report["counts"]["done"],
            "bags_per_minute": 60.0 * report["counts"]["done"] / wall, "scheduler": report["scheduler"]}


def summarise(runs: list[dict[str, Any]], repeats: int) -> dict[str, Any]:
    """Medians per variant and the paired ratios."""
    by = {v: [r for r in runs if r["variant"] == v] for v in VARIANTS}
    med = {v: statistics.median(r["process_seconds"] for r in rs) for v, rs in by.items()}
    paired = [by["dask-1"][k]["process_seconds"] / by["loop"][k]["process_seconds"] for k in range(repeats)]
    return {
        "median_process_seconds": med,
        "bags_per_minute": {v: 60.0 * by[v][0]["bags"] / med[v] for v in VARIANTS},
        "dask1_over_loop_per_repeat": paired,
        "dask_overhead_percent": 100.0 * (med["dask-1"] / med["loop"] - 1.0),
        "speedup_2_workers_over_1": med["dask-1"] / med["dask-2"],
        "per_bag_seconds_in_tasks": {v: statistics.median(r["task_seconds_sum"] for r in by[v]) / by[v][0]["bags"]
                                     for v in VARIANTS},
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bags", type=int, default=40)
    p.add_argument("--distinct", type=int, default=8)
    p.add_argument("--frames", type=int, default=50)
    p.add_argument("--size", default="160x120")
    p.add_argument("--preset", default="realtime")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--out", default=str(REPO / "bench" / "results" / "batch.json"))
    p.add_argument("--loop-run", nargs=2, metavar=("BAGS", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.loop_run:
        loop_main(*args.loop_run, args.preset)
        return 0
    w, h = (int(x) for x in args.size.split("x"))
    os.environ.setdefault("NUMBA_CACHE_DIR", str(REPO / ".venv" / "numba_cache"))
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        bags = Path(tmp) / "bags"
        make_bags(bags, args.bags, args.distinct, args.frames, (w, h))
        run_variant("loop", bags, Path(tmp) / "warm", args.preset)  # JIT cache and file cache warm
        runs = []
        for r in range(args.repeats):
            order = VARIANTS[r % 3:] + VARIANTS[:r % 3]
            for v in order:
                runs.append(run_variant(v, bags, Path(tmp) / "out", args.preset) | {"repeat": r})
                print(json.dumps(runs[-1]), flush=True)
    result = {"command": "python -m bench.batch " + " ".join(argv if argv is not None else sys.argv[1:]),
              "bags": args.bags, "distinct": args.distinct, "frames": args.frames, "size": args.size,
              "preset": args.preset, "repeats": args.repeats, "machine": platform.platform(),
              "cores": os.cpu_count(), "runs": runs, "summary": summarise(runs, args.repeats)}
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
