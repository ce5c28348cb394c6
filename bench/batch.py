"""Batch evaluation on Dask: the Dask layer against a plain loop on one worker, and throughput with 1 and 2 workers.
How the runs are paired and what each ratio means: docs/bags.md, "eval over many bags: a batch on Dask".

    .venv/bin/python -m bench.batch [--size 160x120:24 --size 320x240:12] [--repeats 3]
                                    [--variants loop,dask-1,dask-2] [--out bench/results/batch/batch.json]
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
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
from flow_node.bag.results import EvalOptions
from flow_node.bag.scenes import SCENES
from flow_node.bag.synth import SynthSpec, write_synth_bag
from flow_node.core.config import FlowConfig

from .common import REPO, run_record, write_json, wxh

VARIANTS = ("loop", "dask-1", "dask-2")  # order() pairs them
DISTINCT, FRAMES, PRESET = 8, 50, "realtime"


def make_bags(folder: Path, count: int, distinct: int, frames: int, size: tuple[int, int]) -> None:
    """``distinct`` synthetic bags, copied (content-identical, other names) up to ``count`` bags."""
    for k in range(distinct):
        write_synth_bag(folder / f"bag_{k:03d}", SynthSpec(scene=SCENES[k % len(SCENES)], frames=frames, size=size,
                                                           seed=k))
    for k in range(distinct, count):
        shutil.copytree(folder / f"bag_{k % distinct:03d}", folder / f"bag_{k:03d}")


def loop_main(bags: str, out: str) -> None:
    """The peer: every job in a plain loop in this process, then the same batch report."""
    start = time.monotonic()
    configs = [FlowConfig.preset(PRESET)]
    opts = EvalOptions(progress=False)
    jobs = make_jobs(find_bags([bags], exclude=out), Path(out), configs, opts)
    Path(out).mkdir(parents=True)
    outcomes = [evaluate_bag(job) for job in jobs]
    write_batch_report(outcomes, Path(out), configs, time.monotonic() - start, "plain loop, 1 process")


def command(variant: str, bags: Path, out: Path) -> list[str]:
    if variant == "loop":
        return [sys.executable, "-m", "bench.batch", "--loop-run", str(bags), str(out)]
    return [sys.executable, "-m", "flow_node.bag", "eval", str(bags), "--output", str(out), "--preset", PRESET,
            "--workers", variant.split("-")[1], "-q"]


def run_variant(variant: str, bags: Path, out: Path) -> dict[str, Any]:
    """One timed run in a fresh interpreter; the numbers of its batch report."""
    shutil.rmtree(out, ignore_errors=True)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.monotonic()
    proc = subprocess.run(command(variant, bags, out), cwd=REPO, capture_output=True, text=True)
    wall = time.monotonic() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)  # the process and its worker processes, reaped
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if proc.returncode != 0:
        raise SystemExit(f"{variant} failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    report = json.loads((out / "report.json").read_text())
    tasks = [r["task_seconds"] for r in report["bags"]]
    return {"variant": variant, "process_seconds": wall, "cpu_seconds": cpu, "batch_seconds": report["wall_seconds"],
            "task_seconds_sum": sum(tasks), "bags": report["counts"]["done"],
            "bags_per_minute": 60.0 * report["counts"]["done"] / wall, "scheduler": report["scheduler"]}


def order(repeat: int, variants: tuple[str, ...] = VARIANTS) -> tuple[str, ...]:
    """A/B/C then C/B/A: loop and dask-1 always back to back, and so are dask-1 and dask-2."""
    return variants if repeat % 2 == 0 else variants[::-1]


def _ratios(by: dict[str, list[dict[str, Any]]], a: str, b: str, repeats: int,
            what: str = "process_seconds") -> list[float]:
    return [by[a][k][what] / by[b][k][what] for k in range(repeats)]


def summarise(runs: list[dict[str, Any]], repeats: int) -> dict[str, Any]:
    """Medians per variant, bags per minute, the paired ratios dask-1 / loop (wall, CPU seconds of the process
    and its workers, seconds outside the tasks) and dask-1 / dask-2 per repeat and their medians (docs/bags.md)."""
    variants = [v for v in VARIANTS if any(r["variant"] == v for r in runs)]
    by = {v: [r for r in runs if r["variant"] == v] for v in variants}
    med = {v: statistics.median(r["process_seconds"] for r in rs) for v, rs in by.items()}
    out: dict[str, Any] = {"median_process_seconds": med,
                           "bags_per_minute": {v: 60.0 * by[v][0]["bags"] / med[v] for v in variants},
                           "seconds_outside_tasks": {v: [r["process_seconds"] - r["task_seconds_sum"] for r in rs]
                                                     for v, rs in by.items() if v != "dask-2"}}
    if "dask-1" in by and "loop" in by:
        over_loop = _ratios(by, "dask-1", "loop", repeats)
        outside = [a - b for a, b in zip(out["seconds_outside_tasks"]["dask-1"], out["seconds_outside_tasks"]["loop"],
                                         strict=True)]
        cpu_over_loop = _ratios(by, "dask-1", "loop", repeats, "cpu_seconds")
        out |= {"dask1_over_loop_per_repeat": over_loop, "dask1_over_loop_median": statistics.median(over_loop),
                "dask1_over_loop_cpu_per_repeat": cpu_over_loop,
                "dask1_over_loop_cpu_median": statistics.median(cpu_over_loop),
                "dask1_minus_loop_outside_tasks_per_repeat": outside,
                "dask1_minus_loop_outside_tasks_median": statistics.median(outside),
                "dask1_minus_loop_outside_tasks_over_loop_median": statistics.median(
                    d / r["process_seconds"] for d, r in zip(outside, by["loop"], strict=True))}
    if "dask-1" in by and "dask-2" in by:
        speedup = _ratios(by, "dask-1", "dask-2", repeats)
        out |= {"speedup_2_over_1_workers_per_repeat": speedup,
                "speedup_2_over_1_workers_median": statistics.median(speedup)}
    return out


def _size(text: str) -> tuple[int, int, int]:
    size, _, count = text.partition(":")
    return *wxh(size), int(count or 24)


def measure_size(tmp: Path, size: tuple[int, int, int], args: argparse.Namespace) -> dict[str, Any]:
    """The paired whole-process runs on BAGS bags of one size."""
    w, h, count = size
    bags = tmp / f"bags_{w}x{h}"
    make_bags(bags, count, min(DISTINCT, count), FRAMES, (w, h))
    run_variant("loop", bags, tmp / "warm")  # JIT cache and file cache warm
    runs = []
    for r in range(args.repeats):
        for v in order(r, tuple(args.variants.split(","))):
            runs.append(run_variant(v, bags, tmp / "out") | {"repeat": r})
            print(json.dumps(runs[-1] | {"size": f"{w}x{h}"}), flush=True)
    result = {"size": f"{w}x{h}", "bags": count, "runs": runs,
              "summary": summarise(runs, args.repeats) if runs else None}
    shutil.rmtree(bags)
    print(json.dumps(result["summary"]), flush=True)
    return result


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--size", type=_size, action="append", metavar="WxH:BAGS",
                   help="frame size and bag count; repeatable (default: 160x120:24 and 320x240:12)")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--variants", default=",".join(VARIANTS), help="a subset of loop,dask-1,dask-2, in that order")
    p.add_argument("--out", default=str(REPO / "bench" / "results" / "batch" / "batch.json"))
    p.add_argument("--loop-run", nargs=2, metavar=("BAGS", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.loop_run:
        loop_main(*args.loop_run)
        return 0
    if any(os.environ.get(k) != v for k, v in WORKER_ENV.items()):  # run as the workers do (malloc reads it at start)
        os.execve(sys.executable, [sys.executable, "-m", "bench.batch", *sys.argv[1:]],
                  os.environ | WORKER_ENV | {"NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR",
                                                                               str(REPO / ".venv" / "numba_cache"))})
    started, head = time.monotonic(), run_record("bench.batch", argv)
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        sizes = [measure_size(Path(tmp), size, args) for size in args.size or [(160, 120, 24), (320, 240, 12)]]
    write_json(Path(args.out), {**head, "frames": FRAMES, "distinct": DISTINCT, "preset": PRESET,
                                "repeats": args.repeats, "platform": platform.platform(),
                                "load_average_at_end": os.getloadavg(), "bench_seconds": time.monotonic() - started,
                                "sizes": sizes})
    for size in sizes:
        print(size["size"], size["bags"], "bags:", json.dumps(size["summary"], indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
