"""Batch evaluation on Dask: throughput with 1 and 2 workers, and the Dask layer against a plain loop.

    .venv/bin/python -m bench.batch [--bags 24] [--distinct 8] [--frames 50] [--size 160x120]
                                    [--preset realtime] [--repeats 3] [--out bench/results/batch.json]

Writes ``--distinct`` synthetic bags (flow_bag synth, scenes in turn, seeds 0..) and copies them up to
``--bags``. Every run writes into a fresh output (nothing cached). Two measurements:

1. **Throughput**, whole processes: ``flow_bag eval FOLDER --workers N`` (embedded LocalCluster, N = 1, 2)
   and ``loop`` (one process running ``evaluate_bag`` for every job in a plain for loop: the same per-bag
   work without Dask), each a fresh interpreter timed from start to exit (imports, cluster start and stop,
   JIT cache loads included); interleaved, the order rotated every repeat. Bags per minute.
2. **The Dask layer's cost, paired bag by bag**: with ``dask scheduler`` and one ``dask worker`` running
   (separate processes, so that no scheduler thread shares this process's GIL), every bag is evaluated
   twice in turn (who goes first alternates): once by ``evaluate_bag`` in this process, once submitted to
   the worker and waited for (``Client.submit(...).result()``: pickling, scheduling, the worker's thread,
   the outcome's transfer). The two runs of a bag are seconds apart, so the machine's
   load (shared by other jobs) is the same for both; the median of the per-bag ratios is the cost per
   bag. The fixed cost of a batch is measured beside it: ``import distributed`` in a fresh interpreter,
   and starting and closing the cluster (median of 3). Both processes run in ``WORKER_ENV`` (one numeric
   thread, glibc keeping freed memory): this process re-executes itself with it.

The machine is shared: compare the paired ratios, not absolute times.
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
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

from flow_node.bag.batch import WORKER_ENV, BagJob, dask_client, evaluate_bag, find_bags, make_jobs
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
    proc = subprocess.run(command(variant, bags, out, preset), cwd=REPO, capture_output=True, text=True)
    wall = time.monotonic() - start
    if proc.returncode != 0:
        raise SystemExit(f"{variant} failed ({proc.returncode}): {proc.stderr.strip()[-2000:]}")
    report = json.loads((out / "report.json").read_text())
    tasks = [r["task_seconds"] for r in report["bags"]]
    return {"variant": variant, "process_seconds": wall, "batch_seconds": report["wall_seconds"],
            "task_seconds_sum": sum(tasks), "bags": report["counts"]["done"],
            "bags_per_minute": 60.0 * report["counts"]["done"] / wall, "scheduler": report["scheduler"]}


def summarise(runs: list[dict[str, Any]], repeats: int) -> dict[str, Any]:
    """Medians per variant, bags per minute, the 2-worker speed-up (paired per repeat and of the medians)."""
    by = {v: [r for r in runs if r["variant"] == v] for v in VARIANTS}
    med = {v: statistics.median(r["process_seconds"] for r in rs) for v, rs in by.items()}
    return {
        "median_process_seconds": med,
        "bags_per_minute": {v: 60.0 * by[v][0]["bags"] / med[v] for v in VARIANTS},
        "speedup_2_over_1_workers_per_repeat": [by["dask-1"][k]["process_seconds"] / by["dask-2"][k]["process_seconds"]
                                                for k in range(repeats)],
        "speedup_2_over_1_workers": med["dask-1"] / med["dask-2"],
        "dask1_over_loop_per_repeat": [by["dask-1"][k]["process_seconds"] / by["loop"][k]["process_seconds"]
                                       for k in range(repeats)],
    }


def _timed(fn: Any) -> float:
    start = time.monotonic()
    fn()
    return time.monotonic() - start


def _relocated(job: BagJob, out: Path) -> BagJob:
    return BagJob(job.bag, job.name, str(out / "bags" / job.name), job.configs, job.opts, job.config_digest)


@contextmanager
def external_worker(work: Path) -> Iterator[str]:
    """`dask scheduler` and one `dask worker --no-nanny --nthreads 1` (distributed's CLIs) on 127.0.0.1, so
    that this process holds no scheduler thread while it runs the loop; the worker inherits WORKER_ENV (no
    nanny to override it). Yields the scheduler address; stops both."""
    dask = str(Path(sys.executable).with_name("dask"))
    info = work / "scheduler.json"
    work.mkdir(parents=True, exist_ok=True)
    procs = [subprocess.Popen([dask, "scheduler", "--host", "127.0.0.1", "--port", "0", "--no-dashboard",
                               "--scheduler-file", str(info)], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        deadline = time.monotonic() + 60
        while not info.exists() and time.monotonic() < deadline:
            time.sleep(0.2)
        address = json.loads(info.read_text())["address"]
        procs.append(subprocess.Popen([dask, "worker", address, "--no-nanny", "--nthreads", "1", "--host",
                                       "127.0.0.1", "--no-dashboard"], stdout=subprocess.DEVNULL,
                                      stderr=subprocess.DEVNULL))
        yield address
    finally:
        for proc in procs[::-1]:
            proc.terminate()
            try:
                proc.wait(timeout=15)
            except subprocess.TimeoutExpired:
                proc.kill()


def paired_layer_cost(bags: Path, work: Path, preset: str) -> dict[str, Any]:
    """Per bag: seconds evaluated here vs submitted to one Dask worker, alternating; and the fixed costs of
    a batch (import of distributed, embedded cluster start and close)."""
    jobs = make_jobs(find_bags([str(bags)]), work / "loop", [FlowConfig.preset(preset)], EvalOptions(progress=False))
    pairs = []
    with external_worker(work) as address, dask_client(address) as client:
        evaluate_bag(_relocated(jobs[0], work / "warm-loop"))  # JIT cache and imports warm on both sides
        client.submit(evaluate_bag, _relocated(jobs[0], work / "warm-dask"), pure=False).result()
        for k, job in enumerate(jobs):
            here, there = _relocated(job, work / "loop"), _relocated(job, work / "dask")
            loop = lambda j=here: evaluate_bag(j)  # noqa: E731
            dask = lambda j=there: client.submit(evaluate_bag, j, pure=False).result()  # noqa: E731
            first, second = (loop, dask) if k % 2 == 0 else (dask, loop)
            t1, t2 = _timed(first), _timed(second)
            pairs.append({"bag": job.name, "loop": t1 if k % 2 == 0 else t2, "dask": t2 if k % 2 == 0 else t1})
    # after the pairs: a closed LocalCluster leaves threads in this process that would slow the loop
    imports = [float(subprocess.run([sys.executable, "-c", "import time; t = time.perf_counter(); import distributed; "
                                     "print(time.perf_counter() - t)"], capture_output=True, text=True,
                                    check=True).stdout) for _ in range(3)]
    starts, closes = [], []
    for _ in range(3):
        start = time.monotonic()
        ctx = dask_client(None, 1)
        ctx.__enter__()
        starts.append(time.monotonic() - start)
        closes.append(_timed(lambda c=ctx: c.__exit__(None, None, None)))
    ratios = [p["dask"] / p["loop"] for p in pairs]
    per_bag = statistics.median(p["loop"] for p in pairs)
    fixed = statistics.median(imports) + statistics.median(starts) + statistics.median(closes)
    return {
        "pairs": pairs, "import_distributed_seconds": imports, "cluster_start_seconds": starts,
        "cluster_close_seconds": closes, "per_bag_loop_seconds_median": per_bag,
        "per_bag_dask_over_loop_median": statistics.median(ratios),
        "per_bag_dask_over_loop_sum": sum(p["dask"] for p in pairs) / sum(p["loop"] for p in pairs),
        "fixed_seconds": fixed,
        # batch size from which the fixed cost is <= 5 %, counting no per-bag gain (a ratio < 1 as 1)
        "bags_for_5_percent": fixed / (per_bag * max(0.05 - max(statistics.median(ratios) - 1.0, 0.0), 1e-9)),
    }


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--bags", type=int, default=24)
    p.add_argument("--distinct", type=int, default=8)
    p.add_argument("--frames", type=int, default=50)
    p.add_argument("--size", default="160x120")
    p.add_argument("--preset", default="realtime")
    p.add_argument("--repeats", type=int, default=3)
    p.add_argument("--out", default=str(REPO / "bench" / "results" / "batch.json"))
    p.add_argument("--paired-only", action="store_true", help="skip the throughput runs")
    p.add_argument("--loop-run", nargs=2, metavar=("BAGS", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.loop_run:
        loop_main(*args.loop_run, args.preset)
        return 0
    if any(os.environ.get(k) != v for k, v in WORKER_ENV.items()):  # run as the workers do (malloc reads it at start)
        os.execve(sys.executable, [sys.executable, "-m", "bench.batch", *sys.argv[1:]],
                  os.environ | WORKER_ENV | {"NUMBA_CACHE_DIR": os.environ.get("NUMBA_CACHE_DIR",
                                                                               str(REPO / ".venv" / "numba_cache"))})
    w, h = (int(x) for x in args.size.split("x"))
    with tempfile.TemporaryDirectory(prefix="bench_batch_") as tmp:
        bags = Path(tmp) / "bags"
        make_bags(bags, args.bags, args.distinct, args.frames, (w, h))
        run_variant("loop", bags, Path(tmp) / "warm", args.preset)  # JIT cache and file cache warm
        runs = []
        for r in range(0 if args.paired_only else args.repeats):
            order = VARIANTS[r % 3:] + VARIANTS[:r % 3]
            for v in order:
                runs.append(run_variant(v, bags, Path(tmp) / "out", args.preset) | {"repeat": r})
                print(json.dumps(runs[-1]), flush=True)
        paired = paired_layer_cost(bags, Path(tmp) / "paired", args.preset)
        print(json.dumps({k: v for k, v in paired.items() if k != "pairs"}), flush=True)
    result = {"command": "python -m bench.batch " + " ".join(argv if argv is not None else sys.argv[1:]),
              "bags": args.bags, "distinct": args.distinct, "frames": args.frames, "size": args.size,
              "preset": args.preset, "repeats": args.repeats, "machine": platform.platform(),
              "cores": os.cpu_count(), "runs": runs, "paired": paired,
              "summary": summarise(runs, args.repeats) if runs else None}
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    print(json.dumps(result["summary"], indent=1))
    print(json.dumps({k: v for k, v in paired.items() if k != "pairs"}, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
