"""CPU an idle embedded Dask cluster takes from the flow_bag process: milliseconds of CPU per second of wall
time of the one-worker cluster (a thread of this process: scheduler, worker and a connected client), with
Dask's default settings and with flow_node.bag.batch.QUIET_CLUSTER, alternating.

    .venv-bench/bin/python -m bench.idle_cluster --seconds 10 --rounds 3 --out bench/results/idle_cluster.json

What it measures is the bookkeeping the bag's thread shares the GIL with (docs/bags.md); the process's CPU
time (all its threads) over a sleep of ``--seconds``, the process otherwise idle.
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from pathlib import Path

from flow_node.bag import batch

from .common import machine, write_json


def idle_cpu(quiet: bool, seconds: float) -> float:
    """ms of CPU per s of wall time of this process while a one-worker embedded cluster and its client idle."""
    from distributed import Client

    saved = batch.QUIET_CLUSTER
    batch.QUIET_CLUSTER = saved if quiet else {}
    try:
        with batch.local_cluster(1) as cluster, Client(cluster):
            time.sleep(1.0)  # start-up done
            cpu, wall = time.process_time(), time.monotonic()
            time.sleep(seconds)
            return 1e3 * (time.process_time() - cpu) / (time.monotonic() - wall)
    finally:
        batch.QUIET_CLUSTER = saved


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seconds", type=float, default=10.0)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--out", type=Path, default=Path("bench/results/idle_cluster.json"))
    args = ap.parse_args()
    runs: dict[str, list[float]] = {"dask_defaults": [], "quiet": []}
    for k in range(args.rounds):
        for quiet in ((False, True) if k % 2 == 0 else (True, False)):
            runs["quiet" if quiet else "dask_defaults"].append(idle_cpu(quiet, args.seconds))
    result = {"command": "python -m bench.idle_cluster " + " ".join(sys.argv[1:]), "machine": machine(),
              "unit": "ms of CPU per s", "runs": runs, "medians": {k: statistics.median(v) for k, v in runs.items()}}
    write_json(args.out, result)
    print(result["medians"])


if __name__ == "__main__":
    main()
