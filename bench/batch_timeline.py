"""Where the fixed cost of a batch on Dask goes: a timeline of one batch per layout, from timestamps.

    .venv/bin/python -m bench.batch_timeline BAGS [--repeats 2] [--out bench/results/batch_timeline.json]

BAGS is a folder of bags (e.g. written by ``bench.batch``'s make_bags). Each run is a fresh interpreter
(in WORKER_ENV, as bench.batch runs them) that goes through the steps of ``run_batch`` and stamps each one
(seconds since the interpreter's first line): imports, cluster start, submission, first result, all results,
cluster close, batch report. Layouts: ``process-1`` (the embedded cluster as it was before: one worker
process started by Dask's nanny), ``thread-1`` (``local_cluster(1)``: a worker thread of this process),
``process-2`` (``local_cluster(2)``) and ``loop`` (``evaluate_bag`` in a plain loop: the peer). Every task
also stamps its start and end and reports its process's start time, so the worker's spawn, its imports and
its first (JIT cache loading) task show on the same clock. Layouts interleaved, order reversed each repeat.
"""

from __future__ import annotations

import time

T0 = time.time()  # noqa: E402 - first: the clock of every stamp

import argparse  # noqa: E402
import json  # noqa: E402
import os  # noqa: E402
import shutil  # noqa: E402
import statistics  # noqa: E402
import subprocess  # noqa: E402
import sys  # noqa: E402
from pathlib import Path  # noqa: E402
from typing import Any  # noqa: E402

REPO = Path(__file__).resolve().parent.parent
LAYOUTS = ("loop", "process-1", "thread-1", "process-2")


def stamped_task(job: Any) -> tuple[float, float, float, Any]:
    """evaluate_bag with the task's start and end and its process's start time (epoch seconds)."""
    import psutil

    from flow_node.bag.batch import evaluate_bag

    start = time.time()
    outcome = evaluate_bag(job)
    return start, time.time(), psutil.Process().create_time(), outcome


def one_run(layout: str, bags: str, out: str) -> dict[str, Any]:
    marks: list[tuple[str, float]] = []

    def mark(label: str) -> None:
        marks.append((label, time.time() - T0))

    from flow_node.bag.batch import WORKER_ENV, find_bags, local_cluster, make_jobs
    from flow_node.bag.results import EvalOptions
    from flow_node.core.config import FlowConfig

    mark("import flow_node.bag.batch")
    configs = [FlowConfig.preset("realtime")]
    jobs = make_jobs(find_bags([bags], exclude=out), Path(out), configs, EvalOptions(progress=False))
    Path(out).mkdir(parents=True)
    if layout == "loop":
        results = [stamped_task(job) for job in jobs]
        mark("all results")
    else:
        import dask
        from distributed import Client, LocalCluster, as_completed

        mark("import distributed")
        if layout == "process-1":
            with dask.config.set({"distributed.nanny.pre-spawn-environ": WORKER_ENV}):
                cluster = LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                       dashboard_address=":0")
        else:
            cluster = local_cluster(int(layout[-1]))
        client = Client(cluster)
        mark("cluster started, client connected")
        futures = [client.submit(stamped_task, job, pure=False) for job in jobs]
        results = []
        for fut in as_completed(futures):
            results.append(fut.result())
            if len(results) == 1:
                mark("first result")
        mark("all results")
        client.close()
        cluster.close()
        mark("cluster closed")
    from flow_node.bag.batch_report import write_batch_report

    mark("import batch_report (matplotlib)")
    write_batch_report([r[3] for r in results], Path(out), configs, 1.0, layout)
    mark("batch report written")
    results.sort(key=lambda r: r[0])
    tasks = [end - start for start, end, _, _ in results]
    return {"layout": layout, "marks": marks, "bags": len(results),
            "first_task_start": results[0][0] - T0, "first_task_seconds": tasks[0],
            "task_seconds_median": statistics.median(tasks), "task_seconds_sum": sum(tasks),
            "worker_processes_started_at": sorted({round(born - T0, 3) for _, _, born, _ in results})}


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("bags")
    p.add_argument("--repeats", type=int, default=2)
    p.add_argument("--out", default=str(REPO / "bench" / "results" / "batch_timeline.json"))
    p.add_argument("--one", nargs=2, metavar=("LAYOUT", "OUT"), help=argparse.SUPPRESS)
    args = p.parse_args(argv)
    if args.one:
        print(json.dumps(one_run(args.one[0], args.bags, args.one[1])))
        return 0
    from flow_node.bag.batch import WORKER_ENV

    env = os.environ | WORKER_ENV
    runs = []
    for r in range(args.repeats):
        for layout in LAYOUTS if r % 2 == 0 else LAYOUTS[::-1]:
            out = Path(args.out).with_suffix(".tmp")
            shutil.rmtree(out, ignore_errors=True)
            start = time.time()
            proc = subprocess.run([sys.executable, "-m", "bench.batch_timeline", args.bags, "--one", layout, str(out)],
                                  cwd=REPO, env=env, capture_output=True, text=True, check=True)
            run = json.loads(proc.stdout.strip().splitlines()[-1]) | {"process_seconds": time.time() - start,
                                                                        "repeat": r}
            shutil.rmtree(out, ignore_errors=True)
            runs.append(run)
            print(json.dumps(run), flush=True)
    result = {"command": "python -m bench.batch_timeline " + " ".join(argv if argv is not None else sys.argv[1:]),
              "load_average_at_end": os.getloadavg(), "runs": runs}
    Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
