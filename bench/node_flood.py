"""The node under input rates from camera-like to a flood, spun by rclpy's single- or multi-threaded executor.

    .venv/bin/python -m bench.node_flood [--rates 30 100 500] [--presets realtime quality] [--seconds 6]
                                         [--out bench/results/node_flood.json]

The node runs as its own process (as in bench.node_latency), once with ``SingleThreadedExecutor`` (what
``rclpy.spin`` in the node's main() uses) and once with ``MultiThreadedExecutor()`` (default thread count),
which is what a user composing several Python nodes into one process would likely pick. For each preset at
320x240 mono8 and each rate, frames are published open loop for ``--seconds``; reported: frames the node's
callback received per second, flows it published per second, and the mean solve time under that load
(from its /diagnostics) against the engine's solve time measured here just before (the
peer of the ratio). The machine is shared: compare the ratios, not absolute times.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path
from typing import Any

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor, SingleThreadedExecutor

from bench.node_latency import ProcessRig, frames
from flow_node.core.api import FlowEstimator
from flow_node.core.config import FlowConfig
from flow_node.ros.node import FlowNode, keep_freed_memory

EXECUTORS = ("single", "multi")
SIZE = (240, 320)


def serve(executor: str, args: list[str]) -> int:
    """The node's main() with the executor chosen: ``single`` (as rclpy.spin) or ``multi``."""
    keep_freed_memory()
    rclpy.init(args=args)
    node = FlowNode()
    ex = SingleThreadedExecutor() if executor == "single" else MultiThreadedExecutor()
    ex.add_node(node)
    try:
        ex.spin()
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    finally:
        ex.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


def run(preset: str, executor: str, rate: float, seconds: float) -> dict[str, Any]:
    f0, f1 = frames(*SIZE)
    engine = FlowEstimator(FlowConfig.preset(preset))
    engine.warmup()
    engine_s = min(engine.estimate(f0, f1).seconds for _ in range(3))
    rig = ProcessRig(preset, (sys.executable, "-m", "bench.node_flood", "--serve", executor))
    try:
        tp = rig.open_loop(f0, f1, seconds, rate)
    finally:
        rig.close()
    solve = tp["solver_busy_fraction"] * tp["seconds"] / tp["node_outputs"] if tp["node_outputs"] else None
    return {"preset": preset, "executor": executor, "rate_hz": rate, "width": SIZE[1], "height": SIZE[0],
            "backend": rig.backend, "engine_solve_s": engine_s, "node_solve_mean_s": solve,
            "solve_vs_engine_ratio": None if solve is None else solve / engine_s,
            "received_rate_hz": tp["received"] / tp["seconds"], "sent_rate_hz": tp["published"] / tp["seconds"],
            "flows_rate_hz": tp["node_outputs"] / tp["seconds"],
            "throughput": tp}


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if argv[:1] == ["--serve"]:
        return serve(argv[1], argv[2:])
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--rates", type=float, nargs="+", default=[30.0, 100.0, 500.0])
    ap.add_argument("--presets", nargs="+", default=["realtime", "quality"])
    ap.add_argument("--executors", nargs="+", choices=EXECUTORS, default=list(EXECUTORS))
    ap.add_argument("--seconds", type=float, default=6.0, help="open-loop publishing time per case")
    ap.add_argument("--out", default="bench/results/node_flood.json")
    args = ap.parse_args(argv)
    results = []
    for preset in args.presets:
        for rate in args.rates:
            for executor in args.executors:
                r = run(preset, executor, rate, args.seconds)
                results.append(r)
                solve = "no flow" if r["node_solve_mean_s"] is None else (
                    f"{r['node_solve_mean_s'] * 1e3:8.1f} ms (x{r['solve_vs_engine_ratio']:.2f})")
                print(f"{preset:9s} {executor:6s} {rate:5.0f} Hz {r['backend']}: sent {r['sent_rate_hz']:6.1f}/s"
                      f" | received {r['received_rate_hz']:6.1f}/s | flows {r['flows_rate_hz']:6.1f}/s"
                      f" | engine {r['engine_solve_s'] * 1e3:7.1f} ms | solve under load {solve}", flush=True)
    meta = {"command": "python -m bench.node_flood " + " ".join(argv), "python": platform.python_version(),
            "machine": platform.machine(), "cpus": os.cpu_count(),
            "date": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime())}
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps({"meta": meta, "results": results}, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
